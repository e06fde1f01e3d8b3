// Multi-scale vesselness and directional sharpening (lobe/seg/vesselness.h) on synthetic tubes,
// blobs and plates whose expected responses follow from Frangi's measure.
#include "lobe/seg/vesselness.h"

#include "common/expect_error.h"
#include "common/tubes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

using namespace lobe;

namespace {

double median(std::vector<double> v)
{
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0 : v[v.size() / 2];
}

double quantile(std::vector<double> v, double q)
{
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0 : v[static_cast<std::size_t>(q * double(v.size() - 1))];
}

} // namespace

// An oblique bright tube (r = 2 mm, 60 units over the background, noise 4) on an anisotropic grid
// (0.7 x 0.7 x 1.0 mm). On its axis the Hessian has two large negative eigenvalues and one near
// zero, so Frangi's measure is near its structureness factor (1 - exp(-S²/2c²) with S about 0.5
// of the contrast = 30 and c = 10: 0.99), while noise (Hessian norm a few units) stays near 0;
// the eigenvector of the smallest eigenvalue is the tube's direction.
TEST(Vesselness, BrightTubeScoresHighAndPointsAlongItsAxis)
{
    const auto g = test::grid({64, 64, 44}, {0.7, 0.7, 1.0});
    const core::Vec3 a{6, 6, 6}, b{39, 39, 37};
    const core::Vec3 dir = core::normalized(b - a);
    const auto img = test::tube_image(g, {{a, b, 2.0}}, 100, 60, 4.0);
    seg::VesselnessParams p;
    p.structureness = 10;
    const auto v = seg::vesselness(img, p);

    std::vector<double> on_axis, background, alignment;
    for (int k = 0; k < g.size[2]; ++k)
        for (int j = 0; j < g.size[1]; ++j)
            for (int i = 0; i < g.size[0]; ++i) {
                const core::Vec3 q = g.index_to_physical(i, j, k);
                const double d = test::distance_to_segment(q, a, b);
                const double t = core::dot(q - a, dir);
                if (t < 5 || t > core::distance(a, b) - 5)
                    continue; // away from the tube's ends
                const double val = v.vesselness.at(i, j, k);
                if (d < 0.5) {
                    on_axis.push_back(val);
                    const core::Vec3 e{v.axis.c[0].at(i, j, k), v.axis.c[1].at(i, j, k), v.axis.c[2].at(i, j, k)};
                    alignment.push_back(std::abs(core::dot(e, dir)));
                } else if (d > 8) {
                    background.push_back(val);
                }
            }
    ASSERT_GT(on_axis.size(), 20u);
    EXPECT_GT(median(on_axis), 0.5);
    EXPECT_LT(quantile(background, 0.99), 0.1);
    EXPECT_GT(median(alignment), 0.95); // within 18 degrees
    for (double x : on_axis)
        EXPECT_LE(x, 1.0);
}

// A sphere (all three eigenvalues equal at its centre: R_B = 1, so V <= exp(-1/(2·0.25)) = 0.135)
// and a slab (one large eigenvalue, λ2 ≈ 0: R_A ≈ 0, so V ≈ 0) of the same contrast as a tube
// that scores > 0.5.
TEST(Vesselness, BlobsAndPlatesAreNotTubes)
{
    const auto g = test::grid({48, 48, 48}, {1, 1, 1});
    core::ImageF blob(g, 100.f), plate(g, 100.f);
    for (int k = 0; k < 48; ++k)
        for (int j = 0; j < 48; ++j)
            for (int i = 0; i < 48; ++i) {
                const double r = std::sqrt((i - 24.0) * (i - 24.0) + (j - 24.0) * (j - 24.0) + (k - 24.0) * (k - 24.0));
                blob.at(i, j, k) += static_cast<float>(60 * std::clamp(4.5 - r, 0.0, 1.0));
                plate.at(i, j, k) += static_cast<float>(60 * std::clamp(2.5 - std::abs(k - 24.0), 0.0, 1.0));
            }
    const auto tube = test::tube_image(g, {{{24, 4, 24}, {24, 44, 24}, 3.0}}, 100, 60, 0.0);
    seg::VesselnessParams p;
    p.structureness = 10;
    EXPECT_LT(seg::vesselness(blob, p).vesselness.at(24, 24, 24), 0.2);
    EXPECT_LT(seg::vesselness(plate, p).vesselness.at(24, 24, 24), 0.05);
    EXPECT_GT(seg::vesselness(tube, p).vesselness.at(24, 24, 24), 0.5);
}

