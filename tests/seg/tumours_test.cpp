// Tumour segmentation (lobe/seg/tumours.h) against lphantom's three tumours (lobular 24 mL at
// -20 HU, satellite 0.9 mL at -25 HU, one cut by the liver's surface 8.1 mL at -30 HU): Dice, the
// detection of each, the tumour touching the liver's boundary, seed points, a liver without
// tumours. The phantom grid and noise seed (1.2 x 1.2 x 2 mm, seed 21) are not those the method
// was developed on (the default 0.7 x 0.7 x 2.5 mm, seeds 1, 3, 5, 11); bounds are the measured
// values (in the comments) less a margin.
#include "lobe/seg/tumours.h"

#include "common/expect_error.h"
#include "common/tubes.h"
#include "common/orientation.h"
#include "lobe/core/any_image.h"
#include "lphantom/phantom.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

using namespace lobe;

namespace {

struct Case {
    phantom::PhantomResult ph;
    core::ImageF hu;
    core::LabelImage3D liver, vessels;
};

Case make_case(std::array<double, 3> spacing, std::uint64_t seed, const std::function<void(phantom::PhantomParams&)>& edit = {})
{
    phantom::PhantomParams p;
    p.spacing = spacing;
    p.size = phantom::size_for_spacing(spacing);
    p.seed = seed;
    if (edit)
        edit(p);
    Case c{phantom::generate_phantom(p), {}, {}, {}};
    c.hu = core::convert_image<float>(c.ph.ct);
    c.liver = core::LabelImage3D(c.ph.labels.geometry(), 0);
    c.vessels = c.liver;
    for (std::size_t u = 0; u < c.liver.data.size(); ++u) {
        const auto l = c.ph.labels.data[u];
        c.liver.data[u] = l >= 1 && l <= 4 ? 1 : 0;
        c.vessels.data[u] = l == 2 || l == 3 ? 1 : 0;
    }
    return c;
}

//! Dice of the segmented voxels nearest truth tumour t's centroid against that tumour's voxels
//! (the three tumours are far apart, so nearest-centroid assignment splits them cleanly).
double tumour_dice(const Case& c, const core::LabelImage3D& seg, std::size_t t)
{
    const auto& tumours = c.ph.truth.tumours;
    auto nearest = [&](int i, int j, int k) {
        const core::Vec3 p = seg.index_to_physical(i, j, k);
        std::size_t best = 0;
        for (std::size_t n = 1; n < tumours.size(); ++n)
            if (core::distance(p, tumours[n].centroid) < core::distance(p, tumours[best].centroid))
                best = n;
        return best;
    };
    std::size_t s = 0, r = 0, both = 0;
    for (int k = 0; k < seg.size[2]; ++k)
        for (int j = 0; j < seg.size[1]; ++j)
            for (int i = 0; i < seg.size[0]; ++i) {
                const bool a = seg.at(i, j, k) != 0, b = c.ph.labels.at(i, j, k) == 4;
                if ((!a && !b) || nearest(i, j, k) != t)
                    continue;
                s += a;
                r += b;
                both += a && b;
            }
    return s + r ? 2.0 * double(both) / double(s + r) : 0.0;
}

double dice(const core::LabelImage3D& seg, const core::LabelImage3D& labels)
{
    std::size_t s = 0, r = 0, both = 0;
    for (std::size_t u = 0; u < seg.data.size(); ++u) {
        const bool a = seg.data[u] != 0, b = labels.data[u] == 4;
        s += a;
        r += b;
        both += a && b;
    }
    return s + r ? 2.0 * double(both) / double(s + r) : 0.0;
}

} // namespace

