// NIfTI-1 reader and writer: round trips of every pixel type, the three transforms (sform,
// qform with either handedness, pixdim only), scaling, units, byte order, 4-D series, the real
// scans in ../shared/data checked against their MetaImage twins, and every bad input the issue
// lists. Malformed files are made by writing a valid one and patching its header with
// nifti_clib's own struct, so each test changes exactly one field.
#include "lobe/io/nifti.h"
#include "lobe/io/metaimage.h"

#include "common/expect_error.h"
#include "common/synthetic.h"
#include "common/test_data.h"

#include <gtest/gtest.h>
#include <nifti1_io.h>
#include <zlib.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

using namespace lobe;
namespace fs = std::filesystem;
using lobe::test::random_image;

namespace {

// Anisotropic, oblique, off-origin. Spacing and origin are exact in float32 (NIfTI-1 stores
// the affine as float32), so the round trip can be held to 1e-6 mm; the rotation (3-4-5 about
// z, then 7-24-25 about x) has cosines that are not, which costs ~1e-7 per entry.
core::ImageGeometry oblique_geometry(std::array<int, 3> size, bool left_handed = false)
{
    core::ImageGeometry g;
    g.size = size;
    g.spacing = {0.75, 1.25, 2.5};
    g.origin = {-120.5, 87.25, -33.125};
    const double ca = 0.6, sa = 0.8, cb = 24.0 / 25.0, sb = 7.0 / 25.0;
    // Rz(a) * Rx(b), row-major; columns are the image axes.
    g.direction = {ca, -sa * cb, sa * sb, sa, ca * cb, -ca * sb, 0, sb, cb};
    if (left_handed)
        for (int r = 0; r < 3; ++r)
            g.direction[3 * r + 2] = -g.direction[3 * r + 2];
    return g;
}


template <class V>
bool bit_equal(const V& a, const V& b)
{
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(typename V::value_type)) == 0;
}

void expect_geometry_near(const core::ImageGeometry& actual, const core::ImageGeometry& expected, double tol)
{
    EXPECT_EQ(actual.size, expected.size);
    for (int a = 0; a < 3; ++a) {
        EXPECT_NEAR(actual.spacing[a], expected.spacing[a], tol) << "spacing " << a;
        EXPECT_NEAR(actual.origin[a], expected.origin[a], tol) << "origin " << a;
    }
    for (int i = 0; i < 9; ++i)
        EXPECT_NEAR(actual.direction[i], expected.direction[i], tol) << "direction " << i;
}

std::string read_bytes(const fs::path& p)
{
    std::ifstream f(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& p, const std::string& s)
{
    std::ofstream f(p, std::ios::binary | std::ios::trunc);
    f.write(s.data(), static_cast<std::streamsize>(s.size()));
}

// Changes the header of an uncompressed .nii in place through nifti_clib's struct.
void patch_header(const fs::path& p, const std::function<void(nifti_1_header&)>& change)
{
    std::string bytes = read_bytes(p);
    ASSERT_GE(bytes.size(), sizeof(nifti_1_header));
    nifti_1_header h;
    std::memcpy(&h, bytes.data(), sizeof h);
    change(h);
    std::memcpy(bytes.data(), &h, sizeof h);
    write_bytes(p, bytes);
}

void gzip_file(const fs::path& in, const fs::path& out)
{
    const std::string bytes = read_bytes(in);
    gzFile gz = gzopen(out.string().c_str(), "wb");
    ASSERT_NE(gz, nullptr);
    ASSERT_EQ(gzwrite(gz, bytes.data(), static_cast<unsigned>(bytes.size())), static_cast<int>(bytes.size()));
    ASSERT_EQ(gzclose(gz), Z_OK);
}

// A valid little int16 file to break.
fs::path small_nii(const fs::path& dir, const std::string& name = "small.nii")
{
    const fs::path p = dir / name;
    io::write_nifti(p, random_image<std::int16_t>(oblique_geometry({6, 5, 4}), 7));
    return p;
}

// Runs `f`, which must throw E with a message naming `path` (and containing `needle`).
template <class E>
void expect_error(const std::function<void()>& f, const fs::path& path, const std::string& needle = {})
{
    test::expect_error<E>(f, {path.string(), needle});
}

template <class T>
void round_trip(const fs::path& dir, const std::string& ext)
{
    SCOPED_TRACE(std::string(core::pixel_type_name(core::pixel_type_of<T>())) + ext);
    const auto g = oblique_geometry({9, 7, 5});
    const auto img = random_image<T>(g, 42);
    const fs::path p = dir / (std::string(core::pixel_type_name(core::pixel_type_of<T>())) + ext);
    io::write_nifti(p, img);
    const core::AnyImage back = io::read_nifti(p);
    ASSERT_TRUE(std::holds_alternative<core::Image3D<T>>(back));
    const auto& b = std::get<core::Image3D<T>>(back);
    // Spacing and origin are float32-exact and the cosines lose ~1e-7 in float32: 1e-6 holds.
    expect_geometry_near(b, g, 1e-6);
    EXPECT_TRUE(bit_equal(b.data, img.data)) << "voxels differ";
}

} // namespace

