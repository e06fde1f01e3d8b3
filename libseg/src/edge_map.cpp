#include "lobe/seg/edge_map.h"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace lobe::seg {
namespace {

using Index = std::ptrdiff_t;

//! Loops over fewer voxels run on one thread. These passes are light (a few ns per voxel, a
//! 512 x 512 slice in ~0.1-1 ms), so a second thread saves little there, while each fork/join
//! waits for the slower thread: on a busy machine a descheduled helper made edge_map on 512 x 512
//! take ~50 ms instead of 1.5 ms. Volumes (>= 2 slices of 512 x 512) are still parallel.
constexpr Index kParallelMin = Index(1) << 19;

void check_image(const core::ImageGeometry& g, std::size_t data_size, const std::string& what)
{
    core::validate_geometry(g, what);
    if (data_size != g.voxel_count())
        throw core::InvalidInputError(what + ": holds " + std::to_string(data_size) + " values for " +
                                      std::to_string(g.voxel_count()) + " voxels");
}

//! Half-sample mirror (… b a | a b …), the index map of cv::BORDER_REFLECT, for any offset:
//! a symmetric kernel on this extension keeps the image's sum, so smoothing conserves mass.
Index reflect(Index p, Index n)
{
    if (n == 1)
        return 0;
    const Index period = 2 * n;
    p %= period;
    if (p < 0)
        p += period;
    return p < n ? p : period - 1 - p;
}

//! Sampled, normalised Gaussian of σ voxels truncated at 4σ (tail mass < 1e-4).
std::vector<float> gaussian_kernel(double sigma_vox)
{
    const int r = std::max(1, static_cast<int>(std::ceil(4.0 * sigma_vox)));
    std::vector<double> w(static_cast<std::size_t>(2 * r + 1));
    double sum = 0.0;
    for (int t = -r; t <= r; ++t) {
        const double v = std::exp(-0.5 * (t * t) / (sigma_vox * sigma_vox));
        w[static_cast<std::size_t>(t + r)] = v;
        sum += v;
    }
    std::vector<float> k(w.size());
    for (std::size_t t = 0; t < w.size(); ++t)
        k[t] = static_cast<float>(w[t] / sum);
    return k;
}

//! First index of a non-finite value, or -1.
Index first_non_finite(const core::BigVector<float>& d, std::size_t& count)
{
    Index first = std::numeric_limits<Index>::max();
    std::size_t n_bad = 0;
    const Index n = static_cast<Index>(d.size());
#pragma omp parallel for if (n > kParallelMin) schedule(static) reduction(min : first) reduction(+ : n_bad)
    for (Index i = 0; i < n; ++i)
        if (!std::isfinite(d[static_cast<std::size_t>(i)])) {
            ++n_bad;
            first = std::min(first, i);
        }
    count = n_bad;
    return n_bad ? first : -1;
}

//! The value at a rank (0-based, ascending) among the values of `v` that `keep` counts, exactly
//! the one nth_element over them would give: a histogram over [0, vmax] finds the bin holding
//! that rank, then nth_element sorts only that bin, so the cost is O(n) with no copy of the image
//! (a full nth_element on a 512 x 512 slice took 2 ms, as long as CDSG's band field). The counted
//! values must lie in [0, vmax], vmax > 0; `rank_of(n)` gives the rank from their count n > 0.
//! Returns 0 when nothing is counted.
template <class V, class Keep, class RankOf>
float select_rank(const V& v, float vmax, Keep keep, RankOf rank_of)
{
    constexpr int kBins = 4096;
    const float to_bin = static_cast<float>(kBins) / vmax;
    auto bin_of = [&](float x) { return std::min(kBins - 1, static_cast<int>(x * to_bin)); };
    std::vector<std::size_t> hist(kBins, 0);
    const Index n = static_cast<Index>(v.size());
#pragma omp parallel if (n > kParallelMin)
    {
        std::vector<std::size_t> local(kBins, 0);
#pragma omp for schedule(static) nowait
        for (Index i = 0; i < n; ++i) {
            const float x = v[static_cast<std::size_t>(i)];
            if (keep(x))
                ++local[static_cast<std::size_t>(bin_of(x))];
        }
#pragma omp critical
        for (int b = 0; b < kBins; ++b)
            hist[static_cast<std::size_t>(b)] += local[static_cast<std::size_t>(b)];
    }
    std::size_t counted = 0;
    for (std::size_t h : hist)
        counted += h;
    if (counted == 0)
        return 0.f;
    const std::size_t rank = rank_of(counted);
    std::size_t below = 0;
    int b = 0;
    for (; b < kBins; ++b) {
        if (below + hist[static_cast<std::size_t>(b)] > rank)
            break;
        below += hist[static_cast<std::size_t>(b)];
    }
    std::vector<float> in_bin;
    in_bin.reserve(hist[static_cast<std::size_t>(b)]);
    for (float x : v)
        if (keep(x) && bin_of(x) == b)
            in_bin.push_back(x);
    const auto nth = in_bin.begin() + static_cast<Index>(rank - below);
    std::nth_element(in_bin.begin(), nth, in_bin.end());
    return *nth;
}

//! The 99.9th percentile of the non-zero values of `v` (all >= 0, max `vmax` > 0), exactly.
float robust_max(const core::BigVector<float>& v, float vmax)
{
    return select_rank(v, vmax, [](float x) { return x > 0.f; }, [](std::size_t nonzero) {
        return static_cast<std::size_t>(std::ceil(0.999 * static_cast<double>(nonzero))) - 1;
    });
}

} // namespace

