// Level-set evolution against flows whose solution is known in closed form (curvature flow of a
// circle and a sphere, constant normal speed, constant advection), convergence onto a target,
// topology changes, the narrow band against a full-grid run, the stopping rules and the errors.
#include "lobe/seg/level_set.h"

#include "common/expect_error.h"
#include "common/masks.h"

#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <vector>

using namespace lobe;
using seg::LevelSetParams;
using seg::SpeedTerms;

namespace {

constexpr double kPi = 3.14159265358979323846;

core::ImageGeometry grid(int nx, int ny, int nz, double hx = 1, double hy = 1, double hz = 1)
{
    core::ImageGeometry g;
    g.size = {nx, ny, nz};
    g.spacing = {hx, hy, hz};
    return g;
}

// Parameters for a run of a fixed number of iterations (no convergence stop).
LevelSetParams fixed_run(int iterations, int band = 4)
{
    LevelSetParams p;
    p.band_voxels = band;
    p.max_iterations = iterations;
    p.convergence_tolerance = 0.0; // the measure is never < 0: no early stop
    return p;
}

using test::count;

// Radius of the disc (2-D) or ball (3-D) with the mask's physical area or volume.
double equivalent_radius(const core::LabelImage3D& m)
{
    const double cell = m.spacing[0] * m.spacing[1] * (m.size[2] > 1 ? m.spacing[2] : 1.0);
    const double amount = double(count(m)) * cell;
    return m.size[2] > 1 ? std::cbrt(amount * 3.0 / (4.0 * kPi)) : std::sqrt(amount / kPi);
}

double dice(const core::LabelImage3D& a, const core::LabelImage3D& b)
{
    std::size_t both = 0, na = 0, nb = 0;
    for (std::size_t v = 0; v < a.data.size(); ++v) {
        na += a.data[v] != 0;
        nb += b.data[v] != 0;
        both += a.data[v] != 0 && b.data[v] != 0;
    }
    return 2.0 * double(both) / double(na + nb);
}

// Face-connected components of the mask.
int components(const core::LabelImage3D& m)
{
    std::vector<std::uint8_t> seen(m.data.size(), 0);
    int n = 0;
    std::vector<std::array<int, 3>> stack;
    for (int k = 0; k < m.size[2]; ++k)
        for (int j = 0; j < m.size[1]; ++j)
            for (int i = 0; i < m.size[0]; ++i) {
                if (!m.at(i, j, k) || seen[m.index(i, j, k)])
                    continue;
                ++n;
                seen[m.index(i, j, k)] = 1;
                stack.push_back({i, j, k});
                while (!stack.empty()) {
                    const auto c = stack.back();
                    stack.pop_back();
                    for (int a = 0; a < 3; ++a)
                        for (int s = -1; s <= 1; s += 2) {
                            auto q = c;
                            q[std::size_t(a)] += s;
                            if (!m.contains(q[0], q[1], q[2]) || !m.at(q[0], q[1], q[2]) ||
                                seen[m.index(q[0], q[1], q[2])])
                                continue;
                            seen[m.index(q[0], q[1], q[2])] = 1;
                            stack.push_back(q);
                        }
                }
            }
    return n;
}

core::LabelImage3D disc_mask(const core::ImageGeometry& g, double cx, double cy, double r_mm)
{
    core::LabelImage3D m(g, 0);
    for (int j = 0; j < g.size[1]; ++j)
        for (int i = 0; i < g.size[0]; ++i)
            if (std::hypot((i - cx) * g.spacing[0], (j - cy) * g.spacing[1]) < r_mm)
                m.at(i, j, 0) = 1;
    return m;
}

bool all_finite(const core::ImageF& img)
{
    for (float v : img.data)
        if (!std::isfinite(v))
            return false;
    return true;
}

} // namespace

// Curve-shortening flow of a circle: dR/dt = -ε/R, so R(t)^2 = R0^2 - 2εt. The scheme is first-order
// and the area-equivalent radius of the pixel mask is within ~0.1 px of the true one at R ≈ 12, so
// half a voxel is a safe bound (the brief allows one; observed 0.20).
TEST(LevelSet, CurvatureFlowShrinksCircleAsPredicted)
{
    const auto g = grid(64, 64, 1);
    const double r0 = 20.0, eps = 1.0;
    const auto phi0 = seg::level_set_from_seeds(g, {{32.0, 32.0, 0.0}}, r0);
    SpeedTerms terms;
    terms.curvature_weight = eps;
    // Δt = 0.7 / (4 ε Σ 1/h^2) = 0.0875; 1463 steps are t = 128, R = 12.
    const auto r = seg::evolve_level_set(phi0, terms, fixed_run(1463));
    EXPECT_NEAR(r.time_step, 0.0875, 1e-12);
    const double t = r.iterations * r.time_step;
    const double expected = std::sqrt(r0 * r0 - 2.0 * eps * t);
    EXPECT_NEAR(equivalent_radius(r.mask), expected, 0.5) << "t = " << t;
    EXPECT_FALSE(r.converged);
    EXPECT_GT(r.reinitialisations, 0);
}