TEST(Nifti, RoundTripsEveryPixelTypeBitExact)
{
    const fs::path dir = test::scratch_dir();
    for (const std::string ext : {".nii", ".nii.gz"}) {
        round_trip<std::uint8_t>(dir, ext);
        round_trip<std::int8_t>(dir, ext);
        round_trip<std::int16_t>(dir, ext);
        round_trip<std::uint16_t>(dir, ext);
        round_trip<std::int32_t>(dir, ext);
        round_trip<std::uint32_t>(dir, ext);
        round_trip<float>(dir, ext);
        round_trip<double>(dir, ext);
    }
    // The .nii.gz really is gzip (magic 1f 8b) and the .nii really is not.
    const std::string gz = read_bytes(dir / "int16.nii.gz");
    ASSERT_GE(gz.size(), 2u);
    EXPECT_EQ(static_cast<unsigned char>(gz[0]), 0x1f);
    EXPECT_EQ(static_cast<unsigned char>(gz[1]), 0x8b);
    // 9 x 7 x 5 int16 after the 352-byte header, exactly.
    EXPECT_EQ(fs::file_size(dir / "int16.nii"), 352u + 9u * 7u * 5u * 2u);
}

TEST(Nifti, WritesBothTransformsInMmWithScannerCode)
{
    const fs::path dir = test::scratch_dir();
    const fs::path p = small_nii(dir);
    const io::NiftiHeader h = io::read_nifti_header(p);
    EXPECT_EQ(h.sform_code, NIFTI_XFORM_SCANNER_ANAT);
    EXPECT_EQ(h.qform_code, NIFTI_XFORM_SCANNER_ANAT);
    EXPECT_EQ(h.transform, io::NiftiTransform::Sform);
    EXPECT_EQ(h.data_offset, 352);
    EXPECT_FALSE(h.scaled);
    // nifti_clib's own reading of our file: mm units, and both transforms place the far corner
    // at the same RAS point. The qform is a float32 quaternion, so allow 1e-4 mm over ~20 mm.
    nifti_image* nim = nifti_image_read(p.string().c_str(), 0);
    ASSERT_NE(nim, nullptr);
    EXPECT_EQ(nim->xyz_units, NIFTI_UNITS_MM);
    for (int r = 0; r < 3; ++r) {
        const float i = 5, j = 4, k = 3;
        const auto& s4 = nim->sto_xyz.m[r];
        const auto& q4 = nim->qto_xyz.m[r];
        const float s = s4[0] * i + s4[1] * j + s4[2] * k + s4[3];
        const float q = q4[0] * i + q4[1] * j + q4[2] * k + q4[3];
        EXPECT_NEAR(static_cast<double>(s), static_cast<double>(q), 1e-4) << "row " << r;
    }
    nifti_image_free(nim);
}

TEST(Nifti, RoundTrips2DImage)
{
    const fs::path dir = test::scratch_dir();
    const auto g = oblique_geometry({17, 9, 1});
    const auto img = random_image<float>(g, 3);
    for (const std::string name : {"slice.nii", "slice.nii.gz"}) {
        const fs::path p = dir / name;
        io::write_nifti(p, img);
        const io::NiftiHeader h = io::read_nifti_header(p);
        EXPECT_EQ(h.ndims, 2); // written as a 2-D file
        const auto back = std::get<core::ImageF>(io::read_nifti(p));
        // The third axis (spacing 2.5, oblique direction) survives in pixdim[3] and the sform.
        expect_geometry_near(back, g, 1e-6);
        EXPECT_TRUE(bit_equal(back.data, img.data));
    }
}

