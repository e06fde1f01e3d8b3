#include "lobe/mesh/tetrahedralize.h"

#include "lobe/core/errors.h"
#include "lobe/mesh/quality.h"
#include "lobe/mesh/surface.h"
#include "mesh/label_shapes.h"
#include "mesh/surface_distance.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <tuple>

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

TEST(MeshLabels, CubeJoinedToSphereConformsAtTheInterface)
{
    // The thesis's two-tissue scene: a cube (label 1, x in [6, 26]) and a ball of radius 8 centred
    // on its +x face (label 2 where outside the cube). Their interface is the disc x = 26,
    // radius 8 (area 64 pi), within the voxelisation (the disc's rim is stair-stepped).
    auto img = test::empty_labels(40);
    test::paint_sphere(img, {26, 19.5, 19.5}, 8, 2);
    test::paint_box(img, {6, 9.5, 9.5}, {26, 29.5, 29.5}, 1);
    mesh::MeshParams p;
    p.size = 2.5;
    p.threads = 1;
    const auto res = mesh::mesh_labels(img, p);
    const auto& m = res.mesh;
    ASSERT_EQ(core::mesh_problem(m), "");
    // Conforming: every face is shared by at most two tets; a face seen from one label only
    // once must be on the outer boundary (no hanging face inside), and interface faces have a
    // tet of each label.
    double interface_area = 0;
    int boundary_faces = 0;
    for (const auto& [f, sides] : face_sides(m)) {
        ASSERT_LE(sides.size(), 2u);
        if (sides.size() == 1)
            ++boundary_faces;
        if (sides.size() == 2 && sides[0] != sides[1]) {
            const Vec3& a = m.vertices[f[0]];
            interface_area += core::norm(core::cross(m.vertices[f[1]] - a, m.vertices[f[2]] - a)) / 2;
            // An interface face lies on the plane x = 26 (the cube's face), to within a voxel.
            for (auto v : f)
                EXPECT_NEAR(m.vertices[v].x, 26.5, 1.0);
        }
    }
    std::printf("interface area %.1f mm^2 (disc %.1f), %d boundary faces\n", interface_area, 64 * kPi, boundary_faces);
    EXPECT_NEAR(interface_area, 64 * kPi, 0.15 * 64 * kPi);
    // No duplicated vertices across tissues: no two vertices closer than 1e-6 mm.
    auto v = m.vertices;
    std::sort(v.begin(), v.end(), [](const Vec3& a, const Vec3& b) { return a.x < b.x; });
    int duplicates = 0;
    for (std::size_t i = 0; i < v.size(); ++i)
        for (std::size_t j = i + 1; j < v.size() && v[j].x - v[i].x < 1e-6; ++j)
            duplicates += core::distance(v[i], v[j]) < 1e-6;
    EXPECT_EQ(duplicates, 0);
    // Volumes: each tissue within 5% of its label volume (the surface follows the voxel
    // boundary to a fraction of a voxel; the ball part has ~1000 voxels of ~3000 mm^3 surface).
    ASSERT_EQ(res.tissues.size(), 2u);
    for (const auto& t : res.tissues) {
        std::printf("tissue %d: mesh %.1f label %.1f mm^3, %lld tets\n", t.label, t.mesh_volume, t.label_volume,
                    static_cast<long long>(t.tets));
        EXPECT_NEAR(t.mesh_volume, t.label_volume, 0.05 * t.label_volume);
        EXPECT_EQ(t.components, 1);
        EXPECT_EQ(t.components_meshed, 1);
    }
    EXPECT_GT(min_dihedral_deg(m), 5.0);
}

