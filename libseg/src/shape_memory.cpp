#include "lobe/seg/shape_memory.h"

#include "lobe/seg/distance_transform.h"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

namespace lobe::seg {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

//! One axial slice of a mask as a view: pixel (i, j) is m[i + nx * j].
struct SliceView {
    const std::uint8_t* m = nullptr;
    int nx = 0, ny = 0;
    double sx = 1.0, sy = 1.0;
};

//! Area [mm^2], centroid [mm] and bounding box of a slice mask.
struct SliceMoments {
    std::size_t count = 0;
    double area = 0.0, cx = 0.0, cy = 0.0;
    int i0 = 0, i1 = -1, j0 = 0, j1 = -1; //!< inclusive bounding box
};

SliceMoments moments(const SliceView& s)
{
    SliceMoments r;
    r.i0 = s.nx;
    r.j0 = s.ny;
    double sx = 0.0, sy = 0.0;
    for (int j = 0; j < s.ny; ++j)
        for (int i = 0; i < s.nx; ++i)
            if (s.m[i + static_cast<std::size_t>(s.nx) * j]) {
                ++r.count;
                sx += i;
                sy += j;
                r.i0 = std::min(r.i0, i);
                r.i1 = std::max(r.i1, i);
                r.j0 = std::min(r.j0, j);
                r.j1 = std::max(r.j1, j);
            }
    r.area = static_cast<double>(r.count) * s.sx * s.sy;
    if (r.count > 0) {
        r.cx = sx / static_cast<double>(r.count) * s.sx;
        r.cy = sy / static_cast<double>(r.count) * s.sy;
    }
    return r;
}

//! A rectangle of the slice grid, inclusive.
struct Box {
    int i0, i1, j0, j1;
    int w() const { return i1 - i0 + 1; }
    int h() const { return j1 - j0 + 1; }
};

Box union_box(const SliceMoments& a, const SliceMoments& b, int pad, int nx, int ny)
{
    return {std::max(0, std::min(a.i0, b.i0) - pad), std::min(nx - 1, std::max(a.i1, b.i1) + pad),
            std::max(0, std::min(a.j0, b.j0) - pad), std::min(ny - 1, std::max(a.j1, b.j1) + pad)};
}

//! Exact Euclidean distance [mm] to the mask inside `box` (the nearest mask pixel must lie in
//! the box, which holds when the box contains the whole mask).
core::BigVector<float> distance_in_box(const SliceView& s, const Box& box)
{
    core::ImageGeometry g;
    g.size = {box.w(), box.h(), 1};
    g.spacing = {s.sx, s.sy, 1.0};
    core::LabelImage3D f(g, 0);
    for (int j = 0; j < box.h(); ++j)
        for (int i = 0; i < box.w(); ++i)
            f.data[static_cast<std::size_t>(i) + static_cast<std::size_t>(box.w()) * j] =
                s.m[static_cast<std::size_t>(box.i0 + i) + static_cast<std::size_t>(s.nx) * (box.j0 + j)] ? 1 : 0;
    return euclidean_distance(f).data;
}

//! What one ordered transition (previous -> next) measures.
struct Transition {
    double radius_prev = 0.0; //!< equivalent radius of the previous slice [mm]
    double outward = 0.0, envelope = 0.0, inward = 0.0, log_ratio = 0.0, centroid = 0.0, dice = 0.0;
};

//! Labels of the 8-connected components of a slice mask inside `box` (0 = background).
cv::Mat components_in_box(const SliceView& s, const Box& box, int& n)
{
    cv::Mat m(box.h(), box.w(), CV_8U);
    for (int j = 0; j < box.h(); ++j)
        for (int i = 0; i < box.w(); ++i)
            m.at<std::uint8_t>(j, i) =
                s.m[static_cast<std::size_t>(box.i0 + i) + static_cast<std::size_t>(s.nx) * (box.j0 + j)] ? 1 : 0;
    cv::Mat lab;
    n = cv::connectedComponents(m, lab, 8, CV_32S);
    return lab;
}

//! Both ordered transitions between two non-empty slices a and b: [0] = a -> b, [1] = b -> a.
//! Motion is measured on the components of each slice that overlap the other slice: a piece
//! that appears or vanishes on its own (a lobe's tip) is not a moving boundary (its area
//! still counts in the area ratio).
std::array<Transition, 2> measure_pair(const SliceView& a, const SliceView& b, const SliceMoments& ma,
                                       const SliceMoments& mb)
{
    const Box box = union_box(ma, mb, 1, a.nx, a.ny);
    const core::BigVector<float> da = distance_in_box(a, box), db = distance_in_box(b, box);
    int na = 0, nb = 0;
    const cv::Mat la = components_in_box(a, box, na), lb = components_in_box(b, box, nb);
    std::vector<std::uint8_t> a_touches(static_cast<std::size_t>(na), 0), b_touches(static_cast<std::size_t>(nb), 0);
    std::size_t both = 0;
    for (int j = 0; j < box.h(); ++j)
        for (int i = 0; i < box.w(); ++i) {
            const int ca = la.at<std::int32_t>(j, i), cb = lb.at<std::int32_t>(j, i);
            if (ca > 0 && cb > 0) {
                a_touches[static_cast<std::size_t>(ca)] = 1;
                b_touches[static_cast<std::size_t>(cb)] = 1;
                ++both;
            }
        }
    double a_from_b = 0.0, b_from_a = 0.0; // farthest pixel of a from b, of b from a
    std::vector<float> new_a, new_b;       // distances of a's pixels outside b, and b's outside a
    for (int j = 0; j < box.h(); ++j)
        for (int i = 0; i < box.w(); ++i) {
            const std::size_t l = static_cast<std::size_t>(i) + static_cast<std::size_t>(box.w()) * j;
            if (a_touches[static_cast<std::size_t>(la.at<std::int32_t>(j, i))])
                a_from_b = std::max(a_from_b, static_cast<double>(db[l]));
            if (b_touches[static_cast<std::size_t>(lb.at<std::int32_t>(j, i))])
                b_from_a = std::max(b_from_a, static_cast<double>(da[l]));
            if (la.at<std::int32_t>(j, i) > 0 && db[l] > 0.f)
                new_a.push_back(db[l]);
            if (lb.at<std::int32_t>(j, i) > 0 && da[l] > 0.f)
                new_b.push_back(da[l]);
        }
    const double dice = 2.0 * static_cast<double>(both) / static_cast<double>(ma.count + mb.count);
    const double shift = std::hypot(ma.cx - mb.cx, ma.cy - mb.cy);
    const double lr = std::log(mb.area / ma.area);
    auto p95 = [](std::vector<float>& v) {
        if (v.empty())
            return 0.0;
        const auto r = static_cast<std::ptrdiff_t>(std::llround(0.95 * static_cast<double>(v.size() - 1)));
        std::nth_element(v.begin(), v.begin() + r, v.end());
        return static_cast<double>(v[static_cast<std::size_t>(r)]);
    };
    const double env_b = p95(new_b), env_a = p95(new_a);
    Transition ab{std::sqrt(ma.area / M_PI), b_from_a, env_b, a_from_b, lr, shift, dice};
    Transition ba{std::sqrt(mb.area / M_PI), a_from_b, env_a, b_from_a, -lr, shift, dice};
    return {ab, ba};
}

double quantile(std::vector<double> v, double q)
{
    if (v.empty())
        return 0.0;
    std::sort(v.begin(), v.end());
    const double pos = std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1);
    const auto lo = static_cast<std::size_t>(std::floor(pos));
    const std::size_t hi = std::min(lo + 1, v.size() - 1);
    return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

SliceView slice_of(const core::LabelImage3D& m, int k)
{
    return {m.data.data() + static_cast<std::size_t>(m.size[0]) * static_cast<std::size_t>(m.size[1]) *
                                static_cast<std::size_t>(k),
            m.size[0], m.size[1], m.spacing[0], m.spacing[1]};
}

void check_one_slice(const core::LabelImage3D& m, const std::string& what)
{
    core::validate_geometry(m, what);
    if (m.size[2] != 1)
        throw core::InvalidInputError(what + " must be one slice (size[2] == 1), not " + std::to_string(m.size[2]));
    if (m.data.size() != m.voxel_count())
        throw core::InvalidInputError(what + ": holds " + std::to_string(m.data.size()) + " values for " +
                                      std::to_string(m.voxel_count()) + " voxels");
}

//! Same in-plane grid; the origins may differ along the slice normal (axial_slice moves the
//! origin to its slice, so consecutive slices differ there).
bool same_plane_grid(const core::ImageGeometry& a, const core::ImageGeometry& b)
{
    core::ImageGeometry bb = b;
    const core::Vec3 d{b.origin[0] - a.origin[0], b.origin[1] - a.origin[1], b.origin[2] - a.origin[2]};
    const core::Vec3 n = a.axis(2);
    const double along = core::dot(d, n);
    for (int c = 0; c < 3; ++c)
        bb.origin[static_cast<std::size_t>(c)] -= along * n[c];
    bb.spacing[2] = a.spacing[2];
    return core::same_grid(a, bb);
}

void check_memory(const ShapeMemory& memory)
{
    if (memory.steps.empty())
        throw core::InvalidInputError("shape memory: no learnt steps (train it first)");
    if (!(memory.margin > 0) || !(memory.allowance_px >= 0))
        throw core::InvalidInputError("shape memory: margin must be positive and allowance_px non-negative");
}

void check_dz(double dz_mm)
{
    if (!std::isfinite(dz_mm) || !(dz_mm > 0))
        throw core::InvalidInputError("shape memory: the slice gap dz must be finite and positive, not " +
                                      std::to_string(dz_mm));
}

int bin_of(const ShapeMemory& memory, double radius, double rho)
{
    int b = 0;
    for (std::size_t s = 0; s < memory.steps.size(); ++s)
        if (radius >= memory.steps[s].radius_min_mm && rho >= memory.steps[s].rho_min)
            b = static_cast<int>(s);
    return b;
}

double phase(double area, double largest)
{
    if (!(largest > 0) || !std::isfinite(largest))
        return 1.0;
    return std::min(1.0, area / largest);
}

double pixel_mm(const core::ImageGeometry& g)
{
    return std::max(g.spacing[0], g.spacing[1]);
}

//! The previous mask dilated (dilate = true) or eroded by `r_mm`, exact Euclidean.
core::LabelImage3D offset_mask(const core::LabelImage3D& previous, double r_mm, bool dilate)
{
    core::LabelImage3D out(previous.geometry(), 0);
    const SliceView s = slice_of(previous, 0);
    const SliceMoments m = moments(s);
    if (m.count == 0)
        throw core::InvalidInputError("shape memory: the previous slice is empty");
    if (dilate) {
        const int pad = static_cast<int>(std::ceil(r_mm / std::min(s.sx, s.sy))) + 1;
        const Box box = union_box(m, m, pad, s.nx, s.ny);
        const core::BigVector<float> d = distance_in_box(s, box);
        for (int j = 0; j < box.h(); ++j)
            for (int i = 0; i < box.w(); ++i)
                if (static_cast<double>(d[static_cast<std::size_t>(i) + static_cast<std::size_t>(box.w()) * j]) <= r_mm)
                    out.data[static_cast<std::size_t>(box.i0 + i) + static_cast<std::size_t>(s.nx) * (box.j0 + j)] = 1;
        return out;
    }
    // Erosion: distance to the background (the grid outside counts as background).
    const Box box = union_box(m, m, 1, s.nx, s.ny);
    core::ImageGeometry g;
    g.size = {box.w(), box.h(), 1};
    g.spacing = {s.sx, s.sy, 1.0};
    core::LabelImage3D bg(g, 1);
    for (int j = 0; j < box.h(); ++j)
        for (int i = 0; i < box.w(); ++i) {
            const int gi = box.i0 + i, gj = box.j0 + j;
            const bool border = gi == 0 || gj == 0 || gi == s.nx - 1 || gj == s.ny - 1;
            if (s.m[static_cast<std::size_t>(gi) + static_cast<std::size_t>(s.nx) * gj] && !border)
                bg.data[static_cast<std::size_t>(i) + static_cast<std::size_t>(box.w()) * j] = 0;
        }
    const core::BigVector<float> d = euclidean_distance(bg).data;
    for (int j = 0; j < box.h(); ++j)
        for (int i = 0; i < box.w(); ++i)
            if (static_cast<double>(d[static_cast<std::size_t>(i) + static_cast<std::size_t>(box.w()) * j]) > r_mm)
                out.data[static_cast<std::size_t>(box.i0 + i) + static_cast<std::size_t>(s.nx) * (box.j0 + j)] = 1;
    return out;
}

struct Allowed {
    double outward, envelope, inward, growth, shrink, centroid;
};

Allowed allowed_at(const ShapeMemory& memory, const ShapeStep& st, double radius_prev, double dz, double px)
{
    const double a = memory.allowance_px * px;
    const double r = std::max(radius_prev, px);
    return {memory.margin * st.outward_per_mm * dz + a, memory.margin * st.envelope_per_mm * dz + a, memory.margin * st.inward_per_mm * dz + a,
            memory.margin * st.growth_per_mm * dz + std::log1p(2.0 * a / r),
            memory.margin * st.shrink_per_mm * dz + std::log1p(2.0 * a / r), memory.margin * st.centroid_per_mm * dz + a};
}

std::string fmt(double v)
{
    std::ostringstream s;
    s.precision(3);
    s << v;
    return s.str();
}

} // namespace