core::ImageF apply_window(const core::ImageF& image, const IntensityWindow& window)
{
    check_image(image, image.data.size(), "apply_window: image");
    if (!std::isfinite(window.level) || !std::isfinite(window.width))
        throw core::InvalidInputError("apply_window: the window level and width must be finite");
    core::ImageF out = image;
    if (window.width <= 0.0)
        return out; // documented in EdgeMapParams: a non-positive width means "already in [0,1]"
    const double lo = window.level - 0.5 * window.width;
    const double inv = 1.0 / window.width;
    const Index n = static_cast<Index>(out.data.size());
#pragma omp parallel for if (n > kParallelMin) schedule(static)
    for (Index i = 0; i < n; ++i) {
        float& v = out.data[static_cast<std::size_t>(i)];
        const double t = (static_cast<double>(v) - lo) * inv;
        // NaN stays NaN (neither comparison holds): edge_map rejects it with a message.
        v = t < 0.0 ? 0.f : (t > 1.0 ? 1.f : static_cast<float>(t));
    }
    return out;
}

core::ImageF gaussian_smooth(const core::ImageF& image, double sigma_mm)
{
    check_image(image, image.data.size(), "gaussian_smooth: image");
    if (std::isnan(sigma_mm))
        throw core::InvalidInputError("gaussian_smooth: sigma is NaN");
    if (sigma_mm <= 0.0)
        return image;
    const int nx = image.size[0], ny = image.size[1], nz = image.size[2];
    const std::size_t slice = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);
    core::ImageF out(image.geometry());

    // In-plane: OpenCV's separable filter is vectorised and handles the mirrored border.
    const double sx = sigma_mm / image.spacing[0], sy = sigma_mm / image.spacing[1];
    const int rx = std::max(1, static_cast<int>(std::ceil(4.0 * sx)));
    const int ry = std::max(1, static_cast<int>(std::ceil(4.0 * sy)));
    for (int k = 0; k < nz; ++k) {
        // cv::Mat wraps the slices without copying; GaussianBlur does not write to its input.
        const cv::Mat src(ny, nx, CV_32F, const_cast<float*>(image.data.data() + slice * static_cast<std::size_t>(k)));
        cv::Mat dst(ny, nx, CV_32F, out.data.data() + slice * static_cast<std::size_t>(k));
        cv::GaussianBlur(src, dst, cv::Size(2 * rx + 1, 2 * ry + 1), sx, sy, cv::BORDER_REFLECT);
    }
    if (nz == 1)
        return out; // a 2-D image is smoothed in-plane only

    // Along z: one output row is a weighted sum of whole input rows, so the inner loop runs
    // over contiguous x and vectorises (a per-column gather would stride by a slice).
    const std::vector<float> w = gaussian_kernel(sigma_mm / image.spacing[2]);
    const int rz = static_cast<int>(w.size() / 2);
    const core::ImageF in_plane = out;
    const Index rows = static_cast<Index>(ny) * nz;
