#include "lobe/seg/vessels.h"

#include "detail/report.h"
#include "detail/volume.h"
#include "lobe/seg/distance_transform.h"
#include "lobe/seg/edge_map.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <deque>
#include <iomanip>
#include <map>
#include <numeric>
#include <sstream>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace lobe::seg {
namespace {

using Clock = std::chrono::steady_clock;

void check_params(const VesselParams& p)
{
    auto nonneg = [](double v, const char* name) { detail::require_nonnegative(v, "segment_vessels", name); };
    nonneg(p.smoothing_mm, "smoothing_mm");
    nonneg(p.parenchyma_erosion_mm, "parenchyma_erosion_mm");
    nonneg(p.vesselness_boost, "vesselness_boost");
    nonneg(p.seed_sigmas, "seed_sigmas");
    nonneg(p.min_contrast, "min_contrast");
    nonneg(p.seed_min_vesselness, "seed_min_vesselness");
    nonneg(p.seed_min_volume_ml, "seed_min_volume_ml");
    nonneg(p.max_gap_mm, "max_gap_mm");
    nonneg(p.root_surface_mm, "root_surface_mm");
    nonneg(p.root_separation_mm, "root_separation_mm");
    nonneg(p.min_branch_mm, "min_branch_mm");
    nonneg(p.root_radius_fraction, "root_radius_fraction");
    nonneg(p.min_tree_length_mm, "min_tree_length_mm");
    nonneg(p.tree_separation, "tree_separation");
    if (!(p.link_threshold > 0 && p.link_threshold < 1))
        throw core::InvalidInputError("segment_vessels: link_threshold must be in (0, 1)");
    if (!(p.object_level > 0 && p.object_level < 1))
        throw core::InvalidInputError("segment_vessels: object_level must be in (0, 1)");
    if (!(p.gradient_width_mm > 0) || !std::isfinite(p.gradient_width_mm))
        throw core::InvalidInputError("segment_vessels: gradient_width_mm must be finite and > 0");
}

//! The voxel of a physical point on grid `g`, or {-1,-1,-1} when outside.
std::array<int, 3> voxel_of(const core::ImageGeometry& g, const core::Vec3& p)
{
    const core::Vec3 c = g.physical_to_index(p);
    const std::array<int, 3> v{static_cast<int>(std::lround(c.x)), static_cast<int>(std::lround(c.y)),
                               static_cast<int>(std::lround(c.z))};
    if (!g.contains(v[0], v[1], v[2]))
        return {-1, -1, -1};
    return v;
}

//! Edges incident to each node.
std::vector<std::vector<int>> incidence(const core::CentrelineGraph& g)
{
    std::vector<std::vector<int>> inc(g.nodes.size());
    for (std::size_t e = 0; e < g.edges.size(); ++e) {
        inc[std::size_t(g.edges[e].from)].push_back(int(e));
        inc[std::size_t(g.edges[e].to)].push_back(int(e));
    }
    return inc;
}

//! Mean radius over the first `mm` of edge `e` seen from node `n`.
double end_thickness(const core::CentrelineEdge& e, int n, double mm)
{
    const bool fwd = e.from == n;
    double len = 0, sum = 0;
    int count = 0;
    const std::size_t m = e.points.size();
    for (std::size_t t = 0; t < m; ++t) {
        const std::size_t i = fwd ? t : m - 1 - t;
        if (t > 0) {
            const std::size_t prev = fwd ? t - 1 : m - t;
            len += core::distance(e.points[prev], e.points[i]);
        }
        if (len > mm && count > 0)
            break;
        sum += e.point_radius[i];
        ++count;
    }
    return count ? sum / count : 0.0;
}

//! Splits edge `e` at polyline point `p` (0 < p < last), returning the new node.
int split_edge(core::CentrelineGraph& g, int e, std::size_t p)
{
    core::CentrelineEdge& ed = g.edges[std::size_t(e)];
    const int node = static_cast<int>(g.nodes.size());
    g.nodes.push_back({ed.points[p], ed.point_radius[p]});
    core::CentrelineEdge tail = ed;
    tail.from = node;
    tail.points.assign(ed.points.begin() + static_cast<std::ptrdiff_t>(p), ed.points.end());
    tail.point_radius.assign(ed.point_radius.begin() + static_cast<std::ptrdiff_t>(p), ed.point_radius.end());
    ed.to = node;
    ed.points.resize(p + 1);
    ed.point_radius.resize(p + 1);
    auto length = [](const core::CentrelineEdge& x) {
        double l = 0;
        for (std::size_t i = 1; i < x.points.size(); ++i)
            l += core::distance(x.points[i - 1], x.points[i]);
        return l;
    };
    auto med = [](std::vector<double> v) {
        std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
        return v[v.size() / 2];
    };
    ed.length_mm = length(ed);
    tail.length_mm = length(tail);
    ed.radius_mm = med(ed.point_radius);
    tail.radius_mm = med(tail.point_radius);
    g.edges.push_back(std::move(tail));
    return node;
}

//! Cuts edge `e` at polyline point `p` (0 < p < last) into two edges that end in two new,
//! separate end nodes there.
void cut_edge(core::CentrelineGraph& g, int e, std::size_t p)
{
    const int mid = split_edge(g, e, p);
    // split_edge made `mid` shared by e (its `to`) and the new last edge (its `from`): give the
    // tail its own node.
    const int twin = static_cast<int>(g.nodes.size());
    g.nodes.push_back(g.nodes[std::size_t(mid)]);
    g.edges.back().from = twin;
}

//! Edges on the path from node a to node b (empty if none), by breadth-first search.
std::vector<int> path_edges(const core::CentrelineGraph& g, const std::vector<std::vector<int>>& inc, int a, int b)
{
    std::vector<int> via(g.nodes.size(), -2);
    std::deque<int> q{a};
    via[std::size_t(a)] = -1;
    while (!q.empty() && via[std::size_t(b)] == -2) {
        const int n = q.front();
        q.pop_front();
        for (int e : inc[std::size_t(n)]) {
            const auto& ed = g.edges[std::size_t(e)];
            const int m = ed.from == n ? ed.to : ed.from;
            if (via[std::size_t(m)] != -2)
                continue;
            via[std::size_t(m)] = e;
            q.push_back(m);
        }
    }
    std::vector<int> path;
    if (via[std::size_t(b)] == -2)
        return path;
    for (int n = b; n != a;) {
        const int e = via[std::size_t(n)];
        path.push_back(e);
        const auto& ed = g.edges[std::size_t(e)];
        n = ed.from == n ? ed.to : ed.from;
    }
    return path;
}

//! A straight tube to paint into the mask.
struct Bridge {
    core::Vec3 a, b;
    double radius = 0;
};

void paint_capsule(core::LabelImage3D& mask, const Bridge& br, std::uint8_t value)
{
    const core::Vec3 ia = mask.physical_to_index(br.a), ib = mask.physical_to_index(br.b);
    std::array<int, 3> lo{}, hi{};
    for (int a = 0; a < 3; ++a) {
        const double r = br.radius / mask.spacing[a] + 1;
        lo[a] = std::max(0, static_cast<int>(std::floor(std::min(ia[a], ib[a]) - r)));
        hi[a] = std::min(mask.size[a] - 1, static_cast<int>(std::ceil(std::max(ia[a], ib[a]) + r)));
    }
    const core::Vec3 d = br.b - br.a;
    const double dd = core::dot(d, d);
    for (int k = lo[2]; k <= hi[2]; ++k)
        for (int j = lo[1]; j <= hi[1]; ++j)
            for (int i = lo[0]; i <= hi[0]; ++i) {
                const core::Vec3 p = mask.index_to_physical(i, j, k);
                const double t = dd > 0 ? std::clamp(core::dot(p - br.a, d) / dd, 0.0, 1.0) : 0.0;
                if (core::distance(p, br.a + d * t) <= br.radius)
                    mask.at(i, j, k) = value;
            }
}

struct Stopwatch {
    std::vector<std::pair<std::string, double>>* out;
    Clock::time_point t0 = Clock::now();
    void lap(const std::string& name)
    {
        const auto t1 = Clock::now();
        out->emplace_back(name, std::chrono::duration<double>(t1 - t0).count());
        t0 = t1;
    }
};

VesselResult vessels_on_patient_axes(const core::ImageF& image, const core::LabelImage3D& liver,
                                     const VesselParams& params, const VesselProgress& progress);

} // namespace