// The stopping function scales the curvature speed: g = 0.5 halves ε, R^2 = R0^2 - εt (observed 0.15).
TEST(LevelSet, StoppingFunctionScalesCurvature)
{
    const auto g = grid(64, 64, 1);
    const double r0 = 20.0, eps = 1.0;
    const auto phi0 = seg::level_set_from_seeds(g, {{32.0, 32.0, 0.0}}, r0);
    const core::ImageF stop(g, 0.5f);
    SpeedTerms terms;
    terms.curvature_weight = eps;
    terms.stopping = &stop;
    const auto r = seg::evolve_level_set(phi0, terms, fixed_run(1500));
    const double t = r.iterations * r.time_step;
    EXPECT_NEAR(equivalent_radius(r.mask), std::sqrt(r0 * r0 - eps * t), 0.5) << "t = " << t;
}

// Mean-curvature flow of a sphere (κ = 2/R): R(t)^2 = R0^2 - 4εt. Same accuracy argument in 3-D
// (observed 0.03).
TEST(LevelSet, CurvatureFlowShrinksSphereAsPredicted)
{
    const auto g = grid(40, 40, 40);
    const double r0 = 14.0, eps = 1.0;
    const auto phi0 = seg::level_set_from_seeds(g, {{20.0, 20.0, 20.0}}, r0);
    SpeedTerms terms;
    terms.curvature_weight = eps;
    // Δt = 0.7 / 12; 480 steps are t = 28, R = sqrt(196 - 112) ≈ 9.2.
    const auto r = seg::evolve_level_set(phi0, terms, fixed_run(480));
    const double t = r.iterations * r.time_step;
    EXPECT_NEAR(equivalent_radius(r.mask), std::sqrt(r0 * r0 - 4.0 * eps * t), 0.5) << "t = " << t;
}

// A constant normal speed P moves every point of the front outwards at P: R = R0 + Pt. Godunov's
// scheme is exact for a plane and first-order on a curve; one voxel of the coarsest axis is the
// bound (the brief's accuracy; observed 0.29 and 0.19 mm, the front lagging slightly).
TEST(LevelSet, ConstantPressureExpandsCircleAtSpeedP)
{
    for (const auto& h : {std::array<double, 2>{1.0, 1.0}, std::array<double, 2>{1.0, 0.6}}) {
        SCOPED_TRACE("spacing " + std::to_string(h[0]) + " x " + std::to_string(h[1]));
        const auto g = grid(int(std::lround(80 / h[0])), int(std::lround(80 / h[1])), 1, h[0], h[1]);
        const double r0 = 8.0, speed = 1.5;
        const auto phi0 = seg::level_set_from_seeds(g, {{g.size[0] / 2.0, g.size[1] / 2.0, 0.0}}, r0);
        const core::ImageF pressure(g, float(speed));
        SpeedTerms terms;
        terms.pressure = &pressure;
        auto p = fixed_run(0);
        const double dt = seg::evolve_level_set(phi0, terms, p).time_step;
        p.max_iterations = int(std::lround(20.0 / speed / dt)); // t = 20/P: R = 28 mm
        const auto r = seg::evolve_level_set(phi0, terms, p);
        const double t = r.iterations * r.time_step;
        EXPECT_NEAR(equivalent_radius(r.mask), r0 + speed * t, std::max(h[0], h[1]));
        EXPECT_GT(r.reinitialisations, 3); // the front crossed the band several times
    }
}

