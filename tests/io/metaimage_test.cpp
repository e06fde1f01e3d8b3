// MetaImage reader and writer: round trips, the real files ITK ships, SLIVER07's layout, and
// every kind of bad input the issue lists.
#include "lobe/io/metaimage.h"

#include "common/expect_error.h"
#include "common/synthetic.h"
#include "common/test_data.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>

using lobe::test::expect_error;
using lobe::test::random_image;

using namespace lobe;
namespace fs = std::filesystem;

namespace {

core::ImageGeometry oblique_geometry(std::array<int, 3> size)
{
    core::ImageGeometry g;
    g.size = size;
    g.spacing = {0.703125, 0.8, 2.5};
    g.origin = {-172.9, 13.25, -368.0};
    // A rotation of 30 degrees about z then 10 about x: columns are unit and orthogonal.
    const double a = M_PI / 6, b = M_PI / 18;
    const double ca = std::cos(a), sa = std::sin(a), cb = std::cos(b), sb = std::sin(b);
    g.direction = {ca, -sa * cb, sa * sb, sa, ca * cb, -ca * sb, 0, sb, cb};
    return g;
}


void write_text(const fs::path& p, const std::string& s)
{
    std::ofstream f(p, std::ios::binary);
    f << s;
}



const std::string kSliverHeader = "ObjectType = Image\n"
                                  "NDims = 3\n"
                                  "BinaryData = True\n"
                                  "BinaryDataByteOrderMSB = False\n"
                                  "CompressedData = False\n"
                                  "TransformMatrix = 1 0 0 0 1 0 0 0 1\n"
                                  "Offset = -172.9 -179.3 -368\n"
                                  "CenterOfRotation = 0 0 0\n"
                                  "AnatomicalOrientation = RAI\n"
                                  "ElementSpacing = 0.74219 0.74219 1.5\n"
                                  "DimSize = 8 6 5\n"
                                  "ElementType = MET_SHORT\n"
                                  "ElementDataFile = liver-orig001.raw\n";

// Writes a SLIVER07-style header and raw data (MET_SHORT, little endian) into dir.
fs::path write_sliver_case(const fs::path& dir, std::size_t raw_bytes)
{
    write_text(dir / "liver-orig001.mhd", kSliverHeader);
    std::string raw(raw_bytes, '\0');
    for (std::size_t i = 0; i + 1 < raw_bytes; i += 2) {
        const auto v = static_cast<std::int16_t>(static_cast<int>(i / 2) * 7 - 1024);
        std::memcpy(&raw[i], &v, 2); // host is little endian (x86), as SLIVER07's files are
    }
    write_text(dir / "liver-orig001.raw", raw);
    return dir / "liver-orig001.mhd";
}

} // namespace

// --- round trips --------------------------------------------------------------------------------

template <class T>
class MetaImageRoundTrip : public ::testing::Test {};
using PixelTypes = ::testing::Types<std::uint8_t, std::int8_t, std::int16_t, std::uint16_t, std::int32_t,
                                    std::uint32_t, float, double>;
TYPED_TEST_SUITE(MetaImageRoundTrip, PixelTypes);

TYPED_TEST(MetaImageRoundTrip, BitExactInEveryLayout)
{
    const auto dir = test::scratch_dir();
    const auto g = oblique_geometry({7, 5, 3});
    const auto img = random_image<TypeParam>(g, 42);
    for (const char* name : {"a.mha", "b.mhd"}) {
        for (bool compress : {false, true}) {
            const fs::path p = dir / (std::string(compress ? "z" : "u") + name);
            io::MetaImageWriteParams params;
            params.compress = compress;
            io::write_metaimage(p, img, params);
            const auto back = io::read_metaimage(p);
            ASSERT_TRUE(std::holds_alternative<core::Image3D<TypeParam>>(back)) << p;
            const auto& b = std::get<core::Image3D<TypeParam>>(back);
            // Values are copied bytes, so equality is exact (memcmp also covers float NaN-free data).
            EXPECT_EQ(0, std::memcmp(b.data.data(), img.data.data(), img.data.size() * sizeof(TypeParam))) << p;
            EXPECT_EQ(b.size, g.size);
            // Numbers are written in shortest round-trip form, so geometry is bit-exact too.
            EXPECT_EQ(b.spacing, g.spacing);
            EXPECT_EQ(b.origin, g.origin);
            EXPECT_EQ(b.direction, g.direction);
        }
    }
    // No temporaries are left behind: exactly the files we asked for (.mhd brings its data file).
    int files = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir))
        ++files;
    EXPECT_EQ(files, 6); // ua.mha za.mha ub.mhd ub.raw zb.mhd zb.zraw
}

