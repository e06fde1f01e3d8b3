#include "lobe/seg/gvf.h"

#include "lobe/seg/edge_map.h"

#include "common/expect_error.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

using namespace lobe;
using seg::GvfModel;
using seg::GvfParams;

namespace {

constexpr double kPi = 3.14159265358979323846;

core::ImageGeometry grid(int nx, int ny, int nz)
{
    core::ImageGeometry g;
    g.size = {nx, ny, nz};
    return g;
}

//! Edge map of a bright disc of radius `radius` centred on (c, c): edge_map with the window
//! off and σ = 1 voxel, so f is a ring of width ~2σ peaking at r = radius.
core::ImageF disc_edge_map(int n, double c, double radius)
{
    core::ImageF im(grid(n, n, 1), 0.f);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            im.at(i, j, 0) = std::hypot(i - c, j - c) < radius ? 1.f : 0.f;
    seg::EdgeMapParams p;
    p.window.width = 0.0;
    return seg::edge_map(im, p).edge;
}

//! Noise edge map in [0, 1]: the largest |∇f| and all frequencies, the worst case for stability.
core::ImageF random_edge_map(const core::ImageGeometry& g, unsigned seed)
{
    core::ImageF f(g);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    for (float& v : f.data)
        v = u(rng);
    return f;
}

float max_abs(const core::ImageF& im)
{
    float m = 0.f;
    for (float v : im.data)
        m = std::max(m, std::abs(v));
    return m;
}

bool all_finite(const seg::VectorField& v)
{
    for (const auto& c : v.c)
        for (float x : c.data)
            if (!std::isfinite(x))
                return false;
    return true;
}

//! The band of the tests: voxels within chessboard distance `r` of an edge voxel (f > t).
core::LabelImage3D dilated_edges(const core::ImageF& f, float t, int r)
{
    core::LabelImage3D band(f.geometry(), 0);
    const int nx = f.size[0], ny = f.size[1], nz = f.size[2];
    const int rz = nz > 1 ? r : 0;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                if (f.at(i, j, k) <= t)
                    continue;
                for (int c = std::max(0, k - rz); c <= std::min(nz - 1, k + rz); ++c)
                    for (int b = std::max(0, j - r); b <= std::min(ny - 1, j + r); ++b)
                        for (int a = std::max(0, i - r); a <= std::min(nx - 1, i + r); ++a)
                            band.at(a, b, c) = 1;
            }
    return band;
}

} // namespace

TEST(Gvf, DiscFieldPointsTowardsTheRingFromInsideAndOutside)
{
    // Ring at r = 20 around (48, 48). Samples 12 voxels inside (r = 8) and 14 outside (r = 34)
    // on 16 angles, far beyond the ring's own gradient (~5 voxels). There v is only what the
    // diffusion carried from the ring's flanks, where ∇f points at the crest: outward inside
    // the ring, inward outside. After 200 steps both models must point at the ring everywhere.
    const core::ImageF f = disc_edge_map(96, 48.0, 20.0);
    for (GvfModel model : {GvfModel::Ggvf, GvfModel::Gvf}) {
        GvfParams p;
        p.model = model;
        p.iterations = 200;
        const seg::GvfResult r = seg::gradient_vector_flow(f, p);
        EXPECT_EQ(r.iterations, 200);
        for (int a = 0; a < 16; ++a) {
            const double ux = std::cos(2 * kPi * a / 16), uy = std::sin(2 * kPi * a / 16);
            for (double radius : {8.0, 34.0}) {
                const int i = static_cast<int>(std::lround(48 + radius * ux));
                const int j = static_cast<int>(std::lround(48 + radius * uy));
                const double vx = r.field.c[0].at(i, j, 0), vy = r.field.c[1].at(i, j, 0);
                // (ring - x) is +u inside and -u outside.
                const double towards = (radius < 20 ? 1.0 : -1.0) * (vx * ux + vy * uy);
                EXPECT_GT(towards, 0.0) << "model " << int(model) << " angle " << a << " r " << radius;
                EXPECT_GT(towards, 0.9 * std::hypot(vx, vy)) << "not radial"; // symmetric up to the grid
            }
        }
    }
}