// Same in 3-D with a thick-slice axis (h = 1, 1, 2): R = R0 + Pt within half the coarsest voxel
// (1 mm; observed 0.58).
TEST(LevelSet, ConstantPressureExpandsSphereAnisotropic)
{
    const auto g = grid(48, 48, 24, 1, 1, 2);
    const double r0 = 6.0;
    const auto phi0 = seg::level_set_from_seeds(g, {{24.0, 24.0, 12.0}}, r0);
    const core::ImageF pressure(g, 1.f);
    SpeedTerms terms;
    terms.pressure = &pressure;
    auto p = fixed_run(0);
    const double dt = seg::evolve_level_set(phi0, terms, p).time_step;
    p.max_iterations = int(std::lround(12.0 / dt)); // R = 18 mm
    const auto r = seg::evolve_level_set(phi0, terms, p);
    EXPECT_NEAR(equivalent_radius(r.mask), r0 + r.iterations * r.time_step, 1.0);
}

// Redistancing on a CT-like anisotropic grid (0.7 x 0.7 x 2.5 mm). The breadth-first search counts
// steps, not mm: a voxel reached first along z from a far part of the front used to keep that far
// distance (and, beyond the band width, stop the search, leaving holes beside the front). From the
// exact signed distance to a sphere, φ after 100 still steps (two periodic re-initialisations)
// must still be that distance within 0.4 mm throughout the band: observed 0.25 mm, the
// first-order flat patches of a front curved across 2.5 mm slices; without the repair 2.6 mm.
TEST(LevelSet, RedistancingKeepsTheBandWholeOnAnisotropicGrids)
{
    const auto g = grid(96, 96, 28, 0.7, 0.7, 2.5);
    const std::array<double, 3> c{33.3, 33.0, 34.1}; // centre [mm], off the voxel centres
    const double radius = 19.0;
    auto exact = [&](int i, int j, int k) {
        return std::sqrt(std::pow(i * 0.7 - c[0], 2) + std::pow(j * 0.7 - c[1], 2) + std::pow(k * 2.5 - c[2], 2)) - radius;
    };
    const auto phi0 = seg::level_set_from_seeds(g, {{c[0] / 0.7, c[1] / 0.7, c[2] / 2.5}}, radius);
    const auto r = seg::evolve_level_set(phi0, SpeedTerms{}, fixed_run(100));
    EXPECT_EQ(r.reinitialisations, 100 / 50);
    const double band = 4 * 2.5; // W = band_voxels x the largest spacing
    double worst = 0.0;
    std::size_t in_band = 0;
    for (int k = 0; k < 28; ++k)
        for (int j = 0; j < 96; ++j)
            for (int i = 0; i < 96; ++i) {
                const double e = exact(i, j, k);
                if (std::abs(e) > band - 2.5) // the outer voxel layer may be the clamp
                    continue;
                ++in_band;
                worst = std::max(worst, std::abs(double(r.phi.at(i, j, k)) - e));
            }
    EXPECT_GT(in_band, 50000u);
    EXPECT_LT(worst, 0.4) << "worst |φ - distance| in the band [mm]";
}

// A negative pressure shrinks at |P|: R = R0 - |P| t (the other Godunov branch; observed 0.17).
TEST(LevelSet, NegativePressureShrinksCircleAtSpeedP)
{
    const auto g = grid(64, 64, 1);
    const auto phi0 = seg::level_set_from_seeds(g, {{32.0, 32.0, 0.0}}, 25.0);
    const core::ImageF pressure(g, -1.f);
    SpeedTerms terms;
    terms.pressure = &pressure;
    const auto r = seg::evolve_level_set(phi0, terms, fixed_run(30));
    EXPECT_NEAR(equivalent_radius(r.mask), 25.0 - r.iterations * r.time_step, 0.5);
}

