// The dark rim of a stacked segmentation (lobe/seg/dark_rim.h, docs/algorithms/liver.md).
#include "lobe/seg/dark_rim.h"

#include "lobe/core/errors.h"
#include "lobe/seg/distance_transform.h"
#include "lobe/seg/edge_map.h"

#include "detail/volume.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace lobe::seg {
namespace {

//! One slice's part of the work: the mask and smoothed grey levels on a window around it.
struct SliceWork {
    detail::Box box; // on the volume's grid, one slice thick
    core::LabelImage3D mask;
    core::ImageF grey;
};

} // namespace

DarkRimResult trim_dark_rim(const core::ImageF& image, const core::LabelImage3D& mask, double median, double low,
                            const DarkRimParams& params)
{
    detail::check_image(image, "trim_dark_rim: the image");
    detail::check_same_grid(image.geometry(), mask, "trim_dark_rim: the mask");
    if (!std::isfinite(median) || !std::isfinite(low) || low > median)
        throw core::InvalidInputError("trim_dark_rim: the object's median and the low end of its band must be finite "
                                      "with low <= median (are " +
                                      std::to_string(median) + ", " + std::to_string(low) + ")");
    if (!(params.level > 0.0 && params.level <= 1.0) || params.ring_voxels < 1 ||
        !(params.max_half_thickness_mm > 0.0) || !std::isfinite(params.max_half_thickness_mm) ||
        !(params.smoothing_mm >= 0.0) || !std::isfinite(params.smoothing_mm))
        throw core::InvalidInputError("trim_dark_rim: level must lie in (0, 1], ring_voxels be >= 1, "
                                      "max_half_thickness_mm finite and > 0 and smoothing_mm finite and >= 0");

    DarkRimResult r;
    r.mask = core::LabelImage3D(mask.geometry(), 0);
    for (std::size_t i = 0; i < mask.data.size(); ++i)
        r.mask.data[i] = mask.data[i] ? 1 : 0;
    const int nz = mask.size[2];
    const double h = std::max(mask.spacing[0], mask.spacing[1]);
    const double ring_mm = params.ring_voxels * h * (1.0 + 1e-6);
    const double touching = std::hypot(mask.spacing[0], mask.spacing[1]) * (1.0 + 1e-6); // a diagonal neighbour
    const std::array<int, 3> margin{params.ring_voxels + 2, params.ring_voxels + 2, 0};

    // Pass 1: each slice's window, its smoothed grey levels, and the darker tissue in its ring.
    std::vector<SliceWork> work(static_cast<std::size_t>(nz));
    std::vector<std::vector<float>> darker(static_cast<std::size_t>(nz));
#pragma omp parallel for schedule(dynamic)
    for (int k = 0; k < nz; ++k) {
        const core::LabelImage3D m = core::axial_slice(r.mask, k);
        const detail::Box b = detail::bounding_box(m);
        if (b.empty())
            continue;
        SliceWork& w = work[static_cast<std::size_t>(k)];
        w.box = detail::grown(b, margin, m.geometry());
        w.mask = detail::crop(m, w.box);
        w.grey = gaussian_smooth(detail::crop(core::axial_slice(image, k), w.box), params.smoothing_mm);
        const core::ImageF from_mask = euclidean_distance(w.mask);
        auto& d = darker[static_cast<std::size_t>(k)];
        for (std::size_t i = 0; i < w.mask.data.size(); ++i)
            if (!w.mask.data[i] && double(from_mask.data[i]) <= ring_mm && double(w.grey.data[i]) < low)
                d.push_back(w.grey.data[i]);
    }
    std::vector<float> all;
    for (const auto& d : darker)
        all.insert(all.end(), d.begin(), d.end());
    if (all.empty())
        return r; // nothing darker than the object around it: no layer to tell apart
    r.neighbour = detail::median_and_robust_sd(std::move(all)).first;
    r.level = std::min(low, median - params.level * (median - r.neighbour));
    r.applied = true;

    // Pass 2: per slice, the dark pieces along the rim.
    std::size_t removed = 0;
#pragma omp parallel for schedule(dynamic) reduction(+ : removed)
    for (int k = 0; k < nz; ++k) {
        SliceWork& w = work[static_cast<std::size_t>(k)];
        if (w.mask.data.empty())
            continue;
        const core::LabelImage3D& m = w.mask;
        core::LabelImage3D dark(m.geometry(), 0), rest(m.geometry(), 0), not_dark(m.geometry(), 0);
        for (std::size_t i = 0; i < m.data.size(); ++i) {
            dark.data[i] = m.data[i] && double(w.grey.data[i]) < r.level;
            rest.data[i] = m.data[i] && !dark.data[i];
            not_dark.data[i] = !dark.data[i];
        }
        if (std::find(dark.data.begin(), dark.data.end(), 1) == dark.data.end() ||
            std::find(rest.data.begin(), rest.data.end(), 1) == rest.data.end())
            continue;
        const core::ImageF from_rest = euclidean_distance(rest);
        const core::ImageF depth = euclidean_distance(not_dark); // half the dark layer's thickness
        cv::Mat cand(m.size[1], m.size[0], CV_8U, cv::Scalar(0));
        for (std::size_t i = 0; i < m.data.size(); ++i)
            cand.data[i] = dark.data[i] && double(from_rest.data[i]) > touching ? 1 : 0;
        cv::Mat labels;
        const int n = cv::connectedComponents(cand, labels, 8, CV_32S);
        if (n <= 1)
            continue;
        std::vector<char> reaches(static_cast<std::size_t>(n), 0);
        std::vector<float> deepest(static_cast<std::size_t>(n), 0.f);
        const int nx = m.size[0], ny = m.size[1];
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const auto l = static_cast<std::size_t>(labels.at<int>(j, i));
                if (l == 0)
                    continue;
                deepest[l] = std::max(deepest[l], depth.at(i, j, 0));
                reaches[l] = reaches[l] || i == 0 || j == 0 || i + 1 == nx || j + 1 == ny || !m.at(i - 1, j, 0) ||
                             !m.at(i + 1, j, 0) || !m.at(i, j - 1, 0) || !m.at(i, j + 1, 0);
            }
        std::size_t here = 0;
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const auto l = static_cast<std::size_t>(labels.at<int>(j, i));
                if (l && reaches[l] && double(deepest[l]) <= params.max_half_thickness_mm) {
                    r.mask.at(w.box.lo[0] + i, w.box.lo[1] + j, k) = 0;
                    ++here;
                }
            }
        removed += here;
    }
    r.removed = removed;
    return r;
}

} // namespace lobe::seg