TEST(MetaImage, WritesTwoDimensionalImagesAsNDims2)
{
    const auto dir = test::scratch_dir();
    core::ImageGeometry g;
    g.size = {4, 3, 1};
    g.spacing = {0.5, 0.25, 1.0};
    g.origin = {10, 20, 0};
    core::Image3D<std::uint8_t> img(g);
    for (std::size_t i = 0; i < img.data.size(); ++i)
        img.data[i] = static_cast<std::uint8_t>(i);
    io::write_metaimage(dir / "slice.mha", img);
    const auto hdr = io::read_metaimage_header(dir / "slice.mha");
    EXPECT_EQ(hdr.ndims, 2);
    EXPECT_NE(test::read_file(dir / "slice.mha").find("DimSize = 4 3\n"), std::string::npos);
    const auto back = std::get<core::Image3D<std::uint8_t>>(io::read_metaimage(dir / "slice.mha"));
    EXPECT_EQ(back.data, img.data);
    EXPECT_EQ(back.origin, g.origin);

    // The same image forced to 3-D keeps a third dimension of 1.
    io::MetaImageWriteParams p3;
    p3.ndims = 3;
    io::write_metaimage(dir / "vol.mha", img, p3);
    EXPECT_EQ(io::read_metaimage_header(dir / "vol.mha").ndims, 3);
}

TEST(MetaImage, ReadsBigEndianData)
{
    const auto dir = test::scratch_dir();
    // Values 1, 256, -2 as big-endian int16: 00 01 | 01 00 | FF FE.
    const std::string header = "NDims = 3\nDimSize = 3 1 1\nElementType = MET_SHORT\n"
                               "BinaryDataByteOrderMSB = True\nElementDataFile = LOCAL\n";
    write_text(dir / "be.mha", header + std::string("\x00\x01\x01\x00\xFF\xFE", 6));
    const auto img = std::get<core::Image3D<std::int16_t>>(io::read_metaimage(dir / "be.mha"));
    EXPECT_EQ(img.data, (core::BigVector<std::int16_t>{1, 256, -2}));

    // ElementByteOrderMSB is the older spelling of the same field (BrainProtonDensity3Slices uses it).
    const std::string f32 = "NDims = 2\nDimSize = 1 1\nElementType = MET_FLOAT\n"
                            "ElementByteOrderMSB = True\nElementDataFile = LOCAL\n";
    write_text(dir / "bef.mha", f32 + std::string("\x3F\xC0\x00\x00", 4)); // 1.5f big endian
    EXPECT_EQ(std::get<core::Image3D<float>>(io::read_metaimage(dir / "bef.mha")).data[0], 1.5f);
}