ShapeMemory train_shape_memory(const std::vector<const core::ImageF*>& images,
                               const std::vector<const core::LabelImage3D*>& liver_masks,
                               const ShapeTrainParams& params)
{
    if (images.empty())
        throw core::InvalidInputError("train_shape_memory: no training volumes");
    if (images.size() != liver_masks.size())
        throw core::InvalidInputError("train_shape_memory: " + std::to_string(images.size()) + " images but " +
                                      std::to_string(liver_masks.size()) + " liver masks");
    const auto& edges = params.radius_edges_mm;
    if (edges.empty() || edges[0] != 0.0 || !std::is_sorted(edges.begin(), edges.end()) ||
        std::adjacent_find(edges.begin(), edges.end()) != edges.end())
        throw core::InvalidInputError("train_shape_memory: radius_edges_mm must start at 0 and increase strictly");
    if (!(params.quantile >= 0.0 && params.quantile <= 1.0) || !(params.margin > 0) || !(params.allowance_px >= 0) ||
        params.intensity_erosion_px < 0 || !(params.envelope_quantile >= 0.0 && params.envelope_quantile <= 1.0))
        throw core::InvalidInputError("train_shape_memory: quantile must be in [0, 1], margin positive, "
                                      "allowance and erosion non-negative");

    ShapeMemory mem;
    mem.margin = params.margin;
    mem.allowance_px = params.allowance_px;
    mem.intensity.modality = params.modality;
    const auto& rho_edges = params.rho_edges;
    if (rho_edges.empty() || rho_edges[0] != 0.0 || !std::is_sorted(rho_edges.begin(), rho_edges.end()) ||
        std::adjacent_find(rho_edges.begin(), rho_edges.end()) != rho_edges.end() || rho_edges.back() > 1.0)
        throw core::InvalidInputError("train_shape_memory: rho_edges must start at 0 and increase strictly up to 1");
    const std::size_t nr = edges.size(), np = rho_edges.size(), nb = nr * np;
    std::vector<std::vector<double>> out(nb), env(nb), in(nb), grow(nb), shrink(nb), cen(nb);
    std::vector<double> dice_min(nb, 1.0);
    std::vector<float> values;
    mem.volume_ml_min = mem.extent_mm_min = mem.max_area_mm2_min = kInf;

    for (std::size_t v = 0; v < images.size(); ++v) {
        const std::string what = "train_shape_memory: volume " + std::to_string(v + 1);
        if (!images[v] || !liver_masks[v])
            throw core::InvalidInputError(what + ": null image or mask");
        core::validate_geometry(*images[v], what + " image");
        if (images[v]->data.size() != images[v]->voxel_count() || liver_masks[v]->data.size() != liver_masks[v]->voxel_count())
            throw core::InvalidInputError(what + ": data size does not match the grid");
        if (!core::same_grid(*images[v], *liver_masks[v]))
            throw core::InvalidInputError(what + ": the liver mask is not on the image's grid");
        // Transitions are measured between axial slices, as `segment_liver` propagates: a
        // coronal or sagittal stack is read on its axial grid (flips alone change nothing that
        // is measured: both directions are pooled and the moments are in-plane).
        const core::AxisOrder order = core::patient_axis_order(*images[v]);
        core::ImageF turned_img;
        core::LabelImage3D turned_mask;
        if (!order.flips_only()) {
            turned_img = core::reorder_axes(*images[v], order);
            turned_mask = core::reorder_axes(*liver_masks[v], order);
        }
        const core::ImageF& img = order.flips_only() ? *images[v] : turned_img;
        const core::LabelImage3D& mask = order.flips_only() ? *liver_masks[v] : turned_mask;

        std::vector<SliceMoments> mom(static_cast<std::size_t>(mask.size[2]));
        std::size_t count = 0;
        int k_first = -1, k_last = -1;
        double max_area = 0.0;
        for (int k = 0; k < mask.size[2]; ++k) {
            mom[static_cast<std::size_t>(k)] = moments(slice_of(mask, k));
            if (mom[static_cast<std::size_t>(k)].count > 0) {
                count += mom[static_cast<std::size_t>(k)].count;
                if (k_first < 0)
                    k_first = k;
                k_last = k;
                max_area = std::max(max_area, mom[static_cast<std::size_t>(k)].area);
                ++mem.slices;
            }
        }
        if (count == 0)
            throw core::InvalidInputError(what + ": the liver mask is empty");
        const double dz = mask.spacing[2];
        const double vol = static_cast<double>(count) * mask.spacing[0] * mask.spacing[1] * dz / 1000.0;
        mem.volume_ml_min = std::min(mem.volume_ml_min, vol);
        mem.volume_ml_max = std::max(mem.volume_ml_max, vol);
        mem.extent_mm_min = std::min(mem.extent_mm_min, (k_last - k_first) * dz);
        mem.extent_mm_max = std::max(mem.extent_mm_max, (k_last - k_first) * dz);
        mem.max_area_mm2_min = std::min(mem.max_area_mm2_min, max_area);
        mem.max_area_mm2_max = std::max(mem.max_area_mm2_max, max_area);

        // Both propagation directions: upward (k -> k+1) and downward (k+1 -> k), each with the
        // largest area met so far in that direction for the phase rho.
        std::vector<std::array<Transition, 2>> pairs(static_cast<std::size_t>(mask.size[2]));
        std::vector<char> have(static_cast<std::size_t>(mask.size[2]), 0);
        for (int k = 0; k + 1 < mask.size[2]; ++k) {
            const auto& ma = mom[static_cast<std::size_t>(k)];
            const auto& mb = mom[static_cast<std::size_t>(k + 1)];
            if (ma.count == 0 || mb.count == 0)
                continue;
            pairs[static_cast<std::size_t>(k)] = measure_pair(slice_of(mask, k), slice_of(mask, k + 1), ma, mb);
            have[static_cast<std::size_t>(k)] = 1;
        }
        auto add = [&](const Transition& t, double area_prev, double largest) {
            const double rho = area_prev / largest;
            std::size_t br = 0, bp = 0;
            while (br + 1 < nr && t.radius_prev >= edges[br + 1])
                ++br;
            while (bp + 1 < np && rho >= rho_edges[bp + 1])
                ++bp;
            const std::size_t b = bp * nr + br;
            out[b].push_back(t.outward / dz);
            env[b].push_back(t.envelope / dz);
            in[b].push_back(t.inward / dz);
            (t.log_ratio >= 0 ? grow[b] : shrink[b]).push_back(std::abs(t.log_ratio) / dz);
            cen[b].push_back(t.centroid / dz);
            dice_min[b] = std::min(dice_min[b], t.dice);
            ++mem.transitions;
        };
        double largest = 0.0;
        for (int k = 0; k + 1 < mask.size[2]; ++k) {
            largest = std::max(largest, mom[static_cast<std::size_t>(k)].area);
            if (!have[static_cast<std::size_t>(k)]) {
                largest = 0.0; // a gap restarts the propagation
                continue;
            }
            add(pairs[static_cast<std::size_t>(k)][0], mom[static_cast<std::size_t>(k)].area, largest);
        }
        largest = 0.0;
        for (int k = mask.size[2] - 2; k >= 0; --k) {
            largest = std::max(largest, mom[static_cast<std::size_t>(k + 1)].area);
            if (!have[static_cast<std::size_t>(k)]) {
                largest = 0.0;
                continue;
            }
            add(pairs[static_cast<std::size_t>(k)][1], mom[static_cast<std::size_t>(k + 1)].area, largest);
        }

        // Intensity inside the mask, eroded in-plane so that partial-volume voxels stay out.
        const std::size_t before = values.size();
        const int nx = mask.size[0], ny = mask.size[1];
        const std::size_t plane = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);
        for (int k = k_first; k <= k_last; ++k) {
            cv::Mat m(ny, nx, CV_8U, const_cast<std::uint8_t*>(mask.data.data() + plane * static_cast<std::size_t>(k)));
            cv::Mat bin = m != 0, er;
            if (params.intensity_erosion_px > 0)
                cv::erode(bin, er, cv::Mat(), cv::Point(-1, -1), params.intensity_erosion_px, cv::BORDER_CONSTANT, 0);
            else
                er = bin;
            for (int j = 0; j < ny; ++j) {
                const std::uint8_t* row = er.ptr<std::uint8_t>(j);
                for (int i = 0; i < nx; ++i)
                    if (row[i])
                        values.push_back(img.data[plane * static_cast<std::size_t>(k) + static_cast<std::size_t>(i) +
                                                  static_cast<std::size_t>(nx) * static_cast<std::size_t>(j)]);
            }
        }
        if (values.size() == before) // erosion removed everything: a thin mask; use it as it is
            for (std::size_t i = 0; i < mask.data.size(); ++i)
                if (mask.data[i])
                    values.push_back(img.data[i]);
    }
    mem.volumes = static_cast<int>(images.size());
    if (mem.transitions == 0)
        throw core::InvalidInputError("train_shape_memory: no two consecutive liver slices in any volume");

    // Per-cell quantiles. Empty cells take the nearest populated larger radius of their phase
    // (else the phase above); then running maxima make every limit non-increasing with the
    // radius and non-decreasing with rho.
    mem.steps.resize(nb);
    for (std::size_t bp = 0; bp < np; ++bp)
        for (std::size_t br = 0; br < nr; ++br) {
            const std::size_t b = bp * nr + br;
            ShapeStep& s = mem.steps[b];
            s.radius_min_mm = edges[br];
            s.radius_max_mm = br + 1 < nr ? edges[br + 1] : kInf;
            s.rho_min = rho_edges[bp];
            s.rho_max = bp + 1 < np ? rho_edges[bp + 1] : kInf;
            s.transitions = out[b].size();
            s.outward_per_mm = quantile(out[b], params.quantile);
            s.envelope_per_mm = quantile(env[b], params.envelope_quantile);
            s.inward_per_mm = quantile(in[b], params.quantile);
            s.growth_per_mm = quantile(grow[b], params.quantile);
            s.shrink_per_mm = quantile(shrink[b], params.quantile);
            s.centroid_per_mm = quantile(cen[b], params.quantile);
            s.dice_min = dice_min[b];
        }
    auto copy_limits = [](ShapeStep& dst, const ShapeStep& src) {
        dst.outward_per_mm = src.outward_per_mm;
        dst.envelope_per_mm = src.envelope_per_mm;
        dst.inward_per_mm = src.inward_per_mm;
        dst.growth_per_mm = src.growth_per_mm;
        dst.shrink_per_mm = src.shrink_per_mm;
        dst.centroid_per_mm = src.centroid_per_mm;
    };
    auto max_limits = [](ShapeStep& dst, const ShapeStep& src) {
        dst.outward_per_mm = std::max(dst.outward_per_mm, src.outward_per_mm);
        dst.envelope_per_mm = std::max(dst.envelope_per_mm, src.envelope_per_mm);
        dst.inward_per_mm = std::max(dst.inward_per_mm, src.inward_per_mm);
        dst.growth_per_mm = std::max(dst.growth_per_mm, src.growth_per_mm);
        dst.shrink_per_mm = std::max(dst.shrink_per_mm, src.shrink_per_mm);
        dst.centroid_per_mm = std::max(dst.centroid_per_mm, src.centroid_per_mm);
    };
    // Rows (phases) from the top down: a row without data copies the row above.
    std::vector<char> row_has(np, 0);
    for (std::size_t b = 0; b < nb; ++b)
        row_has[b / nr] = row_has[b / nr] || mem.steps[b].transitions > 0;
    for (std::size_t bp = np; bp-- > 0;) {
        if (!row_has[bp]) {
            const std::size_t src = bp + 1 < np ? bp + 1 : bp;
            for (std::size_t br = 0; br < nr && src != bp; ++br)
                copy_limits(mem.steps[bp * nr + br], mem.steps[src * nr + br]);
            continue;
        }
        std::size_t top = nr - 1;
        while (mem.steps[bp * nr + top].transitions == 0)
            --top;
        for (std::size_t br = top + 1; br < nr; ++br)
            copy_limits(mem.steps[bp * nr + br], mem.steps[bp * nr + top]);
    }
    if (!row_has[np - 1]) // no transition at the widest phase: should not happen (rho = 1 there)
        for (std::size_t bp = np - 1; bp-- > 0;)
            if (row_has[bp]) {
                for (std::size_t br = 0; br < nr; ++br)
                    copy_limits(mem.steps[(np - 1) * nr + br], mem.steps[bp * nr + br]);
                break;
            }
    for (std::size_t bp = 0; bp < np; ++bp)
        for (std::size_t br = nr - 1; br-- > 0;)
            max_limits(mem.steps[bp * nr + br], mem.steps[bp * nr + br + 1]);
    for (std::size_t bp = 1; bp < np; ++bp)
        for (std::size_t br = 0; br < nr; ++br)
            max_limits(mem.steps[bp * nr + br], mem.steps[(bp - 1) * nr + br]);

    IntensityStats& is = mem.intensity;
    is.voxels = values.size();
    double sum = 0.0, sum2 = 0.0;
    for (float x : values)
        sum += static_cast<double>(x);
    is.mean = sum / static_cast<double>(values.size());
    for (float x : values)
        sum2 += (static_cast<double>(x) - is.mean) * (static_cast<double>(x) - is.mean);
    is.sd = values.size() > 1 ? std::sqrt(sum2 / static_cast<double>(values.size() - 1)) : 0.0;
    for (std::size_t q = 0; q < kIntensityQuantileLevels.size(); ++q) {
        const auto r = static_cast<std::size_t>(
            std::llround(kIntensityQuantileLevels[q] * static_cast<double>(values.size() - 1)));
        std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(r), values.end());
        is.quantiles[q] = values[r];
    }
    return mem;
}

