#include "lobe/seg/vesselness.h"

#include "detail/volume.h"
#include "lobe/seg/dsg.h"
#include "lobe/seg/edge_map.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

namespace lobe::seg {
namespace {

using Index = std::ptrdiff_t;

//! Eigenvalues of the symmetric matrix [[a, d, e], [d, b, f], [e, f, c]] (closed form, Smith
//! 1961), sorted by increasing magnitude.
std::array<double, 3> eigenvalues_sym3(double a, double b, double c, double d, double e, double f)
{
    const double p1 = d * d + e * e + f * f;
    const double q = (a + b + c) / 3.0;
    const double p2 = (a - q) * (a - q) + (b - q) * (b - q) + (c - q) * (c - q) + 2.0 * p1;
    std::array<double, 3> l{q, q, q};
    if (p2 > 1e-30) {
        const double p = std::sqrt(p2 / 6.0);
        const double ba = (a - q) / p, bb = (b - q) / p, bc = (c - q) / p, bd = d / p, be = e / p, bf = f / p;
        const double det = ba * (bb * bc - bf * bf) - bd * (bd * bc - bf * be) + be * (bd * bf - bb * be);
        const double r = std::clamp(det / 2.0, -1.0, 1.0);
        const double phi = std::acos(r) / 3.0;
        l[0] = q + 2.0 * p * std::cos(phi);
        l[2] = q + 2.0 * p * std::cos(phi + 2.0943951023931957); // + 2π/3
        l[1] = 3.0 * q - l[0] - l[2];
    }
    std::sort(l.begin(), l.end(), [](double x, double y) { return std::abs(x) < std::abs(y); });
    return l;
}

//! Unit eigenvector of the same matrix for eigenvalue `lambda`: the longest cross product of two
//! rows of (H - λI), which is orthogonal to both and hence spans the null space.
std::array<double, 3> eigenvector_sym3(double a, double b, double c, double d, double e, double f, double lambda)
{
    const std::array<double, 3> r0{a - lambda, d, e}, r1{d, b - lambda, f}, r2{e, f, c - lambda};
    auto crs = [](const std::array<double, 3>& u, const std::array<double, 3>& v) {
        return std::array<double, 3>{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    };
    const std::array<std::array<double, 3>, 3> cand{crs(r0, r1), crs(r0, r2), crs(r1, r2)};
    double best = -1;
    std::array<double, 3> v{1, 0, 0};
    for (const auto& w : cand) {
        const double n2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
        if (n2 > best) {
            best = n2;
            v = w;
        }
    }
    const double n = std::sqrt(best);
    if (!(n > 1e-30))
        return {1, 0, 0};
    return {v[0] / n, v[1] / n, v[2] / n};
}

//! The σ²-normalised Hessian of `f` at (i, j, k) by central differences in mm (clamped at the
//! borders): {xx, yy, zz, xy, xz, yz}.
struct Hessian {
    double xx, yy, zz, xy, xz, yz;
};

Hessian hessian_at(const core::ImageF& f, int i, int j, int k, double s2)
{
    const int nx = f.size[0], ny = f.size[1], nz = f.size[2];
    const int im = std::max(i - 1, 0), ip = std::min(i + 1, nx - 1);
    const int jm = std::max(j - 1, 0), jp = std::min(j + 1, ny - 1);
    const int km = std::max(k - 1, 0), kp = std::min(k + 1, nz - 1);
    const double hx = f.spacing[0], hy = f.spacing[1], hz = f.spacing[2];
    auto at = [&](int a, int b, int d) { return static_cast<double>(f.at(a, b, d)); };
    const double c = at(i, j, k);
    Hessian h{};
    h.xx = (at(ip, j, k) - 2 * c + at(im, j, k)) / (hx * hx);
    h.yy = (at(i, jp, k) - 2 * c + at(i, jm, k)) / (hy * hy);
    h.zz = (at(i, j, kp) - 2 * c + at(i, j, km)) / (hz * hz);
    h.xy = (at(ip, jp, k) - at(ip, jm, k) - at(im, jp, k) + at(im, jm, k)) / (4 * hx * hy);
    h.xz = (at(ip, j, kp) - at(ip, j, km) - at(im, j, kp) + at(im, j, km)) / (4 * hx * hz);
    h.yz = (at(i, jp, kp) - at(i, jp, km) - at(i, jm, kp) + at(i, jm, km)) / (4 * hy * hz);
    h.xx *= s2;
    h.yy *= s2;
    h.zz *= s2;
    h.xy *= s2;
    h.xz *= s2;
    h.yz *= s2;
    return h;
}

void check_params(const VesselnessParams& p)
{
    if (p.scales_mm.empty())
        throw core::InvalidInputError("vesselness: at least one scale is needed");
    for (double s : p.scales_mm)
        if (!(s > 0) || !std::isfinite(s))
            throw core::InvalidInputError("vesselness: scales must be finite and > 0 mm, got " + std::to_string(s));
    if (!(p.alpha > 0) || !(p.beta > 0) || !std::isfinite(p.alpha) || !std::isfinite(p.beta))
        throw core::InvalidInputError("vesselness: alpha and beta must be finite and > 0");
    if (std::isnan(p.structureness) || std::isinf(p.structureness))
        throw core::InvalidInputError("vesselness: structureness must be finite");
}

} // namespace

VesselnessResult vesselness(const core::ImageF& image, const VesselnessParams& params, const core::LabelImage3D* roi)
{
    detail::check_image(image, "vesselness: image");
    check_params(params);
    if (image.size[2] < 3)
        throw core::InvalidInputError("vesselness: needs a volume of at least 3 slices (got " +
                                      std::to_string(image.size[2]) + ")");
    if (roi)
        detail::check_same_grid(image, *roi, "vesselness: the ROI");

    VesselnessResult res;
    res.vesselness = core::ImageF(image.geometry(), 0.f);
    res.scale_mm = core::ImageF(image.geometry(), 0.f);
    res.axis = VectorField(image.geometry());

    detail::Box box;
    if (roi) {
        box = detail::bounding_box(*roi);
        if (box.empty())
            return res;
    } else {
        box.lo = {0, 0, 0};
        box.hi = {image.size[0] - 1, image.size[1] - 1, image.size[2] - 1};
    }
    const double smax = *std::max_element(params.scales_mm.begin(), params.scales_mm.end());
    const detail::Box outer = detail::grown(box, detail::voxels_for(image, 3.0 * smax), image);
    const core::ImageF sub = detail::crop(image, outer);
    for (float v : sub.data)
        if (!std::isfinite(v))
            throw core::InvalidInputError("vesselness: the image holds non-finite values");

    // The ROI voxels, as indices into the crop.
    std::vector<std::size_t> vox;
    {
        const core::LabelImage3D mask = roi ? detail::crop(*roi, outer) : core::LabelImage3D(sub.geometry(), 1);
        for (int k = box.lo[2] - outer.lo[2]; k <= box.hi[2] - outer.lo[2]; ++k)
            for (int j = box.lo[1] - outer.lo[1]; j <= box.hi[1] - outer.lo[1]; ++j)
                for (int i = box.lo[0] - outer.lo[0]; i <= box.hi[0] - outer.lo[0]; ++i)
                    if (mask.at(i, j, k))
                        vox.push_back(sub.index(i, j, k));
    }
    const Index nv = static_cast<Index>(vox.size());
    const int nx = sub.size[0], ny = sub.size[1];
    auto ijk = [&](std::size_t v) {
        const int i = static_cast<int>(v % static_cast<std::size_t>(nx));
        const int j = static_cast<int>((v / static_cast<std::size_t>(nx)) % static_cast<std::size_t>(ny));
        const int k = static_cast<int>(v / (static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny)));
        return std::array<int, 3>{i, j, k};
    };