TEST(MetaImage, ReadsHeaderSizeAsciiAndAbsolutePaths)
{
    const auto dir = test::scratch_dir();
    // HeaderSize = 4 skips 4 bytes of the data file; HeaderSize = -1 takes the last bytes.
    write_text(dir / "d.raw", std::string("JUNK\x05\x06", 6));
    write_text(dir / "skip.mhd", "NDims = 2\nDimSize = 2 1\nElementType = MET_UCHAR\nHeaderSize = 4\nElementDataFile = d.raw\n");
    EXPECT_EQ(std::get<core::Image3D<std::uint8_t>>(io::read_metaimage(dir / "skip.mhd")).data,
              (core::BigVector<std::uint8_t>{5, 6}));
    write_text(dir / "tail.mhd", "NDims = 2\nDimSize = 2 1\nElementType = MET_UCHAR\nHeaderSize = -1\nElementDataFile = " +
                                     (dir / "d.raw").string() + "\n"); // absolute data path
    EXPECT_EQ(std::get<core::Image3D<std::uint8_t>>(io::read_metaimage(dir / "tail.mhd")).data,
              (core::BigVector<std::uint8_t>{5, 6}));
    // BinaryData = False: whitespace-separated numbers.
    write_text(dir / "ascii.mha", "NDims = 2\nDimSize = 3 1\nElementType = MET_FLOAT\nBinaryData = False\n"
                                  "ElementDataFile = LOCAL\n0.5 -2\n7e1\n");
    EXPECT_EQ(std::get<core::Image3D<float>>(io::read_metaimage(dir / "ascii.mha")).data,
              (core::BigVector<float>{0.5f, -2.0f, 70.0f}));
}

TEST(MetaImage, DecodesFromMemory)
{
    const auto dir = test::scratch_dir();
    core::ImageGeometry g;
    g.size = {5, 4, 2};
    const auto img = random_image<std::uint16_t>(g, 3);
    io::MetaImageWriteParams p;
    p.compress = true;
    io::write_metaimage(dir / "m.mha", img, p);
    const auto images = io::decode_metaimage(test::read_file(dir / "m.mha"), "memory.mha");
    ASSERT_EQ(images.size(), 1u);
    EXPECT_EQ(std::get<core::Image3D<std::uint16_t>>(images[0]).data, img.data);
}

// --- real files ----------------------------------------------------------------------------------

TEST(MetaImage, ReadsEveryItkExampleFile)
{
    const auto dir = test::itk_data_dir();
    LOBE_REQUIRE_PATH(dir);
    int count = 0;
    for (const auto& e : fs::directory_iterator(dir)) {
        const auto ext = e.path().extension().string();
        if (ext != ".mha" && ext != ".mhd")
            continue;
        SCOPED_TRACE(e.path().string());
        const auto hdr = io::read_metaimage_header(e.path());
        const auto images = io::read_metaimage_channels(e.path());
        ASSERT_EQ(images.size(), static_cast<std::size_t>(hdr.channels));
        for (const auto& im : images)
            EXPECT_EQ(std::visit([](const auto& x) { return x.data.size(); }, im), hdr.geometry.voxel_count());
        ++count;
    }
    EXPECT_EQ(count, 21); // every .mha/.mhd in insighttoolkit5-examples 5.2.1
}

TEST(MetaImage, ItkExamplesHaveTheirStatedGeometryAndContent)
{
    const auto dir = test::itk_data_dir();
    LOBE_REQUIRE_PATH(dir);
    // The raw and the zlib-compressed versions of the same slice hold identical pixels.
    const auto plain = std::get<core::Image3D<std::uint8_t>>(io::read_metaimage(dir / "BrainProtonDensitySliceBorder20.mhd"));
    const auto rotated = std::get<core::Image3D<std::uint8_t>>(
        io::read_metaimage(dir / "BrainProtonDensitySliceBorder20DirectionPlus30.mhd"));
    EXPECT_EQ(plain.size, (std::array<int, 3>{221, 257, 1}));
    EXPECT_EQ(plain.data, rotated.data);
    // "Plus30": the x axis is rotated by +30 degrees, i.e. axis 0 = (cos 30, sin 30).
    EXPECT_NEAR(rotated.axis(0).x, std::cos(M_PI / 6), 1e-7);
    EXPECT_NEAR(rotated.axis(0).y, 0.5, 1e-7);
    EXPECT_NEAR(rotated.axis(1).x, -0.5, 1e-7);

    const auto cc = std::get<core::Image3D<float>>(io::read_metaimage(dir / "CorpusCallosumMeanShape.mha"));
    EXPECT_EQ(cc.size, (std::array<int, 3>{58, 31, 1}));
    EXPECT_EQ(cc.spacing[0], 2.0);
    EXPECT_EQ(cc.origin[0], -57.5);
    EXPECT_EQ(cc.origin[1], -30.5);

    // "Position" is MetaIO's alias of Offset.
    const auto b = io::read_metaimage_header(dir / "ResampleImageFilterInput2x3b.mha");
    EXPECT_EQ(b.geometry.origin[0], 60.0);
    EXPECT_EQ(b.geometry.spacing[1], 0.75);

    const auto three = io::read_metaimage_header(dir / "BrainProtonDensity3Slices.mha");
    EXPECT_EQ(three.geometry.size, (std::array<int, 3>{181, 217, 3}));
    EXPECT_FALSE(three.local);

    EXPECT_EQ(io::read_metaimage_channels(dir / "BayesianClassifierInitializerMemberships.mhd").size(), 4u);
    EXPECT_THROW(io::read_metaimage(dir / "itkBrainSliceComplex.mha"), core::InvalidInputError); // 2 channels
}

