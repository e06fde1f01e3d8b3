#include "lobe/seg/dsg.h"

#include "common/expect_error.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

using namespace lobe;

namespace {

core::ImageGeometry grid(int nx, int ny, int nz)
{
    core::ImageGeometry g;
    g.size = {nx, ny, nz};
    return g;
}

float ridge(double d)
{
    return static_cast<float>(std::exp(-d * d / (2 * 1.5 * 1.5)));
}

//! Two edge ridges of equal profile on 64 x 64: a vertical one (normal x) at x = 16 over the
//! whole height, and a horizontal one (normal y) at y = 32 for x >= 32. Their crests at
//! (16, 10) and (48, 32) are 16 voxels from anything else, beyond the 6-voxel reach of the
//! default averaging window (σ = 1.5 mm, truncated at 4σ) and of the Laplacian.
core::ImageF two_ridges(float height = 1.f)
{
    core::ImageF f(grid(64, 64, 1), 0.f);
    for (int j = 0; j < 64; ++j)
        for (int i = 0; i < 64; ++i) {
            float v = ridge(i - 16.0);
            if (i >= 32)
                v = std::max(v, ridge(j - 32.0));
            f.at(i, j, 0) = height * v;
        }
    return f;
}

seg::VectorField uniform_direction(const core::ImageGeometry& g, double x, double y, double z)
{
    seg::VectorField n(g);
    std::fill(n.c[0].data.begin(), n.c[0].data.end(), static_cast<float>(x));
    std::fill(n.c[1].data.begin(), n.c[1].data.end(), static_cast<float>(y));
    std::fill(n.c[2].data.begin(), n.c[2].data.end(), static_cast<float>(z));
    return n;
}

} // namespace

TEST(Dsg, SharpenKernelIsFiniteMonotoneConvexAndFixesTheEnds)
{
    // Below the pole (0.787337) tan∘tan∘tan is a composition of increasing convex functions on
    // [0, π/2), so on a fine grid the first differences are > 0 and the second ones >= 0 (up to
    // double rounding, 1e-12 of the values); H(0) = 0 and H(1) = 1 by construction.
    for (double s : {0.05, 0.5, 0.75, 0.787}) {
        const int n = 10000;
        std::vector<double> h(n + 1);
        for (int i = 0; i <= n; ++i) {
            h[static_cast<std::size_t>(i)] = seg::sharpen_kernel(double(i) / n, s);
            ASSERT_TRUE(std::isfinite(h[static_cast<std::size_t>(i)]));
        }
        EXPECT_EQ(h[0], 0.0);
        EXPECT_NEAR(h[static_cast<std::size_t>(n)], 1.0, 1e-12);
        for (std::size_t i = 1; i <= static_cast<std::size_t>(n); ++i) {
            ASSERT_GT(h[i], h[i - 1]) << "s " << s << " at " << i;
            if (i >= 2) {
                ASSERT_GE(h[i] - 2 * h[i - 1] + h[i - 2], -1e-12) << "s " << s << " at " << i;
            }
        }
        // Convex through (0,0) and (1,1): below the diagonal inside.
        EXPECT_LT(seg::sharpen_kernel(0.5, s), 0.5);
    }
    // Outside [0, 1] the argument is clamped.
    EXPECT_EQ(seg::sharpen_kernel(-3.0), 0.0);
    EXPECT_NEAR(seg::sharpen_kernel(7.0), 1.0, 1e-12);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::sharpen_kernel(0.5, 0.7874), "pole");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::sharpen_kernel(0.5, 0.0), "sharpen_max");
}

TEST(Dsg, AlignedEdgeIsBoostedOverTheOrthogonalOne)
{
    // Both crests have the same f~_H (the same profile, turned by 90°, which the 5-point
    // Laplacian does not see), so the ratio of F is the ratio of the gains 1 + A·c, with
    // c = <(n·∇f)^2> / <|∇f|^2> = cos^2 of the angle between n and the ridge's normal (∇f has one
    // direction in each crest's window). n = x: c = 1 and 0, ratio 1 + A = 2 for A = 1.
    // n at 30°: (1 + cos^2 30°) / (1 + sin^2 30°) = 1.75 / 1.25 = 1.4. Float rounding: 1e-4.
    const core::ImageF f = two_ridges();
    seg::DsgParams p; // A = 1, 3 mm, sharpen_max 0.75, Laplacian on
    const core::ImageF along_x = seg::dsg_edge_map(f, uniform_direction(f, 1, 0, 0), p);
    EXPECT_NEAR(along_x.at(16, 10, 0) / along_x.at(48, 32, 0), 2.0, 1e-4);
    EXPECT_FLOAT_EQ(*std::max_element(along_x.data.begin(), along_x.data.end()), 1.f); // normalised

    const double a = 30.0 * 3.14159265358979323846 / 180.0;
    const core::ImageF tilted = seg::dsg_edge_map(f, uniform_direction(f, std::cos(a), std::sin(a), 0), p);
    EXPECT_NEAR(tilted.at(16, 10, 0) / tilted.at(48, 32, 0), 1.4, 1e-4);

    // A = 3: ratio 1 + A = 4; the sign and length of n do not matter.
    p.gain = 3.0;
    const core::ImageF strong = seg::dsg_edge_map(f, uniform_direction(f, -2, 0, 0), p);
    EXPECT_NEAR(strong.at(16, 10, 0) / strong.at(48, 32, 0), 4.0, 1e-4);
    for (float v : strong.data)
        ASSERT_TRUE(v >= 0.f && v <= 1.f);
}

