#include "lobe/seg/postprocess.h"

#include "lobe/seg/edge_map.h"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace lobe::seg {
namespace {

using Index = std::ptrdiff_t;

//! A box of the input grid, [lo, hi) per axis.
struct Crop {
    std::array<int, 3> lo{}, hi{};
    int n(int a) const { return hi[static_cast<std::size_t>(a)] - lo[static_cast<std::size_t>(a)]; }
};

//! A 0/1 volume on a crop, x fastest.
struct Vol {
    int nx = 0, ny = 0, nz = 0;
    std::vector<std::uint8_t> v;
    std::size_t at(int i, int j, int k) const
    {
        return static_cast<std::size_t>(i) +
               static_cast<std::size_t>(nx) * (static_cast<std::size_t>(j) + static_cast<std::size_t>(ny) * static_cast<std::size_t>(k));
    }
    std::size_t plane() const { return static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny); }
    std::size_t count() const
    {
        std::size_t c = 0;
        for (auto x : v)
            c += x;
        return c;
    }
};

//! Keeps the largest 26-connected component of `m` (in place); returns the voxels removed.
std::size_t keep_largest(Vol& m)
{
    std::vector<std::int32_t> label(m.v.size(), 0);
    std::vector<std::size_t> sizes{0};
    std::vector<std::size_t> queue;
    for (std::size_t s = 0; s < m.v.size(); ++s) {
        if (!m.v[s] || label[s])
            continue;
        const auto id = static_cast<std::int32_t>(sizes.size());
        std::size_t size = 0;
        queue.assign(1, s);
        label[s] = id;
        while (!queue.empty()) {
            const std::size_t p = queue.back();
            queue.pop_back();
            ++size;
            const int i = static_cast<int>(p % static_cast<std::size_t>(m.nx));
            const int j = static_cast<int>((p / static_cast<std::size_t>(m.nx)) % static_cast<std::size_t>(m.ny));
            const int k = static_cast<int>(p / m.plane());
            for (int dk = -1; dk <= 1; ++dk)
                for (int dj = -1; dj <= 1; ++dj)
                    for (int di = -1; di <= 1; ++di) {
                        const int a = i + di, b = j + dj, c = k + dk;
                        if (a < 0 || b < 0 || c < 0 || a >= m.nx || b >= m.ny || c >= m.nz)
                            continue;
                        const std::size_t q = m.at(a, b, c);
                        if (m.v[q] && !label[q]) {
                            label[q] = id;
                            queue.push_back(q);
                        }
                    }
        }
        sizes.push_back(size);
    }
    if (sizes.size() <= 2)
        return 0;
    const auto best = static_cast<std::int32_t>(std::max_element(sizes.begin(), sizes.end()) - sizes.begin());
    std::size_t removed = 0;
    for (std::size_t s = 0; s < m.v.size(); ++s)
        if (m.v[s] && label[s] != best) {
            m.v[s] = 0;
            ++removed;
        }
    return removed;
}

//! Background voxels not 6-connected to the crop's border: the 3-D holes.
std::vector<std::uint8_t> holes_3d(const Vol& m)
{
    std::vector<std::uint8_t> outside(m.v.size(), 0);
    std::vector<std::size_t> queue;
    auto seed = [&](int i, int j, int k) {
        const std::size_t p = m.at(i, j, k);
        if (!m.v[p] && !outside[p]) {
            outside[p] = 1;
            queue.push_back(p);
        }
    };
    for (int k = 0; k < m.nz; ++k)
        for (int j = 0; j < m.ny; ++j)
            for (int i = 0; i < m.nx; ++i)
                if (i == 0 || j == 0 || k == 0 || i == m.nx - 1 || j == m.ny - 1 || k == m.nz - 1)
                    seed(i, j, k);
    while (!queue.empty()) {
        const std::size_t p = queue.back();
        queue.pop_back();
        const int i = static_cast<int>(p % static_cast<std::size_t>(m.nx));
        const int j = static_cast<int>((p / static_cast<std::size_t>(m.nx)) % static_cast<std::size_t>(m.ny));
        const int k = static_cast<int>(p / m.plane());
        if (i > 0) seed(i - 1, j, k);
        if (i < m.nx - 1) seed(i + 1, j, k);
        if (j > 0) seed(i, j - 1, k);
        if (j < m.ny - 1) seed(i, j + 1, k);
        if (k > 0) seed(i, j, k - 1);
        if (k < m.nz - 1) seed(i, j, k + 1);
    }
    std::vector<std::uint8_t> holes(m.v.size(), 0);
    for (std::size_t p = 0; p < m.v.size(); ++p)
        holes[p] = (!m.v[p] && !outside[p]) ? 1 : 0;
    return holes;
}