TEST(Nifti, LeftHandedGeometryFromSformAndFromQform)
{
    const fs::path dir = test::scratch_dir();
    const auto g = oblique_geometry({8, 6, 4}, /*left_handed=*/true);
    const auto img = random_image<std::int16_t>(g, 5);
    const fs::path p = dir / "left.nii";
    io::write_nifti(p, img);

    // Sform: float32-exact spacing/origin, ~1e-7 on cosines.
    expect_geometry_near(std::get<core::ImageI16>(io::read_nifti(p)), g, 1e-6);

    // Without the sform the qform is used, and its negative qfac (pixdim[0] = -1) must flip
    // the third axis. The quaternion is float32, so cosines are good to ~1e-7 (1e-6 asserted).
    float qfac = 0;
    patch_header(p, [&](nifti_1_header& h) {
        qfac = h.pixdim[0];
        h.sform_code = 0;
    });
    EXPECT_EQ(qfac, -1.0f);
    const io::NiftiHeader h = io::read_nifti_header(p);
    EXPECT_EQ(h.transform, io::NiftiTransform::Qform);
    const auto q = std::get<core::ImageI16>(io::read_nifti(p));
    expect_geometry_near(q, g, 1e-6);
    const core::Vec3 axis2 = q.axis(2);
    const core::Vec3 expected2 = g.axis(2);
    EXPECT_GT(core::dot(axis2, expected2), 0.999999); // not flipped
    const core::Vec3 c = cross(q.axis(0), q.axis(1));
    EXPECT_LT(core::dot(c, axis2), -0.999999); // left-handed
    EXPECT_TRUE(bit_equal(q.data, img.data));
}

TEST(Nifti, PixdimOnlyTransformIsRasDiagonal)
{
    const fs::path dir = test::scratch_dir();
    const fs::path p = small_nii(dir);
    patch_header(p, [](nifti_1_header& h) {
        h.sform_code = 0;
        h.qform_code = 0;
    });
    const auto img = std::get<core::ImageI16>(io::read_nifti(p));
    EXPECT_EQ(io::read_nifti_header(p).transform, io::NiftiTransform::Pixdim);
    // Method 1: x = pixdim[1] * i in RAS, origin 0; in LPS the first two axes point backwards.
    const std::array<double, 9> expected{-1, 0, 0, 0, -1, 0, 0, 0, 1};
    for (int i = 0; i < 9; ++i)
        EXPECT_EQ(img.direction[i], expected[i]);
    EXPECT_EQ(img.spacing, (std::array<double, 3>{0.75, 1.25, 2.5})); // pixdim, float32-exact
    EXPECT_EQ(img.origin, (std::array<double, 3>{0, 0, 0}));
}

TEST(Nifti, AppliesScalingAsFloat)
{
    const fs::path dir = test::scratch_dir();
    const fs::path p = dir / "scaled.nii";
    const auto g = oblique_geometry({5, 4, 3});
    const auto img = random_image<std::int16_t>(g, 11);
    io::write_nifti(p, img);

    patch_header(p, [](nifti_1_header& h) {
        h.scl_slope = 2.0f;
        h.scl_inter = -1024.0f;
    });
    const core::AnyImage scaled = io::read_nifti(p);
    ASSERT_TRUE(std::holds_alternative<core::ImageF>(scaled));
    const auto& f = std::get<core::ImageF>(scaled);
    expect_geometry_near(f, g, 1e-6);
    // 2 * v - 1024 is an integer below 2^17 in magnitude: float32 holds it exactly.
    for (std::size_t i = 0; i < img.data.size(); ++i)
        ASSERT_EQ(f.data[i], 2.0f * static_cast<float>(img.data[i]) - 1024.0f) << i;

    // Slope 0 (the standard's "none"), NaN (nibabel's "none") and the identity keep int16.
    for (const float slope : {0.0f, std::numeric_limits<float>::quiet_NaN(), 1.0f}) {
        patch_header(p, [slope](nifti_1_header& h) {
            h.scl_slope = slope;
            h.scl_inter = 0.0f;
        });
        const core::AnyImage raw = io::read_nifti(p);
        ASSERT_TRUE(std::holds_alternative<core::ImageI16>(raw)) << slope;
        EXPECT_TRUE(bit_equal(std::get<core::ImageI16>(raw).data, img.data));
    }

    // A valid slope with a NaN intercept is corrupt.
    patch_header(p, [](nifti_1_header& h) {
        h.scl_slope = 2.0f;
        h.scl_inter = std::numeric_limits<float>::quiet_NaN();
    });
    expect_error<core::InvalidInputError>([&] { io::read_nifti(p); }, p, "scl_inter");

    // float64 data stays float64 when scaled (float32 would lose what the file stored).
    const fs::path pd = dir / "scaled64.nii";
    const auto d = random_image<double>(g, 12);
    io::write_nifti(pd, d);
    patch_header(pd, [](nifti_1_header& h) {
        h.scl_slope = 0.5f;
        h.scl_inter = 3.0f;
    });
    const auto back = std::get<core::Image3D<double>>(io::read_nifti(pd));
    for (std::size_t i = 7; i < d.data.size(); ++i) // after the NaN/inf specials
        ASSERT_EQ(back.data[i], 0.5 * d.data[i] + 3.0) << i;
}

