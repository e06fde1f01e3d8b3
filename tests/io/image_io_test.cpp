// Format dispatch: every writable format round-trips through read_image/write_image.
#include "lobe/io/image_io.h"

#include "lobe/core/errors.h"

#include "common/test_data.h"

#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <chrono>
#include <fstream>

using namespace lobe;
namespace fs = std::filesystem;

TEST(ImageIo, ChoosesTheFormatFromThePath)
{
    EXPECT_EQ(io::image_format("a/b.mhd"), io::ImageFormat::MetaImage);
    EXPECT_EQ(io::image_format("B.MHA"), io::ImageFormat::MetaImage);
    EXPECT_EQ(io::image_format("ct.nii.gz"), io::ImageFormat::Nifti);
    EXPECT_EQ(io::image_format("ct.nii"), io::ImageFormat::Nifti);
    EXPECT_EQ(io::image_format("seg.h5"), io::ImageFormat::Hdf5);
    EXPECT_EQ(io::image_format("x.dcm"), io::ImageFormat::Dicom);
    EXPECT_EQ(io::image_format(test::scratch_dir()), io::ImageFormat::Dicom); // a folder
    try {
        io::image_format("scan.png");
        FAIL();
    } catch (const core::InvalidInputError& e) {
        EXPECT_NE(std::string(e.what()).find("scan.png"), std::string::npos);
        EXPECT_NE(std::string(e.what()).find(".nii.gz"), std::string::npos);
    }
}

TEST(ImageIo, RoundTripsEveryWritableFormat)
{
    const auto dir = test::scratch_dir();
    core::ImageGeometry g;
    g.size = {6, 5, 4};
    g.spacing = {0.7, 0.7, 2.5};
    g.origin = {-120.5, 33.0, -410.25};
    core::Image3D<std::int16_t> img(g);
    for (std::size_t i = 0; i < img.data.size(); ++i)
        img.data[i] = static_cast<std::int16_t>(static_cast<int>(i) * 37 - 1024);
    for (const char* name : {"ct.mha", "ct.mhd", "ct.nii", "ct.nii.gz", "ct.h5"}) {
        SCOPED_TRACE(name);
        io::write_image(dir / name, img);
        const auto back = io::read_image(dir / name);
        ASSERT_TRUE(std::holds_alternative<core::ImageI16>(back));
        const auto& b = std::get<core::ImageI16>(back);
        EXPECT_EQ(b.data, img.data); // integer pixels are stored as they are: exact
        // NIfTI keeps its affine in float32: 1e-4 mm covers float rounding of coordinates ~400 mm.
        EXPECT_TRUE(core::same_grid(b, g, 1e-4));
    }
}

TEST(ImageIo, DicomIsReadOnly)
{
    const auto dir = test::scratch_dir();
    core::ImageGeometry g;
    g.size = {2, 2, 2};
    core::Image3D<float> img(g);
    EXPECT_THROW(io::write_image(dir / "x.dcm", img), core::InvalidInputError);
    EXPECT_THROW(io::write_image(dir, img), core::InvalidInputError);
    EXPECT_TRUE(fs::is_empty(dir));
}

namespace {

// An INRIMAGE-4 file written by hand: the header's fields, padded to 256 bytes, then `data`.
void write_inr(const fs::path& path, const std::string& fields, const std::string& data)
{
    std::string header = "#INRIMAGE-4#{\n" + fields + "##}\n";
    header.insert(header.size() - 4, std::string(256 - header.size(), '\n'));
    std::ofstream(path, std::ios::binary) << header << data;
}

} // namespace

TEST(Inrimage, ReadsByteOrderTypesAndSpacing)
{
    const auto dir = test::scratch_dir();
    // 3 x 2 x 1 unsigned 16-bit, big endian (CPU=sun): voxel i holds 256 i + 1.
    std::string be;
    for (int i = 0; i < 6; ++i) {
        be.push_back(static_cast<char>(i));
        be.push_back(1);
    }
    write_inr(dir / "a.inr", "XDIM=3\nYDIM=2\nZDIM=1\nVDIM=1\nVX=0.5\nVY=0.25\nVZ=2\nTYPE=unsigned fixed\nPIXSIZE=16 bits\nCPU=sun\n", be);
    EXPECT_EQ(io::image_format(dir / "a.inr"), io::ImageFormat::Inrimage);
    const auto img = std::get<core::Image3D<std::uint16_t>>(io::read_image(dir / "a.inr"));
    EXPECT_EQ(img.size, (std::array<int, 3>{3, 2, 1}));
    EXPECT_EQ(img.spacing, (std::array<double, 3>{0.5, 0.25, 2}));
    for (int i = 0; i < 6; ++i)
        EXPECT_EQ(img.data[static_cast<std::size_t>(i)], 256 * i + 1);
    // 32-bit float, little endian (CPU=decm).
    float v[2] = {1.5f, -2.25f};
    std::string le(reinterpret_cast<const char*>(v), sizeof v);
    write_inr(dir / "f.inr", "XDIM=2\nYDIM=1\nZDIM=1\nTYPE=float\nPIXSIZE=32 bits\nCPU=decm\n", le);
    const auto f = std::get<core::ImageF>(io::read_image(dir / "f.inr"));
    EXPECT_EQ(f.data, (core::BigVector<float>{1.5f, -2.25f}));
}