//! `bin` (0/255, CV_8U) with its holes filled: background not 4-connected to the border.
cv::Mat fill_holes_2d(const cv::Mat& bin)
{
    cv::Mat padded;
    cv::copyMakeBorder(bin, padded, 1, 1, 1, 1, cv::BORDER_CONSTANT, 0);
    cv::Mat flood = padded.clone();
    cv::floodFill(flood, cv::Point(0, 0), 255, nullptr, 0, 0, 4);
    // holes = pixels the flood did not reach and that are background
    cv::Mat holes = flood == 0;
    cv::Mat filled = padded | holes;
    return filled(cv::Rect(1, 1, bin.cols, bin.rows)).clone();
}

cv::Mat slice_mat(Vol& m, int k)
{
    return cv::Mat(m.ny, m.nx, CV_8U, m.v.data() + m.plane() * static_cast<std::size_t>(k));
}

//! Per-slice fill of the Omega concavities: regions that a closing of radius (rx, ry) pixels
//! turns into a hole, together with the bridge that closes them (see the docs).
std::size_t fill_concavities(Vol& m, int rx, int ry)
{
    const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * rx + 1, 2 * ry + 1));
    std::size_t added = 0;
    for (int k = 0; k < m.nz; ++k) {
        cv::Mat s = slice_mat(m, k);
        if (cv::countNonZero(s) == 0)
            continue;
        cv::Mat bin = s * 255, padded, closed;
        cv::copyMakeBorder(bin, padded, ry + 1, ry + 1, rx + 1, rx + 1, cv::BORDER_CONSTANT, 0);
        cv::morphologyEx(padded, closed, cv::MORPH_CLOSE, kernel, cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, 0);
        closed = closed(cv::Rect(rx + 1, ry + 1, m.nx, m.ny)).clone();
        const cv::Mat closed_filled = fill_holes_2d(closed);
        const cv::Mat hole = closed_filled & ~closed;
        if (cv::countNonZero(hole) == 0)
            continue;
        const cv::Mat candidate = closed_filled & ~bin;
        cv::Mat lab;
        const int n = cv::connectedComponents(candidate, lab, 8, CV_32S);
        std::vector<std::uint8_t> keep(static_cast<std::size_t>(n), 0);
        for (int j = 0; j < m.ny; ++j)
            for (int i = 0; i < m.nx; ++i)
                if (hole.at<std::uint8_t>(j, i))
                    keep[static_cast<std::size_t>(lab.at<std::int32_t>(j, i))] = 1;
        keep[0] = 0;
        for (int j = 0; j < m.ny; ++j)
            for (int i = 0; i < m.nx; ++i)
                if (keep[static_cast<std::size_t>(lab.at<std::int32_t>(j, i))] && !s.at<std::uint8_t>(j, i)) {
                    s.at<std::uint8_t>(j, i) = 1;
                    ++added;
                }
    }
    return added;
}

//! The level t with #(s > t) closest to `target`, from a 4096-bin histogram of s in (0, 1).
double volume_preserving_level(const std::vector<float>& s, std::size_t target)
{
    constexpr int kBins = 4096;
    std::vector<std::size_t> hist(kBins, 0);
    for (float x : s)
        if (x > 0.f)
            ++hist[static_cast<std::size_t>(std::min(kBins - 1, static_cast<int>(x * kBins)))];
    // Walk down from the top bin until the count above the bin's lower edge reaches the target.
    std::size_t above = 0;
    for (int b = kBins - 1; b >= 0; --b) {
        const std::size_t next = above + hist[static_cast<std::size_t>(b)];
        if (next >= target)
            // choose the edge whose count is closer to the target
            return (next - target < target - above) ? static_cast<double>(b) / kBins
                                                    : static_cast<double>(b + 1) / kBins;
        above = next;
    }
    return 0.0;
}

} // namespace

