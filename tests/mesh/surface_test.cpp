#include "lobe/mesh/surface.h"

#include "lobe/core/errors.h"
#include "lobe/mesh/tetrahedralize.h"
#include "mesh/label_shapes.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace lobe;
using core::Vec3;

namespace {

const double kPi = std::acos(-1.0);

core::TetMesh sphere_mesh(double r = 10)
{
    auto img = test::empty_labels(28);
    test::paint_sphere(img, {13.5, 13.5, 13.5}, r, 1);
    mesh::MeshParams p;
    p.size = 2.0;
    p.threads = 1;
    return mesh::mesh_labels(img, p).mesh;
}

double tet_volume(const core::TetMesh& m, int label)
{
    double v = 0;
    for (std::size_t t = 0; t < m.tets.size(); ++t)
        if (label == 0 || m.tet_labels[t] == label)
            v += core::signed_volume(m, t);
    return v;
}

// A closed tetrahedron surface, outward, shifted by o.
core::TriMesh tetra_surface(const Vec3& o, double s = 1)
{
    core::TriMesh m;
    m.vertices = {o, o + Vec3{s, 0, 0}, o + Vec3{0, s, 0}, o + Vec3{0, 0, s}};
    m.triangles = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    return m;
}

core::TriMesh merge(const core::TriMesh& a, const core::TriMesh& b)
{
    core::TriMesh m = a;
    const auto n = static_cast<std::int32_t>(a.vertices.size());
    m.vertices.insert(m.vertices.end(), b.vertices.begin(), b.vertices.end());
    for (auto t : b.triangles)
        m.triangles.push_back({t[0] + n, t[1] + n, t[2] + n});
    return m;
}

} // namespace

TEST(TissueSurfaces, SphereBoundaryIsClosedAndEnclosesTheTetVolume)
{
    const auto m = sphere_mesh();
    const auto s = mesh::tissue_surfaces(m);
    ASSERT_EQ(s.size(), 2u); // outer (0) and tissue 1, the same faces
    for (const auto& ts : s) {
        const auto c = mesh::check_surface(ts.surface);
        EXPECT_TRUE(c.ok()) << mesh::describe(c);
        EXPECT_EQ(c.components, 1);
        // The divergence theorem: the surface encloses exactly the tets' volume (rounding).
        EXPECT_NEAR(c.volume, tet_volume(m, 0), 1e-9 * c.volume);
    }
}

TEST(TissueSurfaces, TwoTissuesShareTheirInterface)
{
    auto img = test::empty_labels(36);
    test::paint_box(img, {5, 5, 5}, {18, 30, 30}, 1);
    test::paint_box(img, {18.5, 10, 10}, {28, 25, 25}, 2);
    mesh::MeshParams p;
    p.size = 2.5;
    p.threads = 1;
    const auto m = mesh::mesh_labels(img, p).mesh;
    const auto s = mesh::tissue_surfaces(m);
    ASSERT_EQ(s.size(), 3u);
    double area[3]{};
    for (int i = 0; i < 3; ++i) {
        const auto c = mesh::check_surface(s[static_cast<std::size_t>(i)].surface);
        EXPECT_TRUE(c.ok()) << "label " << s[static_cast<std::size_t>(i)].label << ": " << mesh::describe(c);
        EXPECT_NEAR(c.volume, tet_volume(m, s[static_cast<std::size_t>(i)].label), 1e-9 * c.volume);
        area[i] = c.area;
    }
    // Interface faces are in both tissue surfaces and not in the outer one: A1 + A2 - A0 = 2 x
    // interface area, the 15 x 15 mm contact square (to a voxel of stair-step at its rim).
    const double interface = (area[1] + area[2] - area[0]) / 2;
    EXPECT_NEAR(interface, 16.0 * 16.0, 0.15 * 256);
}