TEST(Nifti, ConvertsMetresToMillimetres)
{
    const fs::path dir = test::scratch_dir();
    const fs::path p = small_nii(dir);
    patch_header(p, [](nifti_1_header& h) { h.xyzt_units = SPACE_TIME_TO_XYZT(NIFTI_UNITS_METER, NIFTI_UNITS_SEC); });
    const auto img = std::get<core::ImageI16>(io::read_nifti(p));
    auto g = oblique_geometry({6, 5, 4});
    for (int a = 0; a < 3; ++a) {
        g.spacing[a] *= 1000;
        g.origin[a] *= 1000;
    }
    // The float32 cosine error (~1e-7) times 1000 mm-per-unit: 1e-3 mm.
    expect_geometry_near(img, g, 1e-3);
    EXPECT_EQ(io::read_nifti_header(p).unit_to_mm, 1000.0);
}

TEST(Nifti, ReadsBigEndianFile)
{
    const fs::path dir = test::scratch_dir();
    const fs::path p = dir / "big.nii";
    const auto g = oblique_geometry({7, 3, 2});
    const auto img = random_image<float>(g, 9);
    io::write_nifti(p, img);
    // Swap header and voxels with nifti_clib's own routines: a file a big-endian machine wrote.
    std::string bytes = read_bytes(p);
    nifti_1_header h;
    std::memcpy(&h, bytes.data(), sizeof h);
    swap_nifti_header(&h, 1);
    std::memcpy(bytes.data(), &h, sizeof h);
    nifti_swap_4bytes(img.data.size(), bytes.data() + 352);
    write_bytes(p, bytes);

    EXPECT_TRUE(io::read_nifti_header(p).byte_swapped);
    const auto back = std::get<core::ImageF>(io::read_nifti(p));
    expect_geometry_near(back, g, 1e-6);
    EXPECT_TRUE(bit_equal(back.data, img.data));
}

TEST(Nifti, SeriesNeedsAVolumeIndex)
{
    const fs::path dir = test::scratch_dir();
    const fs::path p = dir / "series.nii.gz";
    // A 4 x 3 x 2 x 3 int16 series written by nifti_clib itself, with a header extension so
    // that the data starts after byte 352.
    const int dims[8] = {4, 4, 3, 2, 3, 1, 1, 1};
    nifti_set_debug_level(0);
    nifti_image* nim = nifti_make_new_nim(dims, DT_INT16, 1);
    ASSERT_NE(nim, nullptr);
    auto* v = static_cast<std::int16_t*>(nim->data);
    for (std::size_t i = 0; i < nim->nvox; ++i)
        v[i] = static_cast<std::int16_t>(1000 + i);
    const char comment[] = "lobe test extension";
    ASSERT_EQ(nifti_add_extension(nim, comment, sizeof comment, NIFTI_ECODE_COMMENT), 0);
    ASSERT_EQ(nifti_set_filenames(nim, p.string().c_str(), 0, 1), 0);
    nifti_image_write(nim);
    nifti_image_free(nim);

    const io::NiftiHeader h = io::read_nifti_header(p);
    EXPECT_EQ(h.volumes, 3);
    EXPECT_GT(h.data_offset, 352);
    expect_error<core::InvalidInputError>([&] { io::read_nifti(p); }, p, "3 volumes");
    expect_error<core::InvalidInputError>([&] { io::read_nifti(p, io::NiftiReadParams{3}); }, p, "volume 3");

    // Volume 2 holds values 1000 + 24*2 ... 1000 + 24*2 + 23, x fastest.
    const auto vol = std::get<core::ImageI16>(io::read_nifti(p, io::NiftiReadParams{2}));
    EXPECT_EQ(vol.size, (std::array<int, 3>{4, 3, 2}));
    for (std::size_t i = 0; i < vol.data.size(); ++i)
        ASSERT_EQ(vol.data[i], 1000 + 48 + static_cast<int>(i)) << i;
}

// ---- real scans: NIfTI against the MetaImage of the same volume -------------------------------

