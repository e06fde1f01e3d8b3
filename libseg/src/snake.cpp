// The three snakes share the level-set core; they differ only in the speed terms they build
// from the image (docs/segmentation.md explains every choice).
#include "lobe/seg/snake.h"

#include "lobe/core/errors.h"
#include "lobe/seg/distance_transform.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace lobe::seg {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0)
{
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

//! The field v (index units, as GVF returns it) turned into a unit physical direction per voxel,
//! scaled by `speed`. A field in index units differentiates along voxels, so its physical
//! direction divides each component by the spacing. Small vectors are not blown up to full
//! speed: |v| is normalised with a floor eps = `floor_fraction` * max |v|, so flat regions of
//! the field (the centre of an even-width fissure) stay slow instead of turning noisy.
VectorField normalised_speed_field(const VectorField& v, double speed, double floor_fraction,
                                   const core::LabelImage3D* only = nullptr)
{
    const core::ImageGeometry& g = v.geometry();
    VectorField out(g);
    const std::size_t n = g.voxel_count();
    const double inv_h[3] = {1.0 / g.spacing[0], 1.0 / g.spacing[1], 1.0 / g.spacing[2]};
    double max_norm = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        double s = 0.0;
        for (int a = 0; a < 3; ++a) {
            const double c = double(v.c[a].data[i]) * inv_h[a];
            s += c * c;
        }
        max_norm = std::max(max_norm, s);
    }
    max_norm = std::sqrt(max_norm);
    if (!(max_norm > 0.0))
        return out;
    const double eps = floor_fraction * max_norm;
#pragma omp parallel for schedule(static)
    for (std::int64_t ii = 0; ii < static_cast<std::int64_t>(n); ++ii) {
        const auto i = static_cast<std::size_t>(ii);
        if (only && !only->data[i])
            continue;
        double c[3];
        double s = 0.0;
        for (int a = 0; a < 3; ++a) {
            c[a] = double(v.c[a].data[i]) * inv_h[a];
            s += c[a] * c[a];
        }
        const double scale = speed / (std::sqrt(s) + eps);
        for (int a = 0; a < 3; ++a)
            out.c[a].data[i] = static_cast<float>(c[a] * scale);
    }
    return out;
}

//! Unit normals of a mask's boundary (gradient of its signed distance), zero where the distance
//! exceeds `width_mm`: the preferred edge directions DSG boosts.
VectorField template_directions(const core::ImageF& template_sdf, double width_mm)
{
    const VectorField grad = gradient(template_sdf);
    VectorField out(template_sdf.geometry());
    const std::size_t n = template_sdf.voxel_count();
    for (std::size_t i = 0; i < n; ++i) {
        if (!(std::abs(double(template_sdf.data[i])) <= width_mm))
            continue;
        double s = 0.0;
        for (int a = 0; a < 3; ++a)
            s += double(grad.c[a].data[i]) * double(grad.c[a].data[i]);
        s = std::sqrt(s);
        if (s > 1e-6)
            for (int a = 0; a < 3; ++a)
                out.c[a].data[i] = static_cast<float>(double(grad.c[a].data[i]) / s);
    }
    return out;
}

//! Boundary voxels of a mask (inside, with a face neighbour outside; in-plane for 2-D).
template <class F>
void for_each_boundary_voxel(const core::LabelImage3D& m, F&& f)
{
    const auto& s = m.size;
    const bool is3d = s[2] > 1;
    for (int k = 0; k < s[2]; ++k)
        for (int j = 0; j < s[1]; ++j)
            for (int i = 0; i < s[0]; ++i) {
                if (!m.at(i, j, k))
                    continue;
                const bool border = (i == 0 || !m.at(i - 1, j, k)) || (i + 1 == s[0] || !m.at(i + 1, j, k)) ||
                                    (j == 0 || !m.at(i, j - 1, k)) || (j + 1 == s[1] || !m.at(i, j + 1, k)) ||
                                    (is3d && ((k == 0 || !m.at(i, j, k - 1)) || (k + 1 == s[2] || !m.at(i, j, k + 1))));
                if (border)
                    f(m.index(i, j, k));
            }
}

