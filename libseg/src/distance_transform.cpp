#include "lobe/seg/distance_transform.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>
#include <vector>

// Method and conventions: docs/algorithms/distance_transform.md.
namespace lobe::seg {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

void check_image(const core::LabelImage3D& img, const char* what)
{
    if (img.data.size() != img.voxel_count())
        throw core::InvalidInputError(std::string(what) + ": the image holds " + std::to_string(img.data.size()) +
                                      " values for " + std::to_string(img.voxel_count()) + " voxels");
}

// Threads only pay off on images this large: each parallel region costs a barrier, and on a
// busy machine a barrier can wait for a whole time slice (the snake calls these on small images).
constexpr std::size_t kParallelVoxels = std::size_t(1) << 16;

// Per-thread buffers for one line; sized once for the longest line so that the line loops
// never allocate.
struct LineScratch {
    std::vector<float> site_in, site_out; // parabola heights (inf = no parabola)
    std::vector<float> env_in, env_out;   // envelopes at the voxel centres
    std::vector<int> v;                   // parabolas on the envelope
    std::vector<double> z;                // where they take over

    explicit LineScratch(int n)
    {
        const auto m = static_cast<std::size_t>(2 * n + 2); // half-voxel lattice plus the two grid faces
        site_in.resize(m);
        site_out.resize(m);
        env_in.resize(static_cast<std::size_t>(n));
        env_out.resize(static_cast<std::size_t>(n));
        v.resize(m);
        z.resize(m + 1);
    }
};

// Felzenszwalb & Huttenlocher's lower envelope: out[t] = min_q f[q] + w (x_t - q)^2 with
// x_t = first + step * t, over the sites q in [0, m) with finite f (inf where there is none).
// Sites are integer positions; w is the squared spacing of that lattice. Returns false (and
// leaves `out` alone) when no site is finite, so that the caller can skip empty lines.
bool lower_envelope(const float* f, int m, double w, int first, int step, int count, float* out, int* v, double* z)
{
    int k = -1;
    for (int q = 0; q < m; ++q) {
        if (f[q] == kInf)
            continue;
        const double fq = static_cast<double>(f[q]) + w * double(q) * double(q);
        if (k < 0) {
            k = 0;
            v[0] = q;
            z[0] = -std::numeric_limits<double>::infinity();
            z[1] = std::numeric_limits<double>::infinity();
            continue;
        }
        double s = 0;
        for (;;) {
            const int r = v[k];
            const double fr = static_cast<double>(f[r]) + w * double(r) * double(r);
            s = (fq - fr) / (2.0 * w * double(q - r));
            if (s > z[k])
                break;
            --k; // z[0] = -inf: the first parabola is never popped
        }
        ++k;
        v[k] = q;
        z[k] = s;
        z[k + 1] = std::numeric_limits<double>::infinity();
    }
    if (k < 0)
        return false;
    int j = 0;
    for (int t = 0; t < count; ++t) {
        const double x = double(first + step * t);
        while (z[j + 1] < x)
            ++j;
        const double d = x - double(v[j]);
        out[t] = static_cast<float>(static_cast<double>(f[v[j]]) + w * d * d);
    }
    return true;
}

// The lines of an image along `axis`: their count, and the first voxel and stride of line L.
struct Lines {
    std::size_t count = 0;
    std::size_t stride = 1;
    int length = 0;
    std::size_t nx = 0, nxy = 0;
    int axis = 0;

