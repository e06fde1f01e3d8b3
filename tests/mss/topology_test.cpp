// Local mesh edits: an edited model must equal the model rebuilt from its mesh, and splits,
// merges and separations must conserve mass, volume and momentum.
#include "lobe/mss/block_mesh.h"
#include "lobe/mss/topology.h"

#include "lobe/core/errors.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <set>

using namespace lobe;

namespace {

mss::Model block(std::array<int, 3> cells, mss::ModelParams p = {})
{
    mss::BlockMeshParams bp;
    bp.cells = cells;
    bp.size = {10.0 * cells[0], 10.0 * cells[1], 10.0 * cells[2]};
    core::TetMesh mesh = mss::make_block_mesh(bp);
    mss::label_sphere(mesh, {5, 5, 5}, 6, 4); // a stiff corner: tissues blend on shared edges
    mss::Model m(mesh, p);
    m.fix_box({-1, -1, -1}, {100, 100, 1e-6});
    return m;
}

double rel(double a, double b) { return std::abs(a - b) / std::max({std::abs(a), std::abs(b), 1e-300}); }

// Everything the model derives from its mesh, compared with a model built afresh from the same
// mesh (same vertex numbering, same fixed nodes). Tolerance 1e-9 relative: both sum the same
// terms, in a different order.
void expect_same_as_rebuilt(const mss::Model& edited)
{
    mss::Model fresh(edited.mesh(), edited.params());
    for (std::size_t i = 0; i < edited.node_count(); ++i)
        fresh.set_fixed(i, edited.is_fixed(i));
    ASSERT_EQ(edited.node_count(), fresh.node_count());
    ASSERT_EQ(edited.tet_count(), fresh.tet_count());
    for (std::size_t i = 0; i < edited.node_count(); ++i) {
        ASSERT_LT(rel(edited.masses()[i], fresh.masses()[i]), 1e-9) << "mass of node " << i;
        ASSERT_EQ(edited.inverse_masses()[i] == 0, fresh.inverse_masses()[i] == 0) << "node " << i;
    }
    auto springs = [](const mss::Model& m) {
        std::map<std::pair<int, int>, std::array<double, 3>> out;
        const auto& s = m.springs();
        for (std::size_t k = 0; k < s.size(); ++k)
            out[{std::min(s.a[k], s.b[k]), std::max(s.a[k], s.b[k])}] = {s.rest_length[k], s.stiffness[k], s.damping[k]};
        return out;
    };
    const auto se = springs(edited), sf = springs(fresh);
    ASSERT_EQ(se.size(), edited.springs().size()) << "a spring is listed twice";
    ASSERT_EQ(se.size(), sf.size());
    for (const auto& [edge, v] : sf) {
        const auto it = se.find(edge);
        ASSERT_NE(it, se.end()) << "missing spring " << edge.first << "-" << edge.second;
        for (int c = 0; c < 3; ++c)
            ASSERT_LT(rel(it->second[std::size_t(c)], v[std::size_t(c)]), 1e-9) << edge.first << "-" << edge.second << " term " << c;
    }
    // Boundary faces with their orientation: rotate each so that its smallest vertex comes first.
    auto faces = [](const mss::Model& m) {
        std::set<std::array<std::int32_t, 3>> out;
        for (auto f : m.surface_faces()) {
            while (f[0] != std::min({f[0], f[1], f[2]}))
                f = {f[1], f[2], f[0]};
            out.insert(f);
        }
        return out;
    };
    EXPECT_EQ(faces(edited), faces(fresh));
    ASSERT_EQ(edited.surface_face_tets().size(), edited.surface_faces().size());
    for (std::size_t f = 0; f < edited.surface_faces().size(); ++f) {
        const auto& q = edited.mesh().tets[std::size_t(edited.surface_face_tets()[f])];
        for (auto v : edited.surface_faces()[f])
            ASSERT_NE(std::find(q.begin(), q.end(), v), q.end()) << "face " << f << " names a tet without it";
    }
    EXPECT_EQ(edited.surface_nodes(), fresh.surface_nodes());
    EXPECT_LT(rel(edited.critical_time_step(), fresh.critical_time_step()), 1e-12);
    EXPECT_LT(rel(edited.gershgorin_time_step(), fresh.gershgorin_time_step()), 1e-12);
    EXPECT_LT(rel(edited.min_edge_length(), fresh.min_edge_length()), 1e-12);
    for (std::size_t t = 0; t < edited.tet_count(); ++t) {
        ASSERT_LT(rel(edited.tet_rest_volumes()[t], fresh.tet_rest_volumes()[t]), 1e-12);
        ASSERT_LT(rel(edited.volume_stiffness()[t], fresh.volume_stiffness()[t]), 1e-9);
    }
}

mss::State moving_state(const mss::Model& m, unsigned seed)
{
    mss::State s = m.rest_state();
    std::mt19937 rng(seed);
    std::normal_distribution<double> g(0, 1);
    for (std::size_t i = 0; i < s.x.size(); ++i) {
        s.x[i] += 2e-4 * g(rng); // 0.2 mm: deformed but not inverted (edges are 10-17 mm)
        s.v[i] = 0.01 * g(rng);
    }
    return s;
}

std::array<double, 3> momentum(const mss::Model& m, const mss::State& s)
{
    std::array<double, 3> p{};
    for (std::size_t i = 0; i < m.node_count(); ++i)
        for (std::size_t c = 0; c < 3; ++c)
            p[c] += m.masses()[i] * s.v[3 * i + c];
    return p;
}

double current_volume(const mss::Model& m, const mss::State& s)
{
    double v = 0;
    for (const auto& q : m.mesh().tets)
        v += core::signed_volume(s.position_mm(std::size_t(q[0])), s.position_mm(std::size_t(q[1])),
                                 s.position_mm(std::size_t(q[2])), s.position_mm(std::size_t(q[3])));
    return v;
}

} // namespace