// A constant field V translates the shape by V t (first-order upwind, eq. 4.32). The centroid
// moves with V up to the mask's digitisation (< 0.3 px; observed 0.06). The scheme's numerical
// diffusion acts like a curvature flow with ε ≈ |V_a| h (1 - |V_a| Δt / h) / 2 per axis (≈ 0.18 mm^2
// here), so the disc also shrinks, R^2 ≈ 100 - 2 · 0.18 · 30: area 314 → about 280. Asserted: area
// loss < 15%, and the shape stays close to a disc (Dice > 0.95, observed 0.968, with the disc of
// equal area at V t; the diffusion is anisotropic, so it flattens the disc a little across V).
TEST(LevelSet, ConstantAdvectionTranslatesShape)
{
    const auto g = grid(80, 80, 1);
    const double cx = 25, cy = 45, rad = 10;
    const auto phi0 = seg::initial_level_set(disc_mask(g, cx, cy, rad));
    seg::VectorField field(g);
    const double vx = 0.8, vy = -0.4;
    std::fill(field.c[0].data.begin(), field.c[0].data.end(), float(vx));
    std::fill(field.c[1].data.begin(), field.c[1].data.end(), float(vy));
    SpeedTerms terms;
    terms.advection = &field;
    auto p = fixed_run(0);
    const double dt = seg::evolve_level_set(phi0, terms, p).time_step;
    EXPECT_NEAR(dt, 0.7 / (vx + std::abs(vy)), 1e-6); // Δt Σ|V_a|/h_a = cfl
    p.max_iterations = int(std::lround(30.0 / dt));   // t = 30: shift (24, -12)
    const auto r = seg::evolve_level_set(phi0, terms, p);
    const double t = r.iterations * r.time_step;
    double sx = 0, sy = 0;
    std::size_t n = 0;
    for (int j = 0; j < g.size[1]; ++j)
        for (int i = 0; i < g.size[0]; ++i)
            if (r.mask.at(i, j, 0)) {
                sx += i;
                sy += j;
                ++n;
            }
    EXPECT_NEAR(sx / double(n), cx + vx * t, 0.3);
    EXPECT_NEAR(sy / double(n), cy + vy * t, 0.3);
    EXPECT_GT(double(n), 0.85 * kPi * rad * rad);
    EXPECT_GT(dice(r.mask, disc_mask(g, cx + vx * t, cy + vy * t, std::sqrt(double(n) / kPi))), 0.95);
}

// The convergence measure counts voxels whose inside status changed, not the net volume change:
// a translating shape keeps its volume but must not be reported converged.
TEST(LevelSet, TranslationIsNotConvergence)
{
    const auto g = grid(96, 32, 1);
    const auto phi0 = seg::initial_level_set(disc_mask(g, 16, 16, 8));
    seg::VectorField field(g);
    std::fill(field.c[0].data.begin(), field.c[0].data.end(), 0.5f);
    SpeedTerms terms;
    terms.advection = &field;
    LevelSetParams p;
    p.max_iterations = 90; // Δt = 1.4: travels 63 voxels, 4 checks, and stays inside the grid
    const auto r = seg::evolve_level_set(phi0, terms, p);
    EXPECT_FALSE(r.converged);
    EXPECT_EQ(r.iterations, 90);
    // 14 voxels per check: about 380 voxels change status against about 45 boundary voxels (≈ 8.5)
    EXPECT_GT(r.last_change, 1.0);
}

// A pressure that is +1 inside a target disc and -1 outside drives any contour inside the target
// onto it and holds it there: the run converges long before max_iterations (observed: 120 of
// 2000) and the result overlaps the target to digitisation accuracy (Dice > 0.98, the brief's
// bound; observed 1: the front settles between the last +1 and the first -1 voxel).
TEST(LevelSet, ConvergesOntoTargetUnderSignedPressure)
{
    const auto g = grid(64, 64, 1);
    const auto target = disc_mask(g, 30.3, 33.6, 20.0);
    core::ImageF pressure(g, -1.f);
    for (std::size_t v = 0; v < target.data.size(); ++v)
        if (target.data[v])
            pressure.data[v] = 1.f;
    SpeedTerms terms;
    terms.pressure = &pressure;
    terms.curvature_weight = 0.1;
    LevelSetParams p;
    const auto phi0 = seg::level_set_from_seeds(g, {{28.0, 30.0, 0.0}}, 4.0);
    const auto r = seg::evolve_level_set(phi0, terms, p);
    EXPECT_TRUE(r.converged);
    EXPECT_LT(r.iterations, p.max_iterations / 4);
    EXPECT_LT(r.last_change, p.convergence_tolerance);
    EXPECT_GT(dice(r.mask, target), 0.98);
    EXPECT_TRUE(all_finite(r.phi));
}

// Two expanding seeds touch and merge into one component (topology changes are free).
TEST(LevelSet, ExpandingSeedsMerge)
{
    const auto g = grid(64, 48, 1);
    const auto phi0 = seg::level_set_from_seeds(g, {{18.0, 24.0, 0.0}, {46.0, 24.0, 0.0}}, 5.0);
    core::LabelImage3D m0(g, 0);
    for (std::size_t v = 0; v < m0.data.size(); ++v)
        m0.data[v] = phi0.data[v] < 0.f;
    EXPECT_EQ(components(m0), 2);
    const core::ImageF pressure(g, 1.f);
    SpeedTerms terms;
    terms.pressure = &pressure;
    const auto r = seg::evolve_level_set(phi0, terms, fixed_run(30)); // t ≈ 15: radius 20 > 14
    EXPECT_EQ(components(r.mask), 1);
}

