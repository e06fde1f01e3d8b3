#include "lobe/seg/rib_cage.h"

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

constexpr double kPi = 3.14159265358979323846;

void check_params(const RibCageParams& p)
{
    auto bad = [](const std::string& what) { throw core::InvalidInputError("rib_cage: " + what); };
    if (!std::isfinite(p.bone_hu) || !std::isfinite(p.body_hu))
        bad("bone_hu and body_hu must be finite");
    if (p.slices_to_combine < 1)
        bad("slices_to_combine must be >= 1, got " + std::to_string(p.slices_to_combine));
    if (!(p.enhance_width_mm >= 0.0) || !std::isfinite(p.enhance_width_mm))
        bad("enhance_width_mm must be finite and >= 0");
    if (!(p.wall_width_mm >= 0.0) || !std::isfinite(p.wall_width_mm))
        bad("wall_width_mm must be finite and >= 0");
    if (p.angles < 16 || p.angles > 7200)
        bad("angles must be in 16..7200, got " + std::to_string(p.angles));
    if (!(p.max_gap_deg >= 0.0 && p.max_gap_deg <= 360.0))
        bad("max_gap_deg must be in [0, 360]");
    if (!(p.min_coverage >= 0.0 && p.min_coverage <= 1.0))
        bad("min_coverage must be in [0, 1]");
    if (!(p.median_deg >= 0.0 && p.median_deg <= 90.0))
        bad("median_deg must be in [0, 90]");
    if (!(p.min_bone_area_mm2 >= 0.0) || !std::isfinite(p.min_bone_area_mm2))
        bad("min_bone_area_mm2 must be finite and >= 0");
    if (!(p.max_depth_mm > 0.0))
        bad("max_depth_mm must be positive");
}

