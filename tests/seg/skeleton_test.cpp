// 3-D thinning and the centre-line graph (lobe/seg/skeleton.h): simple points by hand, the axis
// of a cylinder, topology kept on a ring and on separate parts, a Y-shaped tree with its radii,
// spur pruning, and branch levels on a synthetic tree.
#include "lobe/seg/skeleton.h"

#include "common/expect_error.h"
#include "common/masks.h"
#include "common/tubes.h"
#include "lobe/seg/distance_transform.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

using namespace lobe;

namespace {

int neighbours(const core::LabelImage3D& m, int i, int j, int k)
{
    int n = 0;
    for (int dk = -1; dk <= 1; ++dk)
        for (int dj = -1; dj <= 1; ++dj)
            for (int di = -1; di <= 1; ++di)
                if ((di || dj || dk) && m.contains(i + di, j + dj, k + dk) && m.at(i + di, j + dj, k + dk))
                    ++n;
    return n;
}

using test::count;

core::ImageF wall_distance(const core::LabelImage3D& mask)
{
    core::LabelImage3D bg = mask;
    for (auto& v : bg.data)
        v = v ? 0 : 1;
    return seg::euclidean_distance(bg);
}

} // namespace

TEST(Thinning, SimplePointsByHand)
{
    core::LabelImage3D m(test::grid({7, 7, 7}, {1, 1, 1}), 0);
    m.at(3, 3, 3) = 1;
    EXPECT_FALSE(seg::is_simple_point(m, 3, 3, 3)); // an isolated voxel: removing it removes a part
    for (int i = 1; i < 6; ++i)
        m.at(i, 3, 3) = 1;
    EXPECT_TRUE(seg::is_simple_point(m, 1, 3, 3));  // a line's end
    EXPECT_FALSE(seg::is_simple_point(m, 3, 3, 3)); // a line's middle: removing it cuts the line
    core::LabelImage3D cube(test::grid({7, 7, 7}, {1, 1, 1}), 0);
    for (int k = 1; k < 6; ++k)
        for (int j = 1; j < 6; ++j)
            for (int i = 1; i < 6; ++i)
                cube.at(i, j, k) = 1;
    EXPECT_FALSE(seg::is_simple_point(cube, 3, 3, 3)); // interior: removing it makes a cavity
    EXPECT_TRUE(seg::is_simple_point(cube, 3, 3, 1));  // a face voxel
    EXPECT_TRUE(seg::is_simple_point(cube, 1, 1, 1));  // a corner
}

// A cylinder of radius 4 voxels along x thins to a single curve on its axis: every voxel within
// one voxel of the axis, no voxel with more than two neighbours, and about its length (the ends
// recede by up to the radius as the flat end faces are peeled).
TEST(Thinning, CylinderBecomesItsAxis)
{
    const auto g = test::grid({50, 15, 15}, {1, 1, 1});
    const auto mask = test::tube_mask(g, {{{5, 7, 7}, {44, 7, 7}, 4.0}});
    const auto skel = seg::thin(mask);
    const std::size_t n = count(skel);
    EXPECT_GE(n, 30u);
    EXPECT_LE(n, 50u);
    int ends = 0;
    for (int k = 0; k < 15; ++k)
        for (int j = 0; j < 15; ++j)
            for (int i = 0; i < 50; ++i)
                if (skel.at(i, j, k)) {
                    EXPECT_LE(std::abs(j - 7), 1);
                    EXPECT_LE(std::abs(k - 7), 1);
                    const int nb = neighbours(skel, i, j, k);
                    EXPECT_GE(nb, 1);
                    EXPECT_LE(nb, 2);
                    ends += nb == 1;
                }
    EXPECT_EQ(ends, 2);
}