TEST(MeshLabels, EverySeparatePieceIsMeshed)
{
    // One label in three pieces: a ball of radius 9, one of radius 5 and a small one of radius
    // 3 (113 voxels, just above the 100-voxel bar), far apart.
    auto img = test::empty_labels(48);
    test::paint_sphere(img, {12, 12, 12}, 9, 1);
    test::paint_sphere(img, {36, 36, 36}, 5, 1);
    test::paint_sphere(img, {36, 10, 38}, 3, 1);
    mesh::MeshParams p;
    p.size = 2.5;
    p.threads = 1;
    const auto res = mesh::mesh_labels(img, p);
    ASSERT_EQ(core::mesh_problem(res.mesh), "");
    ASSERT_EQ(res.components.size(), 3u);
    for (const auto& c : res.components) {
        std::printf("piece: %lld voxels, label %.1f mesh %.1f mm^3, %lld tets\n", static_cast<long long>(c.voxels),
                    c.label_volume, c.mesh_volume, static_cast<long long>(c.tets));
        EXPECT_TRUE(c.meshed);
        // Small pieces have relatively more surface, where facets cut corners: 15% for the
        // radius-3 piece, which is 2.5 voxels across its stair-steps.
        EXPECT_NEAR(c.mesh_volume, c.label_volume, 0.15 * c.label_volume);
    }
    EXPECT_EQ(res.tissues[0].components_meshed, 3);
}

TEST(MeshLabels, ParallelModeGivesAValidMesh)
{
    // Two threads (CGAL's TBB mode): the mesh differs run to run but must be as valid and as
    // accurate as the serial one (same 4% volume bound as the serial sphere test).
    auto img = test::empty_labels(32);
    test::paint_sphere(img, {15.5, 15.5, 15.5}, 12, 1);
    mesh::MeshParams p;
    p.size = 2.0;
    p.threads = 2;
    const auto res = mesh::mesh_labels(img, p);
    ASSERT_EQ(core::mesh_problem(res.mesh), "");
    const double exact = 4.0 / 3 * kPi * 12 * 12 * 12;
    EXPECT_NEAR(label_mesh_volume(res.mesh, 1), exact, 0.04 * exact);
    EXPECT_EQ(res.components.size(), 1u);
    EXPECT_TRUE(res.components[0].meshed);
}

TEST(MeshLabels, DirectionMatrixPlacesTheMeshInPhysicalSpace)
{
    // A box of label 1 at index [4, 11] x [4, 19] x [4, 7] in a grid whose axes are permuted and
    // flipped (x' = -z, y' = x, z' = y: determinant +1 after a flip of one axis gives -1, which
    // reverses orientation); the mesh's bounding box must be the box's physical extent, to
    // within half a voxel each side (the surface lies between voxel centres).
    core::ImageGeometry g;
    g.size = {16, 24, 12};
    g.spacing = {1.0, 0.5, 2.0};
    g.origin = {5, 6, 7};
    g.direction = {0, 0, -1, 1, 0, 0, 0, 1, 0}; // columns: axis i -> +y, axis j -> +z, axis k -> -x
    core::LabelImage3D img(g, 0);
    for (int k = 4; k <= 7; ++k)
        for (int j = 4; j <= 19; ++j)
            for (int i = 4; i <= 11; ++i)
                img.at(i, j, k) = 1;
    mesh::MeshParams p;
    p.size = 2.0;
    p.threads = 1;
    const auto res = mesh::mesh_labels(img, p);
    ASSERT_EQ(core::mesh_problem(res.mesh), "");
    Vec3 lo{1e9, 1e9, 1e9}, hi{-1e9, -1e9, -1e9};
    for (const auto& v : res.mesh.vertices)
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], v[a]);
            hi[a] = std::max(hi[a], v[a]);
        }
    // Index box corners (3.5..11.5, 3.5..19.5, 3.5..7.5) in physical space.
    const Vec3 a = img.index_to_physical(Vec3{3.5, 3.5, 3.5}), b = img.index_to_physical(Vec3{11.5, 19.5, 7.5});
    for (int ax = 0; ax < 3; ++ax) {
        EXPECT_NEAR(lo[ax], std::min(a[ax], b[ax]), 0.5 * 2.0) << "axis " << ax; // half the largest voxel
        EXPECT_NEAR(hi[ax], std::max(a[ax], b[ax]), 0.5 * 2.0) << "axis " << ax;
    }
    const double box = 8 * 1.0 * 16 * 0.5 * 4 * 2.0;
    // CGAL does not protect sharp edges on an image domain: the cube's 12 edges are chamfered by
    // about a voxel (12 x 8 mm x (1 mm)^2 / 2 = 48 mm^3, 9% of this 8 mm cube; measured 8%).
    EXPECT_NEAR(res.tissues[0].mesh_volume, box, 0.12 * box);
}

