#include "lobe/seg/edge_map.h"

#include "common/expect_error.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <utility>
#include <vector>

using namespace lobe;
using seg::EdgeMapParams;

namespace {

core::ImageGeometry grid(int nx, int ny, int nz, double sx = 1.0, double sy = 1.0, double sz = 1.0)
{
    core::ImageGeometry g;
    g.size = {nx, ny, nz};
    g.spacing = {sx, sy, sz};
    return g;
}

double sum(const core::ImageF& im)
{
    double s = 0.0;
    for (float v : im.data)
        s += double(v);
    return s;
}

} // namespace

TEST(EdgeMap, WindowMapsLevelPlusMinusHalfWidthToZeroAndOne)
{
    // W400/L70: [-130, 270] HU -> [0, 1], linear inside, clamped outside; float rounding only.
    core::ImageF im(grid(6, 1, 1));
    im.data = {-1000.f, -130.f, 70.f, 170.f, 270.f, 3000.f};
    const core::ImageF w = seg::apply_window(im);
    EXPECT_FLOAT_EQ(w.data[0], 0.f);
    EXPECT_NEAR(w.data[1], 0.f, 1e-7);
    EXPECT_NEAR(w.data[2], 0.5f, 1e-7);
    EXPECT_NEAR(w.data[3], 0.75f, 1e-7);
    EXPECT_NEAR(w.data[4], 1.f, 1e-7);
    EXPECT_FLOAT_EQ(w.data[5], 1.f);
    // A width <= 0 means "already in [0, 1]": the image comes back unchanged.
    const core::ImageF same = seg::apply_window(im, {0.0, 0.0});
    EXPECT_EQ(same.data, im.data);
}

TEST(EdgeMap, SmoothingKeepsAConstantIn2DAnd3D)
{
    // Normalised weights and a mirrored border: a constant stays constant up to float sums
    // of ~40 terms (1e-6 relative).
    for (int nz : {1, 7}) {
        core::ImageF im(grid(20, 13, nz, 0.7, 1.3, 2.5), 42.f);
        const core::ImageF s = seg::gaussian_smooth(im, 2.0);
        for (float v : s.data)
            ASSERT_NEAR(v, 42.f, 42.f * 1e-6f) << "nz = " << nz;
    }
}

TEST(EdgeMap, SmoothingPreservesTheImpulseMassAndHasVarianceSigmaSquared)
{
    // Spacing (0.5, 1, 2) mm, σ = 2 mm -> σ = 4, 2, 1 voxels. The symmetric kernel on the
    // half-sample mirror keeps the sum exactly (float: 1e-5), even for an impulse at the border.
    // The second moment along each axis is σ^2 = 4 mm^2 up to the 4σ truncation (~0.1 %) and
    // the sampling (< 1e-8 for σ >= 1 voxel): tolerance 1 %.
    const auto g = grid(41, 21, 13, 0.5, 1.0, 2.0);
    core::ImageF im(g, 0.f);
    im.at(20, 10, 6) = 1.f;
    const core::ImageF s = seg::gaussian_smooth(im, 2.0);
    EXPECT_NEAR(sum(s), 1.0, 1e-5);
    double m2[3] = {0, 0, 0};
    for (int k = 0; k < 13; ++k)
        for (int j = 0; j < 21; ++j)
            for (int i = 0; i < 41; ++i) {
                const double w = s.at(i, j, k);
                m2[0] += w * std::pow((i - 20) * 0.5, 2);
                m2[1] += w * std::pow((j - 10) * 1.0, 2);
                m2[2] += w * std::pow((k - 6) * 2.0, 2);
            }
    for (int a = 0; a < 3; ++a)
        EXPECT_NEAR(m2[a], 4.0, 0.04) << "axis " << a;

    core::ImageF corner(g, 0.f);
    corner.at(0, 1, 12) = 1.f;
    EXPECT_NEAR(sum(seg::gaussian_smooth(corner, 2.0)), 1.0, 1e-5);

    // A 2-D image is smoothed in-plane only, and σ <= 0 is a copy.
    core::ImageF flat(grid(31, 31, 1), 0.f);
    flat.at(15, 15, 0) = 1.f;
    EXPECT_NEAR(sum(seg::gaussian_smooth(flat, 1.5)), 1.0, 1e-5);
    EXPECT_EQ(seg::gaussian_smooth(flat, 0.0).data, flat.data);
}