//! Runs on the volume reordered onto the patient frame (core::patient_axis_order) and reorders the
//! images back: the filters and the skeleton follow voxel order, so without it the same scan
//! stored with reversed axes or as a coronal stack gave slightly different trees (liver.md,
//! "Orientation"). The graph is in mm and needs no mapping.
VesselResult segment_vessels(const core::ImageF& image, const core::LabelImage3D& liver, const VesselParams& params,
                             const VesselProgress& progress)
{
    const core::AxisOrder order = core::patient_axis_order(image);
    if (order.identity())
        return vessels_on_patient_axes(image, liver, params, progress);
    detail::check_image(image, "segment_vessels: image"); // before reordering
    detail::check_same_grid(image, liver, "segment_vessels: the liver mask");
    VesselResult r = vessels_on_patient_axes(core::reorder_axes(image, order), core::reorder_axes(liver, order), params,
                                             progress);
    const core::AxisOrder back = order.inverse();
    for (core::LabelImage3D* m : {&r.labels, &r.seeds})
        if (!m->data.empty())
            *m = core::reorder_axes(*m, back);
    for (core::ImageF* m : {&r.vesselness, &r.feature, &r.connectedness})
        if (!m->data.empty())
            *m = core::reorder_axes(*m, back);
    return r;
}