#pragma omp parallel for if (rows * nx > kParallelMin) schedule(static)
    for (Index row = 0; row < rows; ++row) {
        const Index j = row % ny, k = row / ny;
        float* dst = out.data.data() + static_cast<std::size_t>(k) * slice + static_cast<std::size_t>(j * nx);
        std::fill(dst, dst + nx, 0.f);
        for (int t = -rz; t <= rz; ++t) {
            const Index kk = reflect(k + t, nz);
            const float* src =
                in_plane.data.data() + static_cast<std::size_t>(kk) * slice + static_cast<std::size_t>(j * nx);
            const float wt = w[static_cast<std::size_t>(t + rz)];
            for (int i = 0; i < nx; ++i)
                dst[i] += wt * src[i];
        }
    }
    return out;
}

VectorField gradient(const core::ImageF& image)
{
    check_image(image, image.data.size(), "gradient: image");
    VectorField g(image.geometry());
    const Index nx = image.size[0], ny = image.size[1], nz = image.size[2];
    const Index stride[3] = {1, nx, nx * ny};
    const Index n[3] = {nx, ny, nz};
    const float* f = image.data.data();
    const Index rows = ny * nz;
#pragma omp parallel for if (rows * nx > kParallelMin) schedule(static)
    for (Index row = 0; row < rows; ++row) {
        const Index j = row % ny, k = row / ny;
        const Index base = row * nx;
        const Index pos[3] = {0, j, k};
        for (int a = 0; a < 3; ++a) {
            float* out = g.c[static_cast<std::size_t>(a)].data.data() + base;
            if (n[a] == 1)
                continue; // a flat axis has no derivative (stays zero)
            const float inv_h = static_cast<float>(1.0 / image.spacing[static_cast<std::size_t>(a)]);
            const float inv_2h = 0.5f * inv_h;
            const Index s = stride[a];
            const float* c = f + base;
            if (a == 0) {
                out[0] = (c[1] - c[0]) * inv_h;
                for (Index i = 1; i < nx - 1; ++i)
                    out[i] = (c[i + 1] - c[i - 1]) * inv_2h;
                out[nx - 1] = (c[nx - 1] - c[nx - 2]) * inv_h;
                continue;
            }
            // Along y or z the whole row shares one stencil: one-sided on the first/last row.
            const Index p = pos[a];
            const float* lo = p > 0 ? c - s : c;
            const float* hi = p < n[a] - 1 ? c + s : c;
            const float scale = (p > 0 && p < n[a] - 1) ? inv_2h : inv_h;
            for (Index i = 0; i < nx; ++i)
                out[i] = (hi[i] - lo[i]) * scale;
        }
    }
    return g;
}

core::ImageF magnitude(const VectorField& v)
{
    check_image(v.c[0], v.c[0].data.size(), "magnitude: vector field");
    for (int a = 1; a < 3; ++a)
        if (v.c[static_cast<std::size_t>(a)].data.size() != v.c[0].data.size())
            throw core::InvalidInputError("magnitude: the vector field's components have different sizes");
    core::ImageF out(v.geometry());
    const Index n = static_cast<Index>(out.data.size());
    const float *x = v.c[0].data.data(), *y = v.c[1].data.data(), *z = v.c[2].data.data();
#pragma omp parallel for if (n > kParallelMin) schedule(static)
    for (Index i = 0; i < n; ++i)
        out.data[static_cast<std::size_t>(i)] = std::sqrt(x[i] * x[i] + y[i] * y[i] + z[i] * z[i]);
    return out;
}