// A ring (a torus: one tunnel) thins to a closed loop, and two separate blobs stay two parts:
// thinning deletes only simple points, which change no topology.
TEST(Thinning, KeepsTopology)
{
    const auto g = test::grid({40, 40, 12}, {1, 1, 1});
    std::vector<test::Tube> ring;
    const double pi = std::acos(-1.0);
    for (int s = 0; s < 24; ++s) {
        const double a0 = 2 * pi * s / 24, a1 = 2 * pi * (s + 1) / 24;
        ring.push_back({{20 + 12 * std::cos(a0), 20 + 12 * std::sin(a0), 6}, {20 + 12 * std::cos(a1), 20 + 12 * std::sin(a1), 6}, 3.0});
    }
    const auto skel = seg::thin(test::tube_mask(g, ring));
    std::size_t n = 0;
    for (int k = 0; k < 12; ++k)
        for (int j = 0; j < 40; ++j)
            for (int i = 0; i < 40; ++i)
                if (skel.at(i, j, k)) {
                    ++n;
                    EXPECT_EQ(neighbours(skel, i, j, k), 2); // a loop has no ends
                }
    EXPECT_GT(n, 50u); // about 2π·12 = 75 voxel steps, some diagonal
    EXPECT_LT(n, 100u);

    // Two balls stay two parts, each a voxel or two at its centre.
    const auto two = seg::thin(test::tube_mask(g, {{{5, 5, 6}, {5, 5, 6}, 3.0}, {{30, 30, 6}, {30, 30, 6}, 3.0}}));
    std::size_t near_a = 0, near_b = 0;
    for (int k = 0; k < 12; ++k)
        for (int j = 0; j < 40; ++j)
            for (int i = 0; i < 40; ++i)
                if (two.at(i, j, k)) {
                    const bool a = std::abs(i - 5) <= 1 && std::abs(j - 5) <= 1 && std::abs(k - 6) <= 1;
                    const bool b = std::abs(i - 30) <= 1 && std::abs(j - 30) <= 1 && std::abs(k - 6) <= 1;
                    EXPECT_TRUE(a || b) << i << "," << j << "," << k;
                    near_a += a;
                    near_b += b;
                }
    EXPECT_GE(near_a, 1u);
    EXPECT_GE(near_b, 1u);
    EXPECT_LE(near_a + near_b, 6u);
}

// A Y: a trunk (r = 3 mm, 30 mm) splitting into two branches (r = 2 mm, 25 mm). The graph has one
// branch point of degree 3 and three edges whose median radii are the tubes' to within a voxel
// (the radius is the distance to the background less half a voxel).
TEST(CentrelineGraph, YShapeGivesOneBranchPointWithRadii)
{
    const auto g = test::grid({60, 60, 24}, {1, 1, 1});
    const core::Vec3 root{30, 5, 12}, fork{30, 35, 12};
    const std::vector<test::Tube> y{{root, fork, 3.0}, {fork, {13, 53, 12}, 2.0}, {fork, {47, 53, 12}, 2.0}};
    const auto mask = test::tube_mask(g, y);
    const auto graph = seg::centreline_graph(seg::thin(mask), wall_distance(mask));
    EXPECT_TRUE(core::graph_problem(graph).empty()) << core::graph_problem(graph);
    ASSERT_EQ(graph.edges.size(), 3u);
    ASSERT_EQ(graph.nodes.size(), 4u);
    std::vector<int> degree(graph.nodes.size(), 0);
    for (const auto& e : graph.edges) {
        ++degree[std::size_t(e.from)];
        ++degree[std::size_t(e.to)];
    }
    EXPECT_EQ(std::count(degree.begin(), degree.end(), 3), 1);
    EXPECT_EQ(std::count(degree.begin(), degree.end(), 1), 3);
    std::vector<double> radii;
    for (const auto& e : graph.edges)
        radii.push_back(e.radius_mm);
    std::sort(radii.begin(), radii.end());
    EXPECT_NEAR(radii[0], 2.0, 1.0);
    EXPECT_NEAR(radii[1], 2.0, 1.0);
    EXPECT_NEAR(radii[2], 3.0, 1.0);
    // Edges run from their thicker end: the trunk from the branch point... or from the root end
    // (both are 3 mm); the branches from the branch point.
    for (const auto& e : graph.edges) {
        if (e.radius_mm < 2.6) {
            EXPECT_LT(core::distance(graph.nodes[std::size_t(e.from)].position, fork), 6.0);
        }
    }
}