//! Canny's non-maximum suppression: keeps f only where it is a maximum along the direction of
//! the smoothed image's gradient (quantised to the nearest of the 8 or 26 neighbours), so
//! that the binary edges are one or two voxels thick. Without it a σ = 1 voxel blur makes the
//! edges four voxels thick and every structure thinner than about ten voxels lies entirely in
//! δ1, where CDSG has no pressure.
core::ImageF non_maximum_suppression(const core::ImageF& f, const core::ImageF& smoothed)
{
    const VectorField grad = gradient(smoothed);
    core::ImageF out(f.geometry(), 0.f);
    const int nx = f.size[0], ny = f.size[1], nz = f.size[2];
#pragma omp parallel for schedule(static)
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const std::size_t c = f.index(i, j, k);
                const float v = f.data[c];
                if (!(v > 0.f))
                    continue;
                // The gradient direction in index space (gradient() is per mm).
                double d[3];
                double norm = 0.0;
                for (int a = 0; a < 3; ++a) {
                    d[a] = double(grad.c[a].data[c]) * f.spacing[a];
                    norm = std::max(norm, std::abs(d[a]));
                }
                if (!(norm > 0.0)) {
                    out.data[c] = v; // flat gradient: nothing to compare along
                    continue;
                }
                // Round to the nearest neighbour direction: components below tan(22.5°) of the
                // largest one are dropped.
                int step[3];
                for (int a = 0; a < 3; ++a)
                    step[a] = std::abs(d[a]) >= 0.4142 * norm ? (d[a] > 0 ? 1 : -1) : 0;
                const auto at = [&](int s) {
                    const int a = i + s * step[0], b = j + s * step[1], e = k + s * step[2];
                    return f.contains(a, b, e) ? f.at(a, b, e) : 0.f;
                };
                const float fwd = at(1), bwd = at(-1);
                // Ties are kept on both sides: a step between two voxel centres gives two equal maxima.
                if (v >= fwd && v >= bwd && (v > fwd || v > bwd))
                    out.data[c] = v;
            }
    return out;
}

//! CDSG's binary edges: hysteresis on the full edge map (its connectivity survives corners and
//! T-junctions, where suppression breaks ridges), then thinned to the ridges that suppression keeps.
core::LabelImage3D thin_binary_edges(const core::ImageF& f, const core::ImageF& smoothed, const BinaryEdgeParams& bp)
{
    core::LabelImage3D bin = binary_edges(f, noise_adapted(f, bp, 3.0));
    const core::ImageF ridges = non_maximum_suppression(f, smoothed);
    for (std::size_t i = 0; i < bin.data.size(); ++i)
        bin.data[i] = bin.data[i] && ridges.data[i] > 0.f ? 1 : 0;
    return bin;
}

//! A stopping function of the (competition-weighted) edge map: 1 / (1 + (|∇I| / k)^power),
//! with |∇I| = f * scale since f is |∇I| normalised by `scale`. The GAC's g and CDSG's pressure
//! scaling are both this, with their own k (and CDSG's exponent).
double sharp_stopping(float f, double scale, double k, double power)
{
    return 1.0 / (1.0 + std::pow(double(f) * scale / k, power));
}

//! Everything one run needs besides the competition weight.
struct Context {
    const SnakeParams& params;
    const core::ImageF& phi0;
    EdgeMapResult edges;
    std::optional<core::ImageF> template_sdf;
    core::LabelImage3D aoi;          //!< empty without a template
    VectorField directions;          //!< DSG preferred normals (empty without a template)
    const core::LabelImage3D* region = nullptr; //!< pressure acts only inside (null: everywhere)
};

struct Terms {
    core::ImageF stopping;
    core::ImageF pressure;
    VectorField advection;
    bool has_stopping = false, has_pressure = false, has_advection = false;
};