TEST(Dsg, ZeroDirectionLeavesTheShapeOfF)
{
    // No direction: gain 1 everywhere, so F = normalised f~_H. Without the Laplacian that is
    // H(f / f_max), and with a tiny sharpen_max H is the identity to s^2 (tan∘tan∘tan(u) =
    // u + u^3 + ...): F = f / f_max within 1e-6 for s = 1e-3.
    const core::ImageF f = two_ridges(0.8f);
    const seg::VectorField none(f.geometry());
    seg::DsgParams p;
    p.laplacian_sharpening = false;
    p.sharpen_max = 1e-3;
    const core::ImageF linear = seg::dsg_edge_map(f, none, p);
    for (std::size_t q = 0; q < f.data.size(); ++q)
        ASSERT_NEAR(linear.data[q], f.data[q] / 0.8f, 1e-6);

    p.sharpen_max = 0.75;
    const core::ImageF kernel_only = seg::dsg_edge_map(f, none, p);
    for (std::size_t q = 0; q < f.data.size(); ++q)
        ASSERT_NEAR(kernel_only.data[q], seg::sharpen_kernel(double(f.data[q]) / 0.8, 0.75), 1e-6);
}

TEST(Dsg, LaplacianSharpeningIsFMinusItsLaplacianClampedAtZero)
{
    // f~ = max(H - ∇²H, 0) with the index-unit 5-point Laplacian and the mirrored border
    // (ghost = centre), then / max: recomputed here independently on a random f (1e-5).
    core::ImageF f(grid(23, 19, 1));
    std::mt19937 rng(9);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    for (float& v : f.data)
        v = u(rng);
    const core::ImageF got = seg::dsg_edge_map(f, seg::VectorField(f.geometry()));
    float fmax = 0.f;
    for (float v : f.data)
        fmax = std::max(fmax, v);
    core::ImageF h(f.geometry()), want(f.geometry());
    for (std::size_t q = 0; q < f.data.size(); ++q)
        h.data[q] = static_cast<float>(seg::sharpen_kernel(double(f.data[q]) / double(fmax)));
    float wmax = 0.f;
    for (int j = 0; j < 19; ++j)
        for (int i = 0; i < 23; ++i) {
            const double c = h.at(i, j, 0);
            const double lap = double(h.at(std::max(i - 1, 0), j, 0)) + double(h.at(std::min(i + 1, 22), j, 0)) +
                               double(h.at(i, std::max(j - 1, 0), 0)) + double(h.at(i, std::min(j + 1, 18), 0)) - 4 * c;
            want.at(i, j, 0) = static_cast<float>(std::max(0.0, c - lap));
            wmax = std::max(wmax, want.at(i, j, 0));
        }
    int clamped = 0;
    for (std::size_t q = 0; q < f.data.size(); ++q) {
        ASSERT_NEAR(got.data[q], want.data[q] / wmax, 1e-5);
        clamped += want.data[q] == 0.f;
    }
    EXPECT_GT(clamped, 0); // noise has voxels far below their neighbours: the clamp matters
}

TEST(Dsg, WorksIn3D)
{
    // Same argument as in 2-D: a ridge with normal z (crest k = 8, kept for x < 12) and one with
    // normal x (crest i = 26, kept for z >= 16); n = z boosts the first by 1 + A = 2.
    core::ImageF f(grid(36, 12, 32), 0.f);
    for (int k = 0; k < 32; ++k)
        for (int j = 0; j < 12; ++j)
            for (int i = 0; i < 36; ++i) {
                float v = i < 12 ? ridge(k - 8.0) : 0.f;
                if (k >= 16)
                    v = std::max(v, ridge(i - 26.0));
                f.at(i, j, k) = v;
            }
    const core::ImageF d = seg::dsg_edge_map(f, uniform_direction(f, 0, 0, 1));
    EXPECT_NEAR(d.at(2, 6, 8) / d.at(26, 6, 26), 2.0, 1e-4);
}

TEST(Dsg, InvalidInputsAreRejected)
{
    const core::ImageF f(grid(8, 8, 1), 0.5f);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::dsg_edge_map(f, seg::VectorField(grid(8, 9, 1))),
                      "different grids");
    seg::VectorField n(f.geometry());
    n.c[0].data[5] = std::nanf("");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::dsg_edge_map(f, n), "non-finite");
    seg::DsgParams p;
    p.sharpen_max = 0.8;
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::dsg_edge_map(f, seg::VectorField(f.geometry()), p), "pole");
    // No edges at all: F = 0, not NaN.
    const core::ImageF zero = seg::dsg_edge_map(core::ImageF(f.geometry(), 0.f), seg::VectorField(f.geometry()));
    for (float v : zero.data)
        ASSERT_EQ(v, 0.f);
}
