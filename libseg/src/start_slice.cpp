#include "lobe/seg/start_slice.h"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

namespace lobe::seg {
namespace {

constexpr double kPi = 3.14159265358979323846;

void check_volume(const core::ImageF& image, const std::string& what)
{
    core::validate_geometry(image, what);
    if (image.data.size() != image.voxel_count())
        throw core::InvalidInputError(what + ": holds " + std::to_string(image.data.size()) + " values for " +
                                      std::to_string(image.voxel_count()) + " voxels");
}

bool finite_positive(double v) { return std::isfinite(v) && v > 0; }

//! +1 if slice index k grows towards the head (+z), -1 if towards the feet.
//! \throw InvalidInputError if the third axis is not (mostly) craniocaudal.
int superior_sign(const core::ImageGeometry& g, const std::string& what)
{
    const double zc = g.axis(2).z;
    if (std::abs(zc) < 0.5)
        throw core::InvalidInputError(what + ": the third image axis must be the craniocaudal axis (axial slices); "
                                             "its z component is " + std::to_string(zc));
    return zc > 0 ? 1 : -1;
}

// ------------------------------------------------------------------------------------------
// The heart/lung template, in millimetres in the patient frame centred on the heart:
// x = patient left, y = posterior. Shapes follow the anatomy just above the liver dome: a
// thorax ellipse filled by the two lungs, the heart (oblique, anterior) between them, and the
// posterior mediastinum (spine, aorta) joining the heart to the back.

struct TemplateSample {
    float value = 0;  //!< 1 tissue, 0 lung
    float weight = 0; //!< k(x, y); 0 outside the support
};

struct Ellipse {
    double cx, cy, ax, ay, angle_rad;
    //! normalised radius: < 1 inside
    double rho(double x, double y) const
    {
        const double c = std::cos(angle_rad), s = std::sin(angle_rad);
        const double dx = x - cx, dy = y - cy;
        const double u = c * dx + s * dy, v = -s * dx + c * dy;
        return std::sqrt((u / ax) * (u / ax) + (v / ay) * (v / ay));
    }
};

const Ellipse kThorax{-12, 28, 128, 84, 0};
const Ellipse kSupport{-12, 28, 143, 98, 0};
const Ellipse kHeart{0, 0, 55, 45, -30 * kPi / 180};
constexpr double kHeartBandMm = 10; // half-width of the emphasised heart/lung boundary band
constexpr float kBandWeight = 3.0f, kThoraxWeight = 1.0f, kRimWeight = 0.5f;

TemplateSample template_at(double x, double y)
{
    TemplateSample s;
    if (kSupport.rho(x, y) >= 1.0)
        return s;
    if (kThorax.rho(x, y) >= 1.0) {
        s.value = 1; // chest wall rim: its place varies with the body's size, so a low weight
        s.weight = kRimWeight;
        return s;
    }
    const double rh = kHeart.rho(x, y);
    const bool mediastinum = std::abs(x + 8) < 27 && y > 25;
    s.value = (rh < 1.0 || mediastinum) ? 1.0f : 0.0f;
    // the heart outline is what separates the start slice from the dome slices below it
    const double d = std::abs(rh - 1.0) * std::min(kHeart.ax, kHeart.ay);
    s.weight = d < kHeartBandMm ? kBandWeight : kThoraxWeight;
    return s;
}

//! A template rasterised for one rotation on the working grid: kernels of odd size, the
//! anchor at the centre, for a grid whose in-plane axes map to the patient frame by `axes`.
struct Kernel {
    cv::Mat value, weight; // CV_32F
    double angle_deg = 0;
};

//! axes = {a0x, a0y, a1x, a1y}: the physical x, y of one mm along the grid's u and v axes.
Kernel rasterise(double pixel_u, double pixel_v, const std::array<double, 4>& axes, double angle_deg, double scale)
{
    // the support's farthest point from the heart centre bounds the kernel at any rotation
    double r0 = 0;
    for (int t = 0; t < 720; ++t) {
        const double a = t * kPi / 360;
        r0 = std::max(r0, std::hypot(kSupport.cx + kSupport.ax * std::cos(a), kSupport.cy + kSupport.ay * std::sin(a)));
    }
    const double radius = (r0 + 1.0) * scale;
    const int ru = static_cast<int>(std::ceil(radius / pixel_u));
    const int rv = static_cast<int>(std::ceil(radius / pixel_v));
    Kernel k;
    k.angle_deg = angle_deg;
    k.value = cv::Mat::zeros(2 * rv + 1, 2 * ru + 1, CV_32F);
    k.weight = cv::Mat::zeros(2 * rv + 1, 2 * ru + 1, CV_32F);
    const double a = angle_deg * kPi / 180, c = std::cos(a), s = std::sin(a);
    constexpr int kSub = 3; // supersampling: a smooth template, less angle aliasing
    for (int v = -rv; v <= rv; ++v)
        for (int u = -ru; u <= ru; ++u) {
            double val = 0, w = 0;
            for (int sv = 0; sv < kSub; ++sv)
                for (int su = 0; su < kSub; ++su) {
                    const double du = (u + (su + 0.5) / kSub - 0.5) * pixel_u;
                    const double dv = (v + (sv + 0.5) / kSub - 0.5) * pixel_v;
                    const double x = axes[0] * du + axes[2] * dv, y = axes[1] * du + axes[3] * dv;
                    // the patient is rotated by +a: look the point up in the unrotated frame
                    const double xr = (c * x + s * y) / scale, yr = (-s * x + c * y) / scale;
                    const TemplateSample t = template_at(xr, yr);
                    val += double(t.value) * double(t.weight);
                    w += double(t.weight);
                }
            k.weight.at<float>(v + rv, u + ru) = static_cast<float>(w / (kSub * kSub));
            k.value.at<float>(v + rv, u + ru) = w > 0 ? static_cast<float>(val / w) : 0.0f;
        }
    return k;
}

// ------------------------------------------------------------------------------------------
// Weighted NCC by FFT: for a template t with weights w and image f,
//   N  = Σ w (t - t̄) f        = corr(f, w (t - t̄))
//   S1 = Σ w f, S2 = Σ w f²    = corr(f, w), corr(f², w)
//   R  = N / sqrt((S2 - S1² / W) · Σ w (t - t̄)²)
// corr(f, k)(x) = Σ_u f(x + u - anchor) k(u), zero outside the image (air maps to 0).

struct KernelSpectra {
    cv::Mat a, w;          // DFTs (CCS) of w (t - t̄) and of w, anchor wrapped to (0, 0)
    double sum_w = 0, var_t = 0;
    double angle_deg = 0;
};

cv::Mat wrapped_spectrum(const cv::Mat& k, cv::Size dft_size)
{
    cv::Mat pad = cv::Mat::zeros(dft_size, CV_32F);
    const int cu = k.cols / 2, cv_ = k.rows / 2;
    for (int v = 0; v < k.rows; ++v)
        for (int u = 0; u < k.cols; ++u) {
            const int pu = ((u - cu) % dft_size.width + dft_size.width) % dft_size.width;
            const int pv = ((v - cv_) % dft_size.height + dft_size.height) % dft_size.height;
            pad.at<float>(pv, pu) += k.at<float>(v, u);
        }
    cv::Mat spec;
    cv::dft(pad, spec);
    return spec;
}

KernelSpectra kernel_spectra(const Kernel& k, cv::Size dft_size)
{
    KernelSpectra ks;
    ks.angle_deg = k.angle_deg;
    const double sw = cv::sum(k.weight)[0];
    const double mean_t = sw > 0 ? k.weight.dot(k.value) / sw : 0;
    cv::Mat centred = k.value - mean_t;
    cv::Mat a = k.weight.mul(centred);
    ks.sum_w = sw;
    ks.var_t = a.dot(centred);
    ks.a = wrapped_spectrum(a, dft_size);
    ks.w = wrapped_spectrum(k.weight, dft_size);
    return ks;
}

cv::Mat correlate(const cv::Mat& image_spec, const cv::Mat& kernel_spec, cv::Size out)
{
    cv::Mat prod, res;
    cv::mulSpectrums(image_spec, kernel_spec, prod, 0, true);
    cv::idft(prod, res, cv::DFT_SCALE | cv::DFT_REAL_OUTPUT);
    return res(cv::Rect(0, 0, out.width, out.height));
}

struct SliceSpectra {
    cv::Mat f, f2; // DFTs (CCS) of the zero-padded feature image and its square
};

SliceSpectra slice_spectra(const cv::Mat& f, cv::Size dft_size)
{
    SliceSpectra s;
    cv::Mat pad = cv::Mat::zeros(dft_size, CV_32F);
    f.copyTo(pad(cv::Rect(0, 0, f.cols, f.rows)));
    cv::dft(pad, s.f);
    pad(cv::Rect(0, 0, f.cols, f.rows)) = f.mul(f);
    cv::dft(pad, s.f2);
    return s;
}

//! The weighted NCC map for one kernel; positions outside `allowed` get -1.
cv::Mat ncc_map(const SliceSpectra& s, const KernelSpectra& k, const cv::Mat& allowed)
{
    const cv::Size out = allowed.size();
    const cv::Mat n = correlate(s.f, k.a, out);
    const cv::Mat s1 = correlate(s.f, k.w, out);
    const cv::Mat s2 = correlate(s.f2, k.w, out);
    cv::Mat r(out, CV_32F, cv::Scalar(-1));
    for (int v = 0; v < out.height; ++v)
        for (int u = 0; u < out.width; ++u) {
            if (!allowed.at<std::uint8_t>(v, u))
                continue;
            const double m1 = double(s1.at<float>(v, u));
            const double var_f = double(s2.at<float>(v, u)) - m1 * m1 / k.sum_w;
            // flat windows (var ~ 0, or FFT round-off below it) carry no pattern: score 0
            const double den = var_f * k.var_t;
            r.at<float>(v, u) = var_f > 1e-4 * k.sum_w && den > 0 ? static_cast<float>(double(n.at<float>(v, u)) / std::sqrt(den)) : 0.0f;
        }
    return r;
}

//! Largest 8-connected component of a binary mask with its holes filled (the body).
cv::Mat filled_largest_component(const cv::Mat& bin)
{
    cv::Mat labels, stats, centroids;
    const int n = cv::connectedComponentsWithStats(bin, labels, stats, centroids, 8, CV_32S);
    if (n <= 1)
        return cv::Mat::zeros(bin.size(), CV_8U);
    int best = 1;
    for (int l = 2; l < n; ++l)
        if (stats.at<int>(l, cv::CC_STAT_AREA) > stats.at<int>(best, cv::CC_STAT_AREA))
            best = l;
    cv::Mat body = labels == best; // 255 / 0
    // fill holes: flood the background from a 1-pixel frame around the image
    cv::Mat framed = cv::Mat::zeros(body.rows + 2, body.cols + 2, CV_8U);
    body.copyTo(framed(cv::Rect(1, 1, body.cols, body.rows)));
    cv::floodFill(framed, cv::Point(0, 0), cv::Scalar(128));
    cv::Mat filled = framed(cv::Rect(1, 1, body.cols, body.rows)) != 128;
    return filled;
}

//! The in-plane axes of the grid in the patient frame (x, y of axis 0 and axis 1).
std::array<double, 4> plane_axes(const core::ImageGeometry& g)
{
    const core::Vec3 a0 = g.axis(0), a1 = g.axis(1);
    return {a0.x, a0.y, a1.x, a1.y};
}

} // namespace

double weighted_ncc(const float* f, const float* t, const float* w, std::size_t count)
{
    double sw = 0, sf = 0, st = 0;
    for (std::size_t i = 0; i < count; ++i) {
        if (!(w[i] >= 0) || !std::isfinite(w[i]))
            throw core::InvalidInputError("weighted_ncc: weights must be finite and >= 0");
        const double wi = w[i];
        sw += wi;
        sf += wi * double(f[i]);
        st += wi * double(t[i]);
    }
    if (!(sw > 0))
        return 0.0;
    const double mf = sf / sw, mt = st / sw;
    double n = 0, vf = 0, vt = 0;
    for (std::size_t i = 0; i < count; ++i) {
        const double df = double(f[i]) - mf, dt = double(t[i]) - mt, wi = w[i];
        n += wi * df * dt;
        vf += wi * df * df;
        vt += wi * dt * dt;
    }
    const double eps = 1e-12 * sw;
    if (vf <= eps || vt <= eps)
        return 0.0;
    return n / std::sqrt(vf * vt);
}

HeartLungTemplate heart_lung_template(double pixel_mm, double rotation_deg, double scale)
{
    if (!finite_positive(pixel_mm) || !finite_positive(scale) || !std::isfinite(rotation_deg))
        throw core::InvalidInputError("heart_lung_template: pixel_mm and scale must be finite and positive, "
                                      "rotation_deg finite");
    const Kernel k = rasterise(pixel_mm, pixel_mm, {1, 0, 0, 1}, rotation_deg, scale);
    core::ImageGeometry g;
    g.size = {k.value.cols, k.value.rows, 1};
    g.spacing = {pixel_mm, pixel_mm, pixel_mm};
    g.origin = {-(k.value.cols / 2) * pixel_mm, -(k.value.rows / 2) * pixel_mm, 0};
    HeartLungTemplate t{core::ImageF(g), core::ImageF(g)};
    std::copy(k.value.begin<float>(), k.value.end<float>(), t.value.data.begin());
    std::copy(k.weight.begin<float>(), k.weight.end<float>(), t.weight.data.begin());
    return t;
}

StartSliceResult find_start_slice(const core::ImageF& vol, const StartSliceParams& p)
{
    const std::string what = "find_start_slice";
    check_volume(vol, what);
    if (!finite_positive(p.pixel_mm) || !finite_positive(p.rotation_step_deg) || !finite_positive(p.coarse_step_deg) ||
        !(p.max_rotation_deg >= 0) || !(p.max_rotation_deg <= 90) || !finite_positive(p.template_scale) ||
        !std::isfinite(p.lung_value) || !std::isfinite(p.tissue_value) || !(p.tissue_value != p.lung_value) ||
        !std::isfinite(p.min_score) || !(p.relative_score >= 0 && p.relative_score <= 1))
        throw core::InvalidInputError(what + ": invalid parameters (pixel_mm, steps, template_scale > 0; "
                                             "0 <= max_rotation_deg <= 90; tissue_value != lung_value; "
                                             "0 <= relative_score <= 1)");
    const int up = superior_sign(vol, what);
    const int nx = vol.size[0], ny = vol.size[1], nz = vol.size[2];
    const int wu = std::max(1, static_cast<int>(std::lround(nx * vol.spacing[0] / p.pixel_mm)));
    const int wv = std::max(1, static_cast<int>(std::lround(ny * vol.spacing[1] / p.pixel_mm)));
    const double pu = nx * vol.spacing[0] / wu, pv = ny * vol.spacing[1] / wv; // actual working pixel [mm]
    const auto axes = plane_axes(vol);

    StartSliceResult res;
    res.slice_scores.assign(static_cast<std::size_t>(nz), 0.0);

    // Angles: coarse for every slice, fine for the start slice.
    auto angles = [&](double step) {
        std::vector<double> a;
        const int n = static_cast<int>(std::floor(p.max_rotation_deg / step + 1e-9));
        for (int i = -n; i <= n; ++i)
            a.push_back(i * step);
        return a;
    };
    const std::vector<double> coarse = angles(p.coarse_step_deg);
    constexpr double kCoarseZmm = 8.0; // pass A samples the slices about this far apart

    // Working grid and FFT size: image plus the largest kernel, zero padded (air outside).
    std::vector<Kernel> kernels;
    for (double a : coarse)
        kernels.push_back(rasterise(pu, pv, axes, a, p.template_scale));
    const cv::Size dft_size(cv::getOptimalDFTSize(wu + kernels[0].value.cols - 1),
                            cv::getOptimalDFTSize(wv + kernels[0].value.rows - 1));
    std::vector<KernelSpectra> spectra;
    for (const auto& k : kernels)
        spectra.push_back(kernel_spectra(k, dft_size));

    // Per slice: feature image, allowed heart positions (deep inside the filled body).
    const double scale = p.tissue_value - p.lung_value;
    auto feature = [&](int k, cv::Mat& allowed) {
        const cv::Mat src(ny, nx, CV_32F,
                          const_cast<float*>(vol.data.data() + static_cast<std::size_t>(nx) * ny * static_cast<std::size_t>(k)));
        cv::Mat small;
        cv::resize(src, small, cv::Size(wu, wv), 0, 0, cv::INTER_AREA);
        cv::Mat f = (small - p.lung_value) / scale;
        cv::max(f, 0.0, f);
        cv::min(f, 1.0, f);
        cv::Mat body = filled_largest_component(f > 0.5);
        cv::Mat dist;
        cv::distanceTransform(body, dist, cv::DIST_L2, 3);
        const double depth_mm = 30.0 * p.template_scale; // the heart lies deep in the chest
        allowed = dist * std::min(pu, pv) >= depth_mm;
        return f;
    };

    // Pass A: slices about coarse_z_mm apart, coarse angles: the best chest slice and angle.
    struct Prepared {
        bool valid = false;
        SliceSpectra s;
        cv::Mat allowed;
    };
    auto prepare = [&](int k) {
        Prepared pr;
        const cv::Mat f = feature(k, pr.allowed);
        pr.valid = cv::countNonZero(pr.allowed) > 0;
        if (pr.valid)
            pr.s = slice_spectra(f, dft_size);
        return pr;
    };
    auto peak = [](const Prepared& pr, const KernelSpectra& ks) {
        double mx = 0;
        if (pr.valid)
            cv::minMaxLoc(ncc_map(pr.s, ks, pr.allowed), nullptr, &mx);
        return mx;
    };
    const int stride = std::max(1, static_cast<int>(std::floor(kCoarseZmm / vol.spacing[2])));
    std::vector<int> coarse_slices;
    for (int k = (nz - 1) % stride; k < nz; k += stride)
        coarse_slices.push_back(k);
    std::vector<double> coarse_score(coarse_slices.size(), 0.0), coarse_angle(coarse_slices.size(), 0.0);
#pragma omp parallel for schedule(dynamic)
    for (int c = 0; c < static_cast<int>(coarse_slices.size()); ++c) {
        const Prepared pr = prepare(coarse_slices[static_cast<std::size_t>(c)]);
        for (const auto& ks : spectra) {
            const double mx = peak(pr, ks);
            if (mx > coarse_score[static_cast<std::size_t>(c)]) {
                coarse_score[static_cast<std::size_t>(c)] = mx;
                coarse_angle[static_cast<std::size_t>(c)] = ks.angle_deg;
            }
        }
    }
    const std::size_t cbest = static_cast<std::size_t>(std::max_element(coarse_score.begin(), coarse_score.end()) - coarse_score.begin());
    const int kA = coarse_slices[cbest];
    std::ostringstream msg;
    msg.precision(3);
    // slice_scores are filled (pass C at the coarse angle) even when nothing matches, for plots
    const bool matched = coarse_score[cbest] >= p.min_score;
    // Pass B: rotational TM, fine angles around the coarse best, on the best slice and its
    // neighbours; summed peak scores, refined by a parabola through the best three.
    double angle = coarse_angle[cbest];
    std::vector<double> fine;
    // multiples of the fine step (so 0 is always tried) within one coarse step of the coarse best
    for (int n = static_cast<int>(std::ceil((angle - p.coarse_step_deg) / p.rotation_step_deg - 1e-9));
         n * p.rotation_step_deg <= angle + p.coarse_step_deg + 1e-9; ++n)
        if (std::abs(n * p.rotation_step_deg) <= p.max_rotation_deg + 1e-9)
            fine.push_back(n * p.rotation_step_deg);
    if (fine.empty())
        fine.push_back(angle);
    std::vector<Prepared> rot_slices;
    for (int d = -1; d <= 1 && matched; ++d)
        if (kA + d >= 0 && kA + d < nz)
            rot_slices.push_back(prepare(kA + d));
    std::vector<double> total(fine.size(), 0.0);
#pragma omp parallel for schedule(dynamic)
    for (int a = 0; a < static_cast<int>(fine.size()); ++a) {
        const KernelSpectra ks = kernel_spectra(rasterise(pu, pv, axes, fine[static_cast<std::size_t>(a)], p.template_scale), dft_size);
        for (const auto& pr : rot_slices)
            total[static_cast<std::size_t>(a)] += peak(pr, ks);
    }
    const std::size_t ia = static_cast<std::size_t>(std::max_element(total.begin(), total.end()) - total.begin());
    if (matched)
        angle = fine[ia];
    if (matched && ia > 0 && ia + 1 < fine.size()) {
        const double y0 = total[ia - 1], y1 = total[ia], y2 = total[ia + 1];
        const double den = y0 - 2 * y1 + y2;
        if (den < 0)
            angle += std::clamp(0.5 * (y0 - y2) / den, -0.5, 0.5) * p.rotation_step_deg;
    }

    // Pass C: every slice at that rotation; the start slice is the caudal end of the run of
    // slices scoring >= max(min_score, relative_score * best) that contains the best slice.
    const KernelSpectra final_k = kernel_spectra(rasterise(pu, pv, axes, angle, p.template_scale), dft_size);
#pragma omp parallel for schedule(dynamic)
    for (int k = 0; k < nz; ++k)
        res.slice_scores[static_cast<std::size_t>(k)] = peak(prepare(k), final_k);
    const auto it = std::max_element(res.slice_scores.begin(), res.slice_scores.end());
    const double best = *it;
    const int kbest = static_cast<int>(it - res.slice_scores.begin());
    const double thr = std::max(p.min_score, p.relative_score * best);
    if (!matched) {
        msg << "no slice shows the heart between both lungs: best weighted NCC " << coarse_score[cbest] << " (slice "
            << kA << ") < min_score " << p.min_score << "; the volume may not reach the chest";
        res.message = msg.str();
        return res;
    }
    if (!(best >= p.min_score)) {
        msg << "no slice shows the heart between both lungs at rotation " << angle << " deg: best weighted NCC " << best
            << " < min_score " << p.min_score;
        res.message = msg.str();
        return res;
    }
    int kstart = kbest;
    while (kstart - up >= 0 && kstart - up < nz && res.slice_scores[static_cast<std::size_t>(kstart - up)] >= thr)
        kstart -= up;

    // Heart centre: the peak on the start slice.
    const Prepared start_pr = prepare(kstart);
    const cv::Mat map = ncc_map(start_pr.s, final_k, start_pr.allowed);
    double mx = 0;
    cv::Point loc;
    cv::minMaxLoc(map, nullptr, &mx, nullptr, &loc);
    res.found = true;
    res.slice = kstart;
    res.rotation_deg = angle;
    res.score = mx;
    res.heart_centre = {(loc.x + 0.5) * nx / double(wu) - 0.5, (loc.y + 0.5) * ny / double(wv) - 0.5, double(kstart)};
    if (std::abs(angle) >= p.max_rotation_deg - 0.5 * p.rotation_step_deg)
        msg << "rotation at the search limit (the patient may be rotated further); ";
    msg << "start slice " << kstart << " (score " << mx << "; best " << best << " on slice " << kbest
        << "; threshold " << thr << "), rotation " << angle << " deg";
    res.message = msg.str();
    return res;
}

// ------------------------------------------------------------------------------------------
// Seeding

namespace {

struct Cell {
    int k = 0, cu = 0, cv = 0;  // slice, cell column, cell row
    double mean = 0, sd = 0;
    bool candidate = false;     // inside the search region and mean inside the liver range
};

constexpr double kMinContrastFraction = 0.1;
constexpr int kMinCellPixels = 3;

struct SliceCells {
    int k = 0;
    int ncu = 0, ncv = 0;
    std::vector<Cell> cells;    // ncu * ncv, row-major
    double body_area_mm2 = 0;
};

} // namespace

LiverSeedResult seed_liver(const core::ImageF& vol, const StartSliceResult& start, const LiverSeedParams& p)
{
    const std::string what = "seed_liver";
    check_volume(vol, what);
    if (!finite_positive(p.cell_mm) || !std::isfinite(p.body_threshold) || !std::isfinite(p.liver_range_lo) ||
        !std::isfinite(p.liver_range_hi) || !(p.liver_range_hi > p.liver_range_lo) || !finite_positive(p.max_cell_sd) ||
        !finite_positive(p.homogeneity_factor) || !finite_positive(p.acceptance_sigma) || !(p.wall_margin_mm >= 0) ||
        !finite_positive(p.search_depth_mm) || !(p.min_depth_mm >= 0) || !(p.min_area_mm2 >= 0) ||
        !(p.max_body_fraction > 0 && p.max_body_fraction <= 1) || p.erode_cells < 0)
        throw core::InvalidInputError(what + ": invalid parameters (cell_mm, max_cell_sd, homogeneity_factor, "
                                             "acceptance_sigma, search_depth_mm > 0; liver_range_hi > liver_range_lo; "
                                             "0 < max_body_fraction <= 1; wall_margin_mm, min_area_mm2, erode_cells >= 0)");
    const int up = superior_sign(vol, what);
    const int nx = vol.size[0], ny = vol.size[1], nz = vol.size[2];
    const double sx = vol.spacing[0], sy = vol.spacing[1];
    // at least 3 x 3 pixels per cell: the sd of fewer pixels is too noisy to judge homogeneity
    const int cw = std::max(kMinCellPixels, static_cast<int>(std::lround(p.cell_mm / sx)));
    const int ch = std::max(kMinCellPixels, static_cast<int>(std::lround(p.cell_mm / sy)));
    const int ncu = nx / cw, ncv = ny / ch;
    const double cell_area = cw * sx * ch * sy;

    LiverSeedResult res;
    std::ostringstream msg;
    msg.precision(4);
    if (ncu < 1 || ncv < 1) {
        msg << "the slices (" << nx << " x " << ny << ") are smaller than one " << p.cell_mm << " mm cell";
        res.message = msg.str();
        return res;
    }

    // Search region: slices and the side limit in the patient frame.
    const bool with_start = start.found && start.slice >= 0 && start.slice < nz;
    res.used_start_slice = with_start;
    int k_lo = 0, k_hi = nz - 1;
    double heart_x = 0;
    if (with_start) {
        const int depth = static_cast<int>(std::floor(p.search_depth_mm / vol.spacing[2]));
        const int k_end = start.slice - up * depth;
        k_lo = std::clamp(std::min(start.slice, k_end), 0, nz - 1);
        k_hi = std::clamp(std::max(start.slice, k_end), 0, nz - 1);
        heart_x = vol.index_to_physical(start.heart_centre).x;
    }

    // Slices about one cell apart: the seed's exact slice does not matter, the time does.
    const int stride = std::max(1, static_cast<int>(std::floor(p.cell_mm / vol.spacing[2])));
    std::vector<int> ks;
    int k_first = with_start ? start.slice : k_hi;
    if (with_start) {
        const int skip = start.slice - up * static_cast<int>(std::ceil(p.min_depth_mm / vol.spacing[2]));
        if (skip >= k_lo && skip <= k_hi)
            k_first = skip;
    }
    for (int k = k_first; k >= k_lo && k <= k_hi; k += (with_start ? -up : -1) * stride)
        ks.push_back(k);
    std::vector<SliceCells> per_slice(ks.size());
#pragma omp parallel for schedule(dynamic)
    for (int ik = 0; ik < static_cast<int>(ks.size()); ++ik) {
        const int k = ks[static_cast<std::size_t>(ik)];
        const cv::Mat src(ny, nx, CV_32F,
                          const_cast<float*>(vol.data.data() + static_cast<std::size_t>(nx) * ny * static_cast<std::size_t>(k)));
        cv::Mat bin = src > p.body_threshold;
        const cv::Mat body = filled_largest_component(bin);
        const int body_px = cv::countNonZero(body);
        if (body_px == 0)
            continue;
        // the body's extent in the patient frame: its centre and its posterior limit
        cv::Mat dist;
        cv::distanceTransform(body, dist, cv::DIST_L2, 3);
        const double px_mm = std::min(sx, sy);
        double cxsum = 0, ymin = std::numeric_limits<double>::max(), ymax = -ymin;
        for (int j = 0; j < ny; j += 4)
            for (int i = 0; i < nx; i += 4)
                if (body.at<std::uint8_t>(j, i)) {
                    const core::Vec3 q = vol.index_to_physical(i, j, k);
                    cxsum += q.x;
                    ymin = std::min(ymin, q.y);
                    ymax = std::max(ymax, q.y);
                }
        int counted = 0;
        for (int j = 0; j < ny; j += 4)
            for (int i = 0; i < nx; i += 4)
                counted += body.at<std::uint8_t>(j, i) ? 1 : 0;
        const double body_cx = cxsum / std::max(1, counted);
        const double side_x = with_start ? heart_x : body_cx;
        // the back muscles lie behind about 3/4 of the body's depth
        const double y_limit = ymin + 0.75 * (ymax - ymin);

        cv::Mat sum, sqsum;
        cv::integral(src, sum, sqsum, CV_64F, CV_64F);
        SliceCells sc;
        sc.k = k;
        sc.ncu = ncu;
        sc.ncv = ncv;
        sc.body_area_mm2 = body_px * sx * sy;
        sc.cells.resize(static_cast<std::size_t>(ncu) * ncv);
        const double half_diag = 0.5 * std::hypot(cw * sx, ch * sy);
        for (int cv_ = 0; cv_ < ncv; ++cv_)
            for (int cu = 0; cu < ncu; ++cu) {
                Cell& c = sc.cells[static_cast<std::size_t>(cv_) * ncu + cu];
                c.k = k;
                c.cu = cu;
                c.cv = cv_;
                const int i0 = cu * cw, j0 = cv_ * ch, i1 = i0 + cw, j1 = j0 + ch;
                const double n = double(cw) * ch;
                const double s = sum.at<double>(j1, i1) - sum.at<double>(j0, i1) - sum.at<double>(j1, i0) + sum.at<double>(j0, i0);
                const double s2 = sqsum.at<double>(j1, i1) - sqsum.at<double>(j0, i1) - sqsum.at<double>(j1, i0) +
                                  sqsum.at<double>(j0, i0);
                c.mean = s / n;
                c.sd = std::sqrt(std::max(0.0, s2 / n - c.mean * c.mean));
                const int ic = (i0 + i1) / 2, jc = (j0 + j1) / 2;
                if (double(dist.at<float>(jc, ic)) * px_mm < p.wall_margin_mm + half_diag)
                    continue;
                const core::Vec3 q = vol.index_to_physical(core::Vec3{0.5 * (i0 + i1 - 1), 0.5 * (j0 + j1 - 1), double(k)});
                if (q.x >= side_x || q.y > y_limit)
                    continue;
                c.candidate = std::isfinite(c.mean) && c.mean >= p.liver_range_lo && c.mean <= p.liver_range_hi;
            }
        per_slice[static_cast<std::size_t>(ik)] = std::move(sc);
    }
    std::vector<SliceCells> slices;
    for (auto& sc : per_slice)
        if (!sc.cells.empty())
            slices.push_back(std::move(sc));
    if (slices.empty()) {
        res.message = "no body (no voxel above body_threshold " + std::to_string(p.body_threshold) +
                      ") on the searched slices";
        return res;
    }

    // Liver grey level: the mode of the homogeneous candidate cells' means. Pixel noise: the
    // 25th percentile of the candidates' sd (most candidate cells lie inside one tissue).
    std::vector<double> sds;
    for (const auto& sc : slices)
        for (const auto& c : sc.cells)
            if (c.candidate)
                sds.push_back(c.sd);
    if (sds.empty()) {
        msg << "no cell inside the body with a mean in the liver range [" << p.liver_range_lo << ", "
            << p.liver_range_hi << "] on slices " << k_lo << ".." << k_hi;
        res.message = msg.str();
        return res;
    }
    std::nth_element(sds.begin(), sds.begin() + static_cast<std::ptrdiff_t>(sds.size() / 4), sds.end());
    const double noise = sds[sds.size() / 4];
    const double sd_thr = std::min(p.max_cell_sd, p.homogeneity_factor * std::max(noise, 1e-6 * (p.liver_range_hi - p.liver_range_lo)));
    constexpr int kBins = 200;
    const double bin = (p.liver_range_hi - p.liver_range_lo) / kBins;
    std::vector<double> hist(kBins, 0.0);
    int homogeneous = 0;
    for (const auto& sc : slices)
        for (const auto& c : sc.cells)
            if (c.candidate && c.sd <= sd_thr) {
                const int b = std::clamp(static_cast<int>((c.mean - p.liver_range_lo) / bin), 0, kBins - 1);
                hist[static_cast<std::size_t>(b)] += 1;
                ++homogeneous;
            }
    if (homogeneous == 0) {
        msg << "no homogeneous cell (sd <= " << sd_thr << ") with a mean in the liver range";
        res.message = msg.str();
        return res;
    }
    // smooth over about one noise sd of the cell means so that the mode is not a noise spike
    const int r = std::max(1, static_cast<int>(std::lround(0.5 * noise / bin)));
    std::size_t mode = 0;
    double mode_v = -1;
    for (int b = 0; b < kBins; ++b) {
        double v = 0;
        for (int d = -r; d <= r; ++d)
            if (b + d >= 0 && b + d < kBins)
                v += hist[static_cast<std::size_t>(b + d)] * (1.0 - std::abs(d) / (r + 1.0));
        if (v > mode_v) {
            mode_v = v;
            mode = static_cast<std::size_t>(b);
        }
    }
    // refine: the mean of the homogeneous cells within one bin-radius of the mode
    double msum = 0;
    int mcount = 0;
    const double mode_centre = p.liver_range_lo + (static_cast<double>(mode) + 0.5) * bin;
    for (const auto& sc : slices)
        for (const auto& c : sc.cells)
            if (c.candidate && c.sd <= sd_thr && std::abs(c.mean - mode_centre) <= (r + 0.5) * bin) {
                msum += c.mean;
                ++mcount;
            }
    const double liver = mcount > 0 ? msum / mcount : mode_centre;
    const double band = p.acceptance_sigma * std::max(noise, bin);
    res.liver_value = liver;

    // Accepted cells; per slice the largest 4-connected group after erosion; the slice where it
    // is largest.
    const SliceCells* best_slice = nullptr;
    cv::Mat best_group;
    int best_area = 0;
    for (const auto& sc : slices) {
        cv::Mat acc = cv::Mat::zeros(sc.ncv, sc.ncu, CV_8U);
        for (const auto& c : sc.cells)
            if (c.candidate && c.sd <= sd_thr && std::abs(c.mean - liver) <= band)
                acc.at<std::uint8_t>(c.cv, c.cu) = 255;
        if (p.erode_cells > 0)
            cv::erode(acc, acc, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * p.erode_cells + 1, 2 * p.erode_cells + 1)),
                      cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(0));
        cv::Mat labels, stats, centroids;
        const int n = cv::connectedComponentsWithStats(acc, labels, stats, centroids, 4, CV_32S);
        for (int l = 1; l < n; ++l) {
            const int a = stats.at<int>(l, cv::CC_STAT_AREA);
            if (a > best_area) {
                best_area = a;
                best_slice = &sc;
                best_group = labels == l;
            }
        }
    }
    std::vector<double> acc_sd;
    if (best_slice)
        for (const auto& c : best_slice->cells)
            if (best_group.at<std::uint8_t>(c.cv, c.cu))
                acc_sd.push_back(c.sd);
    if (!acc_sd.empty()) {
        std::nth_element(acc_sd.begin(), acc_sd.begin() + static_cast<std::ptrdiff_t>(acc_sd.size() / 2), acc_sd.end());
        res.liver_sigma = acc_sd[acc_sd.size() / 2];
    }
    const double area = best_area * cell_area;
    res.area_mm2 = area;
    msg << "liver value " << liver << " (noise sd " << noise << ", " << homogeneous << " homogeneous cells on slices "
        << k_lo << ".." << k_hi << (with_start ? ", below the start slice" : ", no start slice: whole volume") << ")";
    if (!best_slice || area < p.min_area_mm2) {
        msg << "; the largest group of liver-like cells covers " << area << " mm2 < min_area_mm2 " << p.min_area_mm2
            << ": no liver found";
        res.message = msg.str();
        return res;
    }
    if (area > p.max_body_fraction * best_slice->body_area_mm2) {
        msg << "; the liver-like group covers " << 100.0 * area / best_slice->body_area_mm2
            << "% of the body on slice " << best_slice->k << " (> max_body_fraction): no contrast, not a liver";
        res.message = msg.str();
        return res;
    }
    // Contrast: a liver is surrounded by other tissue (fat, air, bone). A slice whose body is
    // almost all at the liver value (a constant or flat image) gives no liver, whatever its size.
    {
        const int k = best_slice->k;
        const cv::Mat src(ny, nx, CV_32F,
                          const_cast<float*>(vol.data.data() + static_cast<std::size_t>(nx) * ny * static_cast<std::size_t>(k)));
        const cv::Mat body = filled_largest_component(src > p.body_threshold);
        const double tol = 5.0 * std::max(noise, bin);
        cv::Mat differ = (src < liver - tol) | (src > liver + tol);
        const double frac = cv::countNonZero(differ & body) / std::max(1.0, double(cv::countNonZero(body)));
        if (frac < kMinContrastFraction) {
            msg << "; only " << 100.0 * frac << "% of the body on slice " << k << " differs from the liver value by more "
                << "than 5 noise sd: no contrast, not a liver";
            res.message = msg.str();
            return res;
        }
    }
    res.found = true;
    res.slice = best_slice->k;
    res.mask = core::LabelImage3D(core::axial_slice(vol, best_slice->k).geometry(), 0);
    for (const auto& c : best_slice->cells) {
        if (!best_group.at<std::uint8_t>(c.cv, c.cu))
            continue;
        for (int j = c.cv * ch; j < (c.cv + 1) * ch; ++j)
            for (int i = c.cu * cw; i < (c.cu + 1) * cw; ++i)
                res.mask.at(i, j, 0) = 1;
    }
    msg << "; seed of " << area << " mm2 on slice " << res.slice;
    res.message = msg.str();
    return res;
}

} // namespace lobe::seg