TEST(MssTopology, SplitsKeepTheModelEqualToARebuiltOneAndConserveMassVolumeMomentum)
{
    // Every stiffness law (and the FEM, whose springs only damp) after several splits: interior
    // and boundary edges, edges between tissues, a split of a new edge, at uneven t.
    for (auto law : {mss::Stiffness::Havp, mss::Stiffness::VanGelder, mss::Stiffness::Constant, mss::Stiffness::InverseLength}) {
        mss::ModelParams p;
        p.stiffness = law;
        mss::Model m = block({3, 2, 2}, p);
        mss::State s = moving_state(m, 7);
        const double mass = m.total_mass(), rest = m.rest_volume(), vol = current_volume(m, s);
        const auto p0 = momentum(m, s);
        m.enable_editing();
        const auto& sp = m.springs();
        const std::int32_t first = mss::split_edge(m, s, sp.a[0], sp.b[0], 0.3);
        const std::size_t mid = m.springs().size() / 2;
        mss::split_edge(m, s, m.springs().a[mid], m.springs().b[mid], 0.61);
        for (std::size_t k = 0; k < m.springs().size(); ++k) // an edge of the first new vertex
            if (m.springs().a[k] == first || m.springs().b[k] == first) {
                mss::split_edge(m, s, m.springs().a[k], m.springs().b[k], 0.5);
                break;
            }
        for (int k = 0; k < 5; ++k) {
            const std::size_t j = (37 * std::size_t(k) + 11) % m.springs().size();
            mss::split_edge(m, s, m.springs().a[j], m.springs().b[j], 0.25 + 0.1 * k);
        }
        SCOPED_TRACE(mss::stiffness_name(law));
        expect_same_as_rebuilt(m);
        EXPECT_TRUE(core::mesh_problem(m.mesh()).empty());
        // Halves of a tet partition it in the rest shape and in the current state; the new
        // vertex takes exactly the momentum its parents lose (masses tV/4 and (1-t)V/4 move).
        EXPECT_LT(rel(m.total_mass(), mass), 1e-12);
        EXPECT_LT(rel(m.rest_volume(), rest), 1e-12);
        EXPECT_LT(rel(current_volume(m, s), vol), 1e-12);
        const auto p1 = momentum(m, s);
        for (std::size_t c = 0; c < 3; ++c)
            EXPECT_NEAR(p1[c], p0[c], 1e-12 * m.total_mass()) << c;
        EXPECT_EQ(s.x.size(), 3 * m.node_count());
    }
}