TEST(TaubinSmooth, SmoothsWithoutShrinking)
{
    // A voxel-stepped sphere surface (the tet boundary follows the labels' stair steps) plus
    // radial noise; Taubin must remove the noise and keep the volume within 1% (a plain
    // Laplacian with the same 20 steps of 0.5 loses several percent on this mesh).
    const auto m = sphere_mesh();
    const auto clean = mesh::tissue_surfaces(m)[1].surface;
    auto surf = clean;
    const Vec3 c{13.5, 13.5, 13.5};
    std::uint32_t seed = 7;
    for (auto& v : surf.vertices) {
        seed = seed * 1664525u + 1013904223u;
        const double n = ((seed >> 8) / double(1 << 24) - 0.5) * 0.6; // +-0.3 mm
        v = c + (v - c) * (1 + n / core::distance(v, c));
    }
    auto rms_dev = [&](const core::TriMesh& s) {
        double mean = 0, sq = 0;
        for (const auto& v : s.vertices)
            mean += core::distance(v, c);
        mean /= double(s.vertices.size());
        for (const auto& v : s.vertices)
            sq += std::pow(core::distance(v, c) - mean, 2);
        return std::sqrt(sq / double(s.vertices.size()));
    };
    auto rms_between = [](const core::TriMesh& a, const core::TriMesh& b) {
        double sq = 0;
        for (std::size_t i = 0; i < a.vertices.size(); ++i)
            sq += std::pow(core::distance(a.vertices[i], b.vertices[i]), 2);
        return std::sqrt(sq / double(a.vertices.size()));
    };
    const auto smooth = mesh::taubin_smooth(surf), smooth_clean = mesh::taubin_smooth(clean);
    const double v0 = mesh::check_surface(surf).volume, v1 = mesh::check_surface(smooth).volume;
    // The filter is linear in the positions, so smooth(noisy) - smooth(clean) is the filtered
    // noise: a low-pass filter keeps little of white noise (measured 0.07 of 0.17 mm).
    const double noise = rms_between(surf, clean), left = rms_between(smooth, smooth_clean);
    std::printf("radial rms %.3f (clean %.3f) -> %.3f mm, noise %.3f -> %.3f mm, volume %.1f -> %.1f\n", rms_dev(surf),
                rms_dev(clean), rms_dev(smooth), noise, left, v0, v1);
    EXPECT_LT(left, 0.5 * noise);
    // Smoothed, the noisy surface is rounder than the clean one was: the noise is gone and
    // some of the stair steps with it.
    EXPECT_LT(rms_dev(smooth), rms_dev(clean));
    EXPECT_NEAR(v1, v0, 0.01 * v0);
    // The plain Laplacian (20 steps of lambda = 0.5, no mu) shrinks it: the contrast that
    // makes the bound above meaningful.
    std::vector<std::vector<std::int32_t>> nb(surf.vertices.size());
    for (const auto& t : surf.triangles)
        for (int i = 0; i < 3; ++i)
            nb[static_cast<std::size_t>(t[i])].push_back(t[(i + 1) % 3]);
    core::TriMesh lap = surf;
    for (int it = 0; it < 20; ++it) {
        auto next = lap.vertices;
        for (std::size_t i = 0; i < next.size(); ++i) {
            Vec3 avg;
            for (auto j : nb[i])
                avg += lap.vertices[static_cast<std::size_t>(j)];
            next[i] += 0.5 * (avg / double(nb[i].size()) - lap.vertices[i]);
        }
        lap.vertices = next;
    }
    const double v2 = mesh::check_surface(lap).volume;
    std::printf("plain Laplacian volume %.1f\n", v2);
    EXPECT_LT(v2, 0.97 * v0);
    EXPECT_THROW(mesh::taubin_smooth(surf, {10, 0.5, -0.4}), core::InvalidInputError); // mu > -lambda
}

TEST(RemeshSurface, ReachesTheTargetEdgeLength)
{
    const auto surf = mesh::tissue_surfaces(sphere_mesh())[1].surface;
    const auto r = mesh::remesh_surface(surf, 1.2);
    double sum = 0;
    int n = 0;
    for (const auto& t : r.triangles)
        for (int i = 0; i < 3; ++i, ++n)
            sum += core::distance(r.vertices[static_cast<std::size_t>(t[i])], r.vertices[static_cast<std::size_t>(t[(i + 1) % 3])]);
    // Isotropic remeshing splits edges above 4/3 target and collapses below 4/5: the mean lands
    // within 20% of the target.
    EXPECT_NEAR(sum / n, 1.2, 0.2 * 1.2);
    const auto c = mesh::check_surface(r);
    EXPECT_TRUE(c.closed() && c.manifold() && c.oriented()) << mesh::describe(c);
    EXPECT_NEAR(c.volume, mesh::check_surface(surf).volume, 0.03 * c.volume);
}

TEST(CheckSurface, FindsEachDefect)
{
    const auto t = tetra_surface({0, 0, 0});
    auto c = mesh::check_surface(t);
    EXPECT_TRUE(c.ok());
    EXPECT_NEAR(c.volume, 1.0 / 6, 1e-15);
    // Open: one triangle removed leaves 3 boundary edges.
    auto open = t;
    open.triangles.pop_back();
    EXPECT_EQ(mesh::check_surface(open).boundary_edges, 3);
    // One triangle flipped: its 3 edges are traversed twice in the same direction.
    auto flipped = t;
    std::swap(flipped.triangles[0][1], flipped.triangles[0][2]);
    EXPECT_EQ(mesh::check_surface(flipped).inconsistent_edges, 3);
    // Inward: all flipped: consistent but negative volume.
    auto inward = t;
    for (auto& f : inward.triangles)
        std::swap(f[1], f[2]);
    c = mesh::check_surface(inward);
    EXPECT_FALSE(c.oriented());
    EXPECT_EQ(c.inconsistent_edges, 0);
    // Two tetrahedra sharing one vertex: a non-manifold vertex.
    // (the second is the first mirrored through the origin, its corner welded onto vertex 0).
    auto pinched = merge(t, tetra_surface({0, 0, 0}, -1));
    for (auto& f : pinched.triangles)
        for (auto& v : f)
            if (v == 4)
                v = 0;
    c = mesh::check_surface(pinched);
    EXPECT_EQ(c.non_manifold_vertices, 1);
    // Two overlapping tetrahedra: self-intersections.
    c = mesh::check_surface(merge(t, tetra_surface({0.2, 0.2, 0.2})));
    EXPECT_GT(c.self_intersections, 0);
    EXPECT_FALSE(c.ok());
}