TEST(EdgeMap, GradientOfALinearRampIsExactWithAnisotropicSpacing)
{
    // I = 2x - 3y + 0.5z in mm: central and one-sided differences are exact on a linear
    // function; only float rounding of values up to ~100 remains (1e-4 per mm).
    const auto g = grid(9, 7, 5, 0.7, 1.9, 3.1);
    core::ImageF im(g);
    for (int k = 0; k < 5; ++k)
        for (int j = 0; j < 7; ++j)
            for (int i = 0; i < 9; ++i)
                im.at(i, j, k) = static_cast<float>(2.0 * i * 0.7 - 3.0 * j * 1.9 + 0.5 * k * 3.1);
    const seg::VectorField d = seg::gradient(im);
    for (std::size_t q = 0; q < im.data.size(); ++q) {
        ASSERT_NEAR(d.c[0].data[q], 2.0, 1e-4);
        ASSERT_NEAR(d.c[1].data[q], -3.0, 1e-4);
        ASSERT_NEAR(d.c[2].data[q], 0.5, 1e-4);
    }
    const core::ImageF m = seg::magnitude(d);
    EXPECT_NEAR(m.data[0], std::sqrt(4.0 + 9.0 + 0.25), 1e-4);

    // 2-D: the k component is exactly zero.
    core::ImageF flat(grid(9, 7, 1, 0.7, 1.9, 3.1));
    for (int j = 0; j < 7; ++j)
        for (int i = 0; i < 9; ++i)
            flat.at(i, j, 0) = static_cast<float>(i * 0.7 + j * 1.9);
    const seg::VectorField d2 = seg::gradient(flat);
    for (std::size_t q = 0; q < flat.data.size(); ++q) {
        ASSERT_NEAR(d2.c[0].data[q], 1.0, 1e-4);
        ASSERT_EQ(d2.c[2].data[q], 0.f);
    }
}

TEST(EdgeMap, StoppingFunctionIsOneWhenFlatAndSmallOnAStep)
{
    // A full-window step (0 -> 1) at x = 31.5, σ = 1 mm. Discretely, the smoothed step has
    // I(32) - I(30) = w0 + w1 = 0.64091 with the sampled Gaussian (w0 = 0.39894,
    // w1 = 0.24197), so max |∇I| = 0.3205 /mm and g = 1 / (1 + (0.3205 / 0.05)^2) = 0.0238 < 0.1.
    // Every non-zero magnitude lies in the step's columns, all rows alike, so the 99.9th
    // percentile is the max and f = 1 there. Beyond 4σ + 1 voxels the image is flat: g = 1.
    core::ImageF ct(grid(64, 64, 1), -1000.f);
    for (int j = 0; j < 64; ++j)
        for (int i = 32; i < 64; ++i)
            ct.at(i, j, 0) = 1000.f;
    const seg::EdgeMapResult r = seg::edge_map(ct);
    EXPECT_NEAR(r.scale, 0.3205, 0.003);
    float gmin = 1.f, fmax = 0.f, fmin = 1.f;
    for (std::size_t q = 0; q < r.edge.data.size(); ++q) {
        gmin = std::min(gmin, r.stopping.data[q]);
        fmax = std::max(fmax, r.edge.data[q]);
        fmin = std::min(fmin, r.edge.data[q]);
    }
    EXPECT_LT(gmin, 0.1f);
    EXPECT_NEAR(gmin, 0.0238f, 0.001f);
    EXPECT_FLOAT_EQ(fmax, 1.f);
    EXPECT_GE(fmin, 0.f);
    for (int j = 0; j < 64; ++j)
        for (int i : {0, 10, 25, 38, 50, 63}) {
            ASSERT_GT(r.stopping.at(i, j, 0), 0.999f);
            ASSERT_LT(r.edge.at(i, j, 0), 1e-3f);
        }
    EXPECT_NEAR(r.intensity.at(0, 0, 0), 0.f, 1e-6);
    EXPECT_NEAR(r.intensity.at(63, 0, 0), 1.f, 1e-6);
}