namespace {

// Every voxel centre of `nii` must be a voxel centre of `mhd` (to 1e-3 mm) holding the same
// value. This compares in physical space, so it holds whatever index order each file uses.
template <class T>
void expect_same_volume(const core::Image3D<T>& nii, const core::Image3D<T>& mhd)
{
    ASSERT_EQ(nii.voxel_count(), mhd.voxel_count());
    for (int a = 0; a < 3; ++a)
        EXPECT_NEAR(nii.spacing[a], mhd.spacing[a], 1e-3);
    double worst = 0;
    std::size_t outside = 0, differ = 0;
    for (int k = 0; k < nii.size[2]; ++k)
        for (int j = 0; j < nii.size[1]; ++j)
            for (int i = 0; i < nii.size[0]; ++i) {
                const core::Vec3 q = mhd.physical_to_index(nii.index_to_physical(i, j, k));
                const int qi = static_cast<int>(std::lround(q.x)), qj = static_cast<int>(std::lround(q.y)),
                          qk = static_cast<int>(std::lround(q.z));
                const core::Vec3 off{(q.x - qi) * mhd.spacing[0], (q.y - qj) * mhd.spacing[1],
                                     (q.z - qk) * mhd.spacing[2]};
                worst = std::max(worst, core::norm(off));
                if (!mhd.contains(qi, qj, qk)) {
                    ++outside;
                    continue;
                }
                if (nii.at(i, j, k) != mhd.at(qi, qj, qk))
                    ++differ;
            }
    EXPECT_LT(worst, 1e-3) << "mm between a NIfTI voxel centre and the nearest MetaImage one";
    EXPECT_EQ(outside, 0u);
    EXPECT_EQ(differ, 0u);
}

// The far corner through nifti_clib's own affine (nifti_image_read -> sto_xyz), RAS -> LPS.
core::Vec3 corner_by_nifti_clib(const fs::path& p, std::array<int, 3> ijk)
{
    nifti_set_debug_level(0);
    nifti_image* nim = nifti_image_read(p.string().c_str(), 0);
    if (!nim)
        return {NAN, NAN, NAN};
    const mat44& m = nim->sform_code > 0 ? nim->sto_xyz : nim->qto_xyz;
    core::Vec3 ras;
    for (int r = 0; r < 3; ++r)
        ras[r] = static_cast<double>(m.m[r][0]) * ijk[0] + static_cast<double>(m.m[r][1]) * ijk[1] +
                 static_cast<double>(m.m[r][2]) * ijk[2] + static_cast<double>(m.m[r][3]);
    nifti_image_free(nim);
    return {-ras.x, -ras.y, ras.z};
}

template <class T>
void check_against_metaimage(const fs::path& nii_path, const fs::path& mhd_path)
{
    SCOPED_TRACE(nii_path.string());
    const auto nii = std::get<core::Image3D<T>>(io::read_nifti(nii_path));
    core::AnyImage mhd_any;
    try {
        mhd_any = io::read_metaimage(mhd_path);
    } catch (const std::exception& e) {
        GTEST_SKIP() << "read_metaimage is not ready: " << e.what();
    }
    ASSERT_TRUE(std::holds_alternative<core::Image3D<T>>(mhd_any));
    expect_same_volume(nii, std::get<core::Image3D<T>>(mhd_any));

    const std::array<int, 3> far{nii.size[0] - 1, nii.size[1] - 1, nii.size[2] - 1};
    const core::Vec3 ours = nii.index_to_physical(far[0], far[1], far[2]);
    const core::Vec3 theirs = corner_by_nifti_clib(nii_path, far);
    // Same float32 affine, evaluated in double by both: 1e-3 mm is generous.
    EXPECT_LT(core::distance(ours, theirs), 1e-3) << "far corner vs nifti_clib's sto_xyz";
}

} // namespace

