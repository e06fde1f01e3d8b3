#include "lobe/core/geometry.h"
#include "lobe/core/tet_mesh.h"
#include "lobe/core/tri_mesh.h"

#include <gtest/gtest.h>

using namespace lobe::core;

namespace {
TetMesh unit_tet()
{
    TetMesh m;
    m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    m.tets = {{0, 1, 2, 3}};
    m.tet_labels = {1};
    return m;
}
} // namespace

TEST(TetMesh, PositiveOrientationHasPositiveVolume)
{
    auto m = unit_tet();
    EXPECT_NEAR(signed_volume(m, 0), 1.0 / 6.0, 1e-15); // the corner tet of the unit cube
    EXPECT_EQ(mesh_problem(m), "");
    std::swap(m.tets[0][0], m.tets[0][1]); // an odd permutation flips the sign
    EXPECT_NEAR(signed_volume(m, 0), -1.0 / 6.0, 1e-15);
    EXPECT_NE(mesh_problem(m).find("not positively oriented"), std::string::npos);
}

TEST(TetMesh, MalformedMeshesAreNamed)
{
    auto m = unit_tet();
    m.tet_labels.clear();
    EXPECT_NE(mesh_problem(m).find("tet labels"), std::string::npos);
    m = unit_tet();
    m.tets[0][3] = 4;
    EXPECT_NE(mesh_problem(m).find("outside [0, 4)"), std::string::npos);
    m = unit_tet();
    m.tets[0][3] = 0;
    EXPECT_NE(mesh_problem(m).find("repeats a vertex"), std::string::npos);
}

TEST(TriMesh, MalformedMeshesAreNamed)
{
    TriMesh t;
    t.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    t.triangles = {{0, 1, 2}};
    EXPECT_EQ(mesh_problem(t), "");
    t.triangles = {{0, 1, -1}};
    EXPECT_NE(mesh_problem(t).find("vertex index -1"), std::string::npos);
    t.triangles = {{0, 1, 1}};
    EXPECT_NE(mesh_problem(t).find("repeats"), std::string::npos);
    EXPECT_NEAR(norm(cross(Vec3{1, 0, 0}, Vec3{0, 1, 0}) - Vec3{0, 0, 1}), 0.0, 1e-15);
}

TEST(Geometry, ClosestPointOnTriangleInEachRegion)
{
    // Right triangle in the z = 0 plane; one query per Voronoi region, each with its answer
    // known by construction (exact in floating point: every coordinate is a small dyadic).
    const Vec3 a{0, 0, 0}, b{4, 0, 0}, c{0, 4, 0};
    auto near = [](const Vec3& p, const Vec3& q) { return distance(p, q) < 1e-12; };
    EXPECT_TRUE(near(closest_on_triangle({1, 1, 3}, a, b, c), {1, 1, 0}));    // above the face
    EXPECT_TRUE(near(closest_on_triangle({-1, -1, 2}, a, b, c), a));          // beyond vertex a
    EXPECT_TRUE(near(closest_on_triangle({6, -1, 0}, a, b, c), b));           // beyond vertex b
    EXPECT_TRUE(near(closest_on_triangle({-1, 7, 0}, a, b, c), c));           // beyond vertex c
    EXPECT_TRUE(near(closest_on_triangle({2, -3, 1}, a, b, c), {2, 0, 0}));   // beyond edge ab
    EXPECT_TRUE(near(closest_on_triangle({-2, 1, -1}, a, b, c), {0, 1, 0}));  // beyond edge ac
    EXPECT_TRUE(near(closest_on_triangle({3, 3, 0}, a, b, c), {2, 2, 0}));    // beyond edge bc
    // A degenerate (collinear) triangle still gives a point on it, never NaN.
    const Vec3 q = closest_on_triangle({1, 1, 0}, a, b, {2, 0, 0});
    EXPECT_TRUE(near(q, {1, 0, 0}));
}