    Lines(const core::ImageGeometry& g, int a) : axis(a)
    {
        nx = static_cast<std::size_t>(g.size[0]);
        nxy = nx * static_cast<std::size_t>(g.size[1]);
        length = g.size[a];
        count = g.voxel_count() / static_cast<std::size_t>(length);
        stride = a == 0 ? 1 : a == 1 ? nx : nxy;
    }
    // For y and z, L = i + nx * (the other index): consecutive L are neighbours along x.
    std::size_t first(std::size_t L) const
    {
        if (axis == 0)
            return L * nx;
        if (axis == 1)
            return (L % nx) + (L / nx) * nxy; // L = i + nx * k
        return L;                             // L = i + nx * j
    }
};

// Lines along y or z gathered this many at a time: neighbours along x share cache lines, so a
// block turns each strided read into one cache line used 16 times instead of once.
constexpr std::size_t kBlock = 16;

// Runs work(line, mask_line) on every line along y or z (axis > 0), in place, in parallel;
// make_worker() gives each thread its own worker (and scratch). `mask` may be null.
template <class MakeWorker>
void for_each_line(const Lines& lines, float* d2, const std::uint8_t* mask, MakeWorker make_worker)
{
    const auto n = static_cast<std::size_t>(lines.length);
    const std::size_t nx = lines.nx, per_row = (nx + kBlock - 1) / kBlock;
    const auto groups = static_cast<long long>(lines.count / nx * per_row);
#pragma omp parallel if (lines.count * n >= kParallelVoxels)
    {
        auto work = make_worker();
        std::vector<float> buf(n * kBlock);
        std::vector<std::uint8_t> mbuf(mask ? n * kBlock : 0);
#pragma omp for schedule(static)
        for (long long G = 0; G < groups; ++G) {
            const auto g = static_cast<std::size_t>(G);
            const std::size_t i0 = g % per_row * kBlock, nb = std::min(kBlock, nx - i0);
            const std::size_t first = lines.first(g / per_row * nx + i0);
            for (std::size_t t = 0; t < n; ++t) {
                const std::size_t at = first + t * lines.stride;
                for (std::size_t l = 0; l < nb; ++l)
                    buf[l * n + t] = d2[at + l];
                if (mask)
                    for (std::size_t l = 0; l < nb; ++l)
                        mbuf[l * n + t] = mask[at + l];
            }
            for (std::size_t l = 0; l < nb; ++l)
                work(buf.data() + l * n, mask ? mbuf.data() + l * n : nullptr);
            for (std::size_t t = 0; t < n; ++t) {
                const std::size_t at = first + t * lines.stride;
                for (std::size_t l = 0; l < nb; ++l)
                    d2[at + l] = buf[l * n + t];
            }
        }
    }
}

// Squared distance [mm^2] along x to the nearest feature voxel centre of each row.
void row_pass_centres(const core::LabelImage3D& features, float* d2)
{
    const Lines lines(features, 0);
    const int n = lines.length;
    const double h2 = features.spacing[0] * features.spacing[0];
    const auto count = static_cast<long long>(lines.count);
#pragma omp parallel for schedule(static) if (lines.count * std::size_t(n) >= kParallelVoxels)
    for (long long L = 0; L < count; ++L) {
        const std::size_t b = lines.first(static_cast<std::size_t>(L));
        const std::uint8_t* f = features.data.data() + b;
        float* out = d2 + b;
        // Forward then backward scan for the index distance to the nearest feature.
        int last = -1;
        for (int i = 0; i < n; ++i) {
            if (f[i])
                last = i;
            out[i] = last < 0 ? kInf : static_cast<float>(h2 * double(i - last) * double(i - last));
        }
        last = -1;
        for (int i = n - 1; i >= 0; --i) {
            if (f[i])
                last = i;
            if (last >= 0)
                out[i] = std::min(out[i], static_cast<float>(h2 * double(last - i) * double(last - i)));
        }
    }
}

// One separable pass of the exact EDT along axis y or z: d2 <- min over the line of
// d2 + (h (p - q))^2.
void line_pass_centres(const core::ImageGeometry& g, int axis, float* d2)
{
    const Lines lines(g, axis);
    const int n = lines.length;
    const double w = g.spacing[axis] * g.spacing[axis];
    for_each_line(lines, d2, nullptr, [n, w] {
        return [n, w, s = LineScratch(n)](float* line, const std::uint8_t*) mutable {
            if (lower_envelope(line, n, w, 0, 1, n, s.env_in.data(), s.v.data(), s.z.data()))
                std::copy(s.env_in.begin(), s.env_in.end(), line);
        };
    });
}

// --- signed distance -------------------------------------------------------------------------
//
// phi is the exact signed distance from each voxel centre to the surface of the union of the
// inside voxels' boxes (each voxel a closed box of its spacing around its centre; the space
// outside the grid counts as outside, except across an axis one voxel long: a 2-D image is not
// a one-slice slab). Along each axis the zero level thus lies half a voxel
// outside the boundary voxels, and phi < 0 exactly at the mask.
//
// The nearest point of a union of boxes to a voxel centre has coordinates that are voxel centres
// or box faces, i.e. it lies on the lattice of half-voxel steps. The distance transform is
// therefore the exact EDT on that lattice, done separably; a lattice point halfway between two
// voxels along the axis being processed belongs to the union iff one of the two does, so the
// half-voxel sites take the smaller of their two neighbours' values and no upsampled image is
// ever stored. One float per voxel holds, for an inside voxel, the partial squared distance to
// the outside and, for an outside voxel, the one to the inside (its distance to its own class
// is 0 at every stage).

// Along x: squared distance to the nearest box of the other class (grid faces count as outside).
void row_pass_boxes(const core::LabelImage3D& mask, float* d2)
{
    const Lines lines(mask, 0);
    const int n = lines.length;
    const double h2 = mask.spacing[0] * mask.spacing[0];
    const auto count = static_cast<long long>(lines.count);
    // A box d voxels away is (d - 1/2) voxels away.
    const auto box = [h2](int d) { return static_cast<float>(h2 * (double(d) - 0.5) * (double(d) - 0.5)); };
#pragma omp parallel for schedule(static) if (lines.count * std::size_t(n) >= kParallelVoxels)
    for (long long L = 0; L < count; ++L) {
        const std::size_t b = lines.first(static_cast<std::size_t>(L));
        const std::uint8_t* m = mask.data.data() + b;
        float* out = d2 + b;
        // The faces before voxel 0 and after voxel n-1 are outside, unless the image is flat
        // along x (one voxel thick: a lower-dimensional image has no faces there).
        constexpr int kNone = std::numeric_limits<int>::min();
        int last_in = kNone, last_out = n > 1 ? -1 : kNone;
        for (int i = 0; i < n; ++i) {
            if (m[i]) {
                last_in = i;
                out[i] = last_out == kNone ? kInf : box(i - last_out);
            } else {
                last_out = i;
                out[i] = last_in == kNone ? kInf : box(i - last_in);
            }
        }
        last_in = kNone;
        last_out = n > 1 ? n : kNone;
        for (int i = n - 1; i >= 0; --i) {
            if (m[i]) {
                last_in = i;
                if (last_out != kNone)
                    out[i] = std::min(out[i], box(last_out - i));
            } else {
                last_out = i;
                if (last_in != kNone)
                    out[i] = std::min(out[i], box(last_in - i));
            }
        }
    }
}

// Along y or z, on the half-voxel lattice: site u = 2q + 1 is voxel q, u = 2q + 2 the face
// between voxels q and q+1, u = 0 and u = 2n the grid faces (outside).
void line_pass_boxes(const core::LabelImage3D& mask, int axis, float* d2)
{
    const Lines lines(mask, axis);
    const int n = lines.length;
    const int m = 2 * n + 1;
    const double half = 0.5 * mask.spacing[axis];
    const double w = half * half;
    for_each_line(lines, d2, mask.data.data(), [n, m, w] {
        return [n, m, w, s = LineScratch(n)](float* line, const std::uint8_t* in) mutable {
            // Partial distances to the inside (for outside voxels) and to the outside (for
            // inside voxels); a voxel's distance to its own class is 0.
            float* fin = s.site_in.data();
            float* fout = s.site_out.data();
            int inside = 0;
            for (int t = 0; t < n; ++t) {
                const bool is_in = in[t] != 0;
                inside += is_in;
                fin[2 * t + 1] = is_in ? 0.f : line[t];
                fout[2 * t + 1] = is_in ? line[t] : 0.f;
            }
            fin[0] = fin[2 * n] = kInf; // never nearer than voxel 0 or n-1 themselves
            fout[0] = fout[2 * n] = 0.f;
            for (int t = 1; t < n; ++t) {
                fin[2 * t] = std::min(fin[2 * t - 1], fin[2 * t + 1]);
                fout[2 * t] = std::min(fout[2 * t - 1], fout[2 * t + 1]);
            }
            // fout always has a finite site (the grid faces); fin has none when neither this line
            // nor any line crossing it earlier met the inside.
            if (inside < n && !lower_envelope(fin, m, w, 1, 2, n, s.env_in.data(), s.v.data(), s.z.data()))
                std::fill(s.env_in.begin(), s.env_in.end(), kInf);
            if (inside > 0)
                lower_envelope(fout, m, w, 1, 2, n, s.env_out.data(), s.v.data(), s.z.data());
            for (int t = 0; t < n; ++t)
                line[t] = in[t] ? s.env_out[static_cast<std::size_t>(t)] : s.env_in[static_cast<std::size_t>(t)];
        };
    });
}

} // namespace