// A dumbbell (two discs of radius 10 joined by a 7-voxel bar) under a shrinking speed of 1 for t ≈ 5:
// the bar (half-width 3.5) vanishes, the discs keep radius ≈ 5: two components.
TEST(LevelSet, ShrinkingDumbbellSplits)
{
    const auto g = grid(64, 64, 1);
    auto mask = disc_mask(g, 16, 32, 10);
    const auto other = disc_mask(g, 48, 32, 10);
    for (std::size_t v = 0; v < mask.data.size(); ++v)
        mask.data[v] |= other.data[v];
    for (int j = 29; j <= 35; ++j)
        for (int i = 16; i <= 48; ++i)
            mask.at(i, j, 0) = 1;
    EXPECT_EQ(components(mask), 1);
    const core::ImageF pressure(g, -1.f);
    SpeedTerms terms;
    terms.pressure = &pressure;
    terms.curvature_weight = 0.2;
    auto p = fixed_run(0);
    const auto phi0 = seg::initial_level_set(mask);
    const double dt = seg::evolve_level_set(phi0, terms, p).time_step;
    p.max_iterations = int(std::lround(5.0 / dt));
    const auto r = seg::evolve_level_set(phi0, terms, p);
    EXPECT_EQ(components(r.mask), 2);
}

// The hard bound: reaching max_iterations reports converged = false, with a finite φ.
TEST(LevelSet, MaxIterationsIsNotConvergence)
{
    const auto g = grid(48, 48, 1);
    const auto phi0 = seg::level_set_from_seeds(g, {{24.0, 24.0, 0.0}}, 5.0);
    const core::ImageF pressure(g, 1.f);
    SpeedTerms terms;
    terms.pressure = &pressure;
    terms.curvature_weight = 0.5;
    LevelSetParams p;
    p.max_iterations = 25;
    const auto r = seg::evolve_level_set(phi0, terms, p);
    EXPECT_FALSE(r.converged);
    EXPECT_EQ(r.iterations, 25);
    EXPECT_TRUE(all_finite(r.phi));
    EXPECT_GT(r.time_step, 0.0);
}

// A shrinking flow that eliminates the contour stops early with converged = false and an empty mask.
TEST(LevelSet, VanishingFrontStops)
{
    const auto g = grid(32, 32, 1);
    const auto phi0 = seg::level_set_from_seeds(g, {{16.0, 16.0, 0.0}}, 4.0);
    const core::ImageF pressure(g, -1.f);
    SpeedTerms terms;
    terms.pressure = &pressure;
    terms.curvature_weight = 0.5;
    LevelSetParams p;
    const auto r = seg::evolve_level_set(phi0, terms, p);
    EXPECT_FALSE(r.converged);
    EXPECT_LT(r.iterations, 100); // radius 4 at speed >= 1 is gone by t = 4, a few dozen steps
    EXPECT_EQ(count(r.mask), 0u);
    EXPECT_TRUE(all_finite(r.phi));
}

// A φ0 without a front (no voxel inside) is not an error; it cannot converge.
TEST(LevelSet, NoFrontReturnsNotConverged)
{
    const auto g = grid(16, 16, 1);
    const core::ImageF phi0(g, 1.f);
    const auto r = seg::evolve_level_set(phi0, SpeedTerms{}, LevelSetParams{});
    EXPECT_FALSE(r.converged);
    EXPECT_EQ(r.iterations, 0);
    EXPECT_EQ(count(r.mask), 0u);
}