Terms cdsg_terms(const Context& ctx, const core::ImageF& f)
{
    const SnakeParams& p = ctx.params;
    Terms t;
    // Chessboard distance to the binary edges: pressure outside δ1, GVF inside (the hand-over).
    const core::Image3D<std::int32_t> dch =
        chessboard_distance(thin_binary_edges(f, ctx.edges.intensity, p.cdsg.edges));
    core::LabelImage3D band(f.geometry(), 0);
    bool any_band = false;
    for (std::size_t i = 0; i < band.data.size(); ++i)
        if (dch.data[i] >= 0 && dch.data[i] <= p.cdsg.edge_band) {
            band.data[i] = 1;
            any_band = true;
        }

    // External field inside δ1: band-limited GGVF of the (directionally sharpened) edge map.
    VectorField field(f.geometry());
    if (any_band) {
        const bool dsg = p.cdsg.directional_sharpening && !ctx.directions.empty();
        const core::ImageF sharpened = dsg ? dsg_edge_map(f, ctx.directions, p.cdsg.dsg) : core::ImageF();
        GvfParams gp = p.gvf;
        gp.iterations = std::max(1, p.band_gvf_iterations);
        const GvfResult gvf = gradient_vector_flow(dsg ? sharpened : f, band, gp);
        field = normalised_speed_field(gvf.field, p.cdsg.pressure, 0.05, &band);
    }

    if (p.cdsg.pressure_mode == PressureMode::Scalar) {
        t.pressure = core::ImageF(f.geometry(), 0.f);
        const double k = p.cdsg.pressure_stopping_k;
        for (std::size_t i = 0; i < band.data.size(); ++i)
            if (!band.data[i]) {
                double speed = p.cdsg.pressure;
                if (k > 0) {
                    speed *= sharp_stopping(f.data[i], ctx.edges.scale, k, p.cdsg.pressure_stopping_power);
                }
                t.pressure.data[i] = static_cast<float>(speed);
            }
        t.has_pressure = true;
    } else {
        // -∇D_Ch points to the nearest edge; joined with the GVF field into one advection field.
        core::ImageF d(f.geometry(), 0.f);
        for (std::size_t i = 0; i < d.data.size(); ++i)
            d.data[i] = dch.data[i] < 0 ? 0.f : static_cast<float>(dch.data[i]);
        // gradient() is per mm; normalised_speed_field expects index units (times the spacing).
        VectorField gd = gradient(d);
        for (int a = 0; a < 3; ++a)
            for (auto& v : gd.c[a].data)
                v = static_cast<float>(-double(v) * f.spacing[a]);
        const VectorField outside = normalised_speed_field(gd, p.cdsg.pressure, 0.05);
        for (std::size_t i = 0; i < band.data.size(); ++i)
            if (!band.data[i])
                for (int a = 0; a < 3; ++a)
                    field.c[a].data[i] = outside.c[a].data[i];
    }
    t.advection = std::move(field);
    t.has_advection = true;
    t.stopping = ctx.edges.stopping;
    t.has_stopping = true;
    return t;
}

Terms ggvf_terms(const Context& ctx, const core::ImageF& f)
{
    Terms t;
    const GvfResult gvf = gradient_vector_flow(f, ctx.params.gvf);
    t.advection = normalised_speed_field(gvf.field, ctx.params.cdsg.pressure, 0.05);
    t.has_advection = true;
    return t;
}

Terms gac_terms(const Context& ctx, const core::ImageF& f)
{
    const SnakeParams& p = ctx.params;
    Terms t;
    // g from the (possibly competition-weighted) edge strength, with the GAC's own sharper k.
    t.stopping = core::ImageF(f.geometry(), 1.f);
    for (std::size_t i = 0; i < f.data.size(); ++i)
        t.stopping.data[i] = static_cast<float>(sharp_stopping(f.data[i], ctx.edges.scale, p.gac_stopping_k, 2.0));
    t.has_stopping = true;
    t.pressure = t.stopping;
    for (auto& v : t.pressure.data)
        v = static_cast<float>(double(v) * p.gac_pressure);
    t.has_pressure = true;
    // Pull-back -(∇g·N)N: the front moves down the gradient of g, towards the edge.
    VectorField gg = gradient(t.stopping);
    const core::ImageF norms = magnitude(gg);
    const double max_norm = *std::max_element(norms.data.begin(), norms.data.end());
    const double scale = max_norm > 0 ? p.gac_pressure / max_norm : 0.0;
    for (int a = 0; a < 3; ++a)
        for (auto& v : gg.c[a].data)
            v = static_cast<float>(-double(v) * scale);
    t.advection = std::move(gg);
    t.has_advection = true;
    return t;
}

struct Run {
    LevelSetResult ls;
    double field_seconds = 0.0;
    double evolve_seconds = 0.0;
};