EdgeMapResult edge_map(const core::ImageF& image, const EdgeMapParams& params)
{
    check_image(image, image.data.size(), "edge_map: image");
    if (!(params.stopping_k > 0.0) || !std::isfinite(params.stopping_k))
        throw core::InvalidInputError("edge_map: stopping_k must be finite and positive, got " +
                                      std::to_string(params.stopping_k));
    if (!std::isfinite(params.sigma_mm))
        throw core::InvalidInputError("edge_map: sigma_mm must be finite");
    std::size_t bad = 0;
    const Index first = first_non_finite(image.data, bad);
    if (first >= 0) {
        const Index nx = image.size[0], ny = image.size[1];
        throw core::InvalidInputError("edge_map: the image has " + std::to_string(bad) +
                                      " non-finite values (NaN or infinity), the first at voxel (" +
                                      std::to_string(first % nx) + ", " + std::to_string((first / nx) % ny) + ", " +
                                      std::to_string(first / (nx * ny)) + ")");
    }

    EdgeMapResult r;
    r.intensity = gaussian_smooth(apply_window(image, params.window), params.sigma_mm);
    r.gradient_magnitude = magnitude(gradient(r.intensity));

    const auto& gm = r.gradient_magnitude.data;
    float gmax = 0.f;
    const Index n = static_cast<Index>(gm.size());
#pragma omp parallel for if (n > kParallelMin) schedule(static) reduction(max : gmax)
    for (Index i = 0; i < n; ++i)
        gmax = std::max(gmax, gm[static_cast<std::size_t>(i)]);
    // Robust max: the 99.9th percentile of the non-zero magnitudes, so a handful of extreme
    // voxels (e.g. a metal streak when the window is off) cannot squash every other edge. Zeros
    // are left out because in clean images flat voxels are the majority and would pull the
    // percentile down to the weakest edges. Above it, f saturates at 1.
    float scale = gmax > 0.f ? robust_max(gm, gmax) : 0.f;
    if (!(scale > 0.f))
        scale = 1.f; // flat image: f = 0, and f = min(|∇I| / scale, 1) still holds
    r.scale = static_cast<double>(scale);

    r.edge = core::ImageF(image.geometry());
    r.stopping = core::ImageF(image.geometry());
    const float inv_scale = 1.f / scale;
    const float inv_k = static_cast<float>(1.0 / params.stopping_k);
#pragma omp parallel for if (n > kParallelMin) schedule(static)
    for (Index i = 0; i < n; ++i) {
        const auto u = static_cast<std::size_t>(i);
        r.edge.data[u] = std::min(1.f, gm[u] * inv_scale);
        const float q = gm[u] * inv_k;
        r.stopping.data[u] = 1.f / (1.f + q * q);
    }
    return r;
}