TEST(MetaImage, ReadsTheSliver07Layout)
{
    const auto dir = test::scratch_dir();
    const auto path = write_sliver_case(dir, 8 * 6 * 5 * 2);
    const auto img = io::read_metaimage(path);
    ASSERT_TRUE(std::holds_alternative<core::ImageI16>(img));
    const auto& ct = std::get<core::ImageI16>(img);
    EXPECT_EQ(ct.size, (std::array<int, 3>{8, 6, 5}));
    EXPECT_EQ(ct.spacing, (std::array<double, 3>{0.74219, 0.74219, 1.5}));
    EXPECT_EQ(ct.origin, (std::array<double, 3>{-172.9, -179.3, -368.0}));
    EXPECT_EQ(ct.at(0, 0, 0), -1024);
    EXPECT_EQ(ct.at(7, 5, 4), static_cast<std::int16_t>((8 * 6 * 5 - 1) * 7 - 1024));
    // Voxel (1, 0, 2) lies one column and two slices from the origin.
    const auto p = ct.index_to_physical(1, 0, 2);
    EXPECT_DOUBLE_EQ(p.x, -172.9 + 0.74219);
    EXPECT_DOUBLE_EQ(p.z, -368.0 + 3.0);
}

TEST(MetaImage, ReadsTheSharedCtVolume)
{
    const auto path = test::data_dir() / "ct-small" / "ct.mhd";
    LOBE_REQUIRE_PATH(path);
    const auto img = io::read_metaimage(path);
    ASSERT_TRUE(std::holds_alternative<core::ImageI16>(img));
    const auto& ct = std::get<core::ImageI16>(img);
    EXPECT_EQ(ct.size, (std::array<int, 3>{122, 101, 30})); // ../shared/data/README.md
    EXPECT_NEAR(ct.spacing[2], 3.0, 1e-6);
    // A CT in HU: air near -1000 somewhere, tissue and bone above 0.
    const auto [lo, hi] = core::value_range(img);
    EXPECT_LT(lo, -900);
    EXPECT_GT(hi, 200);
}

// --- bad input -----------------------------------------------------------------------------------

TEST(MetaImage, RejectsMissingAndTruncatedFiles)
{
    const auto dir = test::scratch_dir();
    expect_error<core::IoError>([&] { io::read_metaimage(dir / "nope.mhd"); }, {"nope.mhd", "does not exist"});

    write_sliver_case(dir, 8 * 6 * 5 * 2 - 10);
    expect_error<core::IoError>([&] { io::read_metaimage(dir / "liver-orig001.mhd"); },
                                {"liver-orig001", "truncated", "470", "480"});

    fs::remove(dir / "liver-orig001.raw");
    expect_error<core::IoError>([&] { io::read_metaimage(dir / "liver-orig001.mhd"); },
                                {"liver-orig001.raw", "does not exist", "ElementDataFile"});

    // More data than the header describes means the header is wrong too.
    write_sliver_case(dir, 8 * 6 * 5 * 2 + 64);
    expect_error<core::InvalidInputError>([&] { io::read_metaimage(dir / "liver-orig001.mhd"); },
                                          {"liver-orig001", "disagree"});

    // Truncated LOCAL data.
    write_text(dir / "t.mha", "NDims = 2\nDimSize = 4 4\nElementType = MET_SHORT\nElementDataFile = LOCAL\n" +
                                  std::string(10, 'x'));
    expect_error<core::IoError>([&] { io::read_metaimage(dir / "t.mha"); }, {"t.mha", "truncated", "10", "32"});
}