Run run_once(const Context& ctx, float weight)
{
    const SnakeParams& p = ctx.params;
    const auto t0 = Clock::now();
    core::ImageF f = ctx.edges.edge;
    if (weight < 1.f && !ctx.aoi.data.empty()) {
        // G only sets the ratio between edges inside and outside the AOI. Dividing by G keeps
        // the edges outside at their strength (so the binary-edge thresholds keep their
        // meaning there) and lifts the weak edges inside the AOI above them: the competition.
        f = energy_competition(ctx.edges.edge, ctx.aoi, weight);
        for (auto& v : f.data)
            v = std::min(1.f, v / weight);
    }
    Terms t;
    switch (p.method) {
    case SnakeMethod::Cdsg: t = cdsg_terms(ctx, f); break;
    case SnakeMethod::Ggvf: t = ggvf_terms(ctx, f); break;
    case SnakeMethod::Gac: t = gac_terms(ctx, f); break;
    }
    if (ctx.region && t.has_pressure)
        for (std::size_t i = 0; i < t.pressure.data.size(); ++i)
            if (!ctx.region->data[i])
                t.pressure.data[i] = 0.f;
    Run r;
    r.field_seconds = seconds_since(t0);

    SpeedTerms terms;
    terms.curvature_weight = p.curvature_weight;
    terms.stopping = t.has_stopping ? &t.stopping : nullptr;
    terms.pressure = t.has_pressure ? &t.pressure : nullptr;
    terms.advection = t.has_advection ? &t.advection : nullptr;
    const auto t1 = Clock::now();
    r.ls = evolve_level_set(ctx.phi0, terms, p.level_set);
    r.evolve_seconds = seconds_since(t1);
    return r;
}

//! Fraction of the result's boundary voxels that lie outside the AOI (the Auto rule's test).
double fraction_outside(const core::LabelImage3D& mask, const core::LabelImage3D& aoi)
{
    std::size_t total = 0, outside = 0;
    for_each_boundary_voxel(mask, [&](std::size_t i) {
        ++total;
        if (!aoi.data[i])
            ++outside;
    });
    return total ? double(outside) / double(total) : 1.0;
}

} // namespace

