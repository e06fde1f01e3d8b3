// The HDF5 pipeline container: round trips, provenance, XDMF sidecar, compression, atomicity, and
// every malformed file the reader must refuse (fabricated with HDF5's C API).

#include "lobe/io/hdf5.h"

#include "common/expect_error.h"
#include "common/test_data.h"

#include <gtest/gtest.h>
#include <hdf5.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

using lobe::test::expect_error;

namespace {

namespace fs = std::filesystem;
using lobe::core::InvalidInputError;
using lobe::core::IoError;
using lobe::core::Vec3;
using namespace lobe::io;

// ---- helpers ------------------------------------------------------------------------------------


// A direction matrix rotated 30 degrees about (1, 2, 3): columns are unit and orthogonal but
// every entry is non-trivial, so an axis swap or transposition would show.
lobe::core::ImageGeometry oblique_geometry(int nx, int ny, int nz)
{
    lobe::core::ImageGeometry g;
    g.size = {nx, ny, nz};
    g.spacing = {0.703125, 0.8125, 2.5};
    g.origin = {-120.25, 35.5, 1001.125};
    const double n = std::sqrt(14.0), x = 1 / n, y = 2 / n, z = 3 / n;
    const double c = std::cos(M_PI / 6), s = std::sin(M_PI / 6), t = 1 - c;
    g.direction = {t * x * x + c,     t * x * y - s * z, t * x * z + s * y,
                   t * x * y + s * z, t * y * y + c,     t * y * z - s * x,
                   t * x * z - s * y, t * y * z + s * x, t * z * z + c};
    return g;
}

// Every value class a type has: extremes, and for floats NaN, infinities, -0 and a denormal.
template <class T>
lobe::core::Image3D<T> pattern_image(const lobe::core::ImageGeometry& g)
{
    lobe::core::Image3D<T> im(g);
    for (std::size_t i = 0; i < im.data.size(); ++i)
        im.data[i] = static_cast<T>(static_cast<long long>((i * 7919) % 251) - (std::is_signed_v<T> ? 125 : 0));
    im.data[0] = std::numeric_limits<T>::lowest();
    im.data[1] = std::numeric_limits<T>::max();
    if constexpr (std::is_floating_point_v<T>) {
        im.data[2] = std::numeric_limits<T>::quiet_NaN();
        im.data[3] = std::numeric_limits<T>::infinity();
        im.data[4] = -std::numeric_limits<T>::infinity();
        im.data[5] = T(-0.0);
        im.data[6] = std::numeric_limits<T>::denorm_min();
        im.data[7] = T(1) / T(3);
    }
    return im;
}

bool same_bytes(const lobe::core::AnyImage& a, const lobe::core::AnyImage& b)
{
    if (a.index() != b.index())
        return false;
    return std::visit(
        [&](const auto& ia) {
            using I = std::decay_t<decltype(ia)>;
            const auto& ib = std::get<I>(b);
            return ia.data.size() == ib.data.size() &&
                   std::memcmp(ia.data.data(), ib.data.data(), ia.data.size() * sizeof(typename I::value_type)) == 0;
        },
        a);
}

void expect_same_geometry(const lobe::core::ImageGeometry& a, const lobe::core::ImageGeometry& b)
{
    EXPECT_EQ(a.size, b.size);
    // Stored as float64 attributes, so they come back bit-identical; 1e-12 is the stated bound.
    for (int i = 0; i < 3; ++i) {
        EXPECT_NEAR(a.spacing[i], b.spacing[i], 1e-12);
        EXPECT_NEAR(a.origin[i], b.origin[i], 1e-12);
    }
    for (int i = 0; i < 9; ++i)
        EXPECT_NEAR(a.direction[i], b.direction[i], 1e-12);
}

lobe::core::LabelImage3D sphere_labels(int n)
{
    lobe::core::ImageGeometry g = oblique_geometry(n, n, n);
    lobe::core::LabelImage3D im(g);
    const double c = (n - 1) / 2.0;
    for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const double r2 = (i - c) * (i - c) + (j - c) * (j - c) + (k - c) * (k - c);
                im.at(i, j, k) = static_cast<std::uint8_t>(r2 < 0.16 * n * n ? (r2 < 0.02 * n * n ? 4 : 1) : 0);
            }
    return im;
}

const LabelTable kTissues{{0, "background"}, {1, "liver"}, {2, "portal_vein"}, {3, "hepatic_veins"}, {4, "tumour"}};

lobe::core::TriMesh octahedron()
{
    lobe::core::TriMesh m;
    const double r = 10.0 / 3.0; // not representable in float32: float storage would show
    m.vertices = {{r, 0, 0}, {-r, 0, 0}, {0, r, 0}, {0, -r, 0}, {0, 0, r}, {0, 0, -r}};
    for (auto& v : m.vertices)
        v += Vec3{1.0 / 7, -2.0 / 9, 3.0 / 11};
    m.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
    return m;
}

// The unit cube cut into six positively oriented tets around its main diagonal (0 -> 7).
lobe::core::TetMesh cube_tets()
{
    lobe::core::TetMesh m;
    for (int k = 0; k < 2; ++k)
        for (int j = 0; j < 2; ++j)
            for (int i = 0; i < 2; ++i)
                m.vertices.push_back(Vec3{i / 3.0, j / 3.0, k / 3.0} + Vec3{100.1, -50.2, 7.3});
    const int paths[6][2] = {{1, 3}, {1, 5}, {2, 3}, {2, 6}, {4, 5}, {4, 6}};
    for (const auto& p : paths) {
        std::array<std::int32_t, 4> t{0, p[0], p[1], 7};
        if (lobe::core::signed_volume(m.vertices[std::size_t(t[0])], m.vertices[std::size_t(t[1])],
                                      m.vertices[std::size_t(t[2])], m.vertices[std::size_t(t[3])]) < 0)
            std::swap(t[1], t[2]);
        m.tets.push_back(t);
    }
    m.tet_labels = {1, 1, 1, 4, 4, 2};
    return m;
}

Provenance lseg_record()
{
    Provenance p;
    p.tool = "lseg";
    p.version = "0.1.0";
    p.command_line = "lseg ct.mhd -o seg.h5 --method chan-vese";
    p.started = "2024-05-01T12:00:00Z";
    p.parameters = {{"method", "chan-vese"}, {"mu", "0.1"}, {"--roi", "10 20 30"}, {"band.width", "3"}, {"roi/min", "1 2 3"}, {"a", ""}};
    p.timings = {{"load", 0.25}, {"segment", 12.5}, {"write", 1.0 / 3.0}};
    return p;
}

void expect_same(const Provenance& a, const Provenance& b)
{
    EXPECT_EQ(a.tool, b.tool);
    EXPECT_EQ(a.version, b.version);
    EXPECT_EQ(a.command_line, b.command_line);
    EXPECT_EQ(a.started, b.started);
    EXPECT_EQ(a.parameters, b.parameters);
    EXPECT_EQ(a.timings, b.timings); // float64 attributes: exact
}



// Minimal RAII for fabricating files with HDF5's C API.
struct H5Id {
    hid_t id;
    herr_t (*close)(hid_t);
    H5Id(hid_t i, herr_t (*c)(hid_t)) : id(i), close(c) { EXPECT_GE(i, 0); }
    H5Id(const H5Id&) = delete;
    H5Id& operator=(const H5Id&) = delete;
    ~H5Id()
    {
        if (id >= 0)
            close(id);
    }
    operator hid_t() const { return id; }
};