// A tube (r = 4 mm) with a stub (r = 1.5 mm reaching 7 mm from the axis, 3 mm out of the tube) and
// a real side branch (r = 1.5 mm, 20 mm out): the raw skeleton has both side curves; pruning at
// 2 x the radius at the branch point (8 mm) removes the stub (about 5 mm from the axis after the
// thinning shortens its end) and keeps the branch, leaving one branch point with three edges.
TEST(CentrelineGraph, PrunesSpursButKeepsBranches)
{
    const auto g = test::grid({60, 36, 20}, {1, 1, 1});
    const std::vector<test::Tube> shape{{{5, 10, 10}, {54, 10, 10}, 4.0},
                                        {{18, 10, 10}, {18, 17, 10}, 1.5},
                                        {{40, 10, 10}, {40, 30, 10}, 1.5}};
    const auto mask = test::tube_mask(g, shape);
    const auto skel = seg::thin(mask);
    seg::CentrelineParams none;
    none.min_spur_mm = none.spur_radius_factor = none.junction_merge_factor = none.min_component_length_mm = 0;
    none.max_prune_passes = 0;
    const auto raw = seg::centreline_graph(skel, wall_distance(mask), none);
    seg::CentrelineParams p;
    p.spur_radius_factor = 2.0;
    seg::CentrelineStats st;
    const auto pruned = seg::centreline_graph(skel, wall_distance(mask), p, &st);
    EXPECT_EQ(raw.edges.size(), 5u);
    ASSERT_EQ(pruned.edges.size(), 3u);
    EXPECT_EQ(st.spurs_pruned, 1u);
    double longest_side = 0;
    for (const auto& e : pruned.edges)
        if (e.radius_mm < 2.5)
            longest_side = std::max(longest_side, e.length_mm);
    EXPECT_GT(longest_side, 12.0); // the real branch: 20 mm less the tube's radius and its tip
}

// Levels on a hand-made tree: root -> A (trunk); A -> B, C (level 2); B -> D, E (level 3); plus a
// 4 mm twig at C. With min_branch_mm = 10 the twig is not a branching of C (C's continuation keeps
// level 2, the twig gets 3); with 0 it is (both children of C are level 3).
TEST(BranchLevels, GenerationsFromTheRoot)
{
    core::CentrelineGraph g;
    auto node = [&](double x, double y) {
        g.nodes.push_back({{x, y, 0}, 1.0});
        return static_cast<std::int32_t>(g.nodes.size() - 1);
    };
    auto edge = [&](std::int32_t a, std::int32_t b) {
        core::CentrelineEdge e;
        // stored backwards on purpose: assign_branch_levels orients them from the root
        e.from = b;
        e.to = a;
        e.points = {g.nodes[std::size_t(b)].position, g.nodes[std::size_t(a)].position};
        e.point_radius = {1, 1};
        e.length_mm = core::distance(e.points[0], e.points[1]);
        e.radius_mm = 1;
        g.edges.push_back(e);
        return g.edges.size() - 1;
    };
    const auto r = node(0, 0), a = node(0, 30), b = node(-20, 50), c = node(20, 50), d = node(-35, 65),
               e = node(-5, 65), c2 = node(20, 75), twig = node(24, 53);
    const auto ea = edge(r, a), eb = edge(a, b), ec = edge(a, c), ed = edge(b, d), ee = edge(b, e), ec2 = edge(c, c2),
               et = edge(c, twig);
    core::CentrelineGraph h = g;
    seg::assign_branch_levels(g, r, 2, 10.0);
    EXPECT_EQ(g.edges[ea].level, 1);
    EXPECT_EQ(g.edges[eb].level, 2);
    EXPECT_EQ(g.edges[ec].level, 2);
    EXPECT_EQ(g.edges[ed].level, 3);
    EXPECT_EQ(g.edges[ee].level, 3);
    EXPECT_EQ(g.edges[ec2].level, 2); // continues past the twig
    EXPECT_EQ(g.edges[et].level, 3);
    for (const auto& ed_ : g.edges) {
        EXPECT_EQ(ed_.label, 2);
        EXPECT_EQ(ed_.points.front(), g.nodes[std::size_t(ed_.from)].position); // oriented from the root
    }
    EXPECT_EQ(g.edges[ea].from, r);
    seg::assign_branch_levels(h, r, 3, 0.0);
    EXPECT_EQ(h.edges[ec2].level, 3);
    EXPECT_EQ(h.edges[et].level, 3);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::assign_branch_levels(h, 99, 3), "root");
}

TEST(CentrelineGraph, EmptySkeletonAndBadGrids)
{
    const auto g = test::grid({10, 10, 10}, {1, 1, 1});
    const core::LabelImage3D empty(g, 0);
    EXPECT_EQ(count(seg::thin(empty)), 0u);
    EXPECT_TRUE(seg::centreline_graph(empty, core::ImageF(g, 1.f)).edges.empty());
    EXPECT_LOBE_ERROR(core::InvalidInputError,
                      seg::centreline_graph(empty, core::ImageF(test::grid({10, 10, 9}, {1, 1, 1}), 1.f)), "distance map");
}
