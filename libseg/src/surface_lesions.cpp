// Surface lesions of a stacked segmentation (lobe/seg/surface_lesions.h, docs/algorithms/liver.md).
#include "lobe/seg/surface_lesions.h"

#include "lobe/core/errors.h"
#include "lobe/seg/edge_map.h"

#include "detail/volume.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace lobe::seg {

void check_surface_lesion_params(const SurfaceLesionParams& params, const std::string& who)
{
    const auto finite_at_least = [](double v, double low) { return std::isfinite(v) && v >= low; };
    if (!(params.closing_mm > 0.0) || !(params.core_mm > 0.0) || !finite_at_least(params.closing_mm, 0.0) ||
        !finite_at_least(params.core_mm, 0.0) || !finite_at_least(params.min_ml, 0.0) ||
        !finite_at_least(params.smoothing_mm, 0.0) || !(params.core_fraction >= 0.0 && params.core_fraction <= 1.0))
        throw core::InvalidInputError(who + ": closing_mm and core_mm must be finite and > 0, min_ml and smoothing_mm "
                                            "finite and >= 0, core_fraction in [0, 1]");
}

SurfaceLesionResult fill_surface_lesions(const core::ImageF& image, const core::LabelImage3D& mask, double lo,
                                         double hi, const core::LabelImage3D* exclude,
                                         const SurfaceLesionParams& params)
{
    detail::check_image(image, "fill_surface_lesions: the image");
    detail::check_same_grid(image.geometry(), mask, "fill_surface_lesions: the mask");
    if (exclude)
        detail::check_same_grid(image.geometry(), *exclude, "fill_surface_lesions: the exclusion");
    if (!std::isfinite(lo) || !std::isfinite(hi) || !(lo < hi))
        throw core::InvalidInputError("fill_surface_lesions: the grey range [lo, hi) must be finite and not empty (is [" +
                                      std::to_string(lo) + ", " + std::to_string(hi) + "))");
    check_surface_lesion_params(params, "fill_surface_lesions");

    SurfaceLesionResult r;
    r.mask = core::LabelImage3D(mask.geometry(), 0);
    for (std::size_t i = 0; i < mask.data.size(); ++i)
        r.mask.data[i] = mask.data[i] ? 1 : 0;
    const double pixel = std::sqrt(mask.spacing[0] * mask.spacing[1]);
    const double r_px = params.closing_mm / pixel;
    const int pad = static_cast<int>(std::ceil(r_px)) + 2;
    const std::array<int, 3> margin{pad, pad, 0};

    // Candidates, slice by slice. The closing by two exact distance transforms: linear in the
    // pixels, where a 15 mm disc as a kernel is 43 x 43 pixels at 0.7 mm.
    core::LabelImage3D cand(mask.geometry(), 0);
#pragma omp parallel for schedule(dynamic)
    for (int k = 0; k < mask.size[2]; ++k) {
        const core::LabelImage3D m = core::axial_slice(r.mask, k);
        const detail::Box sb = detail::bounding_box(m);
        if (sb.empty())
            continue;
        const detail::Box b = detail::grown(sb, margin, m.geometry());
        core::LabelImage3D mw = detail::crop(m, b);
        const core::ImageF grey = gaussian_smooth(detail::crop(core::axial_slice(image, k), b), params.smoothing_mm);
        const cv::Mat in(mw.size[1], mw.size[0], CV_8U, mw.data.data());
        cv::Mat to_mask, to_outside;
        cv::distanceTransform(in == 0, to_mask, cv::DIST_L2, cv::DIST_MASK_PRECISE);
        cv::distanceTransform(to_mask <= r_px, to_outside, cv::DIST_L2, cv::DIST_MASK_PRECISE);
        for (int j = 0; j < mw.size[1]; ++j)
            for (int i = 0; i < mw.size[0]; ++i) {
                const double v = grey.at(i, j, 0);
                const int gi = b.lo[0] + i, gj = b.lo[1] + j;
                if (double(to_outside.at<float>(j, i)) > r_px && !mw.at(i, j, 0) && v >= lo && v < hi &&
                    !(exclude && exclude->at(gi, gj, k)))
                    cand.at(gi, gj, k) = 1;
            }
    }
    const detail::Box b = detail::bounding_box(cand);
    if (b.empty())
        return r;

    // Each piece's core: what survives an in-plane opening (a lesion is thick, a strip of partial
    // volume or muscle is not).
    const core::LabelImage3D part = detail::crop(cand, b);
    const detail::Components comps = detail::connected_components(part, 26);
    const int ox = std::max(1, static_cast<int>(std::lround(params.core_mm / mask.spacing[0])));
    const int oy = std::max(1, static_cast<int>(std::lround(params.core_mm / mask.spacing[1])));
    const cv::Mat disc = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * ox + 1, 2 * oy + 1));
    std::vector<std::size_t> core_size(comps.sizes.size(), 0);
    for (int k = 0; k < part.size[2]; ++k) {
        const cv::Mat in(part.size[1], part.size[0], CV_8U, const_cast<std::uint8_t*>(&part.data[part.index(0, 0, k)]));
        cv::Mat opened;
        cv::morphologyEx(in, opened, cv::MORPH_OPEN, disc);
        for (int j = 0; j < part.size[1]; ++j)
            for (int i = 0; i < part.size[0]; ++i)
                if (opened.at<uchar>(j, i))
                    ++core_size[static_cast<std::size_t>(comps.id[part.index(i, j, k)])];
    }
    const double voxel_ml = mask.spacing[0] * mask.spacing[1] * mask.spacing[2] / 1000.0;
    std::vector<char> keep(comps.sizes.size(), 0);
    for (std::size_t q = 0; q < comps.sizes.size(); ++q)
        keep[q] = double(core_size[q]) * voxel_ml >= params.min_ml &&
                  double(core_size[q]) >= params.core_fraction * double(comps.sizes[q]);
    for (int k = 0; k < part.size[2]; ++k)
        for (int j = 0; j < part.size[1]; ++j)
            for (int i = 0; i < part.size[0]; ++i) {
                const std::int32_t id = comps.id[part.index(i, j, k)];
                if (id >= 0 && keep[static_cast<std::size_t>(id)]) {
                    r.mask.at(b.lo[0] + i, b.lo[1] + j, b.lo[2] + k) = 1;
                    ++r.added;
                }
            }
    return r;
}

} // namespace lobe::seg