TEST(MetaImage, RejectsBadHeaderFields)
{
    const auto dir = test::scratch_dir();
    struct Case {
        const char* name;
        std::string header;
        std::vector<std::string> fragments;
    };
    const std::string tail = "ElementDataFile = LOCAL\n";
    const std::vector<Case> cases = {
        {"type.mha", "NDims = 2\nDimSize = 2 2\nElementType = MET_COMPLEX\n" + tail, {"ElementType", "MET_COMPLEX", "not supported"}},
        {"zero_spacing.mha", "NDims = 2\nDimSize = 2 2\nElementSpacing = 0 1\nElementType = MET_UCHAR\n" + tail, {"spacing", "positive"}},
        {"neg_spacing.mha", "NDims = 2\nDimSize = 2 2\nElementSpacing = 1 -0.5\nElementType = MET_UCHAR\n" + tail, {"spacing", "-0.5"}},
        {"nan_spacing.mha", "NDims = 2\nDimSize = 2 2\nElementSpacing = nan 1\nElementType = MET_UCHAR\n" + tail, {"spacing", "nan"}},
        {"overflow.mha", "NDims = 3\nDimSize = 4294967296 4294967296 4294967296\nElementType = MET_UCHAR\n" + tail, {"DimSize", "exceed"}},
        {"huge.mha", "NDims = 3\nDimSize = 100000 100000 100000\nElementType = MET_UCHAR\n" + tail, {"DimSize", "limit"}},
        {"negdim.mha", "NDims = 2\nDimSize = 2 -3\nElementType = MET_UCHAR\n" + tail, {"DimSize", "-3", "positive"}},
        {"count.mha", "NDims = 3\nDimSize = 2 2\nElementType = MET_UCHAR\n" + tail, {"DimSize", "2 values, expected 3"}},
        {"ndims.mha", "NDims = 4\nDimSize = 2 2 2 2\nElementType = MET_UCHAR\n" + tail, {"NDims = 4", "not supported"}},
        {"nodims.mha", "NDims = 2\nElementType = MET_UCHAR\n" + tail, {"no DimSize"}},
        {"nofile.mha", "NDims = 2\nDimSize = 2 2\nElementType = MET_UCHAR\n", {"no ElementDataFile"}},
        {"list.mhd", "NDims = 2\nDimSize = 2 2\nElementType = MET_UCHAR\nElementDataFile = LIST\n", {"LIST", "not supported"}},
        {"pattern.mhd", "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = slice%03d.raw 1 2 1\n", {"pattern"}},
        {"singular.mha", "NDims = 2\nDimSize = 2 2\nTransformMatrix = 1 0 1 0\nElementType = MET_UCHAR\n" + tail, {"singular"}},
        {"text.mha", "NDims = 2\nDimSize = two 2\nElementType = MET_UCHAR\n" + tail, {"DimSize", "not a list of numbers"}},
        {"garbage.mha", std::string("\x89PNG\r\n\x1a\n\x00\x00\x00\x0dIHDR", 16), {"not of the form"}},
        {"object.mha", "ObjectType = Mesh\nNDims = 2\nDimSize = 2 2\nElementType = MET_UCHAR\n" + tail, {"ObjectType", "not Image"}},
    };
    for (const auto& c : cases) {
        SCOPED_TRACE(c.name);
        // Binary data follows a complete header, as in a real file.
        const bool complete = c.header.find("ElementDataFile") != std::string::npos;
        write_text(dir / c.name, c.header + std::string(complete ? 64 : 0, '\0'));
        try {
            io::read_metaimage(dir / c.name);
            ADD_FAILURE() << "accepted";
        } catch (const core::InvalidInputError& e) {
            const std::string msg = e.what();
            EXPECT_NE(msg.find(c.name), std::string::npos) << msg;
            for (const auto& f : c.fragments)
                EXPECT_NE(msg.find(f), std::string::npos) << "'" << msg << "' lacks '" << f << "'";
        }
    }
}