// The narrow band is an optimisation, not a different method: the same flow (curvature, pressure,
// rotation, merging fronts) on a band of 4 voxels and on a band covering the grid agrees to a
// fraction of a voxel: fewer differing voxels than 2% of the contour, φ within 0.15 mm at the front
// (observed: 0 voxels, 0.08 mm). These flows keep φ a distance function, so the full-grid run, which
// is re-initialised only every 50 iterations, solves the same discrete problem; under a strongly
// varying pressure its φ drifts from a distance and the first-order errors of the two runs differ
// (the band run is then the closer one to a 4x finer grid).
TEST(LevelSet, NarrowBandMatchesFullGrid)
{
    const auto g = grid(72, 72, 1);
    const core::ImageF pressure(g, 0.4f);
    seg::VectorField field(g);
    for (int j = 0; j < 72; ++j)
        for (int i = 0; i < 72; ++i) {
            field.c[0].at(i, j, 0) = float(-(j - 36) * 0.02);
            field.c[1].at(i, j, 0) = float((i - 36) * 0.02);
        }
    SpeedTerms terms;
    terms.pressure = &pressure;
    terms.advection = &field;
    terms.curvature_weight = 0.3;
    const auto phi0 = seg::level_set_from_seeds(g, {{30.0, 36.0, 0.0}, {44.0, 30.0, 0.0}}, 7.0);
    const auto narrow = seg::evolve_level_set(phi0, terms, fixed_run(150, 4));
    const auto full = seg::evolve_level_set(phi0, terms, fixed_run(150, 200));
    EXPECT_EQ(full.reinitialisations, 150 / 50); // only the periodic ones: the band never nears its edge
    EXPECT_GT(narrow.reinitialisations, 150 / 50);
    std::size_t differ = 0, boundary = 0;
    double worst = 0;
    for (int j = 1; j < 71; ++j)
        for (int i = 1; i < 71; ++i) {
            differ += narrow.mask.at(i, j, 0) != full.mask.at(i, j, 0);
            const bool edge = full.mask.at(i, j, 0) && (!full.mask.at(i - 1, j, 0) || !full.mask.at(i + 1, j, 0) ||
                                                        !full.mask.at(i, j - 1, 0) || !full.mask.at(i, j + 1, 0));
            boundary += edge;
            if (std::abs(full.phi.at(i, j, 0)) < 1.f)
                worst = std::max(worst, double(std::abs(narrow.phi.at(i, j, 0) - full.phi.at(i, j, 0))));
        }
    EXPECT_GT(boundary, 100u);
    EXPECT_LE(double(differ), 0.02 * double(boundary)) << differ << " of " << boundary;
    EXPECT_LT(worst, 0.15);
}

// The vectorised row-run update and the scalar one compute the same arithmetic, so they must
// give the same bits, for every combination of terms, in 2-D and 3-D, with fronts that touch the
// grid border (where runs mix both paths). A compiler that fused a product into a sum (FMA) in
// one of them, or a select that picked the wrong side, would differ after a few steps: the
// differences grow through 60 iterations and several re-initialisations.
TEST(LevelSet, VectorisedUpdateGivesTheScalarBits)
{
    for (const int nz : {1, 14}) {
        const auto g = grid(37, 29, nz, 0.8, 1.0, 2.0);
        core::ImageF pressure(g, 0.f), stop(g, 0.f);
        seg::VectorField field(g);
        for (int k = 0; k < nz; ++k)
            for (int j = 0; j < 29; ++j)
                for (int i = 0; i < 37; ++i) {
                    pressure.at(i, j, k) = float(0.6 * std::sin(0.3 * i + 0.2 * j) + 0.1 * std::cos(0.5 * k));
                    stop.at(i, j, k) = float(1.0 / (1.0 + 0.05 * ((i * 7 + j * 3 + k) % 11)));
                    field.c[0].at(i, j, k) = float(0.3 * std::cos(0.2 * j));
                    field.c[1].at(i, j, k) = float(-0.25 * std::sin(0.15 * i));
                    field.c[2].at(i, j, k) = float(0.2 * std::sin(0.4 * (i + j)));
                }
        // A ball that crosses the x = 0 and y = 0 borders, and a second one inside.
        const auto phi0 = seg::level_set_from_seeds(g, {{2.0, 3.0, (nz - 1) / 2.0}, {24.0, 18.0, (nz - 1) / 3.0}}, 6.0);
        for (int mask = 0; mask < 16; ++mask) {
            SpeedTerms terms;
            terms.curvature_weight = mask & 1 ? 0.4 : 0.0;
            terms.stopping = mask & 2 ? &stop : nullptr;
            terms.pressure = mask & 4 ? &pressure : nullptr;
            terms.advection = mask & 8 ? &field : nullptr;
            auto p = fixed_run(60);
            const auto vec = seg::evolve_level_set(phi0, terms, p);
            p.vectorise = false;
            const auto scalar = seg::evolve_level_set(phi0, terms, p);
            ASSERT_EQ(vec.reinitialisations, scalar.reinitialisations) << "nz " << nz << " terms " << mask;
            std::size_t differ = 0;
            for (std::size_t v = 0; v < vec.phi.data.size(); ++v)
                differ += std::memcmp(&vec.phi.data[v], &scalar.phi.data[v], sizeof(float)) != 0;
            EXPECT_EQ(differ, 0u) << "nz " << nz << " terms " << mask;
        }
    }
}