TEST(Nifti, CtSmallMatchesMetaImage)
{
    const fs::path dir = test::data_dir() / "ct-small";
    LOBE_REQUIRE_PATH(dir / "ct.nii.gz");
    check_against_metaimage<std::int16_t>(dir / "ct.nii.gz", dir / "ct.mhd");

    // Numbers from ct.nii.gz's header, printed by nifti_clib's disp_nifti_1_header:
    // sform_code 2, srow_x = 3 0 0 -177.956329, srow_y = 0 3 0 11.319, srow_z = 0 0 3 94.301758.
    // In LPS: origin (177.956329, -11.319, 94.301758), axes -x, -y, +z, spacing 3 mm.
    const auto ct = std::get<core::ImageI16>(io::read_nifti(dir / "ct.nii.gz"));
    EXPECT_EQ(ct.size, (std::array<int, 3>{122, 101, 30}));
    EXPECT_NEAR(ct.origin[0], 177.956329, 1e-3);
    EXPECT_NEAR(ct.origin[1], -11.319, 1e-3);
    EXPECT_NEAR(ct.origin[2], 94.301758, 1e-3);
    const std::array<double, 9> flip_xy{-1, 0, 0, 0, -1, 0, 0, 0, 1};
    for (int i = 0; i < 9; ++i)
        EXPECT_EQ(ct.direction[i], flip_xy[i]);
    for (int a = 0; a < 3; ++a)
        EXPECT_EQ(ct.spacing[a], 3.0);
    // ct.mhd stores the same voxels re-ordered to an identity direction, so its Offset is the
    // NIfTI's far corner in x and y: (177.956 - 3 * 121, -11.319 - 3 * 100) = (-185.044, -311.319).
    const core::Vec3 c = ct.index_to_physical(121, 100, 0);
    EXPECT_NEAR(c.x, -185.043671, 1e-3);
    EXPECT_NEAR(c.y, -311.319, 1e-3);
    EXPECT_NEAR(c.z, 94.301758, 1e-3);
}

TEST(Nifti, CtSmallLabelsMatchMetaImage)
{
    const fs::path dir = test::data_dir() / "ct-small";
    LOBE_REQUIRE_PATH(dir / "labels.nii.gz");
    // This file has header extensions (vox_offset 13168): the reader must skip them.
    EXPECT_EQ(io::read_nifti_header(dir / "labels.nii.gz").data_offset, 13168);
    check_against_metaimage<std::uint8_t>(dir / "labels.nii.gz", dir / "labels.mhd");
}

TEST(Nifti, MrSmallMatchesMetaImage)
{
    const fs::path dir = test::data_dir() / "mr-small";
    LOBE_REQUIRE_PATH(dir / "mr.nii.gz");
    check_against_metaimage<std::int16_t>(dir / "mr.nii.gz", dir / "mr.mhd");
    // Here the sform is diag(-3, -3, 3) in RAS, i.e. LPS-aligned: the two files have the same
    // grid, not only the same voxel centres (origin from srow: -168.59964, -166.359436, 28.989641).
    const auto mr = std::get<core::ImageI16>(io::read_nifti(dir / "mr.nii.gz"));
    core::AnyImage mhd;
    try {
        mhd = io::read_metaimage(dir / "mr.mhd");
    } catch (const std::exception& e) {
        GTEST_SKIP() << "read_metaimage is not ready: " << e.what();
    }
    const auto& m = std::get<core::ImageI16>(mhd);
    expect_geometry_near(mr, m, 1e-3);
    EXPECT_TRUE(bit_equal(mr.data, m.data));
    EXPECT_NEAR(mr.origin[0], -168.59964, 1e-3);
}

// ---- bad input -------------------------------------------------------------------------------

TEST(Nifti, MissingFileIsIoError)
{
    const fs::path p = test::scratch_dir() / "absent.nii.gz";
    expect_error<core::IoError>([&] { io::read_nifti(p); }, p, "does not exist");
    expect_error<core::IoError>([&] { io::read_nifti_header(p); }, p, "does not exist");
}

TEST(Nifti, WrongExtensionIsInvalidInput)
{
    const fs::path dir = test::scratch_dir();
    const fs::path p = small_nii(dir);
    const fs::path img = dir / "small.img";
    fs::copy_file(p, img);
    expect_error<core::InvalidInputError>([&] { io::read_nifti(img); }, img, ".nii");
    expect_error<core::InvalidInputError>([&] { io::write_nifti(dir / "out.mha", io::read_nifti(p)); },
                                          dir / "out.mha", ".nii");
}

TEST(Nifti, TruncatedNiiIsIoError)
{
    const fs::path dir = test::scratch_dir();
    const fs::path p = small_nii(dir);
    const std::string bytes = read_bytes(p);
    // Cut inside the voxels: found from the file size, before anything is allocated.
    write_bytes(p, bytes.substr(0, 352 + 50));
    expect_error<core::IoError>([&] { io::read_nifti(p); }, p, "truncated");
    // Cut inside the header.
    write_bytes(p, bytes.substr(0, 200));
    expect_error<core::IoError>([&] { io::read_nifti(p); }, p, "header");
}