TEST(MeshLabels, BorderSpeckEmptyAndOversizedInputs)
{
    // Empty label volume: refused.
    auto img = test::empty_labels(16);
    EXPECT_THROW(mesh::mesh_labels(img), core::InvalidInputError);
    // A single voxel of label 1: dropped, then nothing is left: refused.
    img.at(8, 8, 8) = 1;
    EXPECT_THROW(mesh::mesh_labels(img), core::InvalidInputError);
    // A ball touching the border (cut by the x = 0 face) plus a speck of label 4 inside it:
    // padded, closed, the speck relabelled 1 and reported.
    auto b = test::empty_labels(24);
    test::paint_sphere(b, {3, 12, 12}, 8, 1);
    b.at(5, 12, 12) = 4;
    mesh::MeshParams p;
    p.size = 2.0;
    p.threads = 1;
    const auto res = mesh::mesh_labels(b, p);
    EXPECT_TRUE(res.padded);
    ASSERT_EQ(core::mesh_problem(res.mesh), "");
    bool speck_reported = false;
    for (const auto& w : res.warnings)
        speck_reported = speck_reported || w.find("speck of label 4") != std::string::npos;
    EXPECT_TRUE(speck_reported);
    for (auto l : res.mesh.tet_labels)
        EXPECT_EQ(l, 1);
    // Closed: the cut face at x = -0.5 is meshed, so the volume matches the voxels (5%).
    const double voxels = static_cast<double>(test::count_label(b, 1) + 1); // + the relabelled speck
    EXPECT_NEAR(label_mesh_volume(res.mesh, 1), voxels, 0.05 * voxels);
    double min_x = 1e9;
    for (const auto& v : res.mesh.vertices)
        min_x = std::min(min_x, v.x);
    EXPECT_NEAR(min_x, -0.5, 0.25); // the surface between the border voxels and the padding
    // Too large a mesh: refused before meshing.
    p.size = 0.05;
    EXPECT_THROW(mesh::mesh_labels(b, p), core::InvalidInputError);
}

TEST(MeshLabels, RegionOfInterestIsFinerInsideAndGradedOutside)
{
    // A 40 mm cube of liver; ROI a ball of radius 5 around one corner region. Elements inside
    // must be smaller than those far away: mean edge inside < 0.6 x mean edge beyond 15 mm (the
    // fine size is a third of the coarse one; grading 1.5 reaches the coarse size after ~8 mm).
    auto img = test::empty_labels(44);
    test::paint_box(img, {2, 2, 2}, {41, 41, 41}, 1);
    mesh::MeshParams p;
    p.size = 4.0;
    p.threads = 1;
    p.roi.kind = mesh::RegionOfInterest::Kind::Spheres;
    p.roi.centres = {{12, 12, 12}};
    p.roi.radius = 5;
    const auto res = mesh::mesh_labels(img, p);
    const auto& m = res.mesh;
    ASSERT_EQ(core::mesh_problem(m), "");
    double in_sum = 0, out_sum = 0;
    int in_n = 0, out_n = 0;
    for (const auto& q : m.tets) {
        const Vec3 cen = (m.vertices[q[0]] + m.vertices[q[1]] + m.vertices[q[2]] + m.vertices[q[3]]) / 4;
        double e = 0;
        for (int i = 0; i < 4; ++i)
            for (int j = i + 1; j < 4; ++j)
                e += core::distance(m.vertices[q[i]], m.vertices[q[j]]) / 6;
        const double d = core::distance(cen, {12, 12, 12});
        if (d < 5)
            in_sum += e, ++in_n;
        else if (d > 20)
            out_sum += e, ++out_n;
    }
    ASSERT_GT(in_n, 0);
    ASSERT_GT(out_n, 0);
    std::printf("ROI: mean edge inside %.2f mm (%d tets), beyond 20 mm %.2f mm (%d tets), total %zu\n",
                in_sum / in_n, in_n, out_sum / out_n, out_n, m.tets.size());
    EXPECT_LT(in_sum / in_n, 0.6 * (out_sum / out_n));
}

