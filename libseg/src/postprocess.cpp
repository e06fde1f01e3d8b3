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
//! Labels runs of foreground along x, not voxels: a liver-sized mask has ~10^6 voxels but ~10^5
//! runs, and a run touches a run of one of its four earlier neighbour rows (26-connectivity)
//! when their x ranges overlap after widening by one. Ties go to the component met first in
//! raster order.
std::size_t keep_largest(Vol& m)
{
    struct Run {
        int x0, x1; // [x0, x1]
        std::size_t row;
    };
    const std::size_t rows = static_cast<std::size_t>(m.ny) * static_cast<std::size_t>(m.nz);
    std::vector<Run> runs;
    std::vector<std::size_t> first(rows + 1, 0); // runs of row r: [first[r], first[r + 1])
    for (std::size_t r = 0; r < rows; ++r) {
        first[r] = runs.size();
        const std::uint8_t* line = m.v.data() + r * static_cast<std::size_t>(m.nx);
        for (int i = 0; i < m.nx;) {
            if (!line[i]) {
                ++i;
                continue;
            }
            const int x0 = i;
            while (i < m.nx && line[i])
                ++i;
            runs.push_back({x0, i - 1, r});
        }
    }
    first[rows] = runs.size();
    if (runs.empty())
        return 0;

    std::vector<std::size_t> parent(runs.size());
    for (std::size_t a = 0; a < parent.size(); ++a)
        parent[a] = a;
    auto find = [&](std::size_t a) {
        while (parent[a] != a)
            a = parent[a] = parent[parent[a]];
        return a;
    };
    auto unite = [&](std::size_t a, std::size_t b) {
        a = find(a);
        b = find(b);
        if (a != b)
            parent[std::max(a, b)] = std::min(a, b); // the root is the earliest run
    };
    // Union the runs of row r with those of an earlier row q (two pointers over sorted runs).
    auto join_rows = [&](std::size_t r, std::size_t q) {
        std::size_t a = first[r], b = first[q];
        while (a < first[r + 1] && b < first[q + 1]) {
            if (runs[a].x0 <= runs[b].x1 + 1 && runs[b].x0 <= runs[a].x1 + 1)
                unite(a, b);
            if (runs[a].x1 < runs[b].x1)
                ++a;
            else
                ++b;
        }
    };
    for (int k = 0; k < m.nz; ++k)
        for (int j = 0; j < m.ny; ++j) {
            const std::size_t r = static_cast<std::size_t>(j) + static_cast<std::size_t>(m.ny) * static_cast<std::size_t>(k);
            if (first[r] == first[r + 1])
                continue;
            if (j > 0)
                join_rows(r, r - 1);
            if (k > 0)
                for (int dj = -1; dj <= 1; ++dj)
                    if (j + dj >= 0 && j + dj < m.ny)
                        join_rows(r, r - static_cast<std::size_t>(m.ny) + static_cast<std::size_t>(static_cast<std::ptrdiff_t>(dj)));
        }
    std::vector<std::size_t> size(runs.size(), 0);
    std::size_t components = 0;
    for (std::size_t a = 0; a < runs.size(); ++a) {
        const std::size_t root = find(a);
        components += root == a;
        size[root] += static_cast<std::size_t>(runs[a].x1 - runs[a].x0 + 1);
    }
    if (components <= 1)
        return 0;
    // Roots are each component's earliest run, so scanning roots in order breaks ties in raster order.
    std::size_t best = 0;
    for (std::size_t a = 1; a < runs.size(); ++a)
        if (parent[a] == a && size[a] > size[best])
            best = a;
    std::size_t removed = 0;
    for (std::size_t a = 0; a < runs.size(); ++a)
        if (find(a) != best) {
            std::uint8_t* line = m.v.data() + runs[a].row * static_cast<std::size_t>(m.nx);
            std::fill(line + runs[a].x0, line + runs[a].x1 + 1, std::uint8_t{0});
            removed += static_cast<std::size_t>(runs[a].x1 - runs[a].x0 + 1);
        }
    return removed;
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
double volume_preserving_level(const core::BigVector<float>& s, std::size_t target)
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
    if (r.voxels_in == 0) {
        r.mask = core::LabelImage3D(stacked.geometry(), 0);
        return r;
    }

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

    // Holes of the input, per slice. They contain the 3-D holes (background not 6-connected to
    // the box's border): a 4-connected in-plane path to the slice's border is a 6-connected 3-D
    // path to the box's, so a 3-D flood would add nothing. Sliver07 fills them; Parenchyma
    // restores them.
    Vol holes = m;
    for (int k = 0; k < m.nz; ++k) {
        cv::Mat s = slice_mat(m, k), h = slice_mat(holes, k);
        const cv::Mat filled = fill_holes_2d(s * 255);
        h = (filled & ~(s * 255)) / 255;
        h.copyTo(slice_mat(holes, k));
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
    // Only the box's size is read from here on, and the holes only to restore them: free what
    // the smoothing's float volumes would otherwise sit beside (the 3-D pass sets lseg liver's
    // peak memory).
    std::vector<std::uint8_t>().swap(m.v);
    if (sliver)
        std::vector<std::uint8_t>().swap(holes.v);

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

    r.mask = core::LabelImage3D(stacked.geometry(), 0);
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