//! The largest connected region above `body_hu`, with its holes (lungs, bowel gas) filled.
cv::Mat body_mask(const cv::Mat& hu, double body_hu)
{
    cv::Mat above;
    cv::compare(hu, body_hu, above, cv::CMP_GT); // NaN compares false: not body
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(above, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
    cv::Mat body = cv::Mat::zeros(hu.size(), CV_8U);
    if (contours.empty())
        return body;
    std::size_t best = 0;
    double best_area = -1;
    for (std::size_t c = 0; c < contours.size(); ++c) {
        const double a = cv::contourArea(contours[c]);
        if (a > best_area) {
            best_area = a;
            best = c;
        }
    }
    cv::drawContours(body, contours, static_cast<int>(best), cv::Scalar(1), cv::FILLED);
    return body;
}

//! Circular median of the radii over ±half rays, over the rays that hit bone only.
std::vector<double> circular_median(const std::vector<double>& r, const std::vector<char>& hit, int half)
{
    const int n = static_cast<int>(r.size());
    std::vector<double> out = r, win;
    if (half <= 0)
        return out;
    for (int a = 0; a < n; ++a) {
        if (!hit[static_cast<std::size_t>(a)])
            continue;
        win.clear();
        for (int d = -half; d <= half; ++d) {
            const int b = ((a + d) % n + n) % n;
            if (hit[static_cast<std::size_t>(b)])
                win.push_back(r[static_cast<std::size_t>(b)]);
        }
        std::nth_element(win.begin(), win.begin() + static_cast<std::ptrdiff_t>(win.size() / 2), win.end());
        out[static_cast<std::size_t>(a)] = win[win.size() / 2];
    }
    return out;
}

struct SliceRing {
    bool valid = false;
    double coverage = 0.0;
    RibRing ring;
};

//! Drops the connected components (8-neighbour) of `bone` smaller than `min_px` pixels.
void drop_small(cv::Mat& bone, double min_px)
{
    if (min_px <= 1.0)
        return;
    cv::Mat labels, stats, centroids;
    const int n = cv::connectedComponentsWithStats(bone, labels, stats, centroids, 8, CV_32S);
    std::vector<std::uint8_t> keep(static_cast<std::size_t>(n), 0);
    for (int c = 1; c < n; ++c)
        keep[static_cast<std::size_t>(c)] = stats.at<int>(c, cv::CC_STAT_AREA) >= min_px ? 1 : 0;
    const int* l = labels.ptr<int>(0);
    std::uint8_t* b = bone.ptr<std::uint8_t>(0);
    for (std::size_t q = 0, n_px = bone.total(); q < n_px; ++q)
        b[q] = keep[static_cast<std::size_t>(l[q])];
}

//! One slice: `hu` (the slice itself, for the body) and `bone` (the overlapped bone of the
//! neighbouring slices) → `inside` and `ring`.
SliceRing ring_of_slice(const cv::Mat& hu, const cv::Mat& bone, double sx, double sy, const RibCageParams& p,
                        cv::Mat& inside, cv::Mat& ring, cv::Mat& wall)
{
    SliceRing res;
    const int nx = hu.cols, ny = hu.rows;
    inside.setTo(1);
    ring.setTo(0);
    wall.setTo(0);
    const cv::Mat body = body_mask(hu, p.body_hu);
    const cv::Moments m = cv::moments(body, true);
    if (m.m00 < 1.0)
        return res; // no body: nothing to constrain
    const double cx = m.m10 / m.m00, cy = m.m01 / m.m00; // pixel coordinates
    res.ring.centre_i = cx;
    res.ring.centre_j = cy;

    // Cast rays from the centroid in the physical plane. Along each ray the ring radius is the
    // inner edge of the outermost run of bone inside the body: the ribs are the outermost bone
    // of the trunk, so bone deeper inside (vertebral body, a calcification, contrast) never pulls
    // the ring inwards when a rib lies beyond it, and bone further out (a scapula) only loosens it.
    const int na = p.angles;
    const double step = std::min(sx, sy); // one pixel: a rib is several pixels thick
    const double r_far = std::hypot(nx * sx, ny * sy) + 1.0; // beyond the image: no constraint
    std::vector<double> radius(static_cast<std::size_t>(na), r_far);
    std::vector<char> hit(static_cast<std::size_t>(na), 0);
    for (int a = 0; a < na; ++a) {
        const double th = 2.0 * kPi * a / na;
        const double dx = std::cos(th) / sx, dy = std::sin(th) / sy; // pixels per mm
        bool prev_bone = false;
        double r_in = -1.0, r_skin = 0.0;
        for (double r = 0.0;; r += step) {
            const int i = static_cast<int>(std::lround(cx + r * dx)), j = static_cast<int>(std::lround(cy + r * dy));
            if (i < 0 || j < 0 || i >= nx || j >= ny)
                break;
            const bool in_body = body.at<std::uint8_t>(j, i) != 0;
            if (in_body)
                r_skin = r;
            const bool b = in_body && bone.at<std::uint8_t>(j, i);
            if (b && !prev_bone)
                r_in = r;
            prev_bone = b;
        }
        if (r_in >= 0.0 && r_skin - r_in <= p.max_depth_mm) {
            radius[static_cast<std::size_t>(a)] = r_in;
            hit[static_cast<std::size_t>(a)] = 1;
        }
    }
    const int half = static_cast<int>(std::lround(0.5 * p.median_deg * na / 360.0));
    radius = circular_median(radius, hit, half);

    // Bridge the gaps between ribs; leave wide gaps (the front below the costal margin, a
    // missing rib cage) unconstrained.
    std::vector<char> supported = hit;
    const int first = static_cast<int>(std::find(hit.begin(), hit.end(), 1) - hit.begin());
    if (first == na)
        return res; // no bone at all
    const int max_gap = static_cast<int>(std::floor(p.max_gap_deg * na / 360.0));
    for (int s = 0; s < na;) {
        const int a = (first + s) % na;
        if (hit[static_cast<std::size_t>(a)]) {
            ++s;
            continue;
        }
        int len = 0;
        while (len < na && !hit[static_cast<std::size_t>((a + len) % na)])
            ++len;
        if (len <= max_gap) {
            const double r0 = radius[static_cast<std::size_t>((a - 1 + na) % na)];
            const double r1 = radius[static_cast<std::size_t>((a + len) % na)];
            for (int t = 0; t < len; ++t) {
                const double w = double(t + 1) / double(len + 1);
                radius[static_cast<std::size_t>((a + t) % na)] = (1 - w) * r0 + w * r1;
                supported[static_cast<std::size_t>((a + t) % na)] = 1;
            }
        }
        s += len;
    }
    const auto n_sup = std::count(supported.begin(), supported.end(), 1);
    res.coverage = double(n_sup) / double(na);
    res.ring.radius_mm.resize(static_cast<std::size_t>(na));
    res.ring.supported.resize(static_cast<std::size_t>(na));
    for (std::size_t a = 0; a < static_cast<std::size_t>(na); ++a) {
        res.ring.radius_mm[a] = static_cast<float>(radius[a]);
        res.ring.supported[a] = hit[a] ? 1 : (supported[a] ? 2 : 0);
    }
    res.valid = res.coverage >= p.min_coverage;
    if (!res.valid)
        return res;

    // The ring as a star-shaped polygon about the centroid (simple by construction), filled with
    // sub-pixel vertices.
    constexpr int kShift = 4;
    std::vector<cv::Point> poly(static_cast<std::size_t>(na));
    for (int a = 0; a < na; ++a) {
        const double th = 2.0 * kPi * a / na, r = radius[static_cast<std::size_t>(a)];
        poly[static_cast<std::size_t>(a)] = cv::Point(static_cast<int>(std::lround((cx + r * std::cos(th) / sx) * (1 << kShift))),
                                                      static_cast<int>(std::lround((cy + r * std::sin(th) / sy) * (1 << kShift))));
    }
    inside.setTo(0);
    cv::fillPoly(inside, std::vector<std::vector<cv::Point>>{poly}, cv::Scalar(1), cv::LINE_8, kShift);

    // The bands: inside, within enhance_width_mm (ring) or wall_width_mm (wall) of the outside,
    // on supported rays.
    if (p.enhance_width_mm > 0.0 || p.wall_width_mm > 0.0) {
        cv::Mat dist;
        cv::distanceTransform(inside, dist, cv::DIST_L2, cv::DIST_MASK_5); // ~2 % error: ample for a band
        const double px_mm = std::sqrt(sx * sy); // in-plane spacing is near isotropic in CT
        const float ring_limit = p.enhance_width_mm > 0.0 ? static_cast<float>(p.enhance_width_mm / px_mm + 0.5) : 0.f;
        const float wall_limit = p.wall_width_mm > 0.0 ? static_cast<float>(p.wall_width_mm / px_mm) : 0.f;
        const float limit = std::max(ring_limit, wall_limit);
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const float d = dist.at<float>(j, i);
                if (d <= 0.f || d > limit)
                    continue;
                double th = std::atan2((j - cy) * sy, (i - cx) * sx);
                if (th < 0)
                    th += 2.0 * kPi;
                const int a = static_cast<int>(std::lround(th * na / (2.0 * kPi))) % na;
                if (!supported[static_cast<std::size_t>(a)])
                    continue;
                if (d <= ring_limit)
                    ring.at<std::uint8_t>(j, i) = 1;
                if (d <= wall_limit)
                    wall.at<std::uint8_t>(j, i) = 1;
            }
    }
    return res;
}