// Non-finite input anywhere is rejected up front, as are grid mismatches and bad parameters.
TEST(LevelSet, RejectsBadInput)
{
    const auto g = grid(16, 16, 1);
    const auto phi0 = seg::level_set_from_seeds(g, {{8.0, 8.0, 0.0}}, 4.0);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    {
        auto bad = phi0;
        bad.at(3, 3, 0) = nan;
        EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evolve_level_set(bad, SpeedTerms{}), "phi0", "non-finite");
    }
    {
        core::ImageF pressure(g, 1.f);
        pressure.at(1, 2, 0) = nan;
        SpeedTerms t;
        t.pressure = &pressure;
        EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evolve_level_set(phi0, t), "pressure", "non-finite");
    }
    {
        core::ImageF stop(g, 1.f);
        stop.at(1, 2, 0) = std::numeric_limits<float>::infinity();
        SpeedTerms t;
        t.curvature_weight = 1;
        t.stopping = &stop;
        EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evolve_level_set(phi0, t), "stopping", "non-finite");
        stop.at(1, 2, 0) = -0.5f;
        EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evolve_level_set(phi0, t), "stopping", "negative");
    }
    {
        seg::VectorField field(g);
        field.c[1].at(5, 5, 0) = nan;
        SpeedTerms t;
        t.advection = &field;
        EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evolve_level_set(phi0, t), "advection", "non-finite");
    }
    {
        SpeedTerms t;
        t.curvature_weight = std::numeric_limits<double>::quiet_NaN();
        EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evolve_level_set(phi0, t), "curvature weight");
    }
    {
        const core::ImageF pressure(grid(16, 17, 1), 1.f);
        SpeedTerms t;
        t.pressure = &pressure;
        EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evolve_level_set(phi0, t), "pressure", "grid");
    }
    {
        LevelSetParams p;
        p.band_voxels = 1;
        EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evolve_level_set(phi0, SpeedTerms{}, p), "band_voxels");
        p = {};
        p.cfl = 1.5;
        EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evolve_level_set(phi0, SpeedTerms{}, p), "cfl");
        p = {};
        p.leak_rise = 0.5; // a "rise" to half the lowest growth would fire at once
        EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evolve_level_set(phi0, SpeedTerms{}, p), "leak_rise");
        p = {};
        p.leak_slowdown = 0.0;
        EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evolve_level_set(phi0, SpeedTerms{}, p), "leak_slowdown");
    }
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evolve_level_set(core::ImageF{}, SpeedTerms{}), "phi0");
}

// initial_level_set: φ < 0 reproduces the mask exactly, φ is ±h/2 on either side of a flat boundary
// (the zero level set half a voxel outside the boundary voxels) and grows by h per voxel.
TEST(LevelSet, InitialLevelSetSignConvention)
{
    const auto g = grid(40, 30, 1, 1.0, 0.5);
    auto mask = disc_mask(g, 14, 15, 5.0);
    for (int j = 3; j < 12; ++j)
        for (int i = 25; i < 35; ++i)
            mask.at(i, j, 0) = 1;
    const auto phi = seg::initial_level_set(mask);
    ASSERT_TRUE(core::same_grid(phi.geometry(), g));
    for (std::size_t v = 0; v < mask.data.size(); ++v)
        ASSERT_EQ(phi.data[v] < 0.f, mask.data[v] != 0) << "voxel " << v;
    // a box edge along x (spacing 1): the last inside and first outside voxels
    EXPECT_NEAR(phi.at(34, 7, 0), -0.5, 0.01);
    EXPECT_NEAR(phi.at(35, 7, 0), 0.5, 0.01);
    EXPECT_NEAR(phi.at(37, 7, 0), 2.5, 0.01);

    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::initial_level_set(core::LabelImage3D(g, 0)), "empty");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::initial_level_set(core::LabelImage3D(g, 1)), "whole grid");
}