TEST(MeshLabels, PiecesTouchingAlongAnEdgeGiveManifoldSurfaces)
{
    // Two 9-voxel blocks of one label that touch only along a voxel edge (the line x = y = 11.5):
    // the phantom's defect in small (two sides of its fissure, or liver around a thin vessel,
    // meeting along an edge). CGAL fills the contact with thin tets, so without the repair
    // the tissue surface and the outer one are non-manifold along that line; with it, every
    // surface must be closed, manifold, oriented and free of self-intersections, the repair
    // reported, and the volume it moved small: the contact is a line, so only slivers along it
    // change (measured 2.1 mm^3; bound 1% of the 2916 mm^3 of label).
    auto img = test::empty_labels(24);
    test::paint_box(img, {3, 3, 3}, {11, 11, 20}, 1);
    test::paint_box(img, {12, 12, 3}, {20, 20, 20}, 1);
    mesh::MeshParams p;
    p.size = 3;
    p.threads = 1;
    auto defects = [](const core::TetMesh& m) {
        std::int64_t n = 0;
        for (const auto& s : mesh::tissue_surfaces(m)) {
            const auto c = mesh::check_surface(s.surface);
            n += c.non_manifold_edges + c.non_manifold_vertices;
        }
        return n;
    };
    p.repair_manifold = false;
    const auto raw = mesh::mesh_labels(img, p);
    const auto raw_defects = defects(raw.mesh);
    std::printf("without repair: %lld non-manifold edges and vertices\n", static_cast<long long>(raw_defects));
    EXPECT_GT(raw_defects, 0); // the defect is reproduced: the check below means something

    p.repair_manifold = true;
    const auto res = mesh::mesh_labels(img, p);
    ASSERT_EQ(core::mesh_problem(res.mesh), "");
    const auto& r = res.manifold_repair;
    std::printf("repair: %lld bad vertices -> %lld, %lld tets relabelled (%lld removed), %.2f mm^3\n",
                static_cast<long long>(r.bad_vertices_before), static_cast<long long>(r.bad_vertices_after),
                static_cast<long long>(r.tets_relabelled), static_cast<long long>(r.tets_removed), r.volume);
    EXPECT_GT(r.bad_vertices_before, 0);
    EXPECT_EQ(r.bad_vertices_after, 0);
    for (const auto& s : mesh::tissue_surfaces(res.mesh)) {
        const auto c = mesh::check_surface(s.surface);
        EXPECT_TRUE(c.ok()) << "label " << s.label << ": " << mesh::describe(c);
    }
    const double label_volume = 2 * 9.0 * 9 * 18;
    EXPECT_LT(r.volume, 0.01 * label_volume);
    bool reported = false;
    for (const auto& w : res.warnings)
        reported = reported || w.find("non-manifold") != std::string::npos;
    EXPECT_TRUE(reported);
    EXPECT_NEAR(res.tissues[0].mesh_volume, label_volume, 0.1 * label_volume);
}