TEST(MssTopology, FemFormulationFollowsTheEdits)
{
    mss::ModelParams p;
    p.formulation = mss::Formulation::CorotationalFem;
    mss::Model m = block({2, 2, 1}, p);
    mss::State s = m.rest_state();
    m.enable_editing();
    mss::split_edge(m, s, m.springs().a[3], m.springs().b[3], 0.5);
    expect_same_as_rebuilt(m);
    // The rest state of an edited FEM model is still at rest: zero force on every node.
    std::vector<double> f;
    m.forces(m.rest_state(), f);
    for (double x : f)
        ASSERT_NEAR(x, 0, 1e-12);
}

TEST(MssTopology, MergeUndoesASplit)
{
    mss::Model m = block({2, 2, 2});
    mss::State s = moving_state(m, 3);
    const auto n = m.node_count(), t = m.tet_count(), springs = m.springs().size();
    const double mass = m.total_mass();
    const auto p0 = momentum(m, s);
    m.enable_editing();
    const auto a = m.springs().a[10], b = m.springs().b[10];
    const auto mid = mss::split_edge(m, s, a, b, 0.5);
    EXPECT_EQ(m.node_count(), n + 1);
    EXPECT_GT(m.tet_count(), t);
    ASSERT_TRUE(mss::merge_split(m, s, mid, a, b));
    EXPECT_EQ(m.node_count(), n);
    EXPECT_EQ(m.tet_count(), t);
    EXPECT_EQ(m.springs().size(), springs);
    expect_same_as_rebuilt(m);
    EXPECT_LT(rel(m.total_mass(), mass), 1e-12);
    const auto p1 = momentum(m, s);
    for (std::size_t c = 0; c < 3; ++c)
        EXPECT_NEAR(p1[c], p0[c], 1e-12 * mass) << c;
    // A vertex of the original mesh is no split midpoint: refused, nothing changed.
    EXPECT_FALSE(mss::merge_split(m, s, a, b, m.springs().b[0]));
    EXPECT_EQ(m.node_count(), n);
}

TEST(MssTopology, MergeAfterAnInterveningRemovalRenumbers)
{
    // Two splits, then the first midpoint merged: the last vertex (the second midpoint) takes its
    // index, and the second merge must use the new index the first reported.
    mss::Model m = block({2, 1, 1});
    mss::State s = m.rest_state();
    m.enable_editing();
    const auto a1 = m.springs().a[0], b1 = m.springs().b[0];
    const auto m1 = mss::split_edge(m, s, a1, b1, 0.5);
    // An edge of the far cell (x >= 10 mm), away from every tet the first split touched.
    std::size_t k = 0;
    auto far = [&](std::int32_t v) { return m.mesh().vertices[std::size_t(v)].x > 15; };
    while (!(far(m.springs().a[k]) && far(m.springs().b[k])))
        ++k;
    const auto a2 = m.springs().a[k], b2 = m.springs().b[k];
    auto m2 = mss::split_edge(m, s, a2, b2, 0.5);
    std::vector<std::pair<std::int32_t, std::int32_t>> moved;
    ASSERT_TRUE(mss::merge_split(m, s, m1, a1, b1, &moved));
    ASSERT_EQ(moved.size(), 1u);
    EXPECT_EQ(moved[0], std::make_pair(m2, m1));
    m2 = moved[0].second;
    ASSERT_TRUE(mss::merge_split(m, s, m2, a2, b2));
    expect_same_as_rebuilt(m);
    mss::Model original = block({2, 1, 1});
    EXPECT_EQ(m.node_count(), original.node_count());
    EXPECT_EQ(m.tet_count(), original.tet_count());
}