ShapeCheck check_slice(const ShapeMemory& memory, const core::LabelImage3D& previous,
                       const core::LabelImage3D& candidate, double dz_mm, double largest_area_mm2)
{
    check_memory(memory);
    check_dz(dz_mm);
    check_one_slice(previous, "check_slice: previous");
    check_one_slice(candidate, "check_slice: candidate");
    if (!same_plane_grid(previous, candidate))
        throw core::InvalidInputError("check_slice: the candidate is not on the previous slice's grid");
    const SliceView a = slice_of(previous, 0), b = slice_of(candidate, 0);
    const SliceMoments ma = moments(a), mb = moments(b);
    if (ma.count == 0)
        throw core::InvalidInputError("check_slice: the previous slice is empty");

    ShapeCheck c;
    c.area_previous_mm2 = ma.area;
    c.area_mm2 = mb.area;
    const double radius = std::sqrt(ma.area / M_PI);
    c.rho = phase(ma.area, largest_area_mm2);
    c.bin = bin_of(memory, radius, c.rho);
    const ShapeStep& st = memory.steps[static_cast<std::size_t>(c.bin)];
    const Allowed al = allowed_at(memory, st, radius, dz_mm, pixel_mm(previous));
    c.allowed_outward_mm = al.outward;
    c.allowed_inward_mm = al.inward;
    c.allowed_growth = al.growth;
    c.allowed_shrink = al.shrink;
    c.allowed_centroid_shift_mm = al.centroid;
    if (mb.count == 0) {
        c.log_area_ratio = -kInf;
        c.score = kInf;
        c.reason = "empty";
        return c;
    }
    const Transition t = measure_pair(a, b, ma, mb)[0];
    c.log_area_ratio = t.log_ratio;
    c.outward_mm = t.outward;
    c.inward_mm = t.inward;
    c.centroid_shift_mm = t.centroid;
    c.dice = t.dice;

    struct Criterion {
        double ratio;
        std::string text;
    };
    const Criterion crit[] = {
        {t.outward / al.outward, "outward motion " + fmt(t.outward) + " mm > " + fmt(al.outward) + " mm allowed (leak)"},
        {t.inward / al.inward, "inward motion " + fmt(t.inward) + " mm > " + fmt(al.inward) + " mm allowed (collapse)"},
        {std::max(0.0, t.log_ratio) / al.growth,
         "area grew x" + fmt(std::exp(t.log_ratio)) + " > x" + fmt(std::exp(al.growth)) + " allowed (leak)"},
        {std::max(0.0, -t.log_ratio) / al.shrink,
         "area shrank x" + fmt(std::exp(-t.log_ratio)) + " > x" + fmt(std::exp(al.shrink)) + " allowed (collapse)"},
        {t.centroid / al.centroid,
         "centroid moved " + fmt(t.centroid) + " mm > " + fmt(al.centroid) + " mm allowed"},
    };
    std::size_t worst = 0;
    for (std::size_t i = 1; i < std::size(crit); ++i)
        if (crit[i].ratio > crit[worst].ratio)
            worst = i;
    c.score = crit[worst].ratio;
    c.plausible = c.score <= 1.0;
    if (!c.plausible)
        c.reason = crit[worst].text;
    return c;
}