namespace {

// Quality and accuracy of a one-tissue mesh of an analytic shape, printed for the record.
struct ShapeCheck {
    double volume = 0, min_dihedral = 0, max_radius_edge = 0, below_03 = 0;
    test::HausdorffResult hausdorff;
};

ShapeCheck check_shape(const char* name, const mesh::MeshResult& res, const core::LabelImage3D& img, double exact,
                       double secs)
{
    const auto& m = res.mesh;
    ShapeCheck c;
    c.volume = label_mesh_volume(m, 1);
    const auto q = mesh::evaluate_quality(m);
    c.min_dihedral = q.all.min_dihedral_deg;
    c.max_radius_edge = q.all.max_radius_edge_ratio;
    const auto& comb = q.all.measures[static_cast<int>(mesh::Measure::Combined)];
    c.below_03 = double(comb.bands[0]) / double(comb.count);
    c.hausdorff = test::hausdorff_to_labels(m, img, 2 * img.spacing[2]);
    std::printf("%s: %zu tets in %.2f s, volume %.1f mm^3 (exact %.1f, %+.2f%%; voxels %.1f), Hausdorff to the label "
                "surface %.3f / %.3f mm, dihedral >= %.1f deg, max B %.2f, combined < 0.3: %.1f%%\n",
                name, m.tets.size(), secs, c.volume, exact, 100 * (c.volume / exact - 1), res.tissues[0].label_volume,
                c.hausdorff.mesh_to_labels, c.hausdorff.labels_to_mesh, c.min_dihedral, c.max_radius_edge,
                100 * c.below_03);
    return c;
}

} // namespace

TEST(MeshLabels, FourFifthsSphere)
{
    // The thesis's 4/5 sphere (Fig 6.16-6.18): a ball of radius 10 mm with a fifth removed, the
    // wedge of azimuth [0, 72) degrees about the vertical axis through its centre; exact volume
    // 4/5 x 4/3 pi r^3 = 3351 mm^3. It has what the plain sphere lacks: two flat faces, a concave
    // edge (the axis) and two convex half-circle rims. 1 mm voxels, the centre between voxel
    // centres.
    const double r = 10;
    const Vec3 c{13.5, 13.5, 13.5};
    auto img = test::empty_labels(28);
    for (int k = 0; k < 28; ++k)
        for (int j = 0; j < 28; ++j)
            for (int i = 0; i < 28; ++i) {
                const Vec3 d = Vec3{double(i), double(j), double(k)} - c;
                const double phi = std::atan2(d.y, d.x) * 180 / kPi;
                if (core::norm(d) <= r && !(phi >= 0 && phi < 72))
                    img.at(i, j, k) = 1;
            }
    mesh::MeshParams p;
    p.size = 2.5;
    p.threads = 1;
    const auto t0 = std::chrono::steady_clock::now();
    const auto res = mesh::mesh_labels(img, p);
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ASSERT_EQ(core::mesh_problem(res.mesh), "");
    const double exact = 0.8 * 4.0 / 3 * kPi * r * r * r;
    const auto s = check_shape("4/5 sphere", res, img, exact, secs);
    // Volume (measured -0.7%): the voxels hold the shape to 0.2%; CGAL does not keep sharp
    // edges on an image domain, so it cuts the convex rims and fills the concave axis by up to
    // a voxel; the plain sphere's 4% covers both.
    EXPECT_NEAR(s.volume, exact, 0.04 * exact);
    // Boundary within a voxel of the label surface, both ways (the Hausdorff bound;
    // measured 0.37 mm from the mesh, 0.80 mm from the label surface, at the cut rims).
    EXPECT_LT(s.hausdorff.max(), 1.0);
    // Quality: the exuder and the sliver pass aim at 12 degrees and reach it here (serial runs repeat
    // exactly); the bound is 10. About 16% of the tets rate below 0.3 on the combined
    // measure (the phantom's 13%): bounded at 20%, the combined measure is not optimised.
    EXPECT_GT(s.min_dihedral, 10.0);
    EXPECT_LT(s.below_03, 0.2);
}