core::ImageF euclidean_distance(const core::LabelImage3D& features)
{
    check_image(features, "euclidean_distance");
    core::ImageF d(features.geometry(), kInf); // squared distances until the last step
    if (d.data.empty())
        return d;
    row_pass_centres(features, d.data.data());
    for (int a = 1; a < 3; ++a)
        if (features.size[a] > 1)
            line_pass_centres(features, a, d.data.data());
    const auto n = static_cast<long long>(d.data.size());
    float* p = d.data.data();
#pragma omp parallel for schedule(static) if (std::size_t(n) >= kParallelVoxels)
    for (long long i = 0; i < n; ++i)
        p[i] = std::sqrt(p[i]);
    return d;
}

core::ImageF signed_distance(const core::LabelImage3D& mask)
{
    check_image(mask, "signed_distance");
    core::ImageF phi(mask.geometry(), kInf);
    if (phi.data.empty())
        return phi;
    row_pass_boxes(mask, phi.data.data());
    for (int a = 1; a < 3; ++a)
        if (mask.size[a] > 1)
            line_pass_boxes(mask, a, phi.data.data());
    const auto n = static_cast<long long>(phi.data.size());
    float* p = phi.data.data();
    const std::uint8_t* m = mask.data.data();
#pragma omp parallel for schedule(static) if (std::size_t(n) >= kParallelVoxels)
    for (long long i = 0; i < n; ++i)
        p[i] = m[i] ? -std::sqrt(p[i]) : std::sqrt(p[i]);
    return phi;
}