TEST(MetaImage, RejectsCorruptCompressedData)
{
    const auto dir = test::scratch_dir();
    core::ImageGeometry g;
    g.size = {16, 16, 4};
    const auto img = random_image<std::int16_t>(g, 9);
    io::MetaImageWriteParams p;
    p.compress = true;
    io::write_metaimage(dir / "c.mha", img, p);
    const std::string good = test::read_file(dir / "c.mha");
    const auto hdr = io::read_metaimage_header(dir / "c.mha");

    // Flipped bytes in the middle of the deflate stream.
    std::string bad = good;
    for (std::size_t i = hdr.data_offset + 20; i < hdr.data_offset + 60; ++i)
        bad[i] = static_cast<char>(bad[i] ^ 0x5A);
    write_text(dir / "corrupt.mha", bad);
    EXPECT_THROW(io::read_metaimage(dir / "corrupt.mha"), core::Error);

    // Cut short: CompressedDataSize promises more bytes than follow.
    write_text(dir / "short.mha", good.substr(0, good.size() - 100));
    expect_error<core::IoError>([&] { io::read_metaimage(dir / "short.mha"); }, {"short.mha", "truncated"});

    // A stream that decompresses to less than DimSize asks for.
    std::string header = good.substr(0, hdr.data_offset);
    const auto at = header.find("DimSize = 16 16 4");
    ASSERT_NE(at, std::string::npos);
    header.replace(at, 17, "DimSize = 16 16 5");
    write_text(dir / "small.mha", header + good.substr(hdr.data_offset));
    expect_error<core::IoError>([&] { io::read_metaimage(dir / "small.mha"); }, {"small.mha", "decompresses to 2048", "2560"});

    // A tiny stream cannot hold a huge image: refused before allocating it.
    write_text(dir / "bomb.mha", "NDims = 3\nDimSize = 1024 1024 1024\nElementType = MET_DOUBLE\nCompressedData = True\n"
                                 "CompressedDataSize = 10\nElementDataFile = LOCAL\n0123456789");
    expect_error<core::InvalidInputError>([&] { io::read_metaimage(dir / "bomb.mha"); }, {"bomb.mha", "cannot hold"});
}

TEST(MetaImage, FailedWritesLeaveNothingBehind)
{
    const auto dir = test::scratch_dir();
    core::ImageGeometry g;
    g.size = {3, 3, 3};
    core::Image3D<float> img(g, 1.0f);
    expect_error<core::IoError>([&] { io::write_metaimage(dir / "missing" / "x.mha", img); }, {"missing", "does not exist"});

    // An invalid image does not replace an existing good file.
    io::write_metaimage(dir / "keep.mhd", img);
    const std::string before = test::read_file(dir / "keep.mhd");
    auto broken = img;
    broken.spacing[1] = -1.0;
    expect_error<core::InvalidInputError>([&] { io::write_metaimage(dir / "keep.mhd", broken); }, {"keep.mhd", "spacing"});
    EXPECT_EQ(test::read_file(dir / "keep.mhd"), before);
    broken = img;
    broken.data.pop_back();
    EXPECT_THROW(io::write_metaimage(dir / "keep.mhd", broken), core::InvalidInputError);
    EXPECT_THROW(io::write_metaimage(dir / "x.png", img), core::InvalidInputError);

    EXPECT_EQ(test::list_dir(dir), (std::vector<std::string>{"keep.mhd", "keep.raw"}));
}