TEST(MssTopology, SeparatingTheVerticesOfACutPlaneMakesTwoPieces)
{
    // Two 10 mm cells side by side; the faces on the plane x = 10 are declared cut. Separating
    // its 4 vertices gives two pieces that share no vertex, each with its own new boundary on the
    // plane (the plane's faces are counted twice), and the mass is unchanged.
    mss::Model m = block({2, 1, 1});
    mss::State s = moving_state(m, 5);
    const double mass = m.total_mass();
    const auto p0 = momentum(m, s);
    const auto faces_before = m.surface_faces().size();
    m.enable_editing();
    std::vector<std::uint64_t> cut;
    int plane_faces = 0;
    for (const auto& q : m.mesh().tets)
        for (int skip = 0; skip < 4; ++skip) {
            std::array<std::int32_t, 3> f{};
            int n = 0;
            for (int i = 0; i < 4; ++i)
                if (i != skip)
                    f[std::size_t(n++)] = q[std::size_t(i)];
            if (std::all_of(f.begin(), f.end(), [&](std::int32_t v) { return std::abs(m.mesh().vertices[std::size_t(v)].x - 10) < 1e-9; })) {
                cut.push_back(mss::face_id(f[0], f[1], f[2]));
                ++plane_faces;
            }
        }
    std::sort(cut.begin(), cut.end());
    cut.erase(std::unique(cut.begin(), cut.end()), cut.end());
    ASSERT_EQ(cut.size(), 2u) << "a 10 mm square of the Kuhn split is two triangles";
    std::vector<std::int32_t> plane;
    for (std::size_t i = 0; i < m.node_count(); ++i)
        if (std::abs(m.mesh().vertices[i].x - 10) < 1e-9)
            plane.push_back(std::int32_t(i));
    ASSERT_EQ(plane.size(), 4u);
    int copies = 0;
    for (auto v : plane)
        copies += int(mss::separate_vertex(m, s, v, cut).size());
    EXPECT_EQ(copies, 4);
    EXPECT_EQ(m.surface_faces().size(), faces_before + 4);
    expect_same_as_rebuilt(m);
    EXPECT_LT(rel(m.total_mass(), mass), 1e-12);
    const auto p1 = momentum(m, s);
    for (std::size_t c = 0; c < 3; ++c)
        EXPECT_NEAR(p1[c], p0[c], 1e-12 * mass) << c;
    // No vertex is shared between a tet left of the plane and one right of it.
    std::set<std::int32_t> left, right;
    for (const auto& q : m.mesh().tets) {
        double cx = 0;
        for (auto v : q)
            cx += m.mesh().vertices[std::size_t(v)].x / 4;
        for (auto v : q)
            (cx < 10 ? left : right).insert(v);
    }
    for (auto v : left)
        EXPECT_EQ(right.count(v), 0u) << "vertex " << v << " joins the pieces";
}

TEST(MssTopology, MalformedEditsAreRefusedAndChangeNothing)
{
    mss::Model m = block({2, 1, 1});
    mss::State s = m.rest_state();
    m.enable_editing();
    const auto n = m.node_count(), t = m.tet_count();
    const auto q0 = m.mesh().tets[0];
    auto refused = [&](const mss::MeshEdit& e, const std::string& why) {
        try {
            m.apply(e, s);
            ADD_FAILURE() << "accepted an edit that " << why;
        } catch (const core::InvalidInputError& err) {
            SCOPED_TRACE(err.what());
        }
        EXPECT_EQ(m.node_count(), n);
        EXPECT_EQ(m.tet_count(), t);
        EXPECT_EQ(s.x.size(), 3 * n);
        expect_same_as_rebuilt(m);
    };
    mss::MeshEdit e;
    e.removed_tets = m.vertex_tets(0);
    refused(e, "leaves vertex 0 without a tet");
    e = {};
    e.removed_tets = {0};
    e.added_tets = {{q0[1], q0[0], q0[2], q0[3]}};
    e.added_labels = {1};
    refused(e, "adds an inverted tet");
    e.added_tets = {q0};
    e.added_labels = {9};
    refused(e, "uses a label without material");
    e.added_labels = {1};
    e.removed_tets = {0, 0};
    refused(e, "removes a tet twice");
    e = {};
    e.new_vertices = {{0, 1, 0.5}};
    refused(e, "adds a vertex in no tet");
    e = {};
    e.removed_vertices = {0};
    refused(e, "removes a vertex still in a tet");
    EXPECT_THROW(mss::split_edge(m, s, 0, std::int32_t(n) - 1, 0.5), core::InvalidInputError); // opposite corners
    EXPECT_THROW(mss::split_edge(m, s, m.springs().a[0], m.springs().b[0], 1.0), core::InvalidInputError);
}