TEST(Nifti, CorruptGzipIsIoError)
{
    const fs::path dir = test::scratch_dir();
    // Random voxels (deflate stores them nearly verbatim: only the CRC can see a flipped byte)
    // and smooth voxels (Huffman-coded: a flipped byte breaks decoding or the CRC).
    const auto g = oblique_geometry({64, 64, 8});
    core::ImageI16 smooth(g);
    for (int k = 0; k < 8; ++k)
        for (int j = 0; j < 64; ++j)
            for (int i = 0; i < 64; ++i)
                smooth.at(i, j, k) = static_cast<std::int16_t>((i * j + 7 * k) % 300);
    const std::vector<std::pair<std::string, core::AnyImage>> cases{
        {"random.nii.gz", random_image<std::int16_t>(g, 1)}, {"smooth.nii.gz", smooth}};
    for (const auto& [name, img] : cases) {
        const fs::path p = dir / name;
        io::write_nifti(p, img);
        std::string bytes = read_bytes(p);
        ASSERT_GT(bytes.size(), 1000u);
        bytes[bytes.size() / 2] = static_cast<char>(bytes[bytes.size() / 2] ^ 0x5a);
        write_bytes(p, bytes);
        expect_error<core::IoError>([&] { io::read_nifti(p); }, p, "gzip");

        // Truncated stream.
        io::write_nifti(p, img);
        write_bytes(p, read_bytes(p).substr(0, bytes.size() / 2));
        expect_error<core::IoError>([&] { io::read_nifti(p); }, p);
    }
    // Garbage from the first byte: not even the header decompresses.
    const fs::path junk = dir / "junk.nii.gz";
    write_bytes(junk, std::string("\x1f\x8b\x08\x00") + std::string(400, '\x7f'));
    expect_error<core::IoError>([&] { io::read_nifti(junk); }, junk, "header");
}

TEST(Nifti, ZeroDimIsInvalidInput)
{
    const fs::path p = small_nii(test::scratch_dir());
    patch_header(p, [](nifti_1_header& h) { h.dim[1] = 0; });
    expect_error<core::InvalidInputError>([&] { io::read_nifti(p); }, p, "dim[1] is 0");
    patch_header(p, [](nifti_1_header& h) {
        h.dim[1] = 6;
        h.dim[3] = -4;
    });
    expect_error<core::InvalidInputError>([&] { io::read_nifti(p); }, p, "dim[3] is -4");
    patch_header(p, [](nifti_1_header& h) { h.dim[0] = 9; });
    expect_error<core::InvalidInputError>([&] { io::read_nifti(p); }, p, "dim[0]");
}

TEST(Nifti, HugeDimsAreRefusedBeforeAllocation)
{
    const fs::path dir = test::scratch_dir();
    const fs::path p = small_nii(dir);
    // 32767^3 = 3.5e13 voxels: above kMaxVoxels, refused from the header alone.
    patch_header(p, [](nifti_1_header& h) { h.dim[1] = h.dim[2] = h.dim[3] = 32767; });
    expect_error<core::InvalidInputError>([&] { io::read_nifti(p); }, p, "exceed the limit");

    // 2048 x 2048 x 400 = 1.7e9 voxels is within the limit, but the 3.4 GB it promises are not
    // in the file: an IoError from the file size, not an allocation.
    patch_header(p, [](nifti_1_header& h) {
        h.dim[1] = 2048;
        h.dim[2] = 2048;
        h.dim[3] = 400;
    });
    expect_error<core::IoError>([&] { io::read_nifti(p); }, p, "truncated");
    // The same header gzip-compressed: no gzip stream of this size can expand to 3.4 GB.
    const fs::path gz = dir / "huge.nii.gz";
    gzip_file(p, gz);
    expect_error<core::IoError>([&] { io::read_nifti(gz); }, gz, "cannot expand");
}

TEST(Nifti, BadPixdimIsInvalidInput)
{
    const fs::path p = small_nii(test::scratch_dir());
    for (const float bad : {std::numeric_limits<float>::quiet_NaN(), 0.0f, -1.5f,
                            std::numeric_limits<float>::infinity()}) {
        patch_header(p, [bad](nifti_1_header& h) {
            h.pixdim[1] = 0.75f;
            h.pixdim[2] = bad;
        });
        expect_error<core::InvalidInputError>([&] { io::read_nifti(p); }, p, "pixdim[2]");
    }
}