// Automatic: the K-means tumour layer's components (measured: Dice 0.954; lobular 0.967,
// satellite 0.887, boundary 0.923; 3 tumours, no false positive). The Dice bound is above the
// best LiTS entries' 0.70, on a phantom that is easier than their scans (smooth parenchyma, known
// contrast, the true liver mask: docs/algorithms/tumours.md).
TEST(Tumours, FindsTheLobularTheSatelliteAndTheBoundaryTumour)
{
    const Case c = make_case({1.2, 1.2, 2.0}, 21);
    const auto r = seg::segment_tumours(c.hu, c.liver, &c.vessels);
    ASSERT_TRUE(r.found) << r.message;
    EXPECT_EQ(r.tumours.size(), 3u) << r.message; // multiple tumours, no false positive
    EXPECT_GE(dice(r.mask, c.ph.labels), 0.92);
    ASSERT_EQ(c.ph.truth.tumours.size(), 3u);
    const double minimum[3] = {0.93, 0.80, 0.88}; // lobular, satellite, boundary
    for (std::size_t t = 0; t < 3; ++t)
        EXPECT_GE(tumour_dice(c, r.mask, t), minimum[t]) << c.ph.truth.tumours[t].name;
    // Each reported tumour lies at a truth tumour, with its hypodense contrast (-20..-30 HU).
    for (const auto& rep : r.tumours) {
        double best = 1e300;
        for (const auto& t : c.ph.truth.tumours)
            best = std::min(best, core::distance(rep.centroid, t.centroid));
        EXPECT_LT(best, 6.0);
        EXPECT_LT(rep.contrast, -12.0);
        EXPECT_GT(rep.contrast, -35.0);
    }
    EXPECT_GT(r.parenchyma, 100.0); // 105 HU
    EXPECT_LT(r.parenchyma, 110.0);
}

// The same phantom stored as a coronal stack, with the vessel mask: the same tumours, mask voxel
// for voxel (reordered), centroids in mm. Unlike the vessels' filters and skeleton (which needed
// reordering onto the patient frame: Vessels.ACoronalStackGivesTheSameTrees), the clustering and
// the per-tumour snakes do not depend on voxel order; this guards that.
TEST(Tumours, ACoronalStackGivesTheSameTumours)
{
    const Case c = make_case({1.2, 1.2, 2.0}, 21);
    const core::AxisOrder order = test::coronal_storage();
    const auto axial = seg::segment_tumours(c.hu, c.liver, &c.vessels);
    const core::LabelImage3D vessels = core::reorder_axes(c.vessels, order);
    const auto coronal =
        seg::segment_tumours(core::reorder_axes(c.hu, order), core::reorder_axes(c.liver, order), &vessels);
    ASSERT_TRUE(axial.found) << axial.message;
    EXPECT_TRUE(core::reorder_axes(axial.mask, order).data == coronal.mask.data);
    ASSERT_EQ(coronal.tumours.size(), axial.tumours.size());
    for (std::size_t t = 0; t < axial.tumours.size(); ++t) {
        EXPECT_LT(core::distance(coronal.tumours[t].centroid, axial.tumours[t].centroid), 1e-6);
        EXPECT_EQ(coronal.tumours[t].volume_ml, axial.tumours[t].volume_ml);
    }
}