void check_pair(const core::ImageGeometry& a, std::size_t na, const core::ImageGeometry& b, std::size_t nb,
                const std::string& what)
{
    core::validate_geometry(a, what);
    if (na != a.voxel_count() || nb != b.voxel_count() || !core::same_grid(a, b))
        throw core::InvalidInputError(what + ": the image and the mask are on different grids");
}

} // namespace

RibCageResult rib_cage(const core::ImageF& hu_volume, const RibCageParams& params)
{
    core::validate_geometry(hu_volume, "rib_cage: volume");
    if (hu_volume.data.size() != hu_volume.voxel_count())
        throw core::InvalidInputError("rib_cage: the volume holds " + std::to_string(hu_volume.data.size()) +
                                      " values for " + std::to_string(hu_volume.voxel_count()) + " voxels");
    check_params(params);
    const int nx = hu_volume.size[0], ny = hu_volume.size[1], nz = hu_volume.size[2];
    const std::size_t plane = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);

    RibCageResult r;
    r.inside = core::LabelImage3D(hu_volume.geometry(), 1);
    r.ring = core::LabelImage3D(hu_volume.geometry(), 0);
    r.wall = core::LabelImage3D(hu_volume.geometry(), 0);
    r.valid.assign(static_cast<std::size_t>(nz), 0);
    r.coverage.assign(static_cast<std::size_t>(nz), 0.0);
    r.rings.assign(static_cast<std::size_t>(nz), RibRing{});

    // Bone of every slice once (NaN compares false: not bone).
    core::LabelImage3D bone(hu_volume.geometry(), 0);
    const auto thr = static_cast<float>(params.bone_hu);
    for (std::size_t i = 0; i < bone.data.size(); ++i)
        bone.data[i] = hu_volume.data[i] >= thr ? 1 : 0;

    const int lo_off = (params.slices_to_combine - 1) / 2, hi_off = params.slices_to_combine / 2;