core::LabelImage3D binary_edges(const core::ImageF& edge, const BinaryEdgeParams& params)
{
    check_image(edge, edge.data.size(), "binary_edges: edge map");
    if (!std::isfinite(params.low) || !std::isfinite(params.high) || params.low > params.high)
        throw core::InvalidInputError("binary_edges: need finite thresholds with low <= high, got low = " +
                                      std::to_string(params.low) + ", high = " + std::to_string(params.high));
    const int nx = edge.size[0], ny = edge.size[1], nz = edge.size[2];
    const auto low = static_cast<float>(params.low), high = static_cast<float>(params.high);
    core::LabelImage3D out(edge.geometry(), 0);
    const Index n = static_cast<Index>(edge.data.size());

    // Seeds: strong voxels. 2 marks "weak candidate not yet reached" so the flood fill needs
    // no second image; the candidates left at 2 are dropped at the end.
    std::vector<Index> stack;
#pragma omp parallel for if (n > kParallelMin) schedule(static)
    for (Index i = 0; i < n; ++i) {
        const float f = edge.data[static_cast<std::size_t>(i)];
        out.data[static_cast<std::size_t>(i)] = f >= high ? 1 : (f >= low ? 2 : 0);
    }
    for (Index i = 0; i < n; ++i)
        if (out.data[static_cast<std::size_t>(i)] == 1)
            stack.push_back(i);

    // Flood fill over 26 neighbours; with nz == 1 the bounds check leaves the 8 in-plane ones.
    while (!stack.empty()) {
        const Index p = stack.back();
        stack.pop_back();
        const int i = static_cast<int>(p % nx), j = static_cast<int>((p / nx) % ny),
                  k = static_cast<int>(p / (Index(nx) * ny));
        for (int dk = -1; dk <= 1; ++dk)
            for (int dj = -1; dj <= 1; ++dj)
                for (int di = -1; di <= 1; ++di) {
                    const int a = i + di, b = j + dj, c = k + dk;
                    if (a < 0 || b < 0 || c < 0 || a >= nx || b >= ny || c >= nz)
                        continue;
                    const std::size_t q = edge.index(a, b, c);
                    if (out.data[q] == 2) {
                        out.data[q] = 1;
                        stack.push_back(static_cast<Index>(q));
                    }
                }
    }
#pragma omp parallel for if (n > kParallelMin) schedule(static)
    for (Index i = 0; i < n; ++i) {
        auto& v = out.data[static_cast<std::size_t>(i)];
        if (v == 2)
            v = 0;
    }
    return out;
}

core::ImageF energy_competition(const core::ImageF& edge, const core::LabelImage3D& aoi, float weight)
{
    check_image(edge, edge.data.size(), "energy_competition: edge map");
    check_image(aoi, aoi.data.size(), "energy_competition: area of interest");
    if (!core::same_grid(edge, aoi))
        throw core::InvalidInputError(
            "energy_competition: the edge map and the area of interest are on different grids");
    // G in [0, 1] (thesis: 1, 0.3, 0.2) keeps f' in [0, 1], which GGVF's K assumes.
    if (!std::isfinite(weight) || weight < 0.f || weight > 1.f)
        throw core::InvalidInputError("energy_competition: the weight G must be in [0, 1], got " +
                                      std::to_string(weight));
    core::ImageF out = edge;
    const Index n = static_cast<Index>(out.data.size());
#pragma omp parallel for if (n > kParallelMin) schedule(static)
    for (Index i = 0; i < n; ++i)
        if (aoi.data[static_cast<std::size_t>(i)] == 0)
            out.data[static_cast<std::size_t>(i)] *= weight;
    return out;
}

BinaryEdgeParams noise_adapted(const core::ImageF& f, const BinaryEdgeParams& base, double noise_factor)
{
    // The median: element size/2 of the sorted values (the upper one of an even count).
    float vmax = 0.f;
    bool in_range = true;
    for (float x : f.data) {
        in_range = in_range && x >= 0.f && std::isfinite(x);
        vmax = std::max(vmax, x);
    }
    double median = 0.0; // also for no values, or all zero
    if (!in_range) {     // negative or non-finite values: sort
        std::vector<float> v(f.data.begin(), f.data.end());
        const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
        std::nth_element(v.begin(), mid, v.end());
        median = *mid;
    } else if (vmax > 0.f) {
        median = select_rank(f.data, vmax, [](float) { return true; }, [](std::size_t n) { return n / 2; });
    }
    BinaryEdgeParams p = base;
    p.low = std::max(base.low, noise_factor * median);
    p.high = std::max(base.high, 2.0 * noise_factor * median);
    p.high = std::max(p.high, p.low);
    return p;
}

} // namespace lobe::seg