// The tumour the liver's surface cuts (the thesis's "tumour next to the ribs"): the surface rim,
// left out of the clustering (it averages liver and fat), is given back where the tumour reaches
// it, so the tumour is reported touching the surface and reaches the liver's outer voxel layer.
// Measured volume 9.35 mL against the truth's 8.09 (the rim voxels are whole voxels).
TEST(Tumours, TumourTouchingTheLiverBoundary)
{
    const Case c = make_case({1.2, 1.2, 2.0}, 21);
    const auto r = seg::segment_tumours(c.hu, c.liver, &c.vessels);
    const auto& truth = c.ph.truth.tumours[2];
    ASSERT_TRUE(truth.touches_boundary);
    const seg::TumourReport* rep = nullptr;
    for (const auto& t : r.tumours)
        if (core::distance(t.centroid, truth.centroid) < 6.0)
            rep = &t;
    ASSERT_NE(rep, nullptr) << r.message;
    EXPECT_TRUE(rep->touches_surface);
    EXPECT_NEAR(rep->volume_ml, truth.volume_ml, 0.25 * truth.volume_ml);
    // Some tumour voxel has a 6-neighbour outside the liver.
    bool reaches = false;
    for (int k = 1; k + 1 < r.mask.size[2] && !reaches; ++k)
        for (int j = 1; j + 1 < r.mask.size[1] && !reaches; ++j)
            for (int i = 1; i + 1 < r.mask.size[0] && !reaches; ++i)
                if (r.mask.at(i, j, k) && core::distance(r.mask.index_to_physical(i, j, k), truth.centroid) < 20)
                    reaches = !c.liver.at(i + 1, j, k) || !c.liver.at(i - 1, j, k) || !c.liver.at(i, j + 1, k) ||
                              !c.liver.at(i, j - 1, k) || !c.liver.at(i, j, k + 1) || !c.liver.at(i, j, k - 1);
    EXPECT_TRUE(reaches);
}

// Semi-automatic: a seed at the satellite's centre returns that tumour only (measured Dice 0.82);
// a seed in plain parenchyma returns nothing and says why; a seed outside the liver is refused.
TEST(Tumours, SeedPointsSegmentTheirTumourOnly)
{
    const Case c = make_case({1.2, 1.2, 2.0}, 21);
    const auto& sat = c.ph.truth.tumours[1];
    const auto r = seg::segment_tumours(c.hu, c.liver, &c.vessels, {}, {sat.centroid});
    ASSERT_EQ(r.tumours.size(), 1u) << r.message;
    EXPECT_TRUE(r.tumours[0].from_seed);
    EXPECT_LT(core::distance(r.tumours[0].centroid, sat.centroid), 3.0);
    EXPECT_GE(tumour_dice(c, r.mask, 1), 0.75);

    // 25 mm below the satellite: parenchyma, clear of tumours and large vessels in this phantom.
    const core::Vec3 parenchyma = sat.centroid + core::Vec3{0, 0, -25};
    const auto none = seg::segment_tumours(c.hu, c.liver, &c.vessels, {}, {parenchyma});
    EXPECT_FALSE(none.found);
    EXPECT_NE(none.message.find("not in a hypodense region"), std::string::npos) << none.message;

    EXPECT_LOBE_ERROR(core::InvalidInputError,
                      seg::segment_tumours(c.hu, c.liver, &c.vessels, {}, {core::Vec3{0, 0, 500}}), "seed", "not inside the liver");
}

// No tumours: no K-means layer lies 8 HU or more below the parenchyma, nothing is reported.
TEST(Tumours, NoTumoursReportsNothing)
{
    const Case c = make_case({1.5, 1.5, 3.0}, 8, [](phantom::PhantomParams& p) { p.tumours = false; });
    const auto r = seg::segment_tumours(c.hu, c.liver, &c.vessels);
    EXPECT_FALSE(r.found);
    EXPECT_NE(r.message.find("no tumours"), std::string::npos) << r.message;
    EXPECT_TRUE(std::all_of(r.mask.data.begin(), r.mask.data.end(), [](std::uint8_t v) { return v == 0; }));
}

TEST(Tumours, RefusesBadInput)
{
    const auto g = test::grid({20, 20, 10}, {1, 1, 1});
    const core::ImageF img(g, 100.f);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::segment_tumours(img, core::LabelImage3D(g, 0)), "empty");
    const core::LabelImage3D other(test::grid({20, 20, 9}, {1, 1, 1}), 1);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::segment_tumours(img, other), "liver mask");
    const core::LabelImage3D liver(g, 1);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::segment_tumours(img, liver, &other), "vessel mask");
    core::ImageF nan = img;
    nan.data[7] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::segment_tumours(nan, liver), "non-finite");
    seg::TumourParams p;
    p.kmeans.clusters = 1;
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::segment_tumours(img, liver, nullptr, p), "clusters");
}