    std::vector<float> best(vox.size(), 0.f), best_scale(vox.size(), 0.f);
    std::array<std::vector<float>, 3> best_axis;
    for (auto& a : best_axis)
        a.assign(vox.size(), 0.f);
    const double sign = params.bright ? 1.0 : -1.0;
    const double a2 = 2 * params.alpha * params.alpha, b2 = 2 * params.beta * params.beta;

    for (double sigma : params.scales_mm) {
        const core::ImageF sm = gaussian_smooth(sub, sigma);
        const double s2 = sigma * sigma;
        double c = params.structureness;
        if (c <= 0) {
            // Frangi's c: half the (robust) maximum of the Hessian norm over the ROI.
            std::vector<float> norms(vox.size());
#pragma omp parallel for schedule(static)
            for (Index n = 0; n < nv; ++n) {
                const auto p = ijk(vox[static_cast<std::size_t>(n)]);
                const Hessian h = hessian_at(sm, p[0], p[1], p[2], s2);
                norms[static_cast<std::size_t>(n)] = static_cast<float>(std::sqrt(
                    h.xx * h.xx + h.yy * h.yy + h.zz * h.zz + 2 * (h.xy * h.xy + h.xz * h.xz + h.yz * h.yz)));
            }
            c = 0.5 * detail::quantile(std::move(norms), 0.999);
            if (!(c > 0))
                c = 1.0; // a flat ROI: every response is 0 anyway
        }
        res.structureness.push_back(c);
        const double c2 = 2 * c * c;
#pragma omp parallel for schedule(static)
        for (Index n = 0; n < nv; ++n) {
            const std::size_t u = static_cast<std::size_t>(n);
            const auto p = ijk(vox[u]);
            const Hessian h = hessian_at(sm, p[0], p[1], p[2], s2);
            const auto l = eigenvalues_sym3(h.xx, h.yy, h.zz, h.xy, h.xz, h.yz);
            const double l2 = sign * l[1], l3 = sign * l[2];
            if (l2 >= 0 || l3 >= 0)
                continue; // a bright tube has both cross-section curvatures negative
            const double ra = std::abs(l[1]) / std::abs(l[2]);
            const double rb = std::abs(l[0]) / std::sqrt(std::abs(l[1] * l[2]));
            const double s = l[0] * l[0] + l[1] * l[1] + l[2] * l[2];
            const double v = (1 - std::exp(-ra * ra / a2)) * std::exp(-rb * rb / b2) * (1 - std::exp(-s / c2));
            if (v > static_cast<double>(best[u])) {
                best[u] = static_cast<float>(v);
                best_scale[u] = static_cast<float>(sigma);
                const auto e = eigenvector_sym3(h.xx, h.yy, h.zz, h.xy, h.xz, h.yz, l[0]);
                for (int a = 0; a < 3; ++a)
                    best_axis[static_cast<std::size_t>(a)][u] = static_cast<float>(e[static_cast<std::size_t>(a)]);
            }
        }
    }