TEST(Nifti, NotNifti1IsInvalidInput)
{
    const fs::path dir = test::scratch_dir();
    const fs::path p = small_nii(dir);
    patch_header(p, [](nifti_1_header& h) { std::memcpy(h.magic, "xyz", 4); });
    expect_error<core::InvalidInputError>([&] { io::read_nifti(p); }, p, "magic");
    patch_header(p, [](nifti_1_header& h) { std::memcpy(h.magic, "ni1", 4); });
    expect_error<core::InvalidInputError>([&] { io::read_nifti(p); }, p, ".hdr/.img");
    patch_header(p, [](nifti_1_header& h) {
        std::memcpy(h.magic, "n+1", 4);
        h.sizeof_hdr = 123;
    });
    expect_error<core::InvalidInputError>([&] { io::read_nifti(p); }, p, "sizeof_hdr");

    // A NIfTI-2 header (540 bytes, magic "n+2" at byte 4).
    const fs::path n2 = dir / "two.nii";
    std::string h2(560, '\0');
    const std::int32_t size2 = 540;
    std::memcpy(h2.data(), &size2, 4);
    std::memcpy(h2.data() + 4, "n+2\0\r\n\032\n", 8);
    write_bytes(n2, h2);
    expect_error<core::InvalidInputError>([&] { io::read_nifti(n2); }, n2, "NIfTI-2");

    // A gzip file named .nii.
    const fs::path gz = dir / "zipped.nii";
    io::write_nifti(dir / "real.nii.gz", io::read_nifti(small_nii(dir, "again.nii")));
    fs::copy_file(dir / "real.nii.gz", gz);
    expect_error<core::InvalidInputError>([&] { io::read_nifti(gz); }, gz, "name it .nii.gz");
}

TEST(Nifti, UnsupportedDatatypeIsInvalidInput)
{
    const fs::path p = small_nii(test::scratch_dir());
    for (const short dt : {short(DT_COMPLEX64), short(DT_RGB24), short(DT_INT64), short(DT_BINARY), short(0)}) {
        patch_header(p, [dt](nifti_1_header& h) { h.datatype = dt; });
        expect_error<core::InvalidInputError>([&] { io::read_nifti(p); }, p, "datatype " + std::to_string(dt));
    }
    // Vector data: dim[0] = 5 with 3 components per voxel.
    patch_header(p, [](nifti_1_header& h) {
        h.datatype = DT_INT16;
        h.dim[0] = 5;
        h.dim[4] = 1;
        h.dim[5] = 3;
    });
    expect_error<core::InvalidInputError>([&] { io::read_nifti(p); }, p, "scalar");
}

TEST(Nifti, FailedWriteLeavesNoFile)
{
    const fs::path dir = test::scratch_dir();
    const auto img = random_image<std::uint8_t>(oblique_geometry({4, 4, 4}), 2);

    // Into a folder that does not exist.
    const fs::path missing = dir / "no-such-folder" / "out.nii.gz";
    expect_error<core::IoError>([&] { io::write_nifti(missing, img); }, missing);
    EXPECT_FALSE(fs::exists(missing.parent_path()));

    // Onto a path that is a folder: the temporary is written, the rename fails, and the
    // temporary is removed.
    const fs::path blocked = dir / "blocked.nii";
    fs::create_directory(blocked);
    expect_error<core::IoError>([&] { io::write_nifti(blocked, img); }, blocked);

    // Invalid geometry and mismatched data are refused before anything is created.
    auto bad = img;
    bad.spacing[1] = 0;
    expect_error<core::InvalidInputError>([&] { io::write_nifti(dir / "bad.nii", bad); }, dir / "bad.nii");
    auto short_data = img;
    short_data.data.pop_back();
    expect_error<core::InvalidInputError>([&] { io::write_nifti(dir / "short.nii", short_data); },
                                          dir / "short.nii");
    core::ImageGeometry wide_grid;
    wide_grid.size = {40000, 1, 1};
    const core::LabelImage3D wide(wide_grid);
    expect_error<core::InvalidInputError>([&] { io::write_nifti(dir / "wide.nii", wide); }, dir / "wide.nii",
                                          "32767");

    // Into a read-only folder (root may write anyway, so only checked for other users).
    const fs::path locked = dir / "locked";
    fs::create_directory(locked);
    fs::permissions(locked, fs::perms::owner_read | fs::perms::owner_exec);
    if (::geteuid() != 0) {
        expect_error<core::IoError>([&] { io::write_nifti(locked / "out.nii.gz", img); }, locked / "out.nii.gz",
                                    "cannot create");
        EXPECT_TRUE(fs::is_empty(locked));
    }
    fs::permissions(locked, fs::perms::owner_all);
    fs::remove(locked);

    std::vector<std::string> left;
    for (const auto& e : fs::directory_iterator(dir))
        left.push_back(e.path().filename().string());
    EXPECT_EQ(left, std::vector<std::string>{"blocked.nii"}) << "only the pre-existing folder may remain";
    EXPECT_TRUE(fs::is_empty(blocked));
}