TEST(Gvf, CaptureRangeGrowsWithIterations)
{
    // The explicit stencil moves information one voxel per step, and ∇f is non-zero only
    // within ~5 voxels of the ring (σ = 1 smoothing, 4σ kernel, central difference). At 20
    // voxels outside, v is therefore exactly 0 after 10 steps. After 300 steps (Δt = 0.25,
    // diffusion length sqrt(2·Δt·n) ≈ 12 voxels) it is a clear inward vector at every angle.
    const core::ImageF f = disc_edge_map(96, 48.0, 20.0);
    auto captured = [&](int iterations, double floor) {
        GvfParams p;
        p.iterations = iterations;
        const seg::GvfResult r = seg::gradient_vector_flow(f, p);
        int n = 0;
        for (int a = 0; a < 16; ++a) {
            const double ux = std::cos(2 * kPi * a / 16), uy = std::sin(2 * kPi * a / 16);
            const int i = static_cast<int>(std::lround(48 + 40 * ux)), j = static_cast<int>(std::lround(48 + 40 * uy));
            const double inward = -(double(r.field.c[0].at(i, j, 0)) * ux + double(r.field.c[1].at(i, j, 0)) * uy);
            n += inward > floor;
        }
        return n;
    };
    EXPECT_EQ(captured(10, 0.0), 0);
    EXPECT_EQ(captured(300, 1e-4), 16);
}

TEST(Gvf, BothModelsStayFiniteAndBoundedByTheLargestGradient)
{
    // The time step is cut to 1/max(2·dim·h + p), so each step is a convex combination of v,
    // its neighbours and ∇f: no component can leave [-max|∂f|, max|∂f|] (float slack 1e-5).
    // Random f in [0, 1] is the worst case (every frequency, |∇f| up to 0.5 per axis).
    for (int nz : {1, 12}) {
        const core::ImageF f = random_edge_map(grid(40, 32, nz), 11);
        const seg::VectorField df = seg::gradient(f); // spacing 1: index units, as GVF
        for (GvfModel model : {GvfModel::Gvf, GvfModel::Ggvf}) {
            GvfParams p;
            p.model = model;
            p.iterations = 150;
            p.time_step = 1.0;
            const seg::GvfResult r = seg::gradient_vector_flow(f, p);
            ASSERT_TRUE(all_finite(r.field));
            for (int a = 0; a < 3; ++a)
                EXPECT_LE(max_abs(r.field.c[static_cast<std::size_t>(a)]),
                          max_abs(df.c[static_cast<std::size_t>(a)]) + 1e-5f)
                    << "nz " << nz << " model " << int(model) << " axis " << a;
            EXPECT_TRUE(std::isfinite(r.last_change));
        }
    }
}

TEST(Gvf, TimeStepReductionKeepsALargeMuStable)
{
    // μ = 10 with Δt = 1 has μ·Δt·8 = 80 on the 5-point stencil: the raw explicit scheme would
    // amplify the checkerboard mode by |1 - 80| per step and overflow within ~20 steps. The
    // automatic bound (Δt ≈ 0.999 / (40 + max|∇f|^2)) keeps it bounded, as above.
    const core::ImageF f = random_edge_map(grid(48, 48, 1), 5);
    const seg::VectorField df = seg::gradient(f);
    GvfParams p;
    p.model = GvfModel::Gvf;
    p.mu = 10.0;
    p.time_step = 1.0;
    p.iterations = 100;
    const seg::GvfResult r = seg::gradient_vector_flow(f, p);
    ASSERT_TRUE(all_finite(r.field));
    EXPECT_LE(max_abs(r.field.c[0]), max_abs(df.c[0]) + 1e-5f);
    EXPECT_LE(max_abs(r.field.c[1]), max_abs(df.c[1]) + 1e-5f);
    // With that much smoothing the field is nearly uniform after 100 steps (diffusion length
    // sqrt(2·μΔt·100) ≈ 22 voxels): far smaller than the raw noise gradient.
    EXPECT_LT(max_abs(r.field.c[0]), 0.25f * max_abs(df.c[0]));
}

TEST(Gvf, BandLimitedIsZeroOutsideAndMatchesTheFullFieldDeepInside)
{
    // Band: 6 voxels (chessboard) around f > 0.2. After t = 4 steps, a voxel depends only on
    // voxels within city-block distance 4, so where the band holds that whole neighbourhood the
    // band-limited and full fields run the same float operations: equal to rounding (1e-6).
    // Δt = 0.2 is below both stability bounds, so both use it.
    const core::ImageF f = disc_edge_map(96, 48.0, 20.0);
    const core::LabelImage3D band = dilated_edges(f, 0.2f, 6);
    GvfParams p;
    p.iterations = 4;
    p.time_step = 0.2;
    const seg::GvfResult full = seg::gradient_vector_flow(f, p);
    const seg::GvfResult part = seg::gradient_vector_flow(f, band, p);
    EXPECT_EQ(part.iterations, 4);
    int compared = 0, strong = 0;
    for (int j = 0; j < 96; ++j)
        for (int i = 0; i < 96; ++i) {
            if (!band.at(i, j, 0)) {
                ASSERT_EQ(part.field.c[0].at(i, j, 0), 0.f);
                ASSERT_EQ(part.field.c[1].at(i, j, 0), 0.f);
                continue;
            }
            bool deep = true;
            for (int b = -4; b <= 4 && deep; ++b)
                for (int a = -4; a <= 4 && deep; ++a)
                    if (std::abs(a) + std::abs(b) <= 4) {
                        const int x = i + a, y = j + b;
                        deep = x >= 0 && y >= 0 && x < 96 && y < 96 && band.at(x, y, 0);
                    }
            if (!deep)
                continue;
            ++compared;
            strong += f.at(i, j, 0) > 0.5f;
            for (std::size_t c = 0; c < 2; ++c)
                ASSERT_NEAR(part.field.c[c].at(i, j, 0), full.field.c[c].at(i, j, 0), 1e-6)
                    << "at (" << i << ", " << j << ")";
        }
    EXPECT_GT(compared, 500);
    EXPECT_GT(strong, 100); // the strong edges all lie deep inside the band
}