TEST(MeshLabels, ParaboloidIntrusionIntoACuboid)
{
    // The thesis's paraboloid intrusion pressed into a cuboid (Fig 6.19): a 24 x 24 x 15 mm
    // box (1 x 1 x 1.5 mm voxels, anisotropic on purpose) whose top face is pushed in by a
    // paraboloid of rim radius R = 8 mm and depth d = 7.5 mm, z = top - d (1 - rho^2 / R^2).
    // Exact volume: box - pi R^2 d / 2 = 8640 - 754 = 7886 mm^3.
    core::ImageGeometry g;
    g.size = {30, 30, 14};
    g.spacing = {1.0, 1.0, 1.5};
    core::LabelImage3D img(g, 0);
    const Vec3 lo{2.5, 2.5, 1.5 * 1.5}, hi{26.5, 26.5, 1.5 * 11.5};
    const double R = 8, depth = 7.5, xc = 14.5, yc = 14.5;
    for (int k = 0; k < g.size[2]; ++k)
        for (int j = 0; j < g.size[1]; ++j)
            for (int i = 0; i < g.size[0]; ++i) {
                const Vec3 q = img.index_to_physical(i, j, k);
                if (q.x < lo.x || q.x > hi.x || q.y < lo.y || q.y > hi.y || q.z < lo.z || q.z > hi.z)
                    continue;
                const double rho2 = (q.x - xc) * (q.x - xc) + (q.y - yc) * (q.y - yc);
                if (rho2 < R * R && q.z > hi.z - depth * (1 - rho2 / (R * R)))
                    continue;
                img.at(i, j, k) = 1;
            }
    mesh::MeshParams p;
    p.size = 2.5;
    p.threads = 1;
    const auto t0 = std::chrono::steady_clock::now();
    const auto res = mesh::mesh_labels(img, p);
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ASSERT_EQ(core::mesh_problem(res.mesh), "");
    const double exact = (hi.x - lo.x) * (hi.y - lo.y) * (hi.z - lo.z) - kPi * R * R * depth / 2;
    const auto s = check_shape("paraboloid in cuboid", res, img, exact, secs);
    // The same bounds as the 4/5 sphere, for the same reasons; the Hausdorff bound is the
    // smallest spacing (measured 0.47 / 0.90 mm: the box's edges and corners are chamfered).
    EXPECT_NEAR(s.volume, exact, 0.04 * exact); // measured -0.8%
    EXPECT_LT(s.hausdorff.max(), 1.0);
    EXPECT_GT(s.min_dihedral, 10.0);
    EXPECT_LT(s.below_03, 0.2);
}

TEST(MeshLabels, ThinTissueKeepsItsVolumeWithItsOwnBoundaryTolerance)
{
    // A vessel-like tube (label 2, radius 2.5 mm along x) through a block of liver (label 1) on
    // thick slices (1 x 1 x 2 mm), sized as lmesh is asked for the phantom (liver 8 mm, vessel
    // 2.5 mm, curvature factor 2). The boundary facets are chords: a tube loses about
    // (4/3) delta / R of its cross-section to a tolerance delta, so the curvature factor's
    // 1 mm (cf^2 x 2 mm / 8, 40% of the radius) cuts it short, the default 0.2 x its size
    // (0.5 mm) less, and 0.2 mm (8% of the radius) keeps it within 10% of its label volume (the
    // issue's bound; measured 0.69, 0.82, 0.91: the 2 mm slices cost a few percent more than
    // the chords) while the block stays within 3%.
    core::ImageGeometry g;
    g.size = {40, 28, 14};
    g.spacing = {1.0, 1.0, 2.0};
    core::LabelImage3D img(g, 0);
    for (int k = 1; k < 13; ++k)
        for (int j = 1; j < 27; ++j)
            for (int i = 1; i < 39; ++i) {
                const Vec3 q = img.index_to_physical(i, j, k);
                const double dy = q.y - 13.5, dz = q.z - 13.0;
                img.at(i, j, k) = dy * dy + dz * dz <= 2.5 * 2.5 ? 2 : 1;
            }
    mesh::MeshParams p;
    p.size = 8;
    p.curvature_factor = 2;
    p.threads = 1;
    auto run = [&](double per_size, double own) {
        p.distance_per_size = per_size;
        p.tissue_sizes = {{2, 2.5, own}};
        const auto r = mesh::mesh_labels(img, p);
        EXPECT_EQ(core::mesh_problem(r.mesh), "");
        std::printf("tube tolerance %.2f mm: %zu tets, tube %.3f, block %.3f of the label volume\n",
                    r.tissues[1].facet_distance, r.mesh.tets.size(), r.tissues[1].mesh_volume / r.tissues[1].label_volume,
                    r.tissues[0].mesh_volume / r.tissues[0].label_volume);
        return r;
    };
    const auto coarse = run(1, 0), by_size = run(0.2, 0), fine = run(0.2, 0.2);
    EXPECT_NEAR(coarse.tissues[1].facet_distance, 1.0, 1e-12);
    EXPECT_NEAR(by_size.tissues[1].facet_distance, 0.5, 1e-12);
    EXPECT_NEAR(fine.tissues[1].facet_distance, 0.2, 1e-12);
    auto ratio = [](const mesh::MeshResult& r, std::size_t t) { return r.tissues[t].mesh_volume / r.tissues[t].label_volume; };
    EXPECT_LT(ratio(coarse, 1), ratio(by_size, 1));
    EXPECT_LT(ratio(by_size, 1), ratio(fine, 1));
    EXPECT_NEAR(ratio(fine, 1), 1.0, 0.10);
    EXPECT_NEAR(ratio(fine, 0), 1.0, 0.03);
}

