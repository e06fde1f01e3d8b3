// The vessel pipeline (lobe/seg/vessels.h) against lphantom's ground truth: vessel Dice, centre-line
// recall by branch level, the portal/hepatic separation and trunk names, and the failure cases of
// issue 5: no contrast (nothing reported), a gap in a vessel (bridged). The phantoms here use grids
// and noise seeds the pipeline was not tuned on (it was developed on the default 0.7 x 0.7 x 2.5 mm
// phantom, seeds 1, 3, 5, 11); the bounds are the measured values less a margin, with the
// measurements in the comments (docs/algorithms/vessels.md has the full table).
#include "lobe/seg/vessels.h"

#include "common/expect_error.h"
#include "common/tubes.h"
#include "common/orientation.h"
#include "lobe/core/any_image.h"
#include "lphantom/phantom.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <cmath>
#include <iostream>
#include <limits>
#include <map>
#include <set>

using namespace lobe;

namespace {

struct Case {
    phantom::PhantomParams params;
    phantom::PhantomResult ph;
    core::ImageF hu;
    core::LabelImage3D liver;
};

Case make_case(std::array<double, 3> spacing, std::uint64_t seed, const std::function<void(phantom::PhantomParams&)>& edit = {})
{
    Case c;
    c.params.spacing = spacing;
    c.params.size = phantom::size_for_spacing(spacing);
    c.params.seed = seed;
    if (edit)
        edit(c.params);
    c.ph = phantom::generate_phantom(c.params);
    c.hu = core::convert_image<float>(c.ph.ct);
    c.liver = core::LabelImage3D(c.ph.labels.geometry(), 0);
    for (std::size_t u = 0; u < c.liver.data.size(); ++u)
        c.liver.data[u] = c.ph.labels.data[u] >= 1 && c.ph.labels.data[u] <= 4 ? 1 : 0;
    return c;
}

double dice(const core::LabelImage3D& seg, const core::LabelImage3D& truth, std::set<int> labels)
{
    std::size_t s = 0, t = 0, both = 0;
    for (std::size_t u = 0; u < seg.data.size(); ++u) {
        const bool a = labels.count(seg.data[u]) > 0, b = labels.count(truth.data[u]) > 0;
        s += a;
        t += b;
        both += a && b;
    }
    return s + t ? 2.0 * double(both) / double(s + t) : 1.0;
}

} // namespace

// The whole pipeline at 1.2 x 1.2 x 2 mm, noise seed 21 (measured: vessel Dice 0.955, portal 0.937,
// hepatic 0.961; recall 1.00, 1.00, 1.00, 0.977 at levels 1-4; precision 0.999; every found sample
// in the right tree; 93 % of them at the right level; 1 portal tree, the three hepatic trunks
// named). The Dice bound is far above the fuzzy-connectedness anchors of the literature (0.67 on
// 3D-IRCADb, 0.71 on SLIVER07 scans), which real scans earn with less contrast and noise than
// this phantom's (docs/algorithms/vessels.md says what the phantom leaves out).
TEST(Vessels, PhantomTreesToTheFourthLevel)
{
    const Case c = make_case({1.2, 1.2, 2.0}, 21);
    const auto r = seg::segment_vessels(c.hu, c.liver);
    ASSERT_TRUE(r.found) << r.message;
    EXPECT_TRUE(core::graph_problem(r.graph).empty()) << core::graph_problem(r.graph);
    EXPECT_GE(dice(r.labels, c.ph.labels, {2, 3}), 0.92);
    EXPECT_GE(dice(r.labels, c.ph.labels, {2}), 0.90);
    EXPECT_GE(dice(r.labels, c.ph.labels, {3}), 0.92);
    const auto ev = seg::evaluate_centrelines(r.graph, phantom::truth_graph(c.ph.truth), &c.liver);
    ASSERT_EQ(ev.by_level.size(), 4u);
    for (const auto& l : ev.by_level) {
        std::cout << "level " << l.level << ": recall " << l.recall() << " (" << l.found << "/" << l.samples << ")\n";
        EXPECT_GE(l.recall(), l.level < 4 ? 0.95 : 0.90) << "level " << l.level;
    }
    EXPECT_GE(ev.precision, 0.97);
    EXPECT_GE(double(ev.overall.labelled_right) / double(ev.overall.found), 0.97);
    EXPECT_GE(ev.level_agreement, 0.8);

    // Trees and names (thesis Fig 5.22): one portal tree with PV, RPV, LPV; RHV, MHV, LHV.
    int portal_trees = 0;
    for (const auto& t : r.trees)
        portal_trees += t.label == seg::kPortalVeinLabel;
    EXPECT_EQ(portal_trees, 1);
    EXPECT_TRUE(r.separated_by_contrast); // 175 against 160 HU
    std::map<std::string, const core::CentrelineEdge*> named;
    for (const auto& e : r.graph.edges)
        if (!e.name.empty())
            named[e.name] = &e;
    for (const char* n : {"PV", "RPV", "LPV", "RHV", "MHV", "LHV"})
        EXPECT_EQ(named.count(n), 1u) << n;
    if (named.count("RHV") && named.count("LHV")) { // patient right is -x in LPS
        EXPECT_LT(named["RHV"]->points.back().x, named["LHV"]->points.back().x);
    }
    if (named.count("PV")) {
        EXPECT_EQ(named["PV"]->label, seg::kPortalVeinLabel);
    }
    std::size_t voxels = 0;
    for (auto v : r.labels.data)
        voxels += v != 0;
    EXPECT_NEAR(r.portal_ml + r.hepatic_ml, double(voxels) * 1.2 * 1.2 * 2.0 / 1000, 1e-6);
}