core::Image3D<std::int32_t> chessboard_distance(const core::LabelImage3D& features)
{
    check_image(features, "chessboard_distance");
    core::Image3D<std::int32_t> out(features.geometry(), -1);
    if (out.data.empty() || std::none_of(features.data.begin(), features.data.end(), [](std::uint8_t v) { return v; }))
        return out;

    // A padded copy (one voxel of "far" around every axis longer than one voxel) lets the passes
    // read neighbours without bounds checks.
    std::array<int, 3> pad{}, ps{};
    for (int a = 0; a < 3; ++a) {
        pad[a] = features.size[a] > 1 ? 1 : 0;
        ps[a] = features.size[a] + 2 * pad[a];
    }
    const auto sx = static_cast<std::ptrdiff_t>(ps[0]);
    const auto sxy = sx * ps[1];
    constexpr std::int32_t kFar = std::numeric_limits<std::int32_t>::max() / 2;
    std::vector<std::int32_t> d(static_cast<std::size_t>(sxy) * static_cast<std::size_t>(ps[2]), kFar);
    const auto at = [&](int i, int j, int k) {
        return static_cast<std::size_t>(i + pad[0] + sx * (j + pad[1]) + sxy * (k + pad[2]));
    };
    for (int k = 0; k < features.size[2]; ++k)
        for (int j = 0; j < features.size[1]; ++j)
            for (int i = 0; i < features.size[0]; ++i)
                if (features.at(i, j, k))
                    d[at(i, j, k)] = 0;

    // The half of the 26- (or 8-) neighbourhood that precedes a voxel in raster order; the
    // backward pass uses its mirror. With unit weights the two passes are exact for L-infinity.
    std::vector<std::ptrdiff_t> before;
    for (int dk = -pad[2]; dk <= 0; ++dk)
        for (int dj = -pad[1]; dj <= pad[1]; ++dj)
            for (int di = -pad[0]; di <= pad[0]; ++di) {
                const std::ptrdiff_t o = di + sx * dj + sxy * dk;
                if (o < 0)
                    before.push_back(o);
            }
    const auto relax = [&](std::size_t c, std::ptrdiff_t sign) {
        std::int32_t best = d[c];
        for (const std::ptrdiff_t o : before)
            best = std::min(best, d[static_cast<std::size_t>(static_cast<std::ptrdiff_t>(c) + sign * o)] + 1);
        d[c] = best;
    };
    for (int k = 0; k < features.size[2]; ++k)
        for (int j = 0; j < features.size[1]; ++j)
            for (int i = 0; i < features.size[0]; ++i)
                relax(at(i, j, k), 1);
    for (int k = features.size[2] - 1; k >= 0; --k)
        for (int j = features.size[1] - 1; j >= 0; --j)
            for (int i = features.size[0] - 1; i >= 0; --i)
                relax(at(i, j, k), -1);

    for (int k = 0; k < features.size[2]; ++k)
        for (int j = 0; j < features.size[1]; ++j)
            for (int i = 0; i < features.size[0]; ++i)
                out.at(i, j, k) = d[at(i, j, k)];
    return out;
}

} // namespace lobe::seg