TEST(Gvf, FullBandReproducesTheFullGridIn2DAnd3D)
{
    // The band's zero-flux rule and the grid's mirrored border are the same ghost = centre
    // rule, so a band covering the image gives the full field (rounding only: 1e-6). The
    // 48 x 40 x 20 case (38400 voxels) runs threaded, where the two paths schedule their chunks
    // from different dependency tables (rows vs the band's neighbour lists).
    for (const auto& g : {grid(21, 17, 1), grid(21, 17, 9), grid(48, 40, 20)}) {
        const int nz = g.size[2];
        const core::ImageF f = random_edge_map(g, 3);
        const core::LabelImage3D band(f.geometry(), 1);
        GvfParams p;
        p.iterations = 25;
        const seg::GvfResult full = seg::gradient_vector_flow(f, p);
        const seg::GvfResult part = seg::gradient_vector_flow(f, band, p);
        for (std::size_t c = 0; c < 3; ++c)
            for (std::size_t q = 0; q < f.data.size(); ++q)
                ASSERT_NEAR(part.field.c[c].data[q], full.field.c[c].data[q], 1e-6) << "nz " << nz;
        EXPECT_NEAR(part.last_change, full.last_change, 1e-6);
    }
}

TEST(Gvf, SphereFieldPointsRadiallyIn3D)
{
    // f = exp(-(r - 10)^2 / (2·1.5^2)) around (20, 20, 20). At r = 4 (inside) and r = 16
    // (outside), on the 6 axes and 8 diagonals, the field must point at the shell: cosine with
    // the radial direction > 0.9 inside, < -0.9 outside (the 7-point stencil's anisotropy and
    // rounding to voxels bend it by a few degrees at most).
    core::ImageF f(grid(40, 40, 40));
    for (int k = 0; k < 40; ++k)
        for (int j = 0; j < 40; ++j)
            for (int i = 0; i < 40; ++i) {
                const double r = std::sqrt((i - 20.0) * (i - 20.0) + (j - 20.0) * (j - 20.0) + (k - 20.0) * (k - 20.0));
                f.at(i, j, k) = static_cast<float>(std::exp(-(r - 10) * (r - 10) / (2 * 1.5 * 1.5)));
            }
    GvfParams p;
    p.iterations = 80;
    const seg::GvfResult g = seg::gradient_vector_flow(f, p);
    ASSERT_TRUE(all_finite(g.field));
    std::vector<std::array<double, 3>> dirs = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (int s = 0; s < 8; ++s)
        dirs.push_back({s & 1 ? 1.0 : -1.0, s & 2 ? 1.0 : -1.0, s & 4 ? 1.0 : -1.0});
    for (auto d : dirs) {
        const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (double radius : {4.0, 16.0}) {
            int ijk[3];
            double rad[3], rn = 0.0;
            for (int a = 0; a < 3; ++a) {
                ijk[a] = static_cast<int>(std::lround(20 + radius * d[static_cast<std::size_t>(a)] / len));
                rad[a] = ijk[a] - 20.0;
                rn += rad[a] * rad[a];
            }
            rn = std::sqrt(rn);
            double dot = 0.0, vn = 0.0;
            for (int a = 0; a < 3; ++a) {
                const double v = g.field.c[static_cast<std::size_t>(a)].at(ijk[0], ijk[1], ijk[2]);
                dot += v * rad[a] / rn;
                vn += v * v;
            }
            vn = std::sqrt(vn);
            ASSERT_GT(vn, 1e-4) << "no field reached r = " << radius;
            if (radius < 10)
                EXPECT_GT(dot / vn, 0.9) << "inside, direction " << d[0] << " " << d[1] << " " << d[2];
            else
                EXPECT_LT(dot / vn, -0.9) << "outside, direction " << d[0] << " " << d[1] << " " << d[2];
        }
    }
}