TEST(EdgeMap, RobustScaleIgnoresAFewOutlierVoxels)
{
    // Window off, no smoothing: a step of 0.2 (central difference 0.1 /mm) across the image,
    // noise of ±0.0005 everywhere (so every voxel has a non-zero gradient) and one hot voxel of
    // 50 whose 4 neighbours get |∇I| ≈ 25. 4 voxels of 65536 are 0.006 % < 0.1 %, so the scale
    // is set by the step (0.1 ± 0.001 for the noise) and f on the step is ~1, where a plain
    // max would give 0.1 / 25 = 0.004.
    core::ImageF im(grid(256, 256, 1));
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> noise(-0.0005f, 0.0005f);
    for (int j = 0; j < 256; ++j)
        for (int i = 0; i < 256; ++i)
            im.at(i, j, 0) = (i >= 128 ? 0.7f : 0.5f) + noise(rng);
    im.at(60, 60, 0) = 50.f;
    EdgeMapParams p;
    p.window.width = 0.0;
    p.sigma_mm = 0.0;
    const seg::EdgeMapResult r = seg::edge_map(im, p);
    EXPECT_NEAR(r.scale, 0.1, 0.002);
    EXPECT_GT(r.edge.at(127, 100, 0), 0.97f);
    EXPECT_FLOAT_EQ(r.edge.at(61, 60, 0), 1.f); // the outlier saturates instead of dominating
    for (float f : r.edge.data)
        ASSERT_TRUE(f >= 0.f && f <= 1.f);
}

TEST(EdgeMap, NonFiniteInputIsRejectedWithItsVoxel)
{
    core::ImageF im(grid(8, 6, 2), 0.f);
    im.at(3, 2, 1) = std::numeric_limits<float>::quiet_NaN();
    im.at(5, 5, 1) = std::numeric_limits<float>::infinity();
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::edge_map(im), "edge_map", "2 non-finite", "(3, 2, 1)");
    EdgeMapParams bad;
    bad.stopping_k = 0.0;
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::edge_map(core::ImageF(grid(4, 4, 1), 0.f), bad), "stopping_k");
}

TEST(EdgeMap, FlatImageGivesZeroEdgesAndUnitStopping)
{
    const seg::EdgeMapResult r = seg::edge_map(core::ImageF(grid(16, 16, 3), 55.f));
    EXPECT_EQ(r.scale, 1.0);
    for (std::size_t q = 0; q < r.edge.data.size(); ++q) {
        ASSERT_LT(r.edge.data[q], 1e-5f); // rounding of the smoothing sums only
        ASSERT_GT(r.stopping.data[q], 0.9999f);
    }
}

TEST(EdgeMap, HysteresisKeepsWeakEdgesTouchingStrongOnesIn2D)
{
    // low 0.05, high 0.15. A strong voxel, a weak diagonal chain from it (kept: 8-neighbours),
    // an isolated weak line (dropped), a sub-threshold voxel next to the strong one (dropped).
    core::ImageF f(grid(32, 32, 1), 0.f);
    f.at(5, 5, 0) = 0.5f;
    for (int t = 1; t <= 5; ++t)
        f.at(5 + t, 5 + t, 0) = 0.1f;
    for (int i = 5; i <= 15; ++i)
        f.at(i, 25, 0) = 0.1f;
    f.at(4, 5, 0) = 0.04f;
    const core::LabelImage3D e = seg::binary_edges(f);
    int count = 0;
    for (auto v : e.data)
        count += v;
    EXPECT_EQ(count, 6);
    EXPECT_EQ(e.at(10, 10, 0), 1);
    EXPECT_EQ(e.at(10, 25, 0), 0);
    EXPECT_EQ(e.at(4, 5, 0), 0);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::binary_edges(f, {0.3, 0.1}), "low <= high");
}

TEST(EdgeMap, HysteresisUses26NeighboursIn3D)
{
    // (2,2,2) strong; (3,3,3) touches it only at a corner (kept with 26-connectivity);
    // (5,5,5) is weak and two steps away from any edge (dropped).
    core::ImageF f(grid(8, 8, 8), 0.f);
    f.at(2, 2, 2) = 0.9f;
    f.at(3, 3, 3) = 0.06f;
    f.at(5, 5, 5) = 0.06f;
    const core::LabelImage3D e = seg::binary_edges(f);
    EXPECT_EQ(e.at(2, 2, 2), 1);
    EXPECT_EQ(e.at(3, 3, 3), 1);
    EXPECT_EQ(e.at(5, 5, 5), 0);
}