// Flips one bit of the byte at `at`: a corruption only a checksum can see in raw pixels.
void flip_bit(const fs::path& p, std::streamoff at)
{
    std::fstream f(p, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(at);
    const int c = f.get();
    f.seekp(at);
    f.put(static_cast<char>(c ^ 0x40));
}

H5Id open_rw(const fs::path& p) { return H5Id(H5Fopen(p.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose); }

// Writes a small valid container with one of everything.
void write_full(const fs::path& p)
{
    Hdf5Writer w(p);
    w.write_image("ct", pattern_image<std::int16_t>(oblique_geometry(9, 8, 7)));
    w.write_labels("liver", sphere_labels(12), kTissues);
    w.write_surface("liver", octahedron());
    w.write_tet_mesh("liver", cube_tets(), {{"min_dihedral_angle", std::vector<double>(6, 54.7), "degree"}}, kTissues);
    w.write_provenance(lseg_record());
    w.commit();
}

// Replaces a dataset by one of the given type and shape (no data: fill value), keeping nothing.
void replace_dataset(const fs::path& p, const std::string& path, hid_t type, std::vector<hsize_t> dims, bool chunked = false)
{
    H5Id f = open_rw(p);
    EXPECT_GE(H5Ldelete(f, path.c_str(), H5P_DEFAULT), 0);
    H5Id space(H5Screate_simple(int(dims.size()), dims.data(), nullptr), H5Sclose);
    H5Id dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    if (chunked) {
        std::vector<hsize_t> chunk(dims.size(), 1);
        H5Pset_chunk(dcpl, int(chunk.size()), chunk.data());
    }
    H5Id ds(H5Dcreate2(f, path.c_str(), type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT), H5Dclose);
}

template <class T>
void overwrite_data(const fs::path& p, const std::string& path, hid_t mem_type, const std::vector<T>& data)
{
    H5Id f = open_rw(p);
    H5Id ds(H5Dopen2(f, path.c_str(), H5P_DEFAULT), H5Dclose);
    EXPECT_GE(H5Dwrite(ds, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()), 0);
}

void put_double_attr(hid_t obj, const char* name, std::vector<double> v)
{
    H5Adelete(obj, name);
    const hsize_t n = v.size();
    H5Id s(H5Screate_simple(1, &n, nullptr), H5Sclose);
    H5Id a(H5Acreate2(obj, name, H5T_IEEE_F64LE, s, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    EXPECT_GE(H5Awrite(a, H5T_NATIVE_DOUBLE, v.data()), 0);
}

void put_geometry(hid_t ds)
{
    put_double_attr(ds, "spacing", {1, 1, 1});
    put_double_attr(ds, "origin", {0, 0, 0});
    put_double_attr(ds, "direction", {1, 0, 0, 0, 1, 0, 0, 0, 1});
}

// ---- round trips --------------------------------------------------------------------------------

TEST(Hdf5Container, EveryPixelTypeRoundTripsBitExactWithObliqueGeometry)
{
    const fs::path p = lobe::test::scratch_dir() / "types.h5";
    // 131 > 128 along x: two chunks per row, so chunk boundaries are exercised too.
    const auto g = oblique_geometry(131, 17, 9);
    const std::vector<std::pair<std::string, lobe::core::AnyImage>> images{
        {"u8", pattern_image<std::uint8_t>(g)},   {"i8", pattern_image<std::int8_t>(g)},
        {"i16", pattern_image<std::int16_t>(g)},  {"u16", pattern_image<std::uint16_t>(g)},
        {"i32", pattern_image<std::int32_t>(g)},  {"u32", pattern_image<std::uint32_t>(g)},
        {"f32", pattern_image<float>(g)},         {"f64", pattern_image<double>(g)}};
    {
        Hdf5Writer w(p);
        for (const auto& [name, im] : images)
            w.write_image(name, im);
        w.commit();
    }
    Hdf5Reader r(p);
    EXPECT_EQ(r.schema_version(), 1);
    EXPECT_FALSE(r.lobe_version().empty());
    ASSERT_EQ(r.created().size(), 20u) << r.created(); // YYYY-MM-DDTHH:MM:SSZ
    EXPECT_EQ(r.created()[10], 'T');
    EXPECT_EQ(r.created()[19], 'Z');
    // Listed in the order written (creation order is tracked), not alphabetically.
    EXPECT_EQ(r.images(), (std::vector<std::string>{"u8", "i8", "i16", "u16", "i32", "u32", "f32", "f64"}));
    for (const auto& [name, im] : images) {
        SCOPED_TRACE(name);
        const lobe::core::AnyImage back = r.read_image(name);
        EXPECT_EQ(lobe::core::pixel_type(back), lobe::core::pixel_type(im));
        // Same type in memory and file, little-endian host: HDF5 copies bytes, NaN payloads included.
        EXPECT_TRUE(same_bytes(back, im));
        expect_same_geometry(lobe::core::geometry(back), g);
        const ImageInfo info = r.image_info(name);
        EXPECT_EQ(info.pixel_type, lobe::core::pixel_type(im));
        expect_same_geometry(info.geometry, g);
    }
}

TEST(Hdf5Container, LabelVolumeRoundTripsWithTable)
{
    const fs::path p = lobe::test::scratch_dir() / "seg.h5";
    const auto labels = sphere_labels(20);
    {
        Hdf5Writer w(p);
        w.write_labels("tissues", labels, kTissues);
        w.write_labels("untabled", labels);
        w.commit();
    }
    Hdf5Reader r(p);
    EXPECT_EQ(r.labels(), (std::vector<std::string>{"tissues", "untabled"}));
    EXPECT_TRUE(r.images().empty());
    const LabelVolume v = r.read_labels("tissues");
    EXPECT_EQ(v.image.data, labels.data); // uint8 stored as uint8: exact
    expect_same_geometry(v.image, labels);
    ASSERT_EQ(v.table.size(), kTissues.size());
    for (std::size_t i = 0; i < kTissues.size(); ++i) {
        EXPECT_EQ(v.table[i].value, kTissues[i].value);
        EXPECT_EQ(v.table[i].name, kTissues[i].name);
    }
    EXPECT_TRUE(r.read_labels("untabled").table.empty());
    // A label volume is not an image; asking for it as one names what there is.
    EXPECT_LOBE_ERROR(InvalidInputError, r.read_image("tissues"), p.string(), "no image 'tissues'", "images: none");
}

TEST(Hdf5Container, SurfaceRoundTripsExactly)
{
    const fs::path p = lobe::test::scratch_dir() / "surf.h5";
    const auto mesh = octahedron();
    {
        Hdf5Writer w(p);
        w.write_surface("liver", mesh);
        w.commit();
    }
    Hdf5Reader r(p);
    EXPECT_EQ(r.surfaces(), std::vector<std::string>{"liver"});
    const auto back = r.read_surface("liver");
    // float64 vertices and int32 indices in the file: nothing is rounded.
    EXPECT_EQ(back.vertices.size(), mesh.vertices.size());
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i)
        EXPECT_EQ(back.vertices[i], mesh.vertices[i]);
    EXPECT_EQ(back.triangles, mesh.triangles);
}

TEST(Hdf5Container, TetMeshRoundTripsWithLabelsQualityAndTissueTable)
{
    const fs::path p = lobe::test::scratch_dir() / "mesh.h5";
    const auto mesh = cube_tets();
    ASSERT_EQ(lobe::core::mesh_problem(mesh), "");
    // Written in non-alphabetical order: the reader must return the written order.
    const std::vector<ElementArray> quality{
        {"radius_edge_ratio", {0.61, 0.62, 0.63, 0.64, 0.65, 1.0 / 3.0}, ""},
        {"min_dihedral_angle", {35.26, 35.26, 45.0, 45.0, 60.0, std::numeric_limits<double>::quiet_NaN()}, "degree"}};
    const LabelTable tissues{{1, "liver"}, {2, "portal_vein"}, {4, "tumour"}};
    {
        Hdf5Writer w(p);
        w.write_tet_mesh("liver", mesh, quality, tissues);
        w.commit();
    }
    Hdf5Reader r(p);
    EXPECT_EQ(r.tet_meshes(), std::vector<std::string>{"liver"});
    const TetMeshData back = r.read_tet_mesh("liver");
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i)
        EXPECT_EQ(back.mesh.vertices[i], mesh.vertices[i]); // float64: exact
    EXPECT_EQ(back.mesh.tets, mesh.tets);
    EXPECT_EQ(back.mesh.tet_labels, mesh.tet_labels);
    ASSERT_EQ(back.quality.size(), 2u);
    for (std::size_t q = 0; q < 2; ++q) {
        EXPECT_EQ(back.quality[q].name, quality[q].name);
        EXPECT_EQ(back.quality[q].units, quality[q].units);
        ASSERT_EQ(back.quality[q].values.size(), 6u);
        EXPECT_EQ(std::memcmp(back.quality[q].values.data(), quality[q].values.data(), 6 * sizeof(double)), 0);
    }
    ASSERT_EQ(back.tissues.size(), 3u);
    EXPECT_EQ(back.tissues[2].value, 4);
    EXPECT_EQ(back.tissues[2].name, "tumour");
}

TEST(Hdf5Container, EmptyMeshesRoundTrip)
{
    // Empty datasets cannot be chunked; the writer stores them contiguous and the XDMF skips them.
    const fs::path p = lobe::test::scratch_dir() / "empty.h5";
    {
        Hdf5Writer w(p);
        w.write_surface("nothing", {});
        w.write_tet_mesh("nothing", {});
        w.commit();
    }
    Hdf5Reader r(p);
    EXPECT_TRUE(r.read_surface("nothing").triangles.empty());
    EXPECT_TRUE(r.read_tet_mesh("nothing").mesh.tets.empty());
    EXPECT_EQ(lobe::test::read_file(fs::path(p).replace_extension(".xdmf")).find("nothing"), std::string::npos);
}

TEST(Hdf5Container, ProvenanceKeepsParametersAndTimingsInOrder)
{
    const fs::path p = lobe::test::scratch_dir() / "prov.h5";
    Provenance second;
    second.tool = "lseg refine"; // a space: the group name is sanitised, the attribute is not
    second.version = "0.1.0";
    {
        Hdf5Writer w(p);
        w.write_provenance(lseg_record());
        w.write_provenance(second);
        w.commit();
    }
    Hdf5Reader r(p);
    const auto records = r.provenance();
    ASSERT_EQ(records.size(), 2u);
    expect_same(records[0], lseg_record());
    EXPECT_EQ(records[1].tool, "lseg refine");
    EXPECT_TRUE(records[1].parameters.empty());
    EXPECT_EQ(records[1].started.size(), 20u) << "an empty 'started' is filled with the time of writing";
    H5Id f(H5Fopen(p.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    EXPECT_GT(H5Lexists(f, "/provenance/000_lseg", H5P_DEFAULT), 0);
    EXPECT_GT(H5Lexists(f, "/provenance/001_lseg_refine", H5P_DEFAULT), 0);
}

TEST(Hdf5Container, EachStageKeepsTheHistoryOfTheStagesBefore)
{
    const fs::path dir = lobe::test::scratch_dir();
    {
        Hdf5Writer w(dir / "seg.h5");
        w.write_labels("liver", sphere_labels(8), kTissues);
        w.write_provenance(lseg_record());
        w.commit();
    }
    Provenance lmesh;
    lmesh.tool = "lmesh";
    lmesh.version = "0.2.0";
    lmesh.command_line = "lmesh seg.h5 -o mesh.h5";
    lmesh.parameters = {{"size", "2.0"}};
    lmesh.timings = {{"mesh", 3.5}};
    {
        Hdf5Reader in(dir / "seg.h5");
        Hdf5Writer w(dir / "mesh.h5");
        w.copy_provenance(in);
        w.write_tet_mesh("liver", cube_tets());
        w.write_provenance(lmesh);
        w.commit();
    }
    Provenance lsim;
    lsim.tool = "lsim";
    {
        Hdf5Reader in(dir / "mesh.h5");
        Hdf5Writer w(dir / "sim.h5");
        w.copy_provenance(in);
        w.write_provenance(lsim);
        w.commit();
    }
    const auto history = Hdf5Reader(dir / "sim.h5").provenance();
    ASSERT_EQ(history.size(), 3u);
    expect_same(history[0], lseg_record()); // copied twice, unchanged
    expect_same(history[1], Hdf5Reader(dir / "mesh.h5").provenance()[1]);
    EXPECT_EQ(history[1].tool, "lmesh");
    EXPECT_EQ(history[1].timings, lmesh.timings);
    EXPECT_EQ(history[2].tool, "lsim");
}

TEST(Hdf5Container, ConvenienceFunctionsPickTheOnlyImageOrTheNamedOne)
{
    const fs::path dir = lobe::test::scratch_dir();
    const auto ct = pattern_image<std::int16_t>(oblique_geometry(5, 6, 7));
    write_hdf5_image(dir / "one.h5", ct, "ct");
    EXPECT_TRUE(same_bytes(read_hdf5_image(dir / "one.h5"), ct));
    EXPECT_TRUE(same_bytes(read_hdf5_image(dir / "one.h5", "ct"), ct));
    EXPECT_TRUE(fs::exists(dir / "one.xdmf"));

    {
        Hdf5Writer w(dir / "two.h5");
        w.write_image("ct", ct);
        w.write_labels("liver", sphere_labels(6));
        w.commit();
    }
    EXPECT_LOBE_ERROR(InvalidInputError, read_hdf5_image(dir / "two.h5"), (dir / "two.h5").string(),
                      "several images", "images/ct", "labels/liver");
    EXPECT_EQ(std::get<lobe::core::LabelImage3D>(read_hdf5_image(dir / "two.h5", "liver")).data, sphere_labels(6).data);
    EXPECT_TRUE(same_bytes(read_hdf5_image(dir / "two.h5", "images/ct"), ct));
    EXPECT_LOBE_ERROR(InvalidInputError, read_hdf5_image(dir / "two.h5", "mri"), "no image 'mri'", "images/ct, labels/liver");

    {
        Hdf5Writer w(dir / "none.h5");
        w.write_surface("s", octahedron());
        w.commit();
    }
    EXPECT_LOBE_ERROR(InvalidInputError, read_hdf5_image(dir / "none.h5"), (dir / "none.h5").string(), "contains no image");
}

TEST(Hdf5Container, JoinCommandLineQuotesWhatTheShellWouldSplit)
{
    const char* argv[] = {"lmesh", "in.h5", "-o", "out dir/m.h5", "--name=it's", ""};
    EXPECT_EQ(join_command_line(6, argv), "lmesh in.h5 -o 'out dir/m.h5' '--name=it'\\''s' ''");
}

// ---- storage --------------------------------------------------------------------------------------

TEST(Hdf5Container, DatasetsAreChunkedShuffledCompressedAndChecksummed)
{
    const fs::path dir = lobe::test::scratch_dir();
    lobe::core::ImageGeometry g = oblique_geometry(64, 64, 64);
    lobe::core::Image3D<std::int16_t> im(g, -1000);
    const auto labels = sphere_labels(64);
    for (std::size_t i = 0; i < im.data.size(); ++i)
        im.data[i] = labels.data[i] ? std::int16_t(60) : std::int16_t(-1000);
    const hsize_t raw = im.data.size() * sizeof(std::int16_t);
    write_hdf5_image(dir / "z.h5", im, "ct");
    {
        Hdf5WriteParams params;
        params.gzip_level = 0;
        params.checksum = false;
        Hdf5Writer w(dir / "raw.h5", params);
        w.write_image("ct", im);
        w.commit();
    }

    H5Id f(H5Fopen((dir / "z.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    H5Id ds(H5Dopen2(f, "/images/ct", H5P_DEFAULT), H5Dclose);
    H5Id dcpl(H5Dget_create_plist(ds), H5Pclose);
    EXPECT_EQ(H5Pget_layout(dcpl), H5D_CHUNKED);
    std::vector<H5Z_filter_t> filters;
    unsigned deflate_level = 0;
    for (int i = 0; i < H5Pget_nfilters(dcpl); ++i) {
        unsigned flags = 0, cd[8] = {};
        size_t ncd = 8;
        const H5Z_filter_t id = H5Pget_filter2(dcpl, unsigned(i), &flags, &ncd, cd, 0, nullptr, nullptr);
        filters.push_back(id);
        if (id == H5Z_FILTER_DEFLATE)
            deflate_level = cd[0];
    }
    // Pipeline order matters: shuffle feeds deflate; the checksum covers the stored bytes.
    EXPECT_EQ(filters, (std::vector<H5Z_filter_t>{H5Z_FILTER_SHUFFLE, H5Z_FILTER_DEFLATE, H5Z_FILTER_FLETCHER32}));
    EXPECT_EQ(deflate_level, 1u); // the documented default
    // A two-valued phantom deflates by far more than 10x (runs of identical shuffled bytes).
    EXPECT_LT(H5Dget_storage_size(ds), raw / 10);

    H5Id f2(H5Fopen((dir / "raw.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    H5Id ds2(H5Dopen2(f2, "/images/ct", H5P_DEFAULT), H5Dclose);
    H5Id dcpl2(H5Dget_create_plist(ds2), H5Pclose);
    EXPECT_EQ(H5Pget_nfilters(dcpl2), 0);
    EXPECT_EQ(H5Dget_storage_size(ds2), raw); // uncompressed chunks tile the image exactly
    EXPECT_TRUE(same_bytes(read_hdf5_image(dir / "raw.h5"), im));
}

// Every chunk of `path` in `file` compared with the chunk HDF5's own filter pipeline stores for the
// same values under the same creation properties. The writer filters large datasets itself on every
// core and stores them with H5Dwrite_chunk; byte equality means any HDF5 reader decodes them, and
// reading the values back through HDF5 has already verified each chunk's Fletcher-32 checksum.
void expect_chunks_as_hdf5_writes(const fs::path& file, const std::string& path, const fs::path& reference,
                                  hsize_t min_chunks)
{
    SCOPED_TRACE(file.string() + ": " + path);
    H5Id f(H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    H5Id ds(H5Dopen2(f, path.c_str(), H5P_DEFAULT), H5Dclose);
    H5Id type(H5Dget_type(ds), H5Tclose);
    H5Id space(H5Dget_space(ds), H5Sclose);
    H5Id dcpl(H5Dget_create_plist(ds), H5Pclose);
    const int rank = H5Sget_simple_extent_ndims(space);
    std::vector<unsigned char> values(std::size_t(H5Sget_simple_extent_npoints(space)) * H5Tget_size(type));
    ASSERT_GE(H5Dread(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);

    H5Id rf(H5Fcreate(reference.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
    H5Id rds(H5Dcreate2(rf, "d", type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT), H5Dclose);
    ASSERT_GE(H5Dwrite(rds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);

    hsize_t chunks = 0, reference_chunks = 0;
    // HDF5 1.10 wants the dataspace itself here; H5S_ALL fails.
    ASSERT_GE(H5Dget_num_chunks(ds, space, &chunks), 0);
    ASSERT_GE(H5Dget_num_chunks(rds, space, &reference_chunks), 0);
    ASSERT_GE(chunks, min_chunks); // edge chunks included: the dimensions are not multiples of the chunk
    ASSERT_EQ(chunks, reference_chunks);
    for (hsize_t i = 0; i < chunks; ++i) {
        hsize_t offset[3] = {}, size = 0, reference_size = 0;
        unsigned mask = 1, reference_mask = 1;
        haddr_t addr = 0;
        ASSERT_GE(H5Dget_chunk_info(ds, space, i, offset, &mask, &addr, &size), 0);
        ASSERT_GE(H5Dget_chunk_info_by_coord(rds, offset, &reference_mask, &addr, &reference_size), 0);
        EXPECT_EQ(mask, 0u) << "chunk " << i << ": a filter was skipped";
        EXPECT_EQ(mask, reference_mask);
        ASSERT_EQ(size, reference_size) << "chunk " << i << " at " << offset[0] << "," << offset[1] << "," << offset[2];
        std::vector<unsigned char> a(size), b(size);
        ASSERT_GE(H5Dread_chunk(ds, H5P_DEFAULT, offset, &mask, a.data()), 0);
        ASSERT_GE(H5Dread_chunk(rds, H5P_DEFAULT, offset, &reference_mask, b.data()), 0);
        EXPECT_TRUE(a == b) << "chunk " << i << " differs from HDF5's own (rank " << rank << ")";
    }
}

TEST(Hdf5Container, FilteredChunksAreTheBytesHdf5ItselfWrites)
{
    const fs::path dir = lobe::test::scratch_dir();
    // 130 x 129 x 35 against 128 x 128 chunks in-plane: every type has partial edge chunks.
    const auto g = oblique_geometry(130, 129, 35);
    Hdf5WriteParams level4;
    level4.gzip_level = 4;
    Hdf5WriteParams level9_no_checksum;
    level9_no_checksum.gzip_level = 9;
    level9_no_checksum.checksum = false;
    Hdf5WriteParams checksum_only;
    checksum_only.gzip_level = 0;
    int k = 0;
    for (const Hdf5WriteParams& params : {Hdf5WriteParams{}, level4, level9_no_checksum, checksum_only}) {
        const fs::path p = dir / ("chunks" + std::to_string(k++) + ".h5");
        const auto ct = pattern_image<std::int16_t>(g);
        const auto f32 = pattern_image<float>(g);
        const auto f64 = pattern_image<double>(g);
        lobe::core::LabelImage3D labels(g, 0);
        for (std::size_t i = 0; i < labels.data.size(); ++i)
            labels.data[i] = std::uint8_t((i / 1000) % 3);
        {
            Hdf5Writer w(p, params);
            w.write_image("ct", ct);
            w.write_image("f32", f32);
            w.write_image("f64", f64);
            w.write_labels("labels", labels);
            w.commit();
        }
        // int16 chunks of 128 x 128 x 32 make a 2 x 2 x 2 grid, float 2 x 2 x 3, double 2 x 2 x 5, uint8 2 x 2 x 1.
        expect_chunks_as_hdf5_writes(p, "/images/ct", dir / "ref.h5", 8);
        expect_chunks_as_hdf5_writes(p, "/images/f32", dir / "ref.h5", 12);
        expect_chunks_as_hdf5_writes(p, "/images/f64", dir / "ref.h5", 20);
        expect_chunks_as_hdf5_writes(p, "/labels/labels", dir / "ref.h5", 4);
        EXPECT_TRUE(same_bytes(read_hdf5_image(p, "ct"), ct));
        EXPECT_TRUE(same_bytes(read_hdf5_image(p, "f64"), f64)); // NaN, infinities, -0 and denormals kept
    }
    // Tables go the same way: a 250 x 250 vertex grid has more rows than one 1 MiB chunk holds.
    lobe::core::TriMesh grid;
    const int n = 250;
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x)
            grid.vertices.push_back({0.5 * x, 0.25 * y, 0.001 * x * y});
    for (int y = 0; y + 1 < n; ++y)
        for (int x = 0; x + 1 < n; ++x) {
            const int v = y * n + x;
            grid.triangles.push_back({v, v + 1, v + n});
            grid.triangles.push_back({v + 1, v + n + 1, v + n});
        }
    {
        Hdf5Writer w(dir / "grid.h5");
        w.write_surface("grid", grid);
        w.commit();
    }
    expect_chunks_as_hdf5_writes(dir / "grid.h5", "/surfaces/grid/vertices", dir / "ref.h5", 2);
    expect_chunks_as_hdf5_writes(dir / "grid.h5", "/surfaces/grid/triangles", dir / "ref.h5", 2);
    const lobe::core::TriMesh back = Hdf5Reader(dir / "grid.h5").read_surface("grid");
    EXPECT_EQ(back.vertices, grid.vertices);
    EXPECT_EQ(back.triangles, grid.triangles);
}

// The reader unfilters the chunks of large datasets on every core itself. It must decode what
// HDF5 decodes (every filter set it knows, edge chunks) and, for anything else or anything broken,
// give HDF5's own answer: values or the same error.
TEST(Hdf5Container, ChunksReadInParallelAsHdf5ReadsThem)
{
    const fs::path dir = lobe::test::scratch_dir();
    const auto g = oblique_geometry(130, 129, 35); // 2 x 2 x 2 chunks of int16, with edge chunks
    const auto ct = pattern_image<std::int16_t>(g);
    write_hdf5_image(dir / "ct.h5", ct, "ct");
    // The same values rewritten by HDF5 itself under other filter sets: deflate without shuffle,
    // the checksum alone, and shuffle without deflate (which the fast path leaves to HDF5).
    const std::vector<std::vector<H5Z_filter_t>> sets{
        {H5Z_FILTER_DEFLATE}, {H5Z_FILTER_FLETCHER32}, {H5Z_FILTER_SHUFFLE}, {H5Z_FILTER_DEFLATE, H5Z_FILTER_FLETCHER32}};
    int k = 0;
    for (const auto& set : sets) {
        const fs::path p = dir / ("set" + std::to_string(k++) + ".h5");
        fs::copy_file(dir / "ct.h5", p, fs::copy_options::overwrite_existing);
        {
            H5Id f = open_rw(p);
            EXPECT_GE(H5Ldelete(f, "/images/ct", H5P_DEFAULT), 0);
            const hsize_t dims[3] = {35, 129, 130}, chunk[3] = {32, 128, 128};
            H5Id space(H5Screate_simple(3, dims, nullptr), H5Sclose);
            H5Id dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
            H5Pset_chunk(dcpl, 3, chunk);
            for (H5Z_filter_t id : set) {
                if (id == H5Z_FILTER_DEFLATE)
                    H5Pset_deflate(dcpl, 6);
                else if (id == H5Z_FILTER_SHUFFLE)
                    H5Pset_shuffle(dcpl);
                else
                    H5Pset_fletcher32(dcpl);
            }
            H5Id ds(H5Dcreate2(f, "/images/ct", H5T_STD_I16LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT), H5Dclose);
            ASSERT_GE(H5Dwrite(ds, H5T_NATIVE_INT16, H5S_ALL, H5S_ALL, H5P_DEFAULT, ct.data.data()), 0);
            put_double_attr(ds, "spacing", {g.spacing[0], g.spacing[1], g.spacing[2]});
            put_double_attr(ds, "origin", {g.origin[0], g.origin[1], g.origin[2]});
            put_double_attr(ds, "direction", std::vector<double>(g.direction.begin(), g.direction.end()));
        }
        EXPECT_TRUE(same_bytes(read_hdf5_image(p, "ct"), ct)) << "filter set " << k - 1;
    }
    EXPECT_TRUE(same_bytes(read_hdf5_image(dir / "ct.h5", "ct"), ct));

    // A flipped byte in the middle of a stored chunk (the third of eight): the checksum fails,
    // and the read is HDF5's error, not data.
    haddr_t addr = 0;
    hsize_t size = 0;
    {
        H5Id f(H5Fopen((dir / "ct.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
        H5Id ds(H5Dopen2(f, "/images/ct", H5P_DEFAULT), H5Dclose);
        hsize_t offset[3] = {0, 128, 0};
        unsigned mask = 0;
        ASSERT_GE(H5Dget_chunk_info_by_coord(ds, offset, &mask, &addr, &size), 0);
    }
    flip_bit(dir / "ct.h5", static_cast<std::streamoff>(addr + size / 2));
    EXPECT_LOBE_ERROR(IoError, read_hdf5_image(dir / "ct.h5", "ct"), (dir / "ct.h5").string() + ": /images/ct: cannot read data");
}

TEST(Hdf5Container, CorruptedChunkIsAnIoErrorNotWrongData)
{
    const fs::path p = lobe::test::scratch_dir() / "c.h5";
    Hdf5WriteParams params;
    params.gzip_level = 0; // the flipped byte is then a pixel, not deflate framing: only the checksum can see it
    {
        Hdf5Writer w(p, params);
        w.write_image("ct", pattern_image<std::int16_t>(oblique_geometry(20, 20, 20)));
        w.commit();
    }
    haddr_t addr = 0;
    hsize_t size = 0;
    {
        H5Id f(H5Fopen(p.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
        H5Id ds(H5Dopen2(f, "/images/ct", H5P_DEFAULT), H5Dclose);
        hsize_t offset[3] = {};
        unsigned mask = 0;
        ASSERT_GE(H5Dget_chunk_info_by_coord(ds, offset, &mask, &addr, &size), 0);
        ASSERT_EQ(size, 20u * 20 * 20 * 2 + 4); // raw pixels plus the 4-byte checksum
    }
    flip_bit(p, static_cast<std::streamoff>(addr + size / 2));
    EXPECT_LOBE_ERROR(IoError, read_hdf5_image(p), p.string() + ": /images/ct: cannot read data");
}

// ---- XDMF -------------------------------------------------------------------------------------------

TEST(Hdf5Container, XdmfSidecarIsWellFormedAndReferencesExistingDatasets)
{
    const fs::path dir = lobe::test::scratch_dir();
    const fs::path p = dir / "stage.h5";
    write_full(p);
    const fs::path x = dir / "stage.xdmf";
    ASSERT_TRUE(fs::exists(x));
    const std::string xml = lobe::test::read_file(x);

    if (fs::exists("/usr/bin/xmllint")) {
        const std::string cmd = "/usr/bin/xmllint --noout '" + x.string() + "' 2>&1";
        EXPECT_EQ(std::system(cmd.c_str()), 0) << xml;
    }
    EXPECT_NE(xml.find("Version=\"3.0\""), std::string::npos);

    // Every heavy-data reference: relative file name, an existing dataset, the same shape and type.
    H5Id f(H5Fopen(p.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    int items = 0;
    for (std::size_t pos = xml.find("<DataItem "); pos != std::string::npos; pos = xml.find("<DataItem ", pos + 1)) {
        const std::size_t tag_end = xml.find('>', pos), close = xml.find("</DataItem>", pos);
        ASSERT_NE(close, std::string::npos);
        const std::string tag = xml.substr(pos, tag_end - pos), text = xml.substr(tag_end + 1, close - tag_end - 1);
        const auto attr = [&](const std::string& name) {
            const std::size_t a = tag.find(" " + name + "=\"");
            if (a == std::string::npos)
                return std::string();
            const std::size_t b = a + name.size() + 3;
            return tag.substr(b, tag.find('"', b) - b);
        };
        if (attr("Format") != "HDF")
            continue;
        ++items;
        SCOPED_TRACE(tag + ">" + text);
        const std::size_t colon = text.find(':');
        ASSERT_NE(colon, std::string::npos);
        EXPECT_EQ(text.substr(0, colon), "stage.h5"); // relative, and the final name, not the temporary
        const std::string path = text.substr(colon + 1);
        ASSERT_GT(H5Lexists(f, path.substr(0, path.rfind('/')).c_str(), H5P_DEFAULT), 0);
        ASSERT_GT(H5Lexists(f, path.c_str(), H5P_DEFAULT), 0);
        H5Id ds(H5Dopen2(f, path.c_str(), H5P_DEFAULT), H5Dclose);
        H5Id space(H5Dget_space(ds), H5Sclose);
        hsize_t dims[3] = {};
        const int rank = H5Sget_simple_extent_dims(space, dims, nullptr);
        std::string dims_text;
        for (int d = 0; d < rank; ++d)
            dims_text += (d ? " " : "") + std::to_string(dims[d]);
        EXPECT_EQ(attr("Dimensions"), dims_text);
        H5Id type(H5Dget_type(ds), H5Tclose);
        EXPECT_EQ(attr("Precision"), std::to_string(H5Tget_size(type)));
        const std::string number_type = attr("NumberType");
        const bool is_float = H5Tget_class(type) == H5T_FLOAT;
        EXPECT_EQ(number_type == "Float", is_float);
        if (!is_float) {
            EXPECT_EQ(number_type == "UInt" || number_type == "UChar", H5Tget_sign(type) == H5T_SGN_NONE);
        }
    }
    // ct, labels, surface (vertices + triangles), mesh (vertices, tets, tet_labels, 1 quality).
    EXPECT_EQ(items, 1 + 1 + 2 + 4);

    // Structured grids: XDMF lists dimensions, origin and spacing as z, y, x.
    EXPECT_NE(xml.find(R"(<Topology TopologyType="3DCoRectMesh" Dimensions="7 8 9"/>)"), std::string::npos);
    EXPECT_NE(xml.find(R"(Format="XML">1001.125 35.5 -120.25</DataItem>)"), std::string::npos);
    EXPECT_NE(xml.find(R"(Format="XML">2.5 0.8125 0.703125</DataItem>)"), std::string::npos);
    EXPECT_NE(xml.find(R"(TopologyType="Triangle" NumberOfElements="8")"), std::string::npos);
    EXPECT_NE(xml.find(R"(TopologyType="Tetrahedron" NumberOfElements="6")"), std::string::npos);
    EXPECT_NE(xml.find(R"(Attribute Name="quality_min_dihedral_angle" AttributeType="Scalar" Center="Cell")"),
              std::string::npos);
    EXPECT_NE(xml.find(R"(Attribute Name="tet_labels" AttributeType="Scalar" Center="Cell")"), std::string::npos);
}

TEST(Hdf5Container, XdmfSidecarCanBeSwitchedOff)
{
    const fs::path dir = lobe::test::scratch_dir();
    Hdf5WriteParams params;
    params.write_xdmf = false;
    Hdf5Writer w(dir / "a.h5", params);
    w.write_surface("s", octahedron());
    w.commit();
    EXPECT_EQ(lobe::test::list_dir(dir), std::vector<std::string>{"a.h5"});
}

// ---- atomicity ----------------------------------------------------------------------------------------

TEST(Hdf5Container, WriterDestroyedWithoutCommitLeavesNothing)
{
    const fs::path dir = lobe::test::scratch_dir();
    {
        Hdf5Writer w(dir / "half.h5");
        w.write_image("ct", pattern_image<float>(oblique_geometry(10, 10, 10)));
        EXPECT_EQ(lobe::test::list_dir(dir).size(), 1u); // the temporary exists while writing ...
    }
    EXPECT_TRUE(lobe::test::list_dir(dir).empty()); // ... and is gone, with no .h5 and no .xdmf
}

TEST(Hdf5Container, ExistingFileIsUntouchedUntilCommit)
{
    const fs::path dir = lobe::test::scratch_dir();
    const fs::path p = dir / "stage.h5";
    const auto old_image = pattern_image<std::int16_t>(oblique_geometry(4, 5, 6));
    const auto new_image = pattern_image<float>(oblique_geometry(6, 5, 4));
    write_hdf5_image(p, old_image, "ct");
    const std::string old_bytes = lobe::test::read_file(p), old_xdmf = lobe::test::read_file(dir / "stage.xdmf");
    {
        Hdf5Writer w(p);
        w.write_image("ct", new_image);
        EXPECT_EQ(lobe::test::read_file(p), old_bytes);
        EXPECT_TRUE(same_bytes(read_hdf5_image(p), old_image));
        w.commit();
        EXPECT_LOBE_ERROR(InvalidInputError, w.write_surface("s", octahedron()), p.string(), "already committed");
        EXPECT_LOBE_ERROR(InvalidInputError, w.commit(), "already committed");
    }
    EXPECT_TRUE(same_bytes(read_hdf5_image(p), new_image));
    EXPECT_NE(lobe::test::read_file(dir / "stage.xdmf"), old_xdmf);
    EXPECT_EQ(lobe::test::list_dir(dir), (std::vector<std::string>{"stage.h5", "stage.xdmf"}));

    // A writer that is abandoned leaves the committed pair exactly as it was.
    const std::string committed = lobe::test::read_file(p);
    {
        Hdf5Writer w(p);
        w.write_image("ct", old_image);
    }
    EXPECT_EQ(lobe::test::read_file(p), committed);
    EXPECT_EQ(lobe::test::list_dir(dir), (std::vector<std::string>{"stage.h5", "stage.xdmf"}));
}

// ---- writer refusals ------------------------------------------------------------------------------

TEST(Hdf5Container, WriterRefusesBadArgumentsBeforeWriting)
{
    const fs::path dir = lobe::test::scratch_dir();
    const fs::path p = dir / "w.h5";
    const std::string file = p.string();
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Writer(p, Hdf5WriteParams{12, true, true}), file, "gzip_level 12");
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Writer(dir / "w.xdmf"), "w.xdmf", "sidecar");
    EXPECT_LOBE_ERROR(IoError, Hdf5Writer(dir / "no" / "w.h5"), "does not exist");
    EXPECT_TRUE(lobe::test::list_dir(dir).empty());

    Hdf5Writer w(p);
    const auto im = pattern_image<std::uint8_t>(oblique_geometry(3, 3, 3));
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_image("a/b", im), file, "invalid image name 'a/b'");
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_image("", im), "invalid image name ''");
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_image(".hidden", im), "invalid image name");
    w.write_image("ct", im);
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_image("ct", im), file, "image 'ct' was already written");

    auto bad_geometry = im;
    bad_geometry.spacing[1] = -1;
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_image("neg", bad_geometry), "/images/neg", "spacing along axis 1");
    auto short_data = im;
    short_data.data.pop_back();
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_image("short", short_data), "26 values for 27 voxels");
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_labels("l", sphere_labels(4), {{300, "x"}}), "label value 300");
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_labels("l", sphere_labels(4), {{1, "a"}, {1, "b"}}), "appears twice");

    auto surf = octahedron();
    surf.triangles[3][1] = 99;
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_surface("s", surf), "/surfaces/s", "triangle 3 has vertex index 99");
    surf = octahedron();
    surf.vertices[2].y = std::nan("");
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_surface("s", surf), "vertex 2 has a non-finite coordinate");

    auto tets = cube_tets();
    tets.tets[1][2] = -1;
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_tet_mesh("m", tets), "/meshes/m", "tet 1 has vertex index -1");
    tets = cube_tets();
    std::swap(tets.tets[0][1], tets.tets[0][2]);
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_tet_mesh("m", tets), "tet 0 is not positively oriented");
    tets = cube_tets();
    tets.tet_labels.pop_back();
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_tet_mesh("m", tets), "6 tets but 5 tet labels");
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_tet_mesh("m", cube_tets(), {{"q", {1, 2}, ""}}),
                      "quality measure 'q' has 2 values for 6 tets");

    Provenance rec = lseg_record();
    rec.parameters.push_back({"mu", "0.2"});
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_provenance(rec), file, "parameter 'mu' appears twice");
    rec = lseg_record();
    rec.tool.clear();
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_provenance(rec), "no tool name");
    rec = lseg_record();
    rec.timings.push_back({"nan", std::nan("")});
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_provenance(rec), "timing 'nan' is not finite");

    // Refused writes left the writer usable and the file consistent.
    w.write_provenance(lseg_record());
    w.commit();
    Hdf5Reader r(p);
    EXPECT_EQ(r.images(), std::vector<std::string>{"ct"});
    EXPECT_TRUE(r.surfaces().empty());
    EXPECT_EQ(r.provenance().size(), 1u);
    EXPECT_EQ(r.provenance()[0].tool, "lseg");
}

// ---- reader refusals ------------------------------------------------------------------------------

// A valid container with one of everything, for the tests that then break one thing in it.
struct BrokenFile {
    fs::path dir, p;
    std::string file;
};
BrokenFile full_container()
{
    BrokenFile b;
    b.dir = lobe::test::scratch_dir();
    b.p = b.dir / "bad.h5";
    b.file = b.p.string();
    write_full(b.p);
    return b;
}

TEST(Hdf5Container, MissingFileDirectoryAndNonHdf5AreIoErrors)
{
    const fs::path dir = lobe::test::scratch_dir();
    EXPECT_LOBE_ERROR(IoError, Hdf5Reader(dir / "absent.h5"), (dir / "absent.h5").string(), "no such file");
    EXPECT_LOBE_ERROR(IoError, Hdf5Reader{dir}, "is a directory");
    std::ofstream(dir / "text.h5") << "ObjectType = Image\nNDims = 3\n";
    EXPECT_LOBE_ERROR(IoError, Hdf5Reader(dir / "text.h5"), (dir / "text.h5").string(), "not an HDF5 file");
    std::ofstream(dir / "empty.h5").close();
    EXPECT_LOBE_ERROR(IoError, read_hdf5_image(dir / "empty.h5"), "not an HDF5 file");
}

TEST(Hdf5Container, TruncatedFileIsAnIoError)
{
    const fs::path dir = lobe::test::scratch_dir();
    const fs::path p = dir / "cut.h5";
    write_hdf5_image(p, pattern_image<float>(oblique_geometry(40, 40, 40)), "ct");
    fs::resize_file(p, fs::file_size(p) / 2);
    // The superblock survives (so it is HDF5) but the end of file does not match: HDF5 refuses it.
    EXPECT_LOBE_ERROR(IoError, read_hdf5_image(p), p.string());
}

TEST(Hdf5Container, PlainHdf5FileIsNotALobeContainer)
{
    const fs::path p = lobe::test::scratch_dir() / "plain.h5";
    { H5Id f(H5Fcreate(p.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose); }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader{p}, p.string() + ": not a lobe container (no lobe_schema attribute)");
}

TEST(Hdf5Container, WrongSchemaNameOrVersionOrMissingRootAttribute)
{
    const BrokenFile bad = full_container();
    const fs::path& p = bad.p;
    const std::string& file = bad.file;
    {
        H5Id f = open_rw(p);
        H5Adelete_by_name(f, "/", "lobe_schema_version", H5P_DEFAULT);
        H5Id s(H5Screate(H5S_SCALAR), H5Sclose);
        H5Id a(H5Acreate_by_name(f, "/", "lobe_schema_version", H5T_STD_I32LE, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
        const int seven = 7;
        H5Awrite(a, H5T_NATIVE_INT, &seven);
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader{p}, file + ": schema version 7 is newer than this lobe (1)");
    {
        H5Id f = open_rw(p);
        H5Adelete_by_name(f, "/", "lobe_schema_version", H5P_DEFAULT);
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader{p}, file + ": / has no lobe_schema_version attribute");
    {
        H5Id f = open_rw(p);
        H5Adelete_by_name(f, "/", "created", H5P_DEFAULT);
        H5Adelete_by_name(f, "/", "lobe_schema", H5P_DEFAULT);
        H5Id s(H5Screate(H5S_SCALAR), H5Sclose);
        H5Id t(H5Tcopy(H5T_C_S1), H5Tclose);
        H5Tset_size(t, 5);
        H5Id a(H5Acreate_by_name(f, "/", "lobe_schema", t, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
        H5Awrite(a, t, "other"); // fixed-length, not NUL-terminated: read back exactly
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader{p}, file + ": not a lobe container (lobe_schema is 'other'");
}

TEST(Hdf5Container, MissingOrMalformedGeometryAttributes)
{
    const BrokenFile bad = full_container();
    const fs::path& p = bad.p;
    const std::string& file = bad.file;
    {
        H5Id f = open_rw(p);
        H5Adelete_by_name(f, "/images/ct", "spacing", H5P_DEFAULT);
    }
    {
        Hdf5Reader r(p); // closed before the file is modified again: HDF5 will not reopen it read-write
        EXPECT_LOBE_ERROR(InvalidInputError, r.read_image("ct"), file + ": /images/ct has no spacing attribute");
        EXPECT_LOBE_ERROR(InvalidInputError, r.image_info("ct"), file + ": /images/ct has no spacing attribute");
    }
    {
        H5Id f = open_rw(p);
        H5Id ds(H5Dopen2(f, "/images/ct", H5P_DEFAULT), H5Dclose);
        put_double_attr(ds, "spacing", {1, 2});
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_image("ct"), "/images/ct: attribute spacing has 2 values, expected 3");
    {
        H5Id f = open_rw(p);
        H5Id ds(H5Dopen2(f, "/images/ct", H5P_DEFAULT), H5Dclose);
        put_double_attr(ds, "spacing", {1, -2, 1});
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_image("ct"), file, "/images/ct", "spacing along axis 1");
    {
        H5Id f = open_rw(p);
        H5Id ds(H5Dopen2(f, "/labels/liver", H5P_DEFAULT), H5Dclose);
        H5Adelete(ds, "direction");
        H5Id s(H5Screate(H5S_SCALAR), H5Sclose);
        H5Id t(H5Tcopy(H5T_C_S1), H5Tclose);
        H5Tset_size(t, 4);
        H5Id a(H5Acreate2(ds, "direction", t, s, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
        H5Awrite(a, t, "eye3");
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_labels("liver"), "/labels/liver: attribute direction is string, expected numbers");
}

TEST(Hdf5Container, LabelTableWithoutNames)
{
    const BrokenFile bad = full_container();
    const fs::path& p = bad.p;
    const std::string& file = bad.file;
    {
        H5Id f = open_rw(p);
        H5Adelete_by_name(f, "/labels/liver", "label_names", H5P_DEFAULT);
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_labels("liver"),
                      file + ": /labels/liver has label_values but no label_names attribute");
}

TEST(Hdf5Container, WrongRankTypeOrKindOfObject)
{
    const BrokenFile bad = full_container();
    const fs::path& p = bad.p;
    const std::string& file = bad.file;
    replace_dataset(p, "/images/ct", H5T_STD_I16LE, {9, 8});
    {
        H5Id f = open_rw(p);
        H5Id ds(H5Dopen2(f, "/images/ct", H5P_DEFAULT), H5Dclose);
        put_geometry(ds);
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_image("ct"), file + ": /images/ct has rank 2 (9, 8), expected 3");

    replace_dataset(p, "/images/ct", H5T_STD_I64LE, {2, 2, 2});
    {
        H5Id f = open_rw(p);
        H5Id ds(H5Dopen2(f, "/images/ct", H5P_DEFAULT), H5Dclose);
        put_geometry(ds);
        const std::vector<long long> v(8, 1);
        H5Dwrite(ds, H5T_NATIVE_LLONG, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_image("ct"), file + ": /images/ct has type int64, expected one of");

    replace_dataset(p, "/labels/liver", H5T_STD_I16LE, {2, 2, 2});
    {
        H5Id f = open_rw(p);
        H5Id ds(H5Dopen2(f, "/labels/liver", H5P_DEFAULT), H5Dclose);
        put_geometry(ds);
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_labels("liver"), file + ": /labels/liver has type int16, expected uint8");

    {
        H5Id f = open_rw(p);
        H5Ldelete(f, "/images/ct", H5P_DEFAULT);
        H5Id g(H5Gcreate2(f, "/images/ct", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_image("ct"), file + ": /images/ct is not a dataset");

    replace_dataset(p, "/surfaces/liver/vertices", H5T_IEEE_F64LE, {6, 2});
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_surface("liver"),
                      file + ": /surfaces/liver/vertices has shape (6, 2), expected (n, 3)");
    replace_dataset(p, "/meshes/liver/tets", H5T_IEEE_F32LE, {6, 4});
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_tet_mesh("liver"),
                      file + ": /meshes/liver/tets has type float32, expected int32");
}

TEST(Hdf5Container, AbsurdDimensionsAreRefusedWithoutAllocating)
{
    const BrokenFile bad = full_container();
    const fs::path& p = bad.p;
    const std::string& file = bad.file;
    // 2^20 cubed voxels: the header alone; reading it must fail on the limit, not on malloc.
    replace_dataset(p, "/images/ct", H5T_STD_I16LE, {1u << 20, 1u << 20, 1u << 20}, true);
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_image("ct"), file, "/images/ct", "exceed the limit");
    // 2^30 voxels is under the limit, but nothing is stored: 2 GiB of fill value is not an image.
    replace_dataset(p, "/images/ct", H5T_STD_I16LE, {1024, 1024, 1024}, true);
    {
        H5Id f = open_rw(p);
        H5Id ds(H5Dopen2(f, "/images/ct", H5P_DEFAULT), H5Dclose);
        put_geometry(ds);
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_image("ct"), file + ": /images/ct claims 2147483648 bytes");
    replace_dataset(p, "/meshes/liver/vertices", H5T_IEEE_F64LE, {hsize_t(1) << 40, 3}, true);
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_tet_mesh("liver"), "/meshes/liver/vertices has 1099511627776 rows");
}

TEST(Hdf5Container, MeshIndicesOutOfRange)
{
    const BrokenFile bad = full_container();
    const fs::path& p = bad.p;
    const std::string& file = bad.file;
    overwrite_data<std::int32_t>(p, "/surfaces/liver/triangles", H5T_NATIVE_INT32,
                                 {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 99, 3, 1, 5, 0, 3, 5});
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_surface("liver"),
                      file + ": /surfaces/liver/triangles: triangle 5 has vertex index 99 outside [0, 6)");
    auto mesh = cube_tets();
    std::vector<std::int32_t> flat;
    for (const auto& t : mesh.tets)
        flat.insert(flat.end(), t.begin(), t.end());
    flat[9] = -3;
    overwrite_data(p, "/meshes/liver/tets", H5T_NATIVE_INT32, flat);
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_tet_mesh("liver"),
                      file + ": /meshes/liver: tet 2 has vertex index -3 outside [0, 8)");
}

TEST(Hdf5Container, PerTetArraysOfTheWrongLength)
{
    const BrokenFile bad = full_container();
    const fs::path& p = bad.p;
    const std::string& file = bad.file;
    replace_dataset(p, "/meshes/liver/tet_labels", H5T_STD_I32LE, {5});
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_tet_mesh("liver"),
                      file + ": /meshes/liver/tet_labels has 5 values but the mesh has 6 tets");
    write_full(p);
    replace_dataset(p, "/meshes/liver/quality/min_dihedral_angle", H5T_IEEE_F64LE, {7});
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_tet_mesh("liver"),
                      file + ": /meshes/liver/quality/min_dihedral_angle has 7 values but the mesh has 6 tets");
    write_full(p);
    {
        H5Id f = open_rw(p);
        H5Ldelete(f, "/meshes/liver/tet_labels", H5P_DEFAULT);
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_tet_mesh("liver"), file + ": /meshes/liver/tet_labels is missing");
}

TEST(Hdf5Container, ProvenanceRecordWithoutTool)
{
    const BrokenFile bad = full_container();
    const fs::path& p = bad.p;
    const std::string& file = bad.file;
    {
        H5Id f = open_rw(p);
        H5Adelete_by_name(f, "/provenance/000_lseg", "tool", H5P_DEFAULT);
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).provenance(), file + ": /provenance/000_lseg has no tool attribute");
}

TEST(Hdf5Container, SoftLinksAndExternalStorageAreRefused)
{
    const BrokenFile bad = full_container();
    const fs::path& p = bad.p;
    const std::string& file = bad.file;
    {
        H5Id f = open_rw(p);
        H5Ldelete(f, "/images/ct", H5P_DEFAULT);
        H5Lcreate_soft("/labels/liver", f, "/images/ct", H5P_DEFAULT, H5P_DEFAULT);
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_image("ct"), file + ": /images/ct is a soft or external link");
    {
        // Raw data in an external file: the reader would read whatever file the header names.
        H5Id f = open_rw(p);
        H5Ldelete(f, "/images/ct", H5P_DEFAULT);
        const hsize_t dims[3] = {2, 2, 2};
        H5Id space(H5Screate_simple(3, dims, nullptr), H5Sclose);
        H5Id dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
        H5Pset_external(dcpl, "/etc/hostname", 0, 8);
        H5Id ds(H5Dcreate2(f, "/images/ct", H5T_STD_U8LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT), H5Dclose);
        put_geometry(ds);
    }
    EXPECT_LOBE_ERROR(InvalidInputError, Hdf5Reader(p).read_image("ct"), file + ": /images/ct keeps its data in external files");
}

} // namespace

TEST(Hdf5Container, LabelInfoGivesGeometryWithoutReading)
{
    const auto dir = lobe::test::scratch_dir();
    const auto labels = sphere_labels(12);
    {
        Hdf5Writer w(dir / "l.h5");
        w.write_labels("liver", labels, kTissues);
        w.commit();
    }
    const Hdf5Reader r(dir / "l.h5");
    const ImageInfo info = r.label_info("liver");
    EXPECT_EQ(info.pixel_type, lobe::core::PixelType::UInt8);
    EXPECT_TRUE(lobe::core::same_grid(info.geometry, labels, 1e-12)); // stored as float64: exact
    EXPECT_LOBE_ERROR(InvalidInputError, r.label_info("kidney"), "kidney");
}