core::LabelImage3D plausible_envelope(const ShapeMemory& memory, const core::LabelImage3D& previous, double dz_mm,
                                      double largest_area_mm2)
{
    check_memory(memory);
    check_dz(dz_mm);
    check_one_slice(previous, "plausible_envelope: previous");
    const SliceMoments m = moments(slice_of(previous, 0));
    if (m.count == 0)
        throw core::InvalidInputError("plausible_envelope: the previous slice is empty");
    const double radius = std::sqrt(m.area / M_PI);
    const ShapeStep& st = memory.steps[static_cast<std::size_t>(bin_of(memory, radius, phase(m.area, largest_area_mm2)))];
    return offset_mask(previous, allowed_at(memory, st, radius, dz_mm, pixel_mm(previous)).envelope, true);
}

core::LabelImage3D plausible_core(const ShapeMemory& memory, const core::LabelImage3D& previous, double dz_mm,
                                  double largest_area_mm2)
{
    check_memory(memory);
    check_dz(dz_mm);
    check_one_slice(previous, "plausible_core: previous");
    const SliceMoments m = moments(slice_of(previous, 0));
    if (m.count == 0)
        throw core::InvalidInputError("plausible_core: the previous slice is empty");
    const double radius = std::sqrt(m.area / M_PI);
    const ShapeStep& st = memory.steps[static_cast<std::size_t>(bin_of(memory, radius, phase(m.area, largest_area_mm2)))];
    return offset_mask(previous, allowed_at(memory, st, radius, dz_mm, pixel_mm(previous)).inward, false);
}

} // namespace lobe::seg