TEST(EdgeMap, EnergyCompetitionScalesOutsideTheAreaOfInterest)
{
    core::ImageF f(grid(10, 10, 1), 0.8f);
    core::LabelImage3D aoi(grid(10, 10, 1), 0);
    for (int i = 0; i < 5; ++i)
        aoi.at(i, 3, 0) = 1;
    const core::ImageF c = seg::energy_competition(f, aoi, seg::kCompetitionOn);
    EXPECT_FLOAT_EQ(c.at(2, 3, 0), 0.8f);
    EXPECT_FLOAT_EQ(c.at(7, 3, 0), 0.8f * 0.3f);
    EXPECT_EQ(seg::energy_competition(f, aoi, 1.f).data, f.data); // G = 1: competition off
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::energy_competition(f, core::LabelImage3D(grid(10, 9, 1)), 0.3f),
                      "different grids");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::energy_competition(f, aoi, 1.5f), "[0, 1]");
}

TEST(EdgeMap, NoiseAdaptedThresholdsUseTheExactMedian)
{
    // The median comes from a histogram and a sort of one bin; it must be the very element a
    // full nth_element gives (the thresholds then match bit for bit), with ties, zeros, odd and
    // even counts, one value, and a few values far above the rest (most bins then stay empty).
    const auto reference = [](const core::ImageF& f) {
        std::vector<float> v(f.data.begin(), f.data.end());
        std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
        return double(v[v.size() / 2]);
    };
    const seg::BinaryEdgeParams base{0.01, 0.02};
    std::mt19937 rng(11);
    std::gamma_distribution<float> noise(1.0f, 0.01f);
    for (const auto& [nx, ny] : {std::pair{97, 61}, std::pair{64, 64}, std::pair{1, 1}, std::pair{512, 512}}) {
        core::ImageF f(grid(nx, ny, 1), 0.f);
        for (auto& v : f.data)
            v = std::min(1.f, noise(rng));
        for (std::size_t i = 0; i < f.data.size(); i += 7)
            f.data[i] = 0.f; // zeros and ties
        if (f.data.size() > 10)
            f.data[3] = 1.f; // far above the noise
        const double median = reference(f);
        const seg::BinaryEdgeParams p = seg::noise_adapted(f, base, 3.0);
        EXPECT_EQ(p.low, std::max(base.low, 3.0 * median)) << nx << " x " << ny;
        EXPECT_EQ(p.high, std::max({base.high, 6.0 * median, p.low})) << nx << " x " << ny;
    }
    // Values outside [0, inf) take the plain sort: the median is still the same element.
    core::ImageF g(grid(5, 5, 1), 0.f);
    for (std::size_t i = 0; i < g.data.size(); ++i)
        g.data[i] = 0.01f * float(i) - 0.05f;
    EXPECT_EQ(seg::noise_adapted(g, base, 3.0).low, std::max(base.low, 3.0 * reference(g)));
    // A flat image: median 0, the configured thresholds stand.
    const seg::BinaryEdgeParams flat = seg::noise_adapted(core::ImageF(grid(8, 8, 1), 0.f), base, 3.0);
    EXPECT_EQ(flat.low, base.low);
    EXPECT_EQ(flat.high, base.high);
}

TEST(EdgeMap, Timing512)
{
    // Records the cost on a 512 x 512 CT-like slice (printed); the bound only catches a
    // pathological regression (the measured time is a few ms on 2 cores).
    core::ImageF ct(grid(512, 512, 1, 0.7, 0.7, 1.0));
    std::mt19937 rng(3);
    std::normal_distribution<float> noise(0.f, 20.f);
    for (int j = 0; j < 512; ++j)
        for (int i = 0; i < 512; ++i) {
            const double r = std::hypot(i - 256.0, j - 256.0);
            ct.at(i, j, 0) = (r < 200 ? 60.f : -900.f) + noise(rng);
        }
    seg::edge_map(ct); // warm-up (thread pool, page faults)
    const auto t0 = std::chrono::steady_clock::now();
    const int reps = 5;
    for (int t = 0; t < reps; ++t)
        seg::edge_map(ct);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / reps;
    std::printf("[ timing ] edge_map 512x512: %.2f ms\n", ms);
    EXPECT_LT(ms, 1000.0);
}