// The same phantom stored as a coronal stack (rows along x, columns to the feet, slices to the
// back): segment_vessels runs on the volume reordered onto the patient frame, so the trees are
// the same: the labels voxel for voxel (reordered), the graph node for node in mm. Without the
// reordering the filters and the skeleton followed voxel order (on the demo phantom 87 skeleton
// segments against 78, hepatic 29.78 against 29.79 mL).
TEST(Vessels, ACoronalStackGivesTheSameTrees)
{
    const Case c = make_case({1.2, 1.2, 2.0}, 21);
    const core::AxisOrder order = test::coronal_storage();
    const auto axial = seg::segment_vessels(c.hu, c.liver);
    const auto coronal = seg::segment_vessels(core::reorder_axes(c.hu, order), core::reorder_axes(c.liver, order));
    ASSERT_TRUE(axial.found) << axial.message;
    ASSERT_TRUE(core::same_grid(coronal.labels, core::reorder_axes(c.liver, order)));
    EXPECT_TRUE(core::reorder_axes(axial.labels, order).data == coronal.labels.data);
    ASSERT_EQ(coronal.graph.nodes.size(), axial.graph.nodes.size());
    ASSERT_EQ(coronal.graph.edges.size(), axial.graph.edges.size());
    double furthest = 0;
    for (std::size_t n = 0; n < axial.graph.nodes.size(); ++n)
        furthest = std::max(furthest, core::distance(axial.graph.nodes[n].position, coronal.graph.nodes[n].position));
    EXPECT_LT(furthest, 1e-6); // mm: the same voxels at the same places, to rounding of the origin
    EXPECT_EQ(coronal.portal_ml, axial.portal_ml);
    EXPECT_EQ(coronal.hepatic_ml, axial.hepatic_ml);
}

// No contrast: the vessels have the liver's CT number, so they cannot be seen; the pipeline must
// report nothing rather than noise. Parenchyma noise after smoothing is about 4 HU, the seed level
// 20 HU above the parenchyma (5 noise sigmas); the tumours are darker, not brighter.
TEST(Vessels, NoContrastReportsNothing)
{
    const Case c = make_case({1.5, 1.5, 3.0}, 8, [](phantom::PhantomParams& p) {
        p.hu.portal_vein = p.hu.hepatic_vein = p.hu.liver;
    });
    const auto r = seg::segment_vessels(c.hu, c.liver);
    EXPECT_FALSE(r.found);
    EXPECT_NE(r.message.find("no vessels"), std::string::npos) << r.message;
    EXPECT_TRUE(r.graph.edges.empty());
    EXPECT_TRUE(std::all_of(r.labels.data.begin(), r.labels.data.end(), [](std::uint8_t v) { return v == 0; }));
    EXPECT_EQ(r.portal_ml + r.hepatic_ml, 0.0);

    const Case none = make_case({1.5, 1.5, 3.0}, 9, [](phantom::PhantomParams& p) { p.vessels = false; });
    EXPECT_FALSE(seg::segment_vessels(none.hu, none.liver).found);
}