SnakeResult segment_snake(const core::ImageF& image, const core::LabelImage3D& init, const SnakeParams& params,
                          const core::LabelImage3D* templ, const core::LabelImage3D* region)
{
    if (image.data.empty() || image.voxel_count() != image.data.size())
        throw core::InvalidInputError("segment_snake: the image is empty or its data does not match its size");
    if (!core::same_grid(image, init))
        throw core::InvalidInputError("segment_snake: the initial mask is not on the image's grid");
    if (templ && !core::same_grid(image, *templ))
        throw core::InvalidInputError("segment_snake: the template mask is not on the image's grid");
    if (region && !core::same_grid(image, *region))
        throw core::InvalidInputError("segment_snake: the region mask is not on the image's grid");
    if (params.aoi_width_mm <= 0 || !std::isfinite(params.aoi_width_mm))
        throw core::InvalidInputError("segment_snake: aoi_width_mm must be positive");
    if (params.repeat_keep_voxels < -1)
        throw core::InvalidInputError("segment_snake: repeat_keep_voxels must be -1 (off) or non-negative, got " +
                                      std::to_string(params.repeat_keep_voxels));

    const auto t0 = Clock::now();
    const core::ImageF phi0 = initial_level_set(init); // throws for an empty or full mask
    EdgeMapResult edges = edge_map(image, params.edge); // throws for non-finite values
    Context ctx{params, phi0, std::move(edges), std::nullopt, {}, {}, region};

    const bool competition_possible = templ != nullptr && params.competition != CompetitionMode::Off;
    if (templ) {
        ctx.template_sdf = initial_level_set(*templ);
        ctx.aoi = core::LabelImage3D(image.geometry(), 0);
        for (std::size_t i = 0; i < ctx.aoi.data.size(); ++i)
            ctx.aoi.data[i] = std::abs(double(ctx.template_sdf->data[i])) <= params.aoi_width_mm ? 1 : 0;
        if (params.method == SnakeMethod::Cdsg && params.cdsg.directional_sharpening)
            ctx.directions = template_directions(*ctx.template_sdf, params.aoi_width_mm);
    }
    const double setup_seconds = seconds_since(t0);

    const bool start_on = competition_possible && params.competition == CompetitionMode::On;
    Run run = run_once(ctx, start_on ? kCompetitionOn : 1.f);
    SnakeResult out;
    out.competition_used = start_on;
    out.runs = 1;
    out.field_seconds = setup_seconds + run.field_seconds;
    out.evolve_seconds = run.evolve_seconds;
    if (competition_possible && params.competition == CompetitionMode::Auto &&
        fraction_outside(run.ls.mask, ctx.aoi) > params.aoi_leave_fraction) {
        // The one-repeat rule (thesis L3285-3295): the contour left the AOI, so the edges there
        // were too weak to hold it; weight the edges outside the AOI down and segment once more.
        Run first = std::move(run);
        run = run_once(ctx, kCompetitionOn);
        out.competition_used = true;
        out.runs = 2;
        out.field_seconds += run.field_seconds;
        out.evolve_seconds += run.evolve_seconds;
        if (params.repeat_keep_voxels >= 0) {
            // The repeat only cuts the first run where that left the AOI; elsewhere the first
            // run's edge stands. The repeat stops a voxel or more inside it: lifted and clipped,
            // an edge becomes a plateau with a ridge on its inner side, and the interior's weak
            // edges in the AOI are lifted too (liver.md, "What energy competition's repeat keeps").
            const auto t2 = Clock::now();
            const core::Image3D<std::int32_t> d = chessboard_distance(run.ls.mask);
            for (std::size_t i = 0; i < d.data.size(); ++i)
                run.ls.mask.data[i] =
                    first.ls.mask.data[i] && d.data[i] >= 0 && d.data[i] <= params.repeat_keep_voxels ? 1 : 0;
            const auto inside = std::count_if(run.ls.mask.data.begin(), run.ls.mask.data.end(),
                                              [](std::uint8_t v) { return v != 0; });
            if (inside > 0 && std::size_t(inside) < run.ls.mask.data.size()) // else no boundary to measure from
                run.ls.phi = initial_level_set(run.ls.mask);
            out.field_seconds += seconds_since(t2);
        }
    }
    out.mask = std::move(run.ls.mask);
    out.phi = std::move(run.ls.phi);
    out.iterations = run.ls.iterations;
    out.reinitialisations = run.ls.reinitialisations;
    out.converged = run.ls.converged;
    out.leak_stopped = run.ls.leak_stopped;
    return out;
}

namespace {

//! Trilinear sample of `img` at the index-space point (x, y, z), clamped to the grid.
double sample(const core::ImageF& img, double x, double y, double z)
{
    const double p[3] = {x, y, z};
    int i0[3];
    double w[3];
    for (int a = 0; a < 3; ++a) {
        const double c = std::clamp(p[a], 0.0, double(img.size[a] - 1));
        i0[a] = std::min(static_cast<int>(std::floor(c)), std::max(0, img.size[a] - 2));
        w[a] = img.size[a] > 1 ? c - i0[a] : 0.0;
    }
    double v = 0.0;
    for (int dz = 0; dz < (img.size[2] > 1 ? 2 : 1); ++dz)
        for (int dy = 0; dy < (img.size[1] > 1 ? 2 : 1); ++dy)
            for (int dx = 0; dx < (img.size[0] > 1 ? 2 : 1); ++dx)
                v += (dx ? w[0] : 1 - w[0]) * (dy ? w[1] : 1 - w[1]) * (dz ? w[2] : 1 - w[2]) *
                     double(img.at(i0[0] + dx, i0[1] + dy, i0[2] + dz));
    return v;
}

//! The gate: a voxel the snap added to `before` stays only if its intensity lies at least `level`
//! of the way from the intensity two voxels outwards to the one two voxels inwards along the
//! contour's normal (∇φ). Where the surroundings fall off gradually (soft tissue, then fat) the
//! gradient's ridge lies outside the half-way crossing, and the snap alone overshoots.
void keep_inner_side(core::LabelImage3D& mask, const core::LabelImage3D& before, const core::ImageF& phi,
                     const core::ImageF& intensity, double level)
{
    const double reach = 2.0; // voxels of the in-plane grid
    const bool is3d = mask.size[2] > 1;
    for (int k = 0; k < mask.size[2]; ++k)
        for (int j = 0; j < mask.size[1]; ++j)
            for (int i = 0; i < mask.size[0]; ++i) {
                const std::size_t c = mask.index(i, j, k);
                if (!mask.data[c] || before.data[c])
                    continue;
                // ∇φ per index step, via central differences clamped to the grid.
                const auto d = [&](int a) {
                    int lo[3] = {i, j, k}, hi[3] = {i, j, k};
                    lo[a] = std::max(0, lo[a] - 1);
                    hi[a] = std::min(mask.size[a] - 1, hi[a] + 1);
                    if (hi[a] == lo[a])
                        return 0.0;
                    return (double(phi.at(hi[0], hi[1], hi[2])) - double(phi.at(lo[0], lo[1], lo[2]))) /
                           (hi[a] - lo[a]);
                };
                double n[3] = {d(0), d(1), is3d ? d(2) : 0.0};
                const double norm = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
                if (!(norm > 0.0))
                    continue;
                for (double& v : n)
                    v *= reach / norm;
                const double inner = sample(intensity, i - n[0], j - n[1], k - n[2]);
                const double outer = sample(intensity, i + n[0], j + n[1], k + n[2]);
                if (double(intensity.data[c]) < outer + level * (inner - outer))
                    mask.data[c] = 0;
            }
}

} // namespace

