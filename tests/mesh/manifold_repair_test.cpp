// libmesh's private post-passes on a labelled tetrahedralisation (libmesh/src/detail), on
// hand-built cells where the answer is known. mesh_labels runs them on CGAL's output; the
// meshing tests check their effect there (tetrahedralize_test.cpp).
#include "detail/manifold_repair.h"

#include <gtest/gtest.h>

using namespace lobe;
using core::Vec3;

namespace {

// Cells with neighbours found from shared faces (-1 across a face no other cell has).
mesh::detail::LabelledCells make_cells(std::vector<Vec3> vertices, std::vector<std::array<std::int32_t, 4>> cells,
                                       std::vector<int> labels)
{
    mesh::detail::LabelledCells m;
    m.vertices = std::move(vertices);
    m.cells = std::move(cells);
    m.labels = std::move(labels);
    m.fixed.assign(m.cells.size(), 0);
    m.neighbours.assign(m.cells.size(), {-1, -1, -1, -1});
    for (std::size_t a = 0; a < m.cells.size(); ++a)
        for (std::size_t b = 0; b < m.cells.size(); ++b) {
            if (a == b)
                continue;
            for (std::size_t f = 0; f < 4; ++f) {
                int shared = 0;
                for (std::size_t i = 0; i < 4; ++i)
                    if (i != f)
                        for (auto w : m.cells[b])
                            shared += m.cells[a][i] == w;
                if (shared == 3)
                    m.neighbours[a][f] = static_cast<std::int32_t>(b);
            }
        }
    return m;
}

} // namespace

TEST(ManifoldRepair, TwoTetsSharingOnlyAnEdgeAreSeparated)
{
    // Tets (0,1,2,3) and (0,1,4,5) of one label share the edge 0-1 and nothing else: the
    // label's region is pinched along that edge, so both ends are bad vertices. The cheapest
    // fix drops the smaller tet to the outside, its only neighbour.
    auto m = make_cells({{0, 0, 0}, {0, 0, 1}, {1, 0, 0}, {0, 1, 0}, {-2, 0, 0}, {0, -2, 0}}, {{0, 1, 2, 3}, {0, 1, 4, 5}},
                        {1, 1});
    EXPECT_EQ(mesh::detail::count_non_manifold_vertices(m), 2);
    const auto s = mesh::detail::repair_manifold(m);
    EXPECT_EQ(s.bad_vertices_before, 2);
    EXPECT_EQ(s.bad_vertices_after, 0);
    EXPECT_EQ(s.relabelled, 1);
    EXPECT_EQ(s.removed, 1);
    EXPECT_EQ(m.labels[0], 0); // the first tet is the smaller (1/6 against 4/6)
    EXPECT_EQ(m.labels[1], 1);
    EXPECT_NEAR(s.volume, 1.0 / 6, 1e-12);
    EXPECT_EQ(mesh::detail::count_non_manifold_vertices(m), 0);
}

TEST(ManifoldRepair, FixedCellsNeverChange)
{
    // The same pinch with both tets fixed: no fix is allowed, the two vertices stay bad and are
    // reported.
    auto m = make_cells({{0, 0, 0}, {0, 0, 1}, {1, 0, 0}, {0, 1, 0}, {-2, 0, 0}, {0, -2, 0}}, {{0, 1, 2, 3}, {0, 1, 4, 5}},
                        {1, 1});
    m.fixed = {1, 1};
    const auto s = mesh::detail::repair_manifold(m);
    EXPECT_EQ(s.bad_vertices_after, 2);
    EXPECT_EQ(s.relabelled, 0);
    EXPECT_EQ(m.labels[0], 1);
    EXPECT_EQ(m.labels[1], 1);
}

TEST(PeelBoundarySlivers, RemovesAFlatCapOnly)
{
    // The corner tet (0,1,2,3) and on its slanted face a cap whose fourth vertex lies h above
    // the face's centroid: its smallest dihedral angle goes to 0 with h. Cap and corner are one
    // tissue, the cap's three other faces face the outside.
    auto build = [](double h) {
        const Vec3 n = Vec3{1, 1, 1} / std::sqrt(3.0);
        const Vec3 top = Vec3{1, 1, 1} / 3.0 + n * h;
        return make_cells({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, top}, {{0, 1, 2, 3}, {4, 1, 3, 2}}, {1, 1});
    };
    // h = 0.02: dihedral angles of 2.8 degrees along the face's edges (atan(h / 0.408)): peeled at 12.
    auto flat = build(0.02);
    const auto s = mesh::detail::peel_boundary_slivers(flat, 12);
    EXPECT_EQ(s.tets, 1);
    EXPECT_EQ(flat.labels[1], 0);
    EXPECT_EQ(flat.fixed[1], 1); // stays outside: a repair may not fill it back
    EXPECT_EQ(flat.labels[0], 1);
    // h = 0.4: a plump cap (44 degrees along those edges): kept.
    auto plump = build(0.4);
    EXPECT_EQ(mesh::detail::peel_boundary_slivers(plump, 12).tets, 0);
    EXPECT_EQ(plump.labels[1], 1);
    // The same flat cap buried under three more tets (to a point above it): no face on the
    // outside, so it is the exuder's business, not the peeler's: kept.
    const Vec3 n = Vec3{1, 1, 1} / std::sqrt(3.0);
    const Vec3 top = Vec3{1, 1, 1} / 3.0 + n * 0.02, apex = Vec3{1, 1, 1} / 3.0 + n * 1.0;
    auto buried = make_cells({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, top, apex},
                             {{0, 1, 2, 3}, {4, 1, 3, 2}, {5, 4, 3, 2}, {5, 4, 1, 2}, {5, 4, 1, 3}}, {1, 1, 1, 1, 1});
    EXPECT_EQ(mesh::detail::peel_boundary_slivers(buried, 12).tets, 0);
}