// level_set_from_seeds: the exact signed distance to the balls (−r at a seed at a voxel centre,
// |x − s| − r elsewhere, in mm), one contour per seed; a seed off the grid is an error.
TEST(LevelSet, LevelSetFromSeeds)
{
    const auto g = grid(30, 20, 1, 0.5, 1.0);
    const auto phi = seg::level_set_from_seeds(g, {{6.0, 10.0, 0.0}, {24.0, 10.0, 0.0}}, 2.0);
    EXPECT_NEAR(phi.at(6, 10, 0), -2.0, 1e-6);
    EXPECT_NEAR(phi.at(14, 10, 0), 4.0 - 2.0, 1e-6); // 8 voxels of 0.5 mm from the first seed
    EXPECT_NEAR(phi.at(6, 13, 0), 1.0, 1e-6);
    core::LabelImage3D m(g, 0);
    for (std::size_t v = 0; v < m.data.size(); ++v)
        m.data[v] = phi.data[v] < 0.f;
    EXPECT_EQ(components(m), 2);

    // a ball smaller than a voxel still marks its seed's voxel
    const auto tiny = seg::level_set_from_seeds(g, {{6.4, 10.0, 0.0}}, 0.1);
    EXPECT_LT(tiny.at(6, 10, 0), 0.f);
    // the grid spans [-0.5, size - 0.5) voxels along each axis: a seed on its lower face is inside
    const auto corner = seg::level_set_from_seeds(g, {{-0.5, 10.0, -0.5}}, 0.1);
    EXPECT_LT(corner.at(0, 10, 0), 0.f);

    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::level_set_from_seeds(g, {{30.0, 10.0, 0.0}}, 2.0), "outside");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::level_set_from_seeds(g, {{3.0, -1.0, 0.0}}, 2.0), "outside");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::level_set_from_seeds(g, {{3.0, 3.0, 1.0}}, 2.0), "outside");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::level_set_from_seeds(g, {}, 2.0), "no seeds");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::level_set_from_seeds(g, {{3.0, 3.0, 0.0}}, 0.0), "radius");
}

// The performance target: a 512 x 512 slice with a ~1500 px contour, 300 iterations of the full
// CDSG-like PDE (curvature with g, pressure, advection) in < 50 ms on 2 cores. The bound asserted
// here is 10x looser so that a loaded machine does not fail the suite; the time is printed.
// A full-size run: 300 iterations on a 512 x 512 slice with every term present. It prints the
// time (the benchmark numbers are in docs/algorithms/level_set.md); it asserts only what does
// not depend on the machine's load or a sanitizer: the run completes, stays finite, and keeps
// its front where the pressure's sign change holds it.
TEST(LevelSet, FullRunOn512Slice)
{
    const auto g = grid(512, 512, 1);
    const double r0 = 230.0; // perimeter 1445 px
    const auto phi0 = seg::level_set_from_seeds(g, {{256.0, 256.0, 0.0}}, r0);
    core::ImageF pressure(g, 0.f), stop(g, 1.f);
    seg::VectorField field(g);
    for (int j = 0; j < 512; ++j)
        for (int i = 0; i < 512; ++i) {
            const double rad = std::hypot(i - 256.0, j - 256.0);
            pressure.at(i, j, 0) = rad < 240.0 ? 1.f : -1.f; // converges onto radius 240
            stop.at(i, j, 0) = float(1.0 / (1.0 + 0.01 * (i % 7)));
            field.c[0].at(i, j, 0) = float(0.1 * std::sin(j * 0.05));
            field.c[1].at(i, j, 0) = float(0.1 * std::cos(i * 0.05));
        }
    SpeedTerms terms;
    terms.pressure = &pressure;
    terms.stopping = &stop;
    terms.advection = &field;
    terms.curvature_weight = 0.05;
    for (const double speed : {1.0, -1.0}) {
        // +1: the front moves 10 px and stops; -1 (pressure negated): it shrinks all the way.
        core::ImageF pr = pressure;
        for (auto& v : pr.data)
            v = float(speed) * v;
        terms.pressure = &pr;
        const auto t0 = std::chrono::steady_clock::now();
        const auto r = seg::evolve_level_set(phi0, terms, fixed_run(300));
        const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        std::printf("[ timing ] 512x512, pressure %+.0f: 300 iterations in %.1f ms (%d re-initialisations, dt %.3f)\n",
                    speed, ms, r.reinitialisations, r.time_step);
        EXPECT_EQ(r.iterations, 300);
        for (float v : r.phi.data)
            ASSERT_TRUE(std::isfinite(v));
        if (speed > 0) { // held at radius 240 (within a voxel): the voxel at radius 238 is inside, 242 outside
            EXPECT_TRUE(r.mask.at(256 + 238, 256, 0) && !r.mask.at(256 + 242, 256, 0));
        }
    }
}