namespace {

VesselResult vessels_on_patient_axes(const core::ImageF& image, const core::LabelImage3D& liver,
                                     const VesselParams& params, const VesselProgress& progress)
{
    detail::check_image(image, "segment_vessels: image");
    detail::check_same_grid(image, liver, "segment_vessels: the liver mask");
    check_params(params);
    auto say = [&](const std::string& s) {
        if (progress)
            progress(s);
    };
    const auto t_start = Clock::now();
    VesselResult res;
    res.labels = core::LabelImage3D(image.geometry(), 0);
    Stopwatch sw{&res.timings};

    const detail::Box lbox = detail::bounding_box(liver);
    if (lbox.empty())
        throw core::InvalidInputError("segment_vessels: the liver mask is empty");
    const detail::Box box = detail::grown(lbox, detail::voxels_for(image, 5.0), image);
    const core::ImageF I = detail::crop(image, box);
    core::LabelImage3D L = detail::crop(liver, box);
    for (auto& v : L.data)
        v = v ? 1 : 0;
    for (std::size_t u = 0; u < I.data.size(); ++u)
        if (L.data[u] && !std::isfinite(I.data[u]))
            throw core::InvalidInputError("segment_vessels: the image holds non-finite values inside the liver");
    const double voxel_ml = image.spacing[0] * image.spacing[1] * image.spacing[2] / 1000.0;

    // 1. Smoothing and the parenchyma's statistics (median and MAD are robust to the vessels and
    //    tumours, a few per cent of the liver).
    const core::ImageF S = gaussian_smooth(I, params.smoothing_mm);
    core::LabelImage3D outside = L;
    for (auto& v : outside.data)
        v = v ? 0 : 1;
    const core::ImageF depth = euclidean_distance(outside); // mm to the liver's outside
    core::LabelImage3D inner(L.geometry(), 0);
    std::size_t n_inner = 0;
    for (std::size_t u = 0; u < L.data.size(); ++u)
        if (L.data[u] && static_cast<double>(depth.data[u]) > params.parenchyma_erosion_mm) {
            inner.data[u] = 1;
            ++n_inner;
        }
    if (n_inner < 100)
        for (std::size_t u = 0; u < L.data.size(); ++u)
            inner.data[u] = L.data[u]; // a thin liver: use all of it
    {
        std::vector<float> vals;
        for (std::size_t u = 0; u < S.data.size(); ++u)
            if (inner.data[u])
                vals.push_back(S.data[u]);
        const auto [median, sd] = detail::median_and_robust_sd(std::move(vals));
        res.parenchyma = median;
        res.parenchyma_sigma = std::max(1e-3, sd);
    }
    sw.lap("smoothing");
    say("parenchyma " + detail::fixed(res.parenchyma) + " +- " + detail::fixed(res.parenchyma_sigma) + " (smoothed)");

    // 2. Enhancement: vesselness, then averaging along the vessel axis.
    core::ImageF F = S;                       // intensity the method reads
    core::ImageF Vs(S.geometry(), 0.f);       // vesselness in [0, 1]
    if (params.use_vesselness) {
        // Frangi's c from the contrast that counts as a vessel: a tube of contrast C at its best
        // scale has a σ²-normalised Hessian norm of about 0.52 C, noise a few image units.
        VesselnessParams vp = params.vesselness;
        if (vp.structureness <= 0)
            vp.structureness = 0.5 * params.min_contrast;
        const VesselnessResult V = vesselness(I, vp, &L);
        sw.lap("vesselness");
        if (params.use_directional_sharpening) {
            auto ds = directional_sharpening(S, V, params.sharpening);
            F = std::move(ds.intensity);
            Vs = std::move(ds.vesselness);
            sw.lap("directional sharpening");
        } else {
            Vs = V.vesselness;
        }
    }

    // 3. Seeds: bright, tubular, deep enough in the liver, in components big enough.
    const double seed_level = res.parenchyma + std::max(params.seed_sigmas * res.parenchyma_sigma, params.min_contrast);
    core::LabelImage3D seeds(L.geometry(), 0);
    for (std::size_t u = 0; u < L.data.size(); ++u)
        if (inner.data[u] && static_cast<double>(F.data[u]) >= seed_level &&
            (!params.use_vesselness || static_cast<double>(Vs.data[u]) >= params.seed_min_vesselness))
            seeds.data[u] = 1;
    {
        const auto comps = detail::connected_components(seeds, 26);
        std::vector<std::uint8_t> keep(comps.sizes.size(), 0);
        for (std::size_t c = 0; c < comps.sizes.size(); ++c)
            if (static_cast<double>(comps.sizes[c]) * voxel_ml >= params.seed_min_volume_ml) {
                keep[c] = 1;
                ++res.seed_components;
            }
        for (std::size_t u = 0; u < seeds.data.size(); ++u)
            seeds.data[u] = comps.id[u] >= 0 && keep[std::size_t(comps.id[u])] ? 1 : 0;
    }
    std::vector<float> seed_values;
    for (std::size_t u = 0; u < seeds.data.size(); ++u)
        if (seeds.data[u])
            seed_values.push_back(F.data[u]);
    res.seed_voxels = seed_values.size();
    sw.lap("seeds");
    if (params.keep_images) {
        res.vesselness = core::ImageF(image.geometry(), 0.f);
        detail::paste(res.vesselness, Vs, box);
        res.seeds = core::LabelImage3D(image.geometry(), 0);
        detail::paste(res.seeds, seeds, box);
    }
    auto nothing = [&](const std::string& why) {
        res.found = false;
        res.message = why;
        res.timings.emplace_back("total", std::chrono::duration<double>(Clock::now() - t_start).count());
        say(why);
        return res;
    };
    if (seed_values.empty())
        return nothing("no vessels: no tubular structure inside the liver is brighter than the parenchyma (" +
                       detail::fixed(res.parenchyma) + ") by " + detail::fixed(seed_level - res.parenchyma) + " or more");
    res.vessel_intensity = detail::quantile(seed_values, 0.75);
    res.contrast = res.vessel_intensity - res.parenchyma;
    if (res.contrast < params.min_contrast)
        return nothing("no vessels: vessel contrast " + detail::fixed(res.contrast) + " is below " + detail::fixed(params.min_contrast));
    say("seeds: " + std::to_string(res.seed_components) + " components, " + std::to_string(res.seed_voxels) +
        " voxels; vessels " + detail::fixed(res.vessel_intensity) + " (contrast " + detail::fixed(res.contrast) + ")");

    // 4. The feature: intensity lifted by the vesselness.
    core::ImageF G = F;
    if (params.use_vesselness && params.vesselness_boost > 0)
        for (std::size_t u = 0; u < G.data.size(); ++u)
            G.data[u] += static_cast<float>(params.vesselness_boost * static_cast<double>(Vs.data[u]) * res.contrast);
    const double object_value = res.parenchyma + params.object_level * res.contrast;
    if (params.keep_images) {
        res.feature = core::ImageF(image.geometry(), 0.f);
        detail::paste(res.feature, G, box);
    }

    // 5. Fuzzy connectedness (or plain region growing) from the seeds.
    core::LabelImage3D object(L.geometry(), 0);
    if (params.use_fuzzy_connectedness) {
        FuzzyConnectednessParams fc;
        fc.affinity.object_mean = res.vessel_intensity;
        // h1 = 1/2 where the pair's mean sits at the half-contrast level.
        fc.affinity.object_sigma = (1 - params.object_level) * res.contrast / std::sqrt(2 * std::log(2.0));
        fc.affinity.gradient_sigma = res.contrast / params.gradient_width_mm;
        fc.connectivity = params.connectivity;
        fc.lookup_table = params.lookup_table;
        fc.min_connectedness = params.link_threshold;
        const auto K = fuzzy_connectedness(G, seeds, fc, &L);
        if (params.keep_images) {
            res.connectedness = core::ImageF(image.geometry(), 0.f);
            detail::paste(res.connectedness, K.connectedness, box);
        }
        for (std::size_t u = 0; u < object.data.size(); ++u)
            object.data[u] = static_cast<double>(K.connectedness.data[u]) >= params.link_threshold &&
                                     static_cast<double>(G.data[u]) >= object_value
                                 ? 1
                                 : 0;
        sw.lap("fuzzy connectedness");
    } else {
        core::LabelImage3D above(L.geometry(), 0);
        for (std::size_t u = 0; u < above.data.size(); ++u)
            above.data[u] = (L.data[u] && static_cast<double>(G.data[u]) >= object_value) || seeds.data[u] ? 1 : 0;
        const auto comps = detail::connected_components(above, params.connectivity == 26 ? 26 : 6);
        std::vector<std::uint8_t> seeded(comps.sizes.size(), 0);
        for (std::size_t u = 0; u < seeds.data.size(); ++u)
            if (seeds.data[u])
                seeded[std::size_t(comps.id[u])] = 1;
        for (std::size_t u = 0; u < object.data.size(); ++u)
            object.data[u] = comps.id[u] >= 0 && seeded[std::size_t(comps.id[u])] ? 1 : 0;
        sw.lap("region growing");
    }

    // 6. Skeleton and centre-line graph.
    const core::LabelImage3D skel = thin(object);
    // Radii: the distance to the nearest liver voxel outside the vessels. The liver's outside is
    // not a wall (a trunk is cut there, not narrowed), so a root keeps its radius.
    core::LabelImage3D background(L.geometry(), 0);
    for (std::size_t u = 0; u < background.data.size(); ++u)
        background.data[u] = L.data[u] && !object.data[u] ? 1 : 0;
    const core::ImageF wall = euclidean_distance(background);
    CentrelineParams cp = params.centreline;
    if (!params.use_pruning) {
        cp.min_spur_mm = cp.spur_radius_factor = cp.junction_merge_factor = cp.min_component_length_mm = 0;
        cp.max_prune_passes = 0;
    }
    core::CentrelineGraph graph = centreline_graph(skel, wall, cp, &res.centreline);
    sw.lap("skeleton");

    // 7. Trees: roots, bridges over gaps, contacts between trees, portal or hepatic, levels,
    //    names.
    auto surface_depth = [&](const core::Vec3& p) {
        const auto v = voxel_of(depth, p);
        return v[0] < 0 ? 0.0 : static_cast<double>(depth.at(v[0], v[1], v[2]));
    };
    // The local radius at point p of an edge: the median over ±2 points (single radii are noisy).
    auto local_radius = [&](const core::CentrelineEdge& e, std::size_t p) {
        std::vector<double> r;
        for (std::size_t q = p >= 2 ? p - 2 : 0; q <= std::min(e.points.size() - 1, p + 2); ++q)
            r.push_back(e.point_radius[q]);
        std::nth_element(r.begin(), r.begin() + static_cast<std::ptrdiff_t>(r.size() / 2), r.end());
        return r[r.size() / 2];
    };
    // Where a tree leaves the liver: centre-line points whose vessel reaches the liver surface
    // (depth <= radius + root_surface_mm), thickest first. A trunk is cut by the liver's surface
    // (the portal vein at the hilum, a hepatic vein at the vena cava); branches stay inside.
    struct SurfacePoint {
        int edge = -1;
        std::size_t point = 0;
        double radius = 0;
    };
    auto surface_points = [&](const std::vector<int>& nodes) {
        std::vector<std::uint8_t> in(graph.nodes.size(), 0);
        for (int n : nodes)
            in[std::size_t(n)] = 1;
        std::vector<SurfacePoint> out;
        for (std::size_t e = 0; e < graph.edges.size(); ++e) {
            const auto& ed = graph.edges[e];
            if (!in[std::size_t(ed.from)])
                continue;
            for (std::size_t p = 0; p < ed.points.size(); ++p) {
                const double r = local_radius(ed, p);
                if (surface_depth(ed.points[p]) <= r + params.root_surface_mm)
                    out.push_back({int(e), p, r});
            }
        }
        std::stable_sort(out.begin(), out.end(), [](const SurfacePoint& a, const SurfacePoint& b) { return a.radius > b.radius; });
        return out;
    };
    auto max_radius = [&](const std::vector<int>& nodes) {
        std::vector<std::uint8_t> in(graph.nodes.size(), 0);
        for (int n : nodes)
            in[std::size_t(n)] = 1;
        double r = 0;
        for (const auto& ed : graph.edges)
            if (in[std::size_t(ed.from)])
                for (std::size_t p = 0; p < ed.points.size(); ++p)
                    r = std::max(r, local_radius(ed, p));
        return r;
    };
    // A node at a surface point (splitting its edge when the point is inside it).
    auto node_at = [&](const SurfacePoint& sp) {
        const auto& ed = graph.edges[std::size_t(sp.edge)];
        // An end of the edge within the vessel's radius is the same place.
        const double snap = std::max(sp.radius, 1.0);
        if (sp.point == 0 || core::distance(ed.points[sp.point], ed.points.front()) <= snap)
            return int(ed.from);
        if (sp.point + 1 >= ed.points.size() || core::distance(ed.points[sp.point], ed.points.back()) <= snap)
            return int(ed.to);
        return split_edge(graph, sp.edge, sp.point);
    };
    // The roots of a connected part: its thickest surface point, and any other surface point at
    // least half as thick and root_separation_mm away from the roots so far (trees that touch).
    // None: the part is a fragment (cut off by a gap), rooted at its thickest end.
    double trunk_radius = 0; // the thickest vessel anywhere: roots are trunks
    for (const auto& nodes : graph_components(graph))
        trunk_radius = std::max(trunk_radius, max_radius(nodes));
    auto roots_of = [&](const std::vector<int>& nodes) {
        auto sps = surface_points(nodes);
        const double rmax = max_radius(nodes);
        // Thick enough to be a trunk; of those, the point nearest the surface first (where the
        // trunk leaves), then any other such point root_separation_mm away from the roots so far.
        std::vector<SurfacePoint> thick;
        for (const auto& sp : sps)
            if (sp.radius >= 0.5 * rmax && sp.radius >= params.root_radius_fraction * trunk_radius)
                thick.push_back(sp);
        auto pos = [&](const SurfacePoint& sp) { return graph.edges[std::size_t(sp.edge)].points[sp.point]; };
        std::stable_sort(thick.begin(), thick.end(), [&](const SurfacePoint& a, const SurfacePoint& b) {
            return surface_depth(pos(a)) - a.radius < surface_depth(pos(b)) - b.radius;
        });
        std::vector<SurfacePoint> roots;
        for (const auto& sp : thick) {
            bool far = true;
            for (const auto& r : roots)
                far = far && core::distance(pos(sp), pos(r)) > params.root_separation_mm;
            if (far)
                roots.push_back(sp);
        }
        return roots;
    };
    auto thickest_end = [&](const std::vector<int>& nodes, const std::vector<std::vector<int>>& inc) {
        int best = nodes.empty() ? -1 : nodes.front();
        double thick = -1;
        for (int n : nodes)
            if (inc[std::size_t(n)].size() == 1) {
                const double t = end_thickness(graph.edges[std::size_t(inc[std::size_t(n)][0])], n, 5.0);
                if (t > thick) {
                    thick = t;
                    best = n;
                }
            }
        return best;
    };

    std::vector<Bridge> bridges;
    if (params.bridge_gaps) {
        // A fragment's thick end faces the gap that cut it off: join it to the nearest point of
        // another part ahead of it (snapped to that part's end point when one is near: a gap
        // interrupts a vessel, it does not branch it). One join per pass, until none is left.
        for (int pass = 0; pass < 32; ++pass) {
            const auto comps = graph_components(graph);
            const auto inc = incidence(graph);
            std::vector<int> comp_of(graph.nodes.size(), -1);
            for (std::size_t c = 0; c < comps.size(); ++c)
                for (int n : comps[c])
                    comp_of[std::size_t(n)] = int(c);
            bool joined = false;
            for (std::size_t c = 0; c < comps.size() && !joined; ++c) {
                if (!roots_of(comps[c]).empty())
                    continue;
                const int root = thickest_end(comps[c], inc);
                if (root < 0 || inc[std::size_t(root)].size() != 1)
                    continue;
                const core::Vec3 rp = graph.nodes[std::size_t(root)].position;
                // Outward direction at the root: from the part's centre line 3-8 mm away (robust
                // to a small fork at the end) to the root.
                core::Vec3 inward{0, 0, 0};
                int n_in = 0;
                for (const auto& ed : graph.edges)
                    if (comp_of[std::size_t(ed.from)] == int(c))
                        for (const auto& q : ed.points) {
                            const double d = core::distance(q, rp);
                            if (d >= 3.0 && d <= 8.0) {
                                inward += q;
                                ++n_in;
                            }
                        }
                if (n_in == 0)
                    continue;
                const core::Vec3 out_dir = core::normalized(rp - inward / n_in);
                double best = params.max_gap_mm;
                int best_edge = -1;
                std::size_t best_point = 0;
                for (std::size_t e = 0; e < graph.edges.size(); ++e) {
                    const auto& ed = graph.edges[e];
                    if (comp_of[std::size_t(ed.from)] == int(c))
                        continue;
                    for (std::size_t p = 0; p < ed.points.size(); ++p) {
                        const core::Vec3 d = ed.points[p] - rp;
                        const double dist = core::norm(d);
                        if (dist >= best)
                            continue;
                        if (dist > 1e-6 && core::dot(d, out_dir) < 0.5 * dist)
                            continue; // not within 60 degrees of straight ahead: a gap does not turn
                        best = dist;
                        best_edge = int(e);
                        best_point = p;
                    }
                }
                if (best_edge < 0)
                    continue;
                const auto& te = graph.edges[std::size_t(best_edge)];
                int target;
                if (core::distance(te.points[best_point], te.points.front()) <= 3.0)
                    target = te.from;
                else if (core::distance(te.points[best_point], te.points.back()) <= 3.0)
                    target = te.to;
                else
                    target = split_edge(graph, best_edge, best_point);
                const double r = std::min(graph.nodes[std::size_t(root)].radius_mm,
                                          end_thickness(graph.edges[std::size_t(incidence(graph)[std::size_t(root)][0])], root, 5.0));
                core::CentrelineEdge b;
                b.from = target;
                b.to = root;
                const core::Vec3 tp = graph.nodes[std::size_t(target)].position;
                const int steps = std::max(1, static_cast<int>(std::ceil(core::distance(tp, rp) / 0.5)));
                for (int st = 0; st <= steps; ++st) {
                    b.points.push_back(tp + (rp - tp) * (double(st) / steps));
                    b.point_radius.push_back(r);
                }
                b.radius_mm = r;
                b.length_mm = core::distance(tp, rp);
                bridges.push_back({tp, rp, r});
                graph.edges.push_back(std::move(b));
                ++res.bridges;
                joined = true;
            }
            if (!joined)
                break;
        }
    }

    // Drop trees with too little centre line.
    {
        const auto comps = graph_components(graph);
        std::vector<double> len(comps.size(), 0);
        std::vector<int> comp_of(graph.nodes.size(), -1);
        for (std::size_t c = 0; c < comps.size(); ++c)
            for (int n : comps[c])
                comp_of[std::size_t(n)] = int(c);
        for (const auto& e : graph.edges)
            len[std::size_t(comp_of[std::size_t(e.from)])] += e.length_mm;
        core::CentrelineGraph kept;
        std::vector<int> newid(graph.nodes.size(), -1);
        for (std::size_t n = 0; n < graph.nodes.size(); ++n)
            if (len[std::size_t(comp_of[n])] >= params.min_tree_length_mm && len[std::size_t(comp_of[n])] > 0) {
                newid[n] = int(kept.nodes.size());
                kept.nodes.push_back(graph.nodes[n]);
            }
        for (auto& e : graph.edges)
            if (newid[std::size_t(e.from)] >= 0) {
                e.from = newid[std::size_t(e.from)];
                e.to = newid[std::size_t(e.to)];
                kept.edges.push_back(std::move(e));
            }
        graph = std::move(kept);
    }
    if (graph.edges.empty())
        return nothing("no vessels: the seeds grew into no tree longer than " + detail::fixed(params.min_tree_length_mm, 0) + " mm");

    // Trees that touch: a part with two roots far apart (the portal vein at the hilum and a
    // hepatic vein at the vena cava) is two trees joined where a branch of one grazes the other.
    // Cut the path between the roots at its dimmest point (the contact is partial volume).
    for (int iter = 0; iter < 16; ++iter) {
        bool cut = false;
        for (const auto& nodes : graph_components(graph)) {
            const auto roots = roots_of(nodes);
            if (roots.size() < 2)
                continue;
            // Materialise both roots as nodes (the first split renumbers nothing before it, but
            // may move the second point to a new edge: look it up again by position).
            const core::Vec3 p2 = graph.edges[std::size_t(roots[1].edge)].points[roots[1].point];
            const double rad2 = roots[1].radius;
            const int r1 = node_at(roots[0]);
            SurfacePoint sp2{-1, 0, rad2};
            for (std::size_t e = 0; e < graph.edges.size() && sp2.edge < 0; ++e)
                for (std::size_t q = 0; q < graph.edges[e].points.size(); ++q)
                    if (core::distance(graph.edges[e].points[q], p2) < 1e-9) {
                        sp2.edge = int(e);
                        sp2.point = q;
                        break;
                    }
            if (sp2.edge < 0)
                continue;
            const int r2 = node_at(sp2);
            const auto path = path_edges(graph, incidence(graph), r1, r2);
            const core::Vec3 p1 = graph.nodes[std::size_t(r1)].position;
            double dim = 1e300;
            int cut_e = -1;
            std::size_t cut_p = 0;
            for (int e : path) {
                const auto& ed = graph.edges[std::size_t(e)];
                for (std::size_t p = 1; p + 1 < ed.points.size(); ++p) {
                    if (core::distance(ed.points[p], p1) < 10.0 || core::distance(ed.points[p], p2) < 10.0)
                        continue;
                    const auto v = voxel_of(G, ed.points[p]);
                    if (v[0] < 0)
                        continue;
                    const double g = G.at(v[0], v[1], v[2]);
                    if (g < dim) {
                        dim = g;
                        cut_e = e;
                        cut_p = p;
                    }
                }
            }
            if (cut_e < 0)
                continue;
            cut_edge(graph, cut_e, cut_p);
            ++res.trees_cut;
            cut = true;
            break;
        }
        if (!cut)
            break;
    }

    // Each tree's root; short stubs beyond it (towards the vena cava or the hilum, along
    // partial-volume voxels of the surface) are dropped.
    std::vector<int> root_nodes;
    for (const auto& nodes : graph_components(graph)) {
        const auto roots = roots_of(nodes);
        root_nodes.push_back(roots.empty() ? thickest_end(nodes, incidence(graph)) : node_at(roots[0]));
    }
    {
        const auto inc0 = incidence(graph);
        std::vector<std::uint8_t> drop(graph.edges.size(), 0);
        for (int root : root_nodes) {
            if (inc0[std::size_t(root)].size() < 2)
                continue;
            double r = 0;
            for (int e : inc0[std::size_t(root)])
                r = std::max(r, end_thickness(graph.edges[std::size_t(e)], root, 5.0));
            const double limit = std::max(params.centreline.min_spur_mm, 2.0 * r);
            std::size_t kept = inc0[std::size_t(root)].size();
            for (int e : inc0[std::size_t(root)]) {
                const auto& ed = graph.edges[std::size_t(e)];
                const int other = ed.from == root ? ed.to : ed.from;
                if (kept > 1 && inc0[std::size_t(other)].size() == 1 && ed.length_mm < limit) {
                    drop[std::size_t(e)] = 1;
                    --kept;
                }
            }
        }
        core::CentrelineGraph kept_graph;
        std::vector<int> deg(graph.nodes.size(), 0);
        for (std::size_t e = 0; e < graph.edges.size(); ++e)
            if (!drop[e]) {
                ++deg[std::size_t(graph.edges[e].from)];
                ++deg[std::size_t(graph.edges[e].to)];
            }
        std::vector<int> newid(graph.nodes.size(), -1);
        for (std::size_t n = 0; n < graph.nodes.size(); ++n)
            if (deg[n] > 0) {
                newid[n] = int(kept_graph.nodes.size());
                kept_graph.nodes.push_back(graph.nodes[n]);
            }
        for (std::size_t e = 0; e < graph.edges.size(); ++e)
            if (!drop[e]) {
                auto ed = graph.edges[e];
                ed.from = newid[std::size_t(ed.from)];
                ed.to = newid[std::size_t(ed.to)];
                kept_graph.edges.push_back(std::move(ed));
            }
        for (int& r : root_nodes)
            r = newid[std::size_t(r)];
        graph = std::move(kept_graph);
    }

    const auto comps = graph_components(graph);
    const auto inc = incidence(graph);
    struct Tree {
        std::vector<int> nodes;
        int root = -1;
        double intensity = 0, length = 0, trunk_radius = 0;
        core::Vec3 root_pos;
        int label = 0;
    };
    std::vector<Tree> trees;
    for (const auto& nodes : comps) {
        Tree t;
        t.nodes = nodes;
        for (int r : root_nodes)
            if (r >= 0 && std::find(nodes.begin(), nodes.end(), r) != nodes.end())
                t.root = r;
        if (t.root < 0)
            t.root = thickest_end(nodes, inc);
        t.root_pos = graph.nodes[std::size_t(t.root)].position;
        if (!inc[std::size_t(t.root)].empty())
            t.trunk_radius = end_thickness(graph.edges[std::size_t(inc[std::size_t(t.root)][0])], t.root, 10.0);
        // Mean intensity along the thick part of the centre line (thin vessels are dimmed by
        // partial volume, which says nothing about which tree they belong to).
        double sum = 0;
        int cnt = 0;
        std::vector<std::uint8_t> in_tree(graph.nodes.size(), 0);
        for (int n : nodes)
            in_tree[std::size_t(n)] = 1;
        for (int pass = 0; pass < 2 && cnt == 0; ++pass)
            for (const auto& e : graph.edges) {
                if (!in_tree[std::size_t(e.from)])
                    continue;
                if (pass == 0)
                    t.length += e.length_mm;
                for (std::size_t p = 0; p < e.points.size(); ++p) {
                    if (pass == 0 && e.point_radius[p] < 2.0)
                        continue;
                    const auto v = voxel_of(F, e.points[p]);
                    if (v[0] < 0)
                        continue;
                    sum += static_cast<double>(F.at(v[0], v[1], v[2]));
                    ++cnt;
                }
            }
        t.intensity = cnt ? sum / cnt : res.vessel_intensity;
        trees.push_back(t);
    }

    // Portal or hepatic. By contrast: the best 2-group split of the trees' intensities (weighted
    // by centre-line length); accepted when the groups differ by tree_separation or more. By
    // anatomy otherwise: the portal vein enters at the hilum, below where the hepatic veins join
    // the inferior vena cava under the diaphragm, so the thick tree with the lowest root is portal.
    {
        std::vector<std::size_t> order(trees.size());
        std::iota(order.begin(), order.end(), 0);
        std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return trees[a].intensity < trees[b].intensity; });
        double best_gap = -1;
        std::size_t best_split = 0;
        for (std::size_t s = 1; s < order.size(); ++s) {
            double w0 = 0, m0 = 0, w1 = 0, m1 = 0;
            for (std::size_t i = 0; i < order.size(); ++i) {
                const Tree& t = trees[order[i]];
                (i < s ? w0 : w1) += t.length;
                (i < s ? m0 : m1) += t.length * t.intensity;
            }
            m0 /= std::max(w0, 1e-9);
            m1 /= std::max(w1, 1e-9);
            // Between-group separation weighted like Otsu's criterion.
            const double score = w0 * w1 * (m1 - m0) * (m1 - m0);
            if (score > best_gap) {
                best_gap = score;
                best_split = s;
            }
        }
        double lo = 0, hi = 0;
        if (best_split > 0) {
            double w0 = 0, w1 = 0;
            for (std::size_t i = 0; i < order.size(); ++i) {
                const Tree& t = trees[order[i]];
                (i < best_split ? w0 : w1) += t.length;
                (i < best_split ? lo : hi) += t.length * t.intensity;
            }
            lo /= std::max(w0, 1e-9);
            hi /= std::max(w1, 1e-9);
        }
        if (best_split > 0 && hi - lo >= params.tree_separation) {
            res.separated_by_contrast = true;
            for (std::size_t i = 0; i < order.size(); ++i)
                trees[order[i]].label = i < best_split ? kHepaticVeinLabel : kPortalVeinLabel;
        } else {
            double rmax = 0;
            for (const auto& t : trees)
                rmax = std::max(rmax, t.trunk_radius);
            int portal = -1;
            for (std::size_t i = 0; i < trees.size(); ++i) {
                if (trees[i].trunk_radius < 0.6 * rmax)
                    continue;
                if (portal < 0 || trees[i].root_pos.z < trees[std::size_t(portal)].root_pos.z)
                    portal = int(i);
            }
            for (std::size_t i = 0; i < trees.size(); ++i)
                trees[i].label = int(i) == portal ? kPortalVeinLabel : kHepaticVeinLabel;
            // A lone tree's kind cannot be told from a comparison: judge its root's height in the
            // liver (hepatic veins leave at the top).
            if (trees.size() == 1) {
                double z0 = 1e300, z1 = -1e300;
                for (std::size_t u = 0; u < L.data.size(); ++u)
                    if (L.data[u]) {
                        const int k = static_cast<int>(u / (std::size_t(L.size[0]) * std::size_t(L.size[1])));
                        const double z = L.index_to_physical(0, 0, k).z;
                        z0 = std::min(z0, z);
                        z1 = std::max(z1, z);
                    }
                const double h = (trees[0].root_pos.z - z0) / std::max(z1 - z0, 1e-9);
                trees[0].label = h > 0.6 ? kHepaticVeinLabel : kPortalVeinLabel;
            }
        }
    }
    for (auto& t : trees)
        assign_branch_levels(graph, t.root, t.label, params.use_pruning ? params.min_branch_mm : 0.0);

    // Trunk names (thesis Fig 5.22): the portal trunk PV and its right and left branches RPV,
    // LPV; three hepatic trees RHV, MHV, LHV from the patient's right (-x in LPS) to left.
    {
        const auto inc2 = incidence(graph);
        std::vector<std::size_t> hepatic, portal;
        for (std::size_t i = 0; i < trees.size(); ++i)
            (trees[i].label == kHepaticVeinLabel ? hepatic : portal).push_back(i);
        auto root_edges = [&](const Tree& t) { return inc2[std::size_t(t.root)]; };
        // Hepatic trunks: the thick level-1 edges (two trunks may meet at one root).
        std::vector<int> trunks;
        double rmax = 0;
        for (std::size_t i : hepatic)
            for (int e : root_edges(trees[i]))
                rmax = std::max(rmax, graph.edges[std::size_t(e)].radius_mm);
        for (std::size_t i : hepatic)
            for (int e : root_edges(trees[i]))
                if (graph.edges[std::size_t(e)].radius_mm >= 0.5 * rmax)
                    trunks.push_back(e);
        if (trunks.size() == 3) {
            auto mean_x = [&](int e) {
                double x = 0;
                for (const auto& p : graph.edges[std::size_t(e)].points)
                    x += p.x;
                return x / static_cast<double>(graph.edges[std::size_t(e)].points.size());
            };
            std::sort(trunks.begin(), trunks.end(), [&](int a, int b) { return mean_x(a) < mean_x(b); });
            const char* names[3] = {"RHV", "MHV", "LHV"};
            for (int h = 0; h < 3; ++h)
                graph.edges[std::size_t(trunks[std::size_t(h)])].name = names[h];
        }
        if (!portal.empty()) {
            const Tree& pt = trees[*std::max_element(portal.begin(), portal.end(), [&](std::size_t a, std::size_t b) {
                return trees[a].length < trees[b].length;
            })];
            for (int e : root_edges(pt)) {
                auto& trunk = graph.edges[std::size_t(e)];
                trunk.name = "PV";
                std::vector<int> kids;
                for (int f : inc2[std::size_t(trunk.to)])
                    if (f != e)
                        kids.push_back(f);
                if (kids.size() == 2) {
                    auto& a = graph.edges[std::size_t(kids[0])];
                    auto& b = graph.edges[std::size_t(kids[1])];
                    const bool a_right = a.points.back().x < b.points.back().x;
                    a.name = a_right ? "RPV" : "LPV";
                    b.name = a_right ? "LPV" : "RPV";
                }
            }
        }
    }

    // 8. Labels: every vessel voxel takes the tree of the nearest centre line through the mask
    //    (a breadth-first search from the centre lines); voxels no centre line reaches (noise
    //    pruned from the graph) are dropped: the thesis's region growing from the skeleton.
    for (const auto& br : bridges)
        paint_capsule(object, br, 1);
    core::LabelImage3D lab(L.geometry(), 0);
    std::deque<std::size_t> q;
    for (const auto& e : graph.edges)
        for (std::size_t p = 0; p < e.points.size(); ++p) {
            const auto v = voxel_of(lab, e.points[p]);
            if (v[0] < 0)
                continue;
            const std::size_t u = lab.index(v[0], v[1], v[2]);
            if (!object.data[u] || lab.data[u])
                continue;
            lab.data[u] = static_cast<std::uint8_t>(e.label);
            q.push_back(u);
        }
    const int nx = lab.size[0], ny = lab.size[1], nz = lab.size[2];
    while (!q.empty()) {
        const std::size_t u = q.front();
        q.pop_front();
        const int i = static_cast<int>(u % std::size_t(nx)), j = static_cast<int>((u / std::size_t(nx)) % std::size_t(ny)),
                  k = static_cast<int>(u / (std::size_t(nx) * std::size_t(ny)));
        for (int dk = -1; dk <= 1; ++dk)
            for (int dj = -1; dj <= 1; ++dj)
                for (int di = -1; di <= 1; ++di) {
                    const int ii = i + di, jj = j + dj, kk = k + dk;
                    if (ii < 0 || jj < 0 || kk < 0 || ii >= nx || jj >= ny || kk >= nz)
                        continue;
                    const std::size_t w = lab.index(ii, jj, kk);
                    if (object.data[w] && !lab.data[w]) {
                        lab.data[w] = lab.data[u];
                        q.push_back(w);
                    }
                }
    }
    for (std::size_t u = 0; u < lab.data.size(); ++u)
        if (!L.data[u])
            lab.data[u] = 0; // bridges painted past the liver surface
    detail::paste(res.labels, lab, box);
    sw.lap("trees and labels");

    // Reports.
    std::size_t np = 0, nh = 0;
    for (auto v : lab.data) {
        np += v == kPortalVeinLabel;
        nh += v == kHepaticVeinLabel;
    }
    res.portal_ml = static_cast<double>(np) * voxel_ml;
    res.hepatic_ml = static_cast<double>(nh) * voxel_ml;
    {
        // Volume per tree: voxels nearest each tree's centre line among those of its label.
        std::map<int, double> label_len;
        for (const auto& t : trees)
            label_len[t.label] += t.length;
        const auto inc3 = incidence(graph);
        for (const auto& t : trees) {
            VesselTreeReport r;
            r.label = t.label;
            r.root_node = t.root;
            r.centreline_mm = t.length;
            r.mean_intensity = t.intensity;
            std::vector<std::uint8_t> in_tree(graph.nodes.size(), 0);
            for (int n : t.nodes)
                in_tree[std::size_t(n)] = 1;
            for (const auto& e : graph.edges)
                if (in_tree[std::size_t(e.from)]) {
                    ++r.edges;
                    r.max_level = std::max(r.max_level, static_cast<int>(e.level));
                }
            if (!inc3[std::size_t(t.root)].empty())
                r.name = graph.edges[std::size_t(inc3[std::size_t(t.root)][0])].name;
            // Share of its label's volume in proportion to centre-line length (trees of one label
            // are labelled alike in the mask).
            const double total = t.label == kPortalVeinLabel ? res.portal_ml : res.hepatic_ml;
            r.volume_ml = label_len[t.label] > 0 ? total * t.length / label_len[t.label] : 0.0;
            res.trees.push_back(r);
        }
    }
    res.graph = std::move(graph);
    res.found = true;
    int max_level = 0;
    for (const auto& e : res.graph.edges)
        max_level = std::max(max_level, static_cast<int>(e.level));
    res.message = std::to_string(res.trees.size()) + " trees (" +
                  std::to_string(std::count_if(res.trees.begin(), res.trees.end(), [](const VesselTreeReport& r) {
                      return r.label == kPortalVeinLabel;
                  })) +
                  " portal), " + std::to_string(res.graph.edges.size()) + " segments, " + std::to_string(max_level) +
                  " branch levels; portal " + detail::fixed(res.portal_ml) + " mL, hepatic " + detail::fixed(res.hepatic_ml) + " mL; " +
                  (res.separated_by_contrast ? "trees told apart by contrast" : "trees told apart by anatomy") +
                  (res.bridges ? ", " + std::to_string(res.bridges) + " gaps bridged" : "") +
                  (res.trees_cut ? ", " + std::to_string(res.trees_cut) + " contacts between trees cut" : "");
    res.timings.emplace_back("total", std::chrono::duration<double>(Clock::now() - t_start).count());
    say(res.message);
    return res;
}

} // namespace

