#include "lobe/mesh/tetrahedralize.h"

#include "lobe/core/errors.h"
#include "lobe/mesh/quality.h"
#include "mesh/label_shapes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>

using namespace lobe;
using core::Vec3;

namespace {

const double kPi = std::acos(-1.0);

using Face = std::array<std::int32_t, 3>;

Face sorted_face(std::int32_t a, std::int32_t b, std::int32_t c)
{
    Face f{a, b, c};
    std::sort(f.begin(), f.end());
    return f;
}

// Every face with the labels of the tets on its sides (one entry per side).
std::map<Face, std::vector<int>> face_sides(const core::TetMesh& m)
{
    std::map<Face, std::vector<int>> faces;
    for (std::size_t t = 0; t < m.tets.size(); ++t) {
        const auto& q = m.tets[t];
        const int f[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
        for (const auto& i : f)
            faces[sorted_face(q[i[0]], q[i[1]], q[i[2]])].push_back(m.tet_labels[t]);
    }
    return faces;
}

double min_dihedral_deg(const core::TetMesh& m)
{
    double worst = 180;
    for (const auto& q : m.tets) {
        const auto a = mesh::dihedral_angles(m.vertices[q[0]], m.vertices[q[1]], m.vertices[q[2]], m.vertices[q[3]]);
        worst = std::min(worst, *std::min_element(a.begin(), a.end()) * 180 / kPi);
    }
    return worst;
}

double label_mesh_volume(const core::TetMesh& m, int label)
{
    double v = 0;
    for (std::size_t t = 0; t < m.tets.size(); ++t)
        if (m.tet_labels[t] == label)
            v += core::signed_volume(m, t);
    return v;
}

} // namespace

TEST(MeshLabels, SphereVolumeBoundaryAndQuality)
{
    // Sphere of radius 12 mm on a 32^3 grid of 0.9 mm voxels, placed off the origin, so that
    // spacing and origin are exercised (voxel centres inside the ball).
    const double spacing = 0.9, r = 12;
    auto img = test::empty_labels(32, spacing, {100, -50, 20});
    const Vec3 c{100 + 15.5 * spacing, -50 + 15.5 * spacing, 20 + 15.5 * spacing};
    test::paint_sphere(img, c, r, 1);
    mesh::MeshParams p;
    p.size = 2.5;
    p.threads = 1;
    const auto t0 = std::chrono::steady_clock::now();
    const auto res = mesh::mesh_labels(img, p);
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const auto& m = res.mesh;
    ASSERT_EQ(core::mesh_problem(m), "");
    const double exact = 4.0 / 3 * kPi * r * r * r;
    const double vol = label_mesh_volume(m, 1);
    std::printf("sphere: %zu tets %zu vertices, volume %.1f (exact %.1f, voxels %.1f), min dihedral %.2f, %.2f s\n",
                m.tets.size(), m.vertices.size(), vol, exact, res.tissues[0].label_volume, min_dihedral_deg(m), secs);
    // Boundary: every vertex on a boundary face lies within a voxel of the sphere.
    double hd = 0;
    for (const auto& [f, sides] : face_sides(m))
        if (sides.size() == 1)
            for (auto v : f)
                hd = std::max(hd, std::abs(core::distance(m.vertices[v], c) - r));
    std::printf("boundary max |d - r| = %.3f mm\n", hd);
    EXPECT_LT(hd, spacing);
    EXPECT_NEAR(vol, exact, 0.04 * exact);
    EXPECT_GT(min_dihedral_deg(m), 5.0);
}