TEST(Gvf, DefaultIterationsAndEarlyStop)
{
    // iterations = 0: ceil(longest in-plane row / 3), here ceil(64 / 3) = 22 (512 -> 171).
    const core::ImageF f = random_edge_map(grid(64, 40, 1), 2);
    EXPECT_EQ(seg::gradient_vector_flow(f).iterations, 22);
    // A flat edge map has ∇f = 0, so v stays 0 and the first change (0) is below any tolerance.
    GvfParams p;
    p.tolerance = 1e-6;
    p.iterations = 50;
    const seg::GvfResult r = seg::gradient_vector_flow(core::ImageF(grid(16, 16, 1), 0.5f), p);
    EXPECT_EQ(r.iterations, 1);
    EXPECT_EQ(r.last_change, 0.0);
}

TEST(Gvf, EarlyStopEqualsTheSamePlainStepsOnAThreadedGrid)
{
    // 256 x 256 (65536 voxels) runs on the OpenMP team. The steps are cut into chunks that any
    // thread may take, but every chunk's arithmetic is fixed, so the result is bit-identical
    // however the chunks were shared out: stopping at the first step whose max |Δv| < 1e-3
    // must give exactly the field of that many plain steps, and the step before must still
    // have changed by >= 1e-3. The same holds for a band covering the whole grid.
    const core::ImageF f = disc_edge_map(256, 128.0, 70.0);
    GvfParams p;
    p.iterations = 400;
    p.tolerance = 1e-3;
    const seg::GvfResult stopped = seg::gradient_vector_flow(f, p);
    ASSERT_GT(stopped.iterations, 1);
    ASSERT_LT(stopped.iterations, 400);
    EXPECT_LT(stopped.last_change, 1e-3);
    p.tolerance = 0.0;
    p.iterations = stopped.iterations;
    const seg::GvfResult plain = seg::gradient_vector_flow(f, p);
    for (std::size_t c = 0; c < 2; ++c)
        ASSERT_EQ(plain.field.c[c].data, stopped.field.c[c].data);
    p.iterations = stopped.iterations - 1;
    EXPECT_GE(seg::gradient_vector_flow(f, p).last_change, 1e-3);

    p.iterations = 60;
    const seg::GvfResult full = seg::gradient_vector_flow(f, p);
    const seg::GvfResult band = seg::gradient_vector_flow(f, core::LabelImage3D(f.geometry(), 1), p);
    for (std::size_t c = 0; c < 2; ++c)
        for (std::size_t q = 0; q < f.data.size(); ++q)
            ASSERT_NEAR(band.field.c[c].data[q], full.field.c[c].data[q], 1e-6);
    const seg::GvfResult again = seg::gradient_vector_flow(f, p);
    EXPECT_EQ(again.field.c[0].data, full.field.c[0].data);
}

TEST(Gvf, InvalidInputsAreRejected)
{
    const core::ImageF f(grid(8, 8, 1), 0.f);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::gradient_vector_flow(f, core::LabelImage3D(grid(8, 7, 1), 1)),
                      "different grids");
    GvfParams p;
    p.k = 0.0;
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::gradient_vector_flow(f, p), "k must be");
    p = {};
    p.iterations = -1;
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::gradient_vector_flow(f, p), "iterations");
    core::ImageF nan = f;
    nan.data[3] = std::nanf("");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::gradient_vector_flow(nan), "non-finite");
}

TEST(Gvf, Timing512)
{
    // Records the cost (printed); the bounds only catch a pathological regression.
    const core::ImageF f = disc_edge_map(512, 256.0, 180.0);
    GvfParams p;                     // GGVF, iterations 0 -> 171
    seg::gradient_vector_flow(f, p); // warm-up
    auto t0 = std::chrono::steady_clock::now();
    const seg::GvfResult full = seg::gradient_vector_flow(f, p);
    const double ms_full = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_EQ(full.iterations, 171);

    const core::LabelImage3D band = dilated_edges(f, 0.3f, 3);
    std::size_t count = 0;
    for (auto b : band.data)
        count += b;
    p.iterations = 40;
    t0 = std::chrono::steady_clock::now();
    seg::gradient_vector_flow(f, band, p);
    const double ms_band = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    std::printf("[ timing ] GGVF 512x512, 171 iterations: %.1f ms; band-limited (%.1f %% of the image), 40 iterations: "
                "%.1f ms\n",
                ms_full, 100.0 * double(count) / double(f.data.size()), ms_band);
    EXPECT_LT(ms_full, 10000.0);
    EXPECT_LT(ms_band, 10000.0);
}
