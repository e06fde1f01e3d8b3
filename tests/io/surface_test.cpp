// Surface export/import through assimp: round trip per format (positions, topology, orientation),
// atomic writes (including glTF's .bin), and refusals.

#include "lobe/io/surface.h"

#include "common/expect_error.h"
#include "common/test_data.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <initializer_list>
#include <map>
#include <sstream>
#include <string>
#include <vector>

using lobe::test::expect_error;

namespace {

namespace fs = std::filesystem;
using lobe::core::InvalidInputError;
using lobe::core::IoError;
using lobe::core::TriMesh;
using lobe::core::Vec3;


// An icosphere (icosahedron subdivided `levels` times), outward counter-clockwise triangles,
// centred away from the origin so that a float32 round trip has something to round.
TriMesh icosphere(int levels, double radius, const Vec3& centre)
{
    const double t = (1 + std::sqrt(5.0)) / 2;
    TriMesh m;
    m.vertices = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                  {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    m.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                   {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                   {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    for (auto& v : m.vertices)
        v = lobe::core::normalized(v);
    for (int l = 0; l < levels; ++l) {
        std::map<std::pair<int, int>, int> mid;
        const auto midpoint = [&](int a, int b) {
            const auto key = std::minmax(a, b);
            const auto it = mid.find(key);
            if (it != mid.end())
                return it->second;
            m.vertices.push_back(lobe::core::normalized(m.vertices[std::size_t(a)] + m.vertices[std::size_t(b)]));
            return mid[key] = int(m.vertices.size() - 1);
        };
        std::vector<std::array<std::int32_t, 3>> next;
        for (const auto& f : m.triangles) {
            const int a = midpoint(f[0], f[1]), b = midpoint(f[1], f[2]), c = midpoint(f[2], f[0]);
            next.push_back({f[0], a, c});
            next.push_back({f[1], b, a});
            next.push_back({f[2], c, b});
            next.push_back({a, b, c});
        }
        m.triangles = next;
    }
    for (auto& v : m.vertices)
        v = centre + radius * v;
    return m;
}

TriMesh test_sphere() { return icosphere(2, 25.0, {10.3, -20.7, 35.1}); }

// Signed volume of a closed surface, summed about its vertex centroid: the value does not depend
// on where the centre is, but rounding error then scales with the radius, not with |centre|.
double signed_volume(const TriMesh& m)
{
    Vec3 c;
    for (const auto& v : m.vertices)
        c += v;
    c /= double(m.vertices.size());
    double vol = 0;
    for (const auto& f : m.triangles) {
        const Vec3 a = m.vertices[std::size_t(f[0])] - c, b = m.vertices[std::size_t(f[1])] - c,
                   d = m.vertices[std::size_t(f[2])] - c;
        vol += dot(a, cross(b, d));
    }
    return vol / 6;
}



void check_round_trip(const std::string& file_name, const std::vector<std::string>& expected_files)
{
    const fs::path dir = lobe::test::scratch_dir();
    const fs::path p = dir / file_name;
    const TriMesh mesh = test_sphere();
    const double volume = signed_volume(mesh);
    ASSERT_GT(volume, 0) << "the test sphere must be outward oriented";

    lobe::io::write_surface(p, mesh);
    EXPECT_EQ(lobe::test::list_dir(dir), expected_files) << "nothing but the file (and its sidecar) is left";
    const TriMesh back = lobe::io::read_surface(p);

    ASSERT_EQ(back.triangles.size(), mesh.triangles.size());
    // Identical positions are joined on reading, so even STL (one vertex triple per triangle)
    // gives back one vertex per original vertex.
    EXPECT_EQ(back.vertices.size(), mesh.vertices.size());
    // Topology: corner k of triangle t maps to one read vertex per original vertex, consistently.
    std::map<std::int32_t, std::int32_t> to_read;
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
        for (std::size_t k = 0; k < 3; ++k) {
            const auto o = mesh.triangles[t][k], r = back.triangles[t][k];
            const auto [it, inserted] = to_read.emplace(o, r);
            EXPECT_EQ(it->second, r) << "triangle " << t << " corner " << k;
            // assimp holds coordinates as float32: each is rounded by at most 2^-24 of its size
            // (6e-8), so 1e-6 of the position's norm is a safe bound for every format.
            const Vec3 &a = mesh.vertices[std::size_t(o)], &b = back.vertices[std::size_t(r)];
            EXPECT_LE(lobe::core::distance(a, b), 1e-6 * lobe::core::norm(a)) << "triangle " << t << " corner " << k;
        }
    // Orientation: a flipped winding would flip the sign. Rounding moves each vertex by
    // < 6e-8 * 60 mm = 4e-6 mm; the volume changes by at most area * that, i.e. a relative
    // 3 * 4e-6 / 25 = 5e-7 for this sphere, well inside 1e-5.
    const double back_volume = signed_volume(back);
    EXPECT_GT(back_volume, 0);
    EXPECT_NEAR(back_volume, volume, 1e-5 * volume);
}

TEST(SurfaceIo, StlRoundTrip) { check_round_trip("sphere.stl", {"sphere.stl"}); }
TEST(SurfaceIo, ObjRoundTrip) { check_round_trip("sphere.obj", {"sphere.obj"}); }
TEST(SurfaceIo, PlyRoundTrip) { check_round_trip("sphere.ply", {"sphere.ply"}); }
TEST(SurfaceIo, GltfRoundTrip) { check_round_trip("sphere.gltf", {"sphere.bin", "sphere.gltf"}); }
TEST(SurfaceIo, GlbRoundTrip) { check_round_trip("sphere.glb", {"sphere.glb"}); }
TEST(SurfaceIo, UpperCaseExtensionRoundTrip) { check_round_trip("SPHERE.STL", {"SPHERE.STL"}); }

TEST(SurfaceIo, GltfNamesItsBufferByTheFinalFileName)
{
    const fs::path dir = lobe::test::scratch_dir();
    lobe::io::write_surface(dir / "liver.gltf", test_sphere());
    const std::string json = lobe::test::read_file(dir / "liver.gltf");
    // The buffer was written in a temporary folder under the final name, so the URI is relative
    // and final: moving the pair elsewhere keeps it readable.
    EXPECT_NE(json.find("\"liver.bin\""), std::string::npos) << json.substr(0, 2000);
    EXPECT_EQ(json.find(".tmp"), std::string::npos);
    EXPECT_EQ(json.find(dir.string()), std::string::npos);
}

TEST(SurfaceIo, OverwritesAtomically)
{
    const fs::path dir = lobe::test::scratch_dir();
    const fs::path p = dir / "s.ply";
    lobe::io::write_surface(p, icosphere(0, 1.0, {}));
    lobe::io::write_surface(p, test_sphere());
    EXPECT_EQ(lobe::io::read_surface(p).triangles.size(), 320u); // 20 * 4^2
    EXPECT_EQ(lobe::test::list_dir(dir), std::vector<std::string>{"s.ply"});
}

TEST(SurfaceIo, RefusesUnknownExtensionBeforeWriting)
{
    const fs::path dir = lobe::test::scratch_dir();
    EXPECT_LOBE_ERROR(InvalidInputError, lobe::io::write_surface(dir / "s.vtk", test_sphere()),
                      (dir / "s.vtk").string(), "unknown surface format '.vtk'", ".stl, .obj, .ply, .gltf or .glb");
    EXPECT_LOBE_ERROR(InvalidInputError, lobe::io::write_surface(dir / "noext", test_sphere()), "unknown surface format ''");
    EXPECT_TRUE(lobe::test::list_dir(dir).empty());
}

TEST(SurfaceIo, RefusesMalformedMeshBeforeWriting)
{
    const fs::path dir = lobe::test::scratch_dir();
    TriMesh bad = test_sphere();
    bad.triangles[7][2] = 500;
    EXPECT_LOBE_ERROR(InvalidInputError, lobe::io::write_surface(dir / "s.stl", bad), (dir / "s.stl").string(),
                      "triangle 7 has vertex index 500 outside [0, 162)");
    bad = test_sphere();
    bad.triangles[0][1] = bad.triangles[0][0];
    EXPECT_LOBE_ERROR(InvalidInputError, lobe::io::write_surface(dir / "s.gltf", bad), "triangle 0 repeats a vertex");
    bad = test_sphere();
    bad.vertices[3].z = std::nan("");
    EXPECT_LOBE_ERROR(InvalidInputError, lobe::io::write_surface(dir / "s.obj", bad), "vertex 3 has a non-finite coordinate");
    EXPECT_LOBE_ERROR(InvalidInputError, lobe::io::write_surface(dir / "s.ply", TriMesh{}), "has no triangles");
    EXPECT_TRUE(lobe::test::list_dir(dir).empty());
    EXPECT_LOBE_ERROR(IoError, lobe::io::write_surface(dir / "missing" / "s.stl", test_sphere()), "does not exist");
}

TEST(SurfaceIo, ReadRefusesMissingAndUnreadableFiles)
{
    const fs::path dir = lobe::test::scratch_dir();
    EXPECT_LOBE_ERROR(IoError, lobe::io::read_surface(dir / "absent.stl"), (dir / "absent.stl").string(), "no such file");
    EXPECT_LOBE_ERROR(IoError, lobe::io::read_surface(dir), "is a directory");
    std::ofstream(dir / "junk.stl") << "not a mesh";
    EXPECT_LOBE_ERROR(IoError, lobe::io::read_surface(dir / "junk.stl"), (dir / "junk.stl").string(), "assimp cannot read it");
    // A valid OBJ with points and lines only: a file, but no surface.
    std::ofstream(dir / "lines.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\nl 2 3\n";
    EXPECT_LOBE_ERROR(lobe::core::Error, lobe::io::read_surface(dir / "lines.obj"), (dir / "lines.obj").string());
}

} // namespace