CentrelineEvaluation evaluate_centrelines(const core::CentrelineGraph& segmented, const core::CentrelineGraph& reference,
                                          const core::LabelImage3D* region, const CentrelineMatchParams& params)
{
    const std::string p1 = core::graph_problem(segmented), p2 = core::graph_problem(reference);
    if (!p1.empty())
        throw core::InvalidInputError("evaluate_centrelines: segmented graph: " + p1);
    if (!p2.empty())
        throw core::InvalidInputError("evaluate_centrelines: reference graph: " + p2);
    if (!(params.sample_mm > 0) || !(params.min_tolerance_mm >= 0))
        throw core::InvalidInputError("evaluate_centrelines: sample_mm must be > 0 and min_tolerance_mm >= 0");

    struct Sample {
        core::Vec3 p;
        double r;
        int edge;
    };
    auto sample = [&](const core::CentrelineGraph& g, double step) {
        std::vector<Sample> out;
        for (std::size_t e = 0; e < g.edges.size(); ++e) {
            const auto& ed = g.edges[e];
            for (std::size_t i = 0; i + 1 < ed.points.size(); ++i) {
                const double len = core::distance(ed.points[i], ed.points[i + 1]);
                const int n = std::max(1, static_cast<int>(std::ceil(len / step)));
                for (int s = 0; s < n; ++s) {
                    const double t = double(s) / n;
                    out.push_back({ed.points[i] + (ed.points[i + 1] - ed.points[i]) * t,
                                   ed.point_radius[i] * (1 - t) + ed.point_radius[i + 1] * t, int(e)});
                }
            }
            if (!ed.points.empty())
                out.push_back({ed.points.back(), ed.point_radius.back(), int(e)});
        }
        return out;
    };
    const std::vector<Sample> seg = sample(segmented, 0.5 * params.sample_mm);
    const std::vector<Sample> ref = sample(reference, params.sample_mm);

    // A hash grid over points.
    constexpr double kCell = 4.0;
    auto key = [](const core::Vec3& p) {
        const auto c = [](double v) { return static_cast<std::int64_t>(std::floor(v / kCell)) & 0x1fffff; };
        return (c(p.x) << 42) | (c(p.y) << 21) | c(p.z);
    };
    auto build = [&](const std::vector<Sample>& s) {
        std::unordered_map<std::int64_t, std::vector<int>> h;
        for (std::size_t i = 0; i < s.size(); ++i)
            h[key(s[i].p)].push_back(int(i));
        return h;
    };
    const auto hseg = build(seg), href = build(ref);
    auto nearest = [&](const std::unordered_map<std::int64_t, std::vector<int>>& h, const std::vector<Sample>& s,
                       const core::Vec3& p, double tol) {
        int best = -1;
        double bd = tol;
        const int reach = static_cast<int>(std::ceil(tol / kCell));
        for (int dz = -reach; dz <= reach; ++dz)
            for (int dy = -reach; dy <= reach; ++dy)
                for (int dx = -reach; dx <= reach; ++dx) {
                    const auto it = h.find(key(p + core::Vec3{dx * kCell, dy * kCell, dz * kCell}));
                    if (it == h.end())
                        continue;
                    for (int i : it->second) {
                        const double d = core::distance(s[std::size_t(i)].p, p);
                        if (d <= bd) {
                            bd = d;
                            best = i;
                        }
                    }
                }
        return best;
    };

    CentrelineEvaluation ev;
    std::map<int, LevelRecall> by_level;
    std::map<std::pair<int, int>, LevelRecall> by_tree;
    std::size_t same_level = 0;
    for (const auto& s : ref) {
        if (region) {
            const auto v = voxel_of(*region, s.p);
            if (v[0] < 0 || !region->at(v[0], v[1], v[2]))
                continue;
        }
        const auto& re = reference.edges[std::size_t(s.edge)];
        LevelRecall& a = by_level[re.level];
        LevelRecall& b = by_tree[{re.label, re.level}];
        a.level = b.level = re.level;
        b.label = re.label;
        ++a.samples;
        ++b.samples;
        ++ev.overall.samples;
        const int hit = nearest(hseg, seg, s.p, std::max(s.r, params.min_tolerance_mm));
        if (hit < 0)
            continue;
        ++a.found;
        ++b.found;
        ++ev.overall.found;
        const auto& se = segmented.edges[std::size_t(seg[std::size_t(hit)].edge)];
        if (se.label == re.label) {
            ++a.labelled_right;
            ++b.labelled_right;
            ++ev.overall.labelled_right;
        }
        same_level += se.level == re.level;
    }
    for (const auto& [l, r] : by_level)
        ev.by_level.push_back(r);
    for (const auto& [k, r] : by_tree)
        ev.by_tree_level.push_back(r);
    ev.level_agreement = ev.overall.found ? double(same_level) / double(ev.overall.found) : 0.0;
    std::size_t near = 0;
    for (const auto& s : seg) {
        // within tolerance of the reference line: its radius there, or the minimum
        const int hit = nearest(href, ref, s.p, std::max(params.min_tolerance_mm, 8.0));
        if (hit >= 0 && core::distance(ref[std::size_t(hit)].p, s.p) <= std::max(ref[std::size_t(hit)].r, params.min_tolerance_mm))
            ++near;
    }
    ev.precision = seg.empty() ? 0.0 : double(near) / double(seg.size());
    return ev;
}

} // namespace lobe::seg