TEST(Inrimage, RefusesBadFilesNamingThem)
{
    const auto dir = test::scratch_dir();
    auto refused = [&](const std::string& file, const std::string& fields, const std::string& data,
                       const std::string& what) {
        write_inr(dir / file, fields, data);
        try {
            io::read_image(dir / file);
            ADD_FAILURE() << file << " was read";
        } catch (const core::InvalidInputError& e) {
            const std::string m = e.what();
            EXPECT_NE(m.find(file), std::string::npos) << m;
            EXPECT_NE(m.find(what), std::string::npos) << m;
        }
    };
    const std::string ok = "XDIM=2\nYDIM=2\nZDIM=1\nTYPE=unsigned fixed\nPIXSIZE=8 bits\n";
    refused("short.inr", ok, "ab", "truncated INRIMAGE data");
    refused("vector.inr", ok + "VDIM=3\n", std::string(12, 'x'), "vector INRIMAGE");
    refused("type.inr", "XDIM=2\nYDIM=2\nZDIM=1\nTYPE=packed\nPIXSIZE=8 bits\n", "abcd", "unsupported INRIMAGE pixel type");
    refused("nodim.inr", "YDIM=2\nZDIM=1\nTYPE=unsigned fixed\nPIXSIZE=8 bits\n", "abcd", "XDIM");
    refused("cpu.inr", ok + "CPU=vax\n", "abcd", "byte order");
    // A few hundred bytes promising 2 x 10^9 voxels (the limit allows it): refused from the file's
    // size before anything is allocated, plain or gzipped (each took over 10 s and gigabytes
    // under the fuzzer before; here the test's time bound is the check).
    const std::string huge = "XDIM=2000\nYDIM=1000\nZDIM=1000\nTYPE=unsigned fixed\nPIXSIZE=8 bits\n";
    const auto t0 = std::chrono::steady_clock::now();
    refused("huge.inr", huge, "abcd", "the header promises 2000000000 bytes of voxels but the file holds 4");
    {
        std::string header = "#INRIMAGE-4#{\n" + huge + "##}\n";
        header.insert(header.size() - 4, std::string(256 - header.size(), '\n'));
        gzFile gz = gzopen((dir / "huge.inr.gz").string().c_str(), "wb");
        ASSERT_NE(gz, nullptr);
        gzwrite(gz, header.data(), static_cast<unsigned>(header.size()));
        gzwrite(gz, "abcd", 4);
        gzclose(gz);
        try {
            io::read_image(dir / "huge.inr.gz");
            ADD_FAILURE() << "huge.inr.gz was read";
        } catch (const core::InvalidInputError& e) {
            EXPECT_NE(std::string(e.what()).find("cannot expand to that many"), std::string::npos) << e.what();
        }
    }
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 1.0);
    std::ofstream(dir / "not.inr") << std::string(300, 'x');
    EXPECT_THROW(io::read_image(dir / "not.inr"), core::InvalidInputError);
    EXPECT_THROW(io::write_image(dir / "out.inr", core::LabelImage3D({}, 0)), core::InvalidInputError);
}

TEST(Inrimage, ReadsCgalsLabelledLiver)
{
    // The shared copy of CGAL's Mesh_3 example image: 438 x 353 x 329 uint8, 0.617 x 0.617 x
    // 0.667 mm (docs/benchmarks.md counts its labels: 6 322 002 voxels of 255).
    const auto path = test::data_dir() / "liver-labels-inr" / "liver.inr.gz";
    LOBE_REQUIRE_PATH(path);
    const auto img = std::get<core::LabelImage3D>(io::read_image(path));
    EXPECT_EQ(img.size, (std::array<int, 3>{438, 353, 329}));
    EXPECT_NEAR(img.spacing[0], 0.617, 5e-4);
    EXPECT_NEAR(img.spacing[2], 0.667, 5e-4);
    EXPECT_EQ(std::count(img.data.begin(), img.data.end(), std::uint8_t{255}), 6322002);
}