SnakeResult snap_to_edges(const core::ImageF& image, const core::LabelImage3D& mask, const SnakeParams& params,
                          const SnapParams& snap)
{
    if (image.data.empty() || image.voxel_count() != image.data.size())
        throw core::InvalidInputError("snap_to_edges: the image is empty or its data does not match its size");
    if (!core::same_grid(image, mask))
        throw core::InvalidInputError("snap_to_edges: the mask is not on the image's grid");
    if (snap.band < 1 || snap.iterations < 1 || snap.gvf_iterations < 1 ||
        !(snap.gate_level >= 0.0 && snap.gate_level <= 1.0))
        throw core::InvalidInputError("snap_to_edges: band, iterations and gvf_iterations must be >= 1 and gate_level "
                                      "in [0, 1] (are " +
                                      std::to_string(snap.band) + ", " + std::to_string(snap.iterations) + ", " +
                                      std::to_string(snap.gvf_iterations) + ", " + std::to_string(snap.gate_level) +
                                      ")");
    const auto t0 = Clock::now();
    const core::ImageF phi0 = initial_level_set(mask); // throws for an empty or full mask
    const EdgeMapResult edges = edge_map(image, params.edge);
    const core::Image3D<std::int32_t> dch =
        chessboard_distance(thin_binary_edges(edges.edge, edges.intensity, params.cdsg.edges));
    core::LabelImage3D band(image.geometry(), 0);
    bool any = false;
    for (std::size_t i = 0; i < band.data.size(); ++i)
        if (dch.data[i] >= 0 && dch.data[i] <= snap.band) {
            band.data[i] = 1;
            any = true;
        }
    VectorField field(image.geometry());
    if (any) {
        GvfParams gp = params.gvf;
        gp.iterations = snap.gvf_iterations;
        field =
            normalised_speed_field(gradient_vector_flow(edges.edge, band, gp).field, params.cdsg.pressure, 0.05, &band);
    }
    SnakeResult out;
    out.field_seconds = seconds_since(t0);
    SpeedTerms terms;
    terms.curvature_weight = params.curvature_weight;
    terms.stopping = &edges.stopping;
    terms.advection = &field;
    LevelSetParams lp = params.level_set;
    lp.max_iterations = snap.iterations;
    lp.leak_checks = 0; // no pressure: nothing can leak
    const auto t1 = Clock::now();
    LevelSetResult ls = evolve_level_set(phi0, terms, lp);
    if (snap.gate_level > 0.0)
        keep_inner_side(ls.mask, mask, ls.phi, edges.intensity, snap.gate_level);
    out.evolve_seconds = seconds_since(t1);
    out.mask = std::move(ls.mask);
    out.phi = std::move(ls.phi);
    out.iterations = ls.iterations;
    out.reinitialisations = ls.reinitialisations;
    out.converged = ls.converged;
    return out;
}

} // namespace lobe::seg
