// The dark rim of a stacked segmentation (lobe/seg/dark_rim.h, docs/algorithms/liver.md).
#include "lobe/seg/dark_rim.h"

#include "lobe/core/errors.h"
#include "lobe/seg/distance_transform.h"
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
namespace {

//! One slice's part of the work: the mask and smoothed grey levels on a window around it.
struct SliceWork {
    detail::Box box; // on the volume's grid, one slice thick
    core::LabelImage3D mask;
    core::ImageF grey;
    double ci = 0, cj = 0;                     // the mask's centroid (window pixels)
    std::vector<std::vector<float>> by_sector; // the darker tissue of the ring, per angular sector
};

//! The angular sector (of n around the centroid ci, cj) of pixel i, j.
int sector_of(int i, int j, double ci, double cj, int n)
{
    constexpr double kTwoPi = 6.283185307179586;
    const double a = std::atan2(double(j) - cj, double(i) - ci) + kTwoPi / 2; // [0, 2 pi]
    return std::min(n - 1, static_cast<int>(a / kTwoPi * n));
}

cv::Mat as_mat(core::LabelImage3D& m)
{
    return cv::Mat(m.size[1], m.size[0], CV_8U, m.data.data());
}

//! Keeps the 8-connected pieces of the one-slice mask `m` whose depth (the largest distance
//! from one of its pixels to the outside of the piece) exceeds depth_mm.
void keep_bodies(core::LabelImage3D& m, double depth_mm)
{
    core::LabelImage3D outside(m.geometry(), 0);
    for (std::size_t i = 0; i < m.data.size(); ++i)
        outside.data[i] = !m.data[i];
    const core::ImageF depth = euclidean_distance(outside);
    cv::Mat bin(m.size[1], m.size[0], CV_8U, m.data.data()), labels;
    const int n = cv::connectedComponents(bin, labels, 8, CV_32S);
    std::vector<float> deepest(static_cast<std::size_t>(n), 0.f);
    for (std::size_t i = 0; i < m.data.size(); ++i) {
        const auto l = static_cast<std::size_t>(labels.ptr<int>(0)[i]);
        deepest[l] = std::max(deepest[l], depth.data[i]);
    }
    for (std::size_t i = 0; i < m.data.size(); ++i)
        m.data[i] = m.data[i] && double(deepest[static_cast<std::size_t>(labels.ptr<int>(0)[i])]) > depth_mm ? 1 : 0;
}

//! Clears from `after` (the one-slice mask `before` less what was trimmed) its 8-connected pieces
//! that hold no pixel of `body` but were part of a piece of `before` that did.
void drop_cut_off(const core::LabelImage3D& before, core::LabelImage3D& after, const core::LabelImage3D& body)
{
    cv::Mat b(before.size[1], before.size[0], CV_8U, const_cast<std::uint8_t*>(before.data.data()));
    cv::Mat a(after.size[1], after.size[0], CV_8U, after.data.data());
    cv::Mat lb, la;
    const int nb = cv::connectedComponents(b, lb, 8, CV_32S), na = cv::connectedComponents(a, la, 8, CV_32S);
    std::vector<char> b_body(static_cast<std::size_t>(nb), 0), a_body(static_cast<std::size_t>(na), 0);
    for (std::size_t i = 0; i < body.data.size(); ++i)
        if (body.data[i]) {
            b_body[static_cast<std::size_t>(lb.ptr<int>(0)[i])] = 1;
            a_body[static_cast<std::size_t>(la.ptr<int>(0)[i])] = 1;
        }
    for (std::size_t i = 0; i < after.data.size(); ++i)
        if (after.data[i] && !a_body[static_cast<std::size_t>(la.ptr<int>(0)[i])] &&
            b_body[static_cast<std::size_t>(lb.ptr<int>(0)[i])])
            after.data[i] = 0;
}

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
        !(params.smoothing_mm >= 0.0) || !std::isfinite(params.smoothing_mm) || !(params.body_depth_voxels >= 0.0) ||
        !std::isfinite(params.body_depth_voxels) || params.sectors < 0 || params.sector_min_voxels < 1 ||
        !(params.touching_min_smoothing_px >= 0.0) || !std::isfinite(params.touching_min_smoothing_px))
        throw core::InvalidInputError("trim_dark_rim: level must lie in (0, 1], ring_voxels be >= 1, "
                                      "max_half_thickness_mm finite and > 0, smoothing_mm, touching_min_smoothing_px "
                                      "and body_depth_voxels finite and >= 0, sectors >= 0 and sector_min_voxels >= 1");

    DarkRimResult r;
    r.mask = core::LabelImage3D(mask.geometry(), 0);
    for (std::size_t i = 0; i < mask.data.size(); ++i)
        r.mask.data[i] = mask.data[i] ? 1 : 0;
    const int nz = mask.size[2];
    const double h = std::max(mask.spacing[0], mask.spacing[1]);
    // Whether the smoothing mixes a rim pixel with its neighbours enough to darken a half-object one.
    const bool keep_touching = params.smoothing_mm >= params.touching_min_smoothing_px * h;
    r.touching_kept = keep_touching;
    const cv::Mat ring_disc =
        cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * params.ring_voxels + 1, 2 * params.ring_voxels + 1));
    const std::array<int, 3> margin{params.ring_voxels + 2, params.ring_voxels + 2, 0};
    const int sectors = std::max(1, params.sectors);

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
        cv::Mat ring;
        cv::dilate(as_mat(w.mask), ring, ring_disc);
        const cv::Moments mo = cv::moments(as_mat(w.mask), true);
        w.ci = mo.m10 / mo.m00;
        w.cj = mo.m01 / mo.m00;
        w.by_sector.resize(static_cast<std::size_t>(sectors));
        auto& d = darker[static_cast<std::size_t>(k)];
        const int nx = w.mask.size[0];
        for (std::size_t i = 0; i < w.mask.data.size(); ++i)
            if (!w.mask.data[i] && ring.data[i] && double(w.grey.data[i]) < low) {
                d.push_back(w.grey.data[i]);
                const int pi = static_cast<int>(i % static_cast<std::size_t>(nx)),
                          pj = static_cast<int>(i / static_cast<std::size_t>(nx));
                w.by_sector[static_cast<std::size_t>(sector_of(pi, pj, w.ci, w.cj, sectors))].push_back(w.grey.data[i]);
            }
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
        // The level of each sector: from its own darker tissue where the ring holds enough of it
        // (the muscle under the ribs on one side, fat in front), else the volume's.
        std::vector<double> level(static_cast<std::size_t>(sectors), r.level);
        if (params.sectors > 0)
            for (std::size_t q = 0; q < level.size(); ++q)
                if (static_cast<int>(w.by_sector[q].size()) >= params.sector_min_voxels) {
                    const double nb = detail::quantile(w.by_sector[q], 0.5);
                    level[q] = std::min(low, median - params.level * (median - nb));
                }
        core::LabelImage3D dark(m.geometry(), 0), rest(m.geometry(), 0), not_dark(m.geometry(), 0);
        const int wx = m.size[0];
        for (std::size_t i = 0; i < m.data.size(); ++i) {
            const int pi = static_cast<int>(i % static_cast<std::size_t>(wx)),
                      pj = static_cast<int>(i / static_cast<std::size_t>(wx));
            const double lv =
                params.sectors > 0 ? level[static_cast<std::size_t>(sector_of(pi, pj, w.ci, w.cj, sectors))] : r.level;
            dark.data[i] = m.data[i] && double(w.grey.data[i]) < lv;
            rest.data[i] = m.data[i] && !dark.data[i];
            not_dark.data[i] = !dark.data[i];
        }
        if (std::find(dark.data.begin(), dark.data.end(), 1) == dark.data.end())
            continue;
        // The object's body: the pieces of the rest that are more than a sliver. The partial
        // volume between a dark layer and a bright neighbour (the rib) is as bright as the object
        // but one or two pixels thin, and must not make the layer next to it "touch the object".
        keep_bodies(rest, params.body_depth_voxels * h);
        if (std::find(rest.data.begin(), rest.data.end(), 1) == rest.data.end())
            continue;
        cv::Mat near_rest; // the body and its 8 neighbours: what touches the object is kept
        if (keep_touching)
            cv::dilate(as_mat(rest), near_rest, cv::Mat::ones(3, 3, CV_8U));
        else
            near_rest = as_mat(rest); // a view of the body, only read below
        cv::Mat cand(m.size[1], m.size[0], CV_8U, cv::Scalar(0));
        for (std::size_t i = 0; i < m.data.size(); ++i)
            cand.data[i] = dark.data[i] && !near_rest.data[i] ? 1 : 0;
        if (cv::countNonZero(cand) == 0)
            continue;
        const core::ImageF depth = euclidean_distance(not_dark); // half the dark layer's thickness
        cv::Mat labels;
        const int n = cv::connectedComponents(cand, labels, 8, CV_32S);
        if (n <= 1)
            continue;
        std::vector<char> reaches(static_cast<std::size_t>(n), 0);
        std::vector<float> deepest(static_cast<std::size_t>(n), 0.f);
        std::vector<double> sum(static_cast<std::size_t>(n), 0.0), cnt(static_cast<std::size_t>(n), 0.0);
        const int nx = m.size[0], ny = m.size[1];
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const auto l = static_cast<std::size_t>(labels.at<int>(j, i));
                if (l == 0)
                    continue;
                sum[l] += double(w.grey.at(i, j, 0));
                cnt[l] += 1.0;
                deepest[l] = std::max(deepest[l], depth.at(i, j, 0));
                reaches[l] = reaches[l] || i == 0 || j == 0 || i + 1 == nx || j + 1 == ny || !m.at(i - 1, j, 0) ||
                             !m.at(i + 1, j, 0) || !m.at(i, j - 1, 0) || !m.at(i, j + 1, 0);
            }
        core::LabelImage3D after = m;
        for (std::size_t i = 0; i < m.data.size(); ++i) {
            const auto l = static_cast<std::size_t>(labels.ptr<int>(0)[i]);
            // A thick piece may be a lesion at the surface (liver under SLIVER07), unless it is as dark
            // as the tissue around the liver (fat, lung or gas taken in at the dome or a fissure).
            const bool thin = double(deepest[l]) <= params.max_half_thickness_mm;
            if (l && reaches[l] && (thin || sum[l] / std::max(cnt[l], 1.0) <= r.neighbour))
                after.data[i] = 0;
        }
        // What the trim cut off from the body goes with it (the sliver along the rib); pieces that
        // were apart from the body before stay as they were.
        drop_cut_off(m, after, rest);
        std::size_t here = 0;
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i)
                if (m.at(i, j, 0) && !after.at(i, j, 0)) {
                    r.mask.at(w.box.lo[0] + i, w.box.lo[1] + j, k) = 0;
                    ++here;
                }
        removed += here;
    }
    r.removed = removed;
    return r;
}

} // namespace lobe::seg