TEST(MeshLabels, SpatialOrderRenumbersWithoutChangingTheMesh)
{
    // The same serial run with and without the Hilbert renumbering: the same vertices, tets
    // and labels up to the numbering, and neighbours close in memory (the point of it).
    auto img = test::empty_labels(40, 1.0, {0, 0, 0});
    test::paint_sphere(img, {20, 20, 20}, 16, 1);
    mesh::MeshParams p;
    p.size = 3.5;
    p.threads = 1;
    const auto ordered = mesh::mesh_labels(img, p).mesh;
    p.spatial_order = false;
    const auto plain = mesh::mesh_labels(img, p).mesh;
    ASSERT_EQ(core::mesh_problem(ordered), "");
    ASSERT_EQ(ordered.vertices.size(), plain.vertices.size());
    ASSERT_EQ(ordered.tets.size(), plain.tets.size());
    // Each tet as its sorted corner positions: the two meshes hold the same set (serial runs
    // repeat exactly, so the positions match bit for bit).
    auto corners = [](const core::TetMesh& m) {
        std::vector<std::array<double, 13>> out;
        for (std::size_t t = 0; t < m.tets.size(); ++t) {
            std::array<Vec3, 4> v{};
            for (int i = 0; i < 4; ++i)
                v[static_cast<std::size_t>(i)] = m.vertices[static_cast<std::size_t>(m.tets[t][static_cast<std::size_t>(i)])];
            std::sort(v.begin(), v.end(), [](const Vec3& a, const Vec3& b) {
                return std::tie(a.x, a.y, a.z) < std::tie(b.x, b.y, b.z);
            });
            std::array<double, 13> k{};
            for (std::size_t i = 0; i < 4; ++i) {
                k[3 * i] = v[i].x;
                k[3 * i + 1] = v[i].y;
                k[3 * i + 2] = v[i].z;
            }
            k[12] = m.tet_labels[t];
            out.push_back(k);
        }
        std::sort(out.begin(), out.end());
        return out;
    };
    EXPECT_TRUE(corners(ordered) == corners(plain));
    EXPECT_NEAR(label_mesh_volume(ordered, 1), label_mesh_volume(plain, 1), 1e-9 * label_mesh_volume(plain, 1));
    // Locality: the median index distance between a tet's vertices. CGAL's order scatters
    // them over a large part of the mesh; along a Hilbert curve neighbours sit within a few
    // percent of it (measured: see the printout).
    auto median_span = [](const core::TetMesh& m) {
        std::vector<std::int32_t> span;
        for (const auto& q : m.tets)
            span.push_back(*std::max_element(q.begin(), q.end()) - *std::min_element(q.begin(), q.end()));
        std::nth_element(span.begin(), span.begin() + static_cast<std::ptrdiff_t>(span.size() / 2), span.end());
        return static_cast<double>(span[span.size() / 2]);
    };
    const double so = median_span(ordered), sp = median_span(plain);
    std::printf("median index span of a tet: %.0f ordered, %.0f in CGAL's order (%zu vertices)\n", so, sp,
                ordered.vertices.size());
    EXPECT_LT(so, 0.25 * sp);
}