PostprocessResult postprocess_liver_full(const core::LabelImage3D& stacked, const PostprocessParams& params)
{
    const auto t0 = std::chrono::steady_clock::now();
    core::validate_geometry(stacked, "postprocess_liver: mask");
    if (stacked.data.size() != stacked.voxel_count())
        throw core::InvalidInputError("postprocess_liver: mask holds " + std::to_string(stacked.data.size()) +
                                      " values for " + std::to_string(stacked.voxel_count()) + " voxels");
    if (std::isnan(params.smoothing_mm) || std::isnan(params.concavity_closing_mm))
        throw core::InvalidInputError("postprocess_liver: smoothing_mm and concavity_closing_mm must not be NaN");

    PostprocessResult r;
    r.mask = core::LabelImage3D(stacked.geometry(), 0);
    // Bounding box of the mask.
    std::array<int, 3> lo{stacked.size[0], stacked.size[1], stacked.size[2]}, hi{-1, -1, -1};
    for (int k = 0; k < stacked.size[2]; ++k)
        for (int j = 0; j < stacked.size[1]; ++j)
            for (int i = 0; i < stacked.size[0]; ++i)
                if (stacked.data[stacked.index(i, j, k)]) {
                    ++r.voxels_in;
                    lo = {std::min(lo[0], i), std::min(lo[1], j), std::min(lo[2], k)};
                    hi = {std::max(hi[0], i), std::max(hi[1], j), std::max(hi[2], k)};
                }
    if (r.voxels_in == 0)
        return r;

    // Work on the box plus what the smoothing kernel (4 sigma) and the closing reach.
    const bool sliver = params.convention == LiverConvention::Sliver07;
    const double sigma = std::max(0.0, params.smoothing_mm);
    const double close_mm = sliver ? std::max(0.0, params.concavity_closing_mm) : 0.0;
    Crop crop;
    for (int a = 0; a < 3; ++a) {
        const auto u = static_cast<std::size_t>(a);
        const double reach = 4.0 * sigma + (a < 2 ? close_mm : 0.0);
        const int pad = static_cast<int>(std::ceil(reach / stacked.spacing[u])) + 2;
        crop.lo[u] = std::max(0, lo[u] - pad);
        crop.hi[u] = std::min(stacked.size[a], hi[u] + 1 + pad);
    }
    Vol m;
    m.nx = crop.n(0);
    m.ny = crop.n(1);
    m.nz = crop.n(2);
    m.v.assign(static_cast<std::size_t>(m.nx) * static_cast<std::size_t>(m.ny) * static_cast<std::size_t>(m.nz), 0);
    for (int k = 0; k < m.nz; ++k)
        for (int j = 0; j < m.ny; ++j)
            for (int i = 0; i < m.nx; ++i)
                m.v[m.at(i, j, k)] = stacked.data[stacked.index(i + crop.lo[0], j + crop.lo[1], k + crop.lo[2])] ? 1 : 0;

    if (params.keep_largest_component)
        r.removed_components = keep_largest(m);

    // Holes of the input, per slice (they contain the 3-D holes: a 4-connected in-plane path
    // to the outside is a 6-connected 3-D one). Sliver07 fills them; Parenchyma restores them.
    Vol holes = m;
    for (int k = 0; k < m.nz; ++k) {
        cv::Mat s = slice_mat(m, k), h = slice_mat(holes, k);
        const cv::Mat filled = fill_holes_2d(s * 255);
        h = (filled & ~(s * 255)) / 255;
        h.copyTo(slice_mat(holes, k));
    }
    {
        const std::vector<std::uint8_t> h3 = holes_3d(m);
        for (std::size_t p = 0; p < h3.size(); ++p)
            holes.v[p] = static_cast<std::uint8_t>(holes.v[p] | h3[p]);
    }
    Vol filled = m;
    if (!sliver || params.fill_holes)
        for (std::size_t p = 0; p < m.v.size(); ++p)
            if (holes.v[p]) {
                filled.v[p] = 1;
                ++r.filled_holes;
            }
    if (sliver && close_mm > 0) {
        const int rx = std::max(1, static_cast<int>(std::lround(close_mm / stacked.spacing[0])));
        const int ry = std::max(1, static_cast<int>(std::lround(close_mm / stacked.spacing[1])));
        r.filled_concavities = fill_concavities(filled, rx, ry);
    }
    if (!sliver)
        r.filled_holes = 0;

    // Smooth the filled mask and cut it at the volume-preserving level.
    Vol out = filled;
    if (sigma > 0) {
        core::ImageGeometry g;
        g.size = {m.nx, m.ny, m.nz};
        g.spacing = stacked.spacing;
        core::ImageF f(g);
        for (std::size_t p = 0; p < f.data.size(); ++p)
            f.data[p] = filled.v[p];
        const core::ImageF s = gaussian_smooth(f, sigma);
        const std::size_t target = filled.count();
        double t = params.preserve_volume ? volume_preserving_level(s.data, target) : 0.5;
        // Guard: a level far from 0.5 means a shape thinner than the kernel; do not let it grow
        // or vanish (documented).
        t = std::clamp(t, 0.25, 0.75);
        r.threshold = t;
        for (std::size_t p = 0; p < s.data.size(); ++p)
            out.v[p] = static_cast<double>(s.data[p]) > t ? 1 : 0;
        if (params.keep_largest_component)
            keep_largest(out);
        if (out.count() == 0) // smoothing erased a tiny mask: keep it unsmoothed rather than lose it
            out = filled;
    }
    if (!sliver)
        for (std::size_t p = 0; p < out.v.size(); ++p)
            if (holes.v[p])
                out.v[p] = 0;

    for (int k = 0; k < m.nz; ++k)
        for (int j = 0; j < m.ny; ++j)
            for (int i = 0; i < m.nx; ++i)
                r.mask.data[stacked.index(i + crop.lo[0], j + crop.lo[1], k + crop.lo[2])] = out.v[out.at(i, j, k)];
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return r;
}

core::LabelImage3D postprocess_liver(const core::LabelImage3D& stacked, const PostprocessParams& params)
{
    return postprocess_liver_full(stacked, params).mask;
}

} // namespace lobe::seg
