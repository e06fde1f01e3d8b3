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