// The best scale follows the radius: a disc cross-section of radius r peaks at σ = r/√2, so a
// 1.4 mm tube picks the smallest scale (1.0) and a 5.5 mm tube the largest (4.0) of {1, 1.6, 2.5, 4}.
TEST(Vesselness, ScaleFollowsTheRadius)
{
    const auto g = test::grid({60, 60, 60}, {1, 1, 1});
    seg::VesselnessParams p;
    p.structureness = 10;
    const auto thin = seg::vesselness(test::tube_image(g, {{{30, 5, 30}, {30, 55, 30}, 1.4}}, 100, 60, 0.0), p);
    const auto thick = seg::vesselness(test::tube_image(g, {{{30, 5, 30}, {30, 55, 30}, 5.5}}, 100, 60, 0.0), p);
    EXPECT_DOUBLE_EQ(thin.scale_mm.at(30, 30, 30), 1.0);
    EXPECT_DOUBLE_EQ(thick.scale_mm.at(30, 30, 30), 4.0);
    EXPECT_EQ(thin.structureness.size(), p.scales_mm.size());
}

// Averaging along the axis: the noise inside a tube falls (5 samples 0.7 mm apart over ±1.5 mm,
// trilinearly interpolated, so less than √5 but well over 1.4x), its mean is kept (the profile is
// constant along the axis), and voxels without a vessel axis are untouched.
TEST(DirectionalSharpening, AveragesAlongTheAxisNotAcross)
{
    const auto g = test::grid({40, 40, 80}, {0.7, 0.7, 0.7});
    const core::Vec3 a{14, 14, 3}, b{14, 14, 53};
    const auto img = test::tube_image(g, {{a, b, 2.5}}, 100, 60, 8.0, 3);
    seg::VesselnessParams vp;
    vp.structureness = 10;
    const auto v = seg::vesselness(img, vp);
    const auto ds = seg::directional_sharpening(img, v);

    std::vector<double> before, after;
    std::size_t untouched = 0, no_axis = 0;
    for (int k = 0; k < g.size[2]; ++k)
        for (int j = 0; j < g.size[1]; ++j)
            for (int i = 0; i < g.size[0]; ++i) {
                const core::Vec3 q = g.index_to_physical(i, j, k);
                if (test::distance_to_segment(q, a, b) < 1.0 && q.z > 10 && q.z < 46) {
                    before.push_back(img.at(i, j, k));
                    after.push_back(ds.intensity.at(i, j, k));
                }
                if (v.vesselness.at(i, j, k) < 0.02f) {
                    ++no_axis;
                    untouched += ds.intensity.at(i, j, k) == img.at(i, j, k);
                }
            }
    auto mean_sd = [](const std::vector<double>& x) {
        double m = 0, s = 0;
        for (double y : x)
            m += y;
        m /= double(x.size());
        for (double y : x)
            s += (y - m) * (y - m);
        return std::pair{m, std::sqrt(s / double(x.size() - 1))};
    };
    const auto [m0, s0] = mean_sd(before);
    const auto [m1, s1] = mean_sd(after);
    EXPECT_GT(s0 / s1, 1.4) << s0 << " -> " << s1;
    EXPECT_NEAR(m1, m0, 2.0);
    EXPECT_EQ(untouched, no_axis);
}

TEST(Vesselness, RefusesBadInput)
{
    const auto g = test::grid({8, 8, 8}, {1, 1, 1});
    const core::ImageF img(g, 1.f);
    seg::VesselnessParams p;
    p.scales_mm.clear();
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::vesselness(img, p), "scale");
    p.scales_mm = {-1};
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::vesselness(img, p), "scales");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::vesselness(core::ImageF(test::grid({8, 8, 1}, {1, 1, 1}), 1.f)),
                      "3 slices");
    const core::LabelImage3D roi(test::grid({8, 8, 9}, {1, 1, 1}), 1);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::vesselness(img, {}, &roi), "ROI");
    core::ImageF bad = img;
    bad.data[5] = std::nanf("");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::vesselness(bad), "non-finite");
}