    for (std::size_t u = 0; u < vox.size(); ++u) {
        const auto p = ijk(vox[u]);
        const std::size_t w = image.index(p[0] + outer.lo[0], p[1] + outer.lo[1], p[2] + outer.lo[2]);
        res.vesselness.data[w] = best[u];
        res.scale_mm.data[w] = best_scale[u];
        for (int a = 0; a < 3; ++a)
            res.axis.c[static_cast<std::size_t>(a)].data[w] = best_axis[static_cast<std::size_t>(a)][u];
    }
    return res;
}

DirectionalSharpeningResult directional_sharpening(const core::ImageF& image, const VesselnessResult& v,
                                                   const DirectionalSharpeningParams& params)
{
    detail::check_image(image, "directional_sharpening: image");
    detail::check_same_grid(image, v.vesselness, "directional_sharpening: the vesselness");
    for (const auto& c : v.axis.c)
        detail::check_same_grid(image, c, "directional_sharpening: the vessel axis");
    if (!(params.half_length_mm >= 0) || !std::isfinite(params.half_length_mm) || !std::isfinite(params.step_mm))
        throw core::InvalidInputError("directional_sharpening: half_length_mm must be finite and >= 0");
    if (params.sharpen_max > 0)
        (void)sharpen_kernel(0.5, params.sharpen_max); // throws for a kernel argument past the pole

    DirectionalSharpeningResult r{image, v.vesselness};
    const double step = params.step_mm > 0 ? params.step_mm
                                           : std::min({image.spacing[0], image.spacing[1], image.spacing[2]});
    const int half = params.half_length_mm > 0 ? std::max(1, static_cast<int>(std::lround(params.half_length_mm / step))) : 0;
    const Index n = static_cast<Index>(image.data.size());
    const int nx = image.size[0], ny = image.size[1];
#pragma omp parallel for schedule(dynamic, 4096)
    for (Index s = 0; s < n; ++s) {
        const std::size_t u = static_cast<std::size_t>(s);
        const double vu = static_cast<double>(v.vesselness.data[u]);
        if (!(vu >= params.min_vesselness) || vu <= 0)
            continue;
        const int i = static_cast<int>(u % static_cast<std::size_t>(nx));
        const int j = static_cast<int>((u / static_cast<std::size_t>(nx)) % static_cast<std::size_t>(ny));
        const int k = static_cast<int>(u / (static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny)));
        // The axis in voxel units per mm.
        const double dx = static_cast<double>(v.axis.c[0].data[u]) / image.spacing[0],
                     dy = static_cast<double>(v.axis.c[1].data[u]) / image.spacing[1],
                     dz = static_cast<double>(v.axis.c[2].data[u]) / image.spacing[2];
        double si = 0, sv = 0;
        for (int t = -half; t <= half; ++t) {
            const double d = t * step;
            si += static_cast<double>(detail::sample_trilinear(image, i + d * dx, j + d * dy, k + d * dz));
            sv += static_cast<double>(detail::sample_trilinear(v.vesselness, i + d * dx, j + d * dy, k + d * dz));
        }
        r.intensity.data[u] = static_cast<float>(si / (2 * half + 1));
        r.vesselness.data[u] = static_cast<float>(sv / (2 * half + 1));
    }
    if (params.sharpen_max > 0)
        for (float& x : r.vesselness.data)
            x = static_cast<float>(sharpen_kernel(x, params.sharpen_max));
    return r;
}

} // namespace lobe::seg