#pragma omp parallel for schedule(dynamic)
    for (int k = 0; k < nz; ++k) {
        const std::size_t off = plane * static_cast<std::size_t>(k);
        const cv::Mat hu(ny, nx, CV_32F, const_cast<float*>(hu_volume.data.data() + off));
        cv::Mat slab = cv::Mat::zeros(ny, nx, CV_8U);
        for (int kk = std::max(0, k - lo_off); kk <= std::min(nz - 1, k + hi_off); ++kk) {
            const cv::Mat b(ny, nx, CV_8U, bone.data.data() + plane * static_cast<std::size_t>(kk));
            cv::bitwise_or(slab, b, slab);
        }
        drop_small(slab, params.min_bone_area_mm2 / (hu_volume.spacing[0] * hu_volume.spacing[1]));
        cv::Mat inside(ny, nx, CV_8U, r.inside.data.data() + off);
        cv::Mat ring(ny, nx, CV_8U, r.ring.data.data() + off);
        cv::Mat wall(ny, nx, CV_8U, r.wall.data.data() + off);
        const SliceRing s =
            ring_of_slice(hu, slab, hu_volume.spacing[0], hu_volume.spacing[1], params, inside, ring, wall);
        r.valid[static_cast<std::size_t>(k)] = s.valid ? 1 : 0;
        r.coverage[static_cast<std::size_t>(k)] = s.coverage;
        r.rings[static_cast<std::size_t>(k)] = s.ring;
        if (!s.valid) {
            inside.setTo(1);
            ring.setTo(0);
            wall.setTo(0);
        }
    }
    return r;
}

core::ImageF enhance_rib_edges(const core::ImageF& edge, const core::LabelImage3D& ring, double gain)
{
    check_pair(edge, edge.data.size(), ring, ring.data.size(), "enhance_rib_edges");
    if (!(gain >= 0.0) || !std::isfinite(gain))
        throw core::InvalidInputError("enhance_rib_edges: gain must be finite and >= 0, got " + std::to_string(gain));
    core::ImageF out = edge;
    const auto f = static_cast<float>(1.0 + gain);
    for (std::size_t i = 0; i < out.data.size(); ++i)
        if (ring.data[i])
            out.data[i] = std::min(1.f, out.data[i] * f);
    return out;
}

core::ImageF mask_outside_rib_cage(const core::ImageF& image, const core::LabelImage3D& inside, float background)
{
    check_pair(image, image.data.size(), inside, inside.data.size(), "mask_outside_rib_cage");
    core::ImageF out = image;
    for (std::size_t i = 0; i < out.data.size(); ++i)
        if (!inside.data[i])
            out.data[i] = background;
    return out;
}

} // namespace lobe::seg