// A gap: 5 mm of a level-3 portal branch (truth edge 6, r = 2.5 mm) at 20 % contrast. The branch
// beyond it and its two level-4 children are found and belong to the portal tree, at levels
// continuing the proximal part's (measured: all of the distal centre line, 96 % of it at the right
// level; 1 gap bridged). Without fuzzy connectedness and the break-point connection the distal
// part comes back as a separate tree rooted at level 1 (measured: level agreement 0), so the gap
// is real. (On the default 0.7 x 0.7 x 2.5 mm phantom a 35 % gap needs both: bench/vessels.)
TEST(Vessels, GapIsBridged)
{
    Case c = make_case({1.0, 1.0, 2.0}, 13);
    const auto& e6 = c.ph.truth.vessel_edges[6];
    ASSERT_EQ(e6.level, 3);
    ASSERT_EQ(e6.tree, phantom::VesselTree::Portal);
    phantom::add_vessel_gap(c.ph, c.params, 6, 0.5 * e6.length_mm - 2.5, 5.0, 0.2);
    c.hu = core::convert_image<float>(c.ph.ct);

    // The distal reference: edge 6 beyond the gap and its children (edges 16, 17).
    const core::CentrelineGraph truth = phantom::truth_graph(c.ph.truth);
    core::CentrelineGraph distal = truth;
    distal.edges.clear();
    for (int id : {6, 16, 17}) {
        auto ed = truth.edges[std::size_t(id)];
        if (id == 6)
            ed.points[0] = ed.points[0] + (ed.points[1] - ed.points[0]) * (0.5 + 3.0 / ed.length_mm);
        distal.edges.push_back(ed);
    }
    const auto r = seg::segment_vessels(c.hu, c.liver);
    ASSERT_TRUE(r.found) << r.message;
    const auto ev = seg::evaluate_centrelines(r.graph, distal, &c.liver);
    EXPECT_GE(ev.overall.recall(), 0.9);
    EXPECT_EQ(ev.overall.labelled_right, ev.overall.found);
    EXPECT_GE(ev.level_agreement, 0.8); // levels 3 and 4 beyond the gap: connected to the tree
    int portal_trees = 0;
    for (const auto& t : r.trees)
        portal_trees += t.label == seg::kPortalVeinLabel;
    EXPECT_EQ(portal_trees, 1);

    seg::VesselParams off;
    off.use_fuzzy_connectedness = false;
    off.bridge_gaps = false;
    const auto plain = seg::segment_vessels(c.hu, c.liver, off);
    const auto ev0 = seg::evaluate_centrelines(plain.graph, distal, &c.liver);
    EXPECT_LT(ev0.overall.recall() * ev0.level_agreement, 0.5);
}

// evaluate_centrelines: the phantom's graph against itself finds everything in the right tree; two
// straight vessels (radius 6 and 1.5 mm) moved 4.2 mm sideways are found only where the tolerance
// (the radius, at least 2 mm) covers the shift: the thick one.
TEST(EvaluateCentrelines, ToleranceIsTheRadius)
{
    phantom::PhantomParams p;
    p.spacing = {3, 3, 5};
    p.size = phantom::size_for_spacing(p.spacing);
    const auto truth = phantom::truth_graph(phantom::generate_phantom(p).truth);
    const auto self = seg::evaluate_centrelines(truth, truth);
    EXPECT_EQ(self.overall.found, self.overall.samples);
    EXPECT_EQ(self.overall.labelled_right, self.overall.samples);
    EXPECT_GE(self.level_agreement, 0.95); // samples at a branch point may match the other level's edge
    EXPECT_DOUBLE_EQ(self.precision, 1.0);

    core::CentrelineGraph two;
    two.nodes = {{{0, 0, 0}, 6}, {{50, 0, 0}, 6}, {{0, 30, 0}, 1.5}, {{50, 30, 0}, 1.5}};
    for (int e = 0; e < 2; ++e) {
        core::CentrelineEdge ed;
        ed.from = 2 * e;
        ed.to = 2 * e + 1;
        ed.level = e + 1;
        ed.label = 2;
        ed.points = {two.nodes[std::size_t(2 * e)].position, two.nodes[std::size_t(2 * e + 1)].position};
        ed.radius_mm = e == 0 ? 6 : 1.5;
        ed.point_radius = {ed.radius_mm, ed.radius_mm};
        ed.length_mm = 50;
        two.edges.push_back(ed);
    }
    core::CentrelineGraph moved = two;
    for (auto& e : moved.edges)
        for (auto& q : e.points)
            q.y += 4.2;
    const auto ev = seg::evaluate_centrelines(moved, two);
    ASSERT_EQ(ev.by_level.size(), 2u);
    EXPECT_EQ(ev.by_level[0].recall(), 1.0);
    EXPECT_EQ(ev.by_level[1].recall(), 0.0);
    EXPECT_NEAR(ev.precision, 0.5, 0.02); // the moved thin line lies 4.2 mm from its 1.5 mm reference

    core::CentrelineGraph bad = truth;
    bad.edges[0].to = 10000;
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evaluate_centrelines(bad, truth), "segmented graph");
}

TEST(Vessels, RefusesBadInput)
{
    const auto g = test::grid({20, 20, 10}, {1, 1, 1});
    const core::ImageF img(g, 100.f);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::segment_vessels(img, core::LabelImage3D(g, 0)), "empty");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::segment_vessels(img, core::LabelImage3D(test::grid({20, 20, 9}, {1, 1, 1}), 1)),
                      "liver mask");
    core::ImageF nan = img;
    nan.data[50] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::segment_vessels(nan, core::LabelImage3D(g, 1)), "non-finite");
    seg::VesselParams p;
    p.link_threshold = 1.5;
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::segment_vessels(img, core::LabelImage3D(g, 1), p), "link_threshold");
}
