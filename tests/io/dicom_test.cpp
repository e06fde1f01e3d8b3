// DICOM series reader: the real JPEG 2000 CT series against its label grid, pydicom's files in
// every transfer syntax, and series fabricated here with GDCM's writer for sorting, geometry,
// rescaling and each kind of bad input.
#include "lobe/io/dicom.h"
#include "lobe/io/metaimage.h"

#include "common/expect_error.h"
#include "common/test_data.h"

#include <gdcmDataElement.h>
#include <gdcmDataSet.h>
#include <gdcmFile.h>
#include <gdcmImage.h>
#include <gdcmImageReader.h>
#include <gdcmItem.h>
#include <gdcmSequenceOfItems.h>
#include <gdcmTrace.h>
#include <gdcmTransferSyntax.h>
#include <gdcmWriter.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

using lobe::test::expect_error;

using namespace lobe;
namespace fs = std::filesystem;

namespace {

// ---- fabricating files ------------------------------------------------------------------------

// Puts a text value, padded to even length as DICOM requires (UI with NUL, others with space).
void put_text(gdcm::DataSet& ds, gdcm::Tag tag, gdcm::VR vr, std::string value)
{
    if (value.size() % 2)
        value += vr == gdcm::VR::UI ? '\0' : ' ';
    gdcm::DataElement de(tag);
    de.SetVR(vr);
    de.SetByteValue(value.data(), static_cast<std::uint32_t>(value.size()));
    ds.Replace(de);
}

void put_us(gdcm::DataSet& ds, gdcm::Tag tag, std::uint16_t v)
{
    gdcm::DataElement de(tag);
    de.SetVR(gdcm::VR::US);
    de.SetByteValue(reinterpret_cast<const char*>(&v), 2);
    ds.Replace(de);
}

std::string ds_numbers(std::initializer_list<double> values)
{
    std::string s;
    for (double v : values) {
        char buf[32];
        std::snprintf(buf, sizeof buf, "%.10g", v); // DS holds at most 16 characters
        s += (s.empty() ? "" : "\\") + std::string(buf);
    }
    return s;
}

gdcm::DataElement sequence(gdcm::Tag tag, const std::vector<gdcm::DataSet>& item_sets)
{
    gdcm::SmartPointer<gdcm::SequenceOfItems> sq = new gdcm::SequenceOfItems;
    sq->SetLengthToUndefined();
    for (const auto& set : item_sets) {
        gdcm::Item item;
        item.SetVLToUndefined();
        item.SetNestedDataSet(set);
        sq->AddItem(item);
    }
    gdcm::DataElement de(tag);
    de.SetVR(gdcm::VR::SQ);
    de.SetValue(*sq);
    de.SetVLToUndefined();
    return de;
}

// One slice (or multi-frame file) as the tests want it; fields left empty are not written.
struct SliceSpec {
    int columns = 6, rows = 5, frames = 1;
    std::string position = "0\\0\\0";             // ImagePositionPatient
    std::string orientation = "1\\0\\0\\0\\1\\0"; // ImageOrientationPatient
    std::string pixel_spacing = "0.8\\0.6";       // rows, columns [mm]
    std::string slope, intercept;                 // RescaleSlope/Intercept
    std::string series_uid = "1.2.826.0.1.3680043.10.1138.1";
    std::string modality = "CT";
    std::string description = "synthetic";
    std::string sop_class = "1.2.840.10008.5.1.4.1.1.2"; // CT Image Storage
    int bits_stored = 16, pixel_representation = 1;
    std::vector<std::int16_t> pixels; // columns * rows * frames
    bool pixel_data = true;
    // Extra elements, e.g. functional group sequences.
    std::vector<gdcm::DataElement> extra;
};

int file_counter = 0;

void write_dicom(const fs::path& path, const SliceSpec& s)
{
    gdcm::Trace::WarningOff(); // GDCM's writer warns about what these tests do on purpose
    gdcm::Writer w;
    gdcm::File& file = w.GetFile();
    gdcm::DataSet& ds = file.GetDataSet();
    put_text(ds, gdcm::Tag(0x0008, 0x0016), gdcm::VR::UI, s.sop_class);
    put_text(ds, gdcm::Tag(0x0008, 0x0018), gdcm::VR::UI,
             "1.2.826.0.1.3680043.10.1138.2." + std::to_string(++file_counter));
    put_text(ds, gdcm::Tag(0x0008, 0x0060), gdcm::VR::CS, s.modality);
    put_text(ds, gdcm::Tag(0x0008, 0x103e), gdcm::VR::LO, s.description);
    put_text(ds, gdcm::Tag(0x0020, 0x000d), gdcm::VR::UI, "1.2.826.0.1.3680043.10.1138.3");
    if (!s.series_uid.empty())
        put_text(ds, gdcm::Tag(0x0020, 0x000e), gdcm::VR::UI, s.series_uid);
    if (!s.position.empty())
        put_text(ds, gdcm::Tag(0x0020, 0x0032), gdcm::VR::DS, s.position);
    if (!s.orientation.empty())
        put_text(ds, gdcm::Tag(0x0020, 0x0037), gdcm::VR::DS, s.orientation);
    if (s.pixel_data) {
        put_us(ds, gdcm::Tag(0x0028, 0x0002), 1);
        put_text(ds, gdcm::Tag(0x0028, 0x0004), gdcm::VR::CS, "MONOCHROME2");
        if (s.frames > 1)
            put_text(ds, gdcm::Tag(0x0028, 0x0008), gdcm::VR::IS, std::to_string(s.frames));
        put_us(ds, gdcm::Tag(0x0028, 0x0010), static_cast<std::uint16_t>(s.rows));
        put_us(ds, gdcm::Tag(0x0028, 0x0011), static_cast<std::uint16_t>(s.columns));
        if (!s.pixel_spacing.empty())
            put_text(ds, gdcm::Tag(0x0028, 0x0030), gdcm::VR::DS, s.pixel_spacing);
        put_us(ds, gdcm::Tag(0x0028, 0x0100), 16);
        put_us(ds, gdcm::Tag(0x0028, 0x0101), static_cast<std::uint16_t>(s.bits_stored));
        put_us(ds, gdcm::Tag(0x0028, 0x0102), static_cast<std::uint16_t>(s.bits_stored - 1));
        put_us(ds, gdcm::Tag(0x0028, 0x0103), static_cast<std::uint16_t>(s.pixel_representation));
        if (!s.intercept.empty())
            put_text(ds, gdcm::Tag(0x0028, 0x1052), gdcm::VR::DS, s.intercept);
        if (!s.slope.empty())
            put_text(ds, gdcm::Tag(0x0028, 0x1053), gdcm::VR::DS, s.slope);
        std::vector<std::int16_t> px = s.pixels;
        px.resize(static_cast<std::size_t>(s.columns * s.rows * s.frames), 0);
        gdcm::DataElement de(gdcm::Tag(0x7fe0, 0x0010));
        de.SetVR(gdcm::VR::OW);
        de.SetByteValue(reinterpret_cast<const char*>(px.data()), static_cast<std::uint32_t>(px.size() * 2));
        ds.Replace(de);
    }
    for (const auto& de : s.extra)
        ds.Replace(de);
    file.GetHeader().SetDataSetTransferSyntax(gdcm::TransferSyntax::ExplicitVRLittleEndian);
    w.SetFileName(path.string().c_str());
    ASSERT_TRUE(w.Write()) << path;
}

// Pixel values that say where they are: slice k, row j, column i.
std::vector<std::int16_t> coded_pixels(int columns, int rows, int k)
{
    std::vector<std::int16_t> px;
    for (int j = 0; j < rows; ++j)
        for (int i = 0; i < columns; ++i)
            px.push_back(static_cast<std::int16_t>(1000 * k + 10 * j + i));
    return px;
}

// A regular axial stack of `n` slices along z, written as name0.dcm ... in the given order.
std::vector<fs::path> write_stack(const fs::path& dir, int n, double z0, double dz, const SliceSpec& base = {})
{
    std::vector<fs::path> paths;
    for (int k = 0; k < n; ++k) {
        SliceSpec s = base;
        s.position = ds_numbers({-10.0, 20.0, z0 + k * dz});
        s.pixels = coded_pixels(s.columns, s.rows, k);
        paths.push_back(dir / ("slice" + std::to_string(k) + ".dcm"));
        write_dicom(paths.back(), s);
    }
    return paths;
}

std::vector<char> read_bytes(const fs::path& p)
{
    std::ifstream f(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& p, const std::vector<char>& bytes, std::size_t n)
{
    // A new file rather than a truncated one: ext4 flushes a truncated file to disk on close.
    fs::remove(p);
    std::ofstream f(p, std::ios::binary);
    f.write(bytes.data(), static_cast<std::streamsize>(n));
}


template <class T> const core::Image3D<T>& as(const core::AnyImage& img)
{
    return std::get<core::Image3D<T>>(img);
}

fs::path ct_series()
{
    return test::data_dir() / "ct-dicom-jpeg2000" / "dicom";
}

// The CT series, read once for the tests that only look at it (20 JPEG 2000 slices).
const io::DicomSeries& ct_read()
{
    static const io::DicomSeries s = io::read_dicom_series(ct_series());
    return s;
}
fs::path pydicom(const char* name)
{
    return test::pydicom_data_dir() / name;
}

} // namespace

// ---- the real CT series ---------------------------------------------------------------------

TEST(DicomSeries, ReadsTheJpeg2000CtSeries)
{
    LOBE_REQUIRE_PATH(ct_series());
    const io::DicomSeries& s = ct_read();
    const auto& g = core::geometry(s.image);
    // The numbers ../shared/data/README.md states for this series.
    EXPECT_EQ(g.size, (std::array<int, 3>{512, 512, 20}));
    // PixelSpacing is 0.9765625 exactly; positions step by exactly 2.0 mm (SliceThickness says
    // 3, which the reader must not use).
    EXPECT_NEAR(g.spacing[0], 0.977, 1e-3);
    EXPECT_NEAR(g.spacing[1], 0.977, 1e-3);
    EXPECT_NEAR(g.spacing[2], 2.0, 1e-3);
    // The lowest slice along the normal (0,0,1) is at z = -804.5; x, y are the IPP's.
    EXPECT_NEAR(g.origin[0], -249.512, 1e-3);
    EXPECT_NEAR(g.origin[1], -437.512, 1e-3);
    EXPECT_NEAR(g.origin[2], -804.5, 1e-3);
    for (int i = 0; i < 9; ++i) // IOP is exactly 1\0\0\0\1\0
        EXPECT_EQ(g.direction[static_cast<std::size_t>(i)], i % 4 == 0 ? 1.0 : 0.0);
    EXPECT_EQ(core::pixel_type(s.image), core::PixelType::Int16);
    EXPECT_EQ(s.modality, "CT");
    EXPECT_EQ(s.series_uid, ""); // these files carry an empty SeriesInstanceUID
    ASSERT_EQ(s.files.size(), 20u);
    // Files named by instance: ...573 is at z = -766.5 (top), ...592 at z = -804.5 (bottom).
    EXPECT_EQ(s.files.front().filename().string().substr(s.files.front().filename().string().size() - 3), "592");
    EXPECT_EQ(s.files.back().filename().string().substr(s.files.back().filename().string().size() - 3), "573");
}

TEST(DicomSeries, CtSeriesLiesOnItsLabelGrid)
{
    LOBE_REQUIRE_PATH(ct_series());
    const auto dir = ct_series().parent_path();
    const io::DicomSeries& s = ct_read();
    const auto& ct = as<std::int16_t>(s.image);
    for (const char* name : {"labels.mhd", "liver.mhd"}) {
        SCOPED_TRACE(name);
        const core::AnyImage labels = io::read_metaimage(dir / name);
        // Same grid to 1e-3 mm: the .mhd Offset is written with 6 decimals (-249.511719 for
        // -249.51171875), so they agree to 5e-7 mm.
        EXPECT_TRUE(core::same_grid(ct, core::geometry(labels), 1e-3));
    }
    const auto liver = core::convert_image<std::uint8_t>(io::read_metaimage(dir / "liver.mhd"));
    double sum = 0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < ct.data.size(); ++i)
        if (liver.data[i] == 1) {
            sum += ct.data[i];
            ++n;
        }
    ASSERT_GT(n, 10000u); // the liver is in these slices
    // Liver parenchyma reads 80-100 HU on this contrast CT (README); a wrong intercept, a
    // flipped axis or a wrong slice order would land far outside.
    EXPECT_GT(sum / double(n), 80.0);
    EXPECT_LT(sum / double(n), 100.0);
}

TEST(DicomSeries, CtSeriesAppliesTheIntercept)
{
    LOBE_REQUIRE_PATH(ct_series());
    const io::DicomSeries& s = ct_read();
    const auto& ct = as<std::int16_t>(s.image);
    // Decode the bottom slice with GDCM alone: every HU value must be stored + (-1024),
    // exactly (integers), and the slice must be k = 0.
    gdcm::ImageReader r;
    r.SetFileName(s.files.front().string().c_str());
    ASSERT_TRUE(r.Read());
    const gdcm::Image& im = r.GetImage();
    ASSERT_EQ(im.GetPixelFormat().GetScalarType(), gdcm::PixelFormat::UINT16);
    std::vector<std::uint16_t> stored(512 * 512);
    ASSERT_EQ(im.GetBufferLength(), stored.size() * 2);
    ASSERT_TRUE(im.GetBuffer(reinterpret_cast<char*>(stored.data())));
    std::size_t mismatches = 0;
    for (std::size_t i = 0; i < stored.size(); ++i)
        mismatches += ct.data[i] != static_cast<int>(stored[i]) - 1024;
    EXPECT_EQ(mismatches, 0u);
    // Air outside the body: stored 0 becomes -1024 HU.
    EXPECT_EQ(ct.at(0, 0, 0), static_cast<int>(stored[0]) - 1024);
}

TEST(DicomSeries, ListsTheCtSeries)
{
    LOBE_REQUIRE_PATH(ct_series());
    const auto list = io::list_dicom_series(ct_series());
    ASSERT_EQ(list.size(), 1u);
    EXPECT_EQ(list[0].slices, 20);
    EXPECT_EQ(list[0].size, (std::array<int, 2>{512, 512}));
    EXPECT_EQ(list[0].modality, "CT");
    EXPECT_EQ(list[0].files.size(), 20u);
}

TEST(DicomSeries, ReadsOneFileOfASeries)
{
    LOBE_REQUIRE_PATH(ct_series());
    // The bottom slice (z = -804.5), instance 286.
    const fs::path one = ct_series() / "CT.1.3.12.2.1107.5.1.4.60064.30000022120808113428000016592";
    const io::DicomSeries s = io::read_dicom_series(one);
    const auto& g = core::geometry(s.image);
    EXPECT_EQ(g.size, (std::array<int, 3>{512, 512, 1}));
    EXPECT_NEAR(g.origin[2], -804.5, 1e-9);
    // One slice has no neighbour: SliceThickness (3 mm) is the only thickness it states.
    EXPECT_NEAR(g.spacing[2], 3.0, 1e-9);
}

// ---- pydicom's files --------------------------------------------------------------------------

TEST(DicomSeries, ReadsPydicomCtSmall)
{
    LOBE_REQUIRE_PATH(pydicom("CT_small.dcm"));
    const io::DicomSeries s = io::read_dicom_series(pydicom("CT_small.dcm"));
    const auto& ct = as<std::int16_t>(s.image);
    // Header values as gdcmdump prints them: PixelSpacing 0.661468\0.661468, IPP
    // -158.135803\-179.035797\-75.699997, SpacingBetweenSlices 5; parsed exactly.
    EXPECT_EQ(ct.size, (std::array<int, 3>{128, 128, 1}));
    EXPECT_DOUBLE_EQ(ct.spacing[0], 0.661468);
    EXPECT_DOUBLE_EQ(ct.spacing[1], 0.661468);
    EXPECT_DOUBLE_EQ(ct.spacing[2], 5.0);
    EXPECT_DOUBLE_EQ(ct.origin[0], -158.135803);
    EXPECT_DOUBLE_EQ(ct.origin[1], -179.035797);
    EXPECT_DOUBLE_EQ(ct.origin[2], -75.699997);
    // Stored values read with gdcmraw + od (175, 180 at the first two pixels, 1928 at
    // (64,64), 909 at the last), plus RescaleIntercept -1024, slope 1: exact integers.
    EXPECT_EQ(ct.at(0, 0, 0), 175 - 1024);
    EXPECT_EQ(ct.at(1, 0, 0), 180 - 1024);
    EXPECT_EQ(ct.at(64, 64, 0), 1928 - 1024);
    EXPECT_EQ(ct.at(127, 127, 0), 909 - 1024);
    EXPECT_EQ(s.series_uid, "1.3.6.1.4.1.5962.1.3.1.1.20040119072730.12322");
}

TEST(DicomSeries, AllMrSmallTransferSyntaxesDecodeAlike)
{
    LOBE_REQUIRE_PATH(pydicom("MR_small.dcm"));
    const io::DicomSeries ref = io::read_dicom_series(pydicom("MR_small.dcm"));
    const auto& mr = as<std::int16_t>(ref.image);
    // gdcmdump: 64 x 64, PixelSpacing 0.3125, IPP -83.9063\-91.2000\6.6406; gdcmraw: stored
    // 905, 1019 at the first pixels and 316 at (20,10); no rescale, so values are as stored.
    EXPECT_EQ(mr.size, (std::array<int, 3>{64, 64, 1}));
    EXPECT_DOUBLE_EQ(mr.spacing[0], 0.3125);
    EXPECT_DOUBLE_EQ(mr.origin[0], -83.9063);
    EXPECT_DOUBLE_EQ(mr.origin[1], -91.2);
    EXPECT_DOUBLE_EQ(mr.origin[2], 6.6406);
    EXPECT_EQ(mr.at(0, 0, 0), 905);
    EXPECT_EQ(mr.at(1, 0, 0), 1019);
    EXPECT_EQ(mr.at(20, 10, 0), 316);
    for (const char* name : {"MR_small_bigendian.dcm", "MR_small_expb.dcm", "MR_small_implicit.dcm", "MR_small_RLE.dcm",
                             "MR_small_jp2klossless.dcm", "MR_small_jpeg_ls_lossless.dcm", "MR_small_padded.dcm"}) {
        SCOPED_TRACE(name);
        const io::DicomSeries s = io::read_dicom_series(pydicom(name));
        ASSERT_EQ(core::pixel_type(s.image), core::PixelType::Int16);
        const auto& other = as<std::int16_t>(s.image);
        // Lossless syntaxes of the same pixels: identical values and identical header text.
        EXPECT_TRUE(core::same_grid(mr, other, 0.0));
        EXPECT_EQ(other.data, mr.data);
    }
}

TEST(DicomSeries, TruncatedFileFailsCleanly)
{
    LOBE_REQUIRE_PATH(pydicom("MR_truncated.dcm"));
    // GDCM alone reads this file and decodes its missing rows as zeros; the reader must not.
    expect_error<core::IoError>([] { io::read_dicom_series(pydicom("MR_truncated.dcm")); },
                                {"MR_truncated.dcm", "truncated", "(7fe0,0010)"});
}

TEST(DicomSeries, FilesCutAtAnyByteFailCleanly)
{
    LOBE_REQUIRE_PATH(pydicom("MR_small.dcm"));
    const auto dir = test::scratch_dir();
    const fs::path cut = dir / "cut.dcm";
    // Every cut in the header (where GDCM itself would abort on an assertion) and a sample
    // of cuts in the pixel data, for each encoding: each must be a lobe error naming the file.
    for (const char* name : {"MR_small.dcm", "MR_small_implicit.dcm", "MR_small_bigendian.dcm", "MR_small_RLE.dcm",
                             "MR_small_jp2klossless.dcm", "CT_small.dcm"}) {
        SCOPED_TRACE(name);
        const std::vector<char> bytes = read_bytes(pydicom(name));
        // CT_small.dcm ends with 138 bytes of Data Set Trailing Padding (FFFC,FFFC) after its
        // pixels; without them it is still a complete image.
        const std::size_t complete = bytes.size() - (std::string(name) == "CT_small.dcm" ? 138 : 0);
        int failures = 0;
        for (std::size_t n = 0; n < complete; n += n < 1600 ? 1 : 53) {
            write_bytes(cut, bytes, n);
            try {
                io::read_dicom_files({cut});
                ADD_FAILURE() << "cut at " << n << " of " << bytes.size() << " was read";
            } catch (const core::Error& e) {
                if (std::string(e.what()).find("cut.dcm") == std::string::npos && ++failures < 5)
                    ADD_FAILURE() << "cut at " << n << ": " << e.what();
            }
        }
        write_bytes(cut, bytes, bytes.size());
        EXPECT_NO_THROW(io::read_dicom_files({cut}));
    }
}

TEST(DicomSeries, ReadsRtDoseMultiFrame)
{
    LOBE_REQUIRE_PATH(pydicom("rtdose.dcm"));
    const io::DicomSeries s = io::read_dicom_series(pydicom("rtdose.dcm"));
    // 15 frames of 10 x 10, PixelSpacing 10\10, GridFrameOffsetVector 0\5\...\70, IPP
    // 189.43125\199.43125\-761.87, uint32 doses scaled by DoseGridScaling 1e-6 (not an
    // integer: float32).
    ASSERT_EQ(core::pixel_type(s.image), core::PixelType::Float32);
    const auto& dose = as<float>(s.image);
    EXPECT_EQ(dose.size, (std::array<int, 3>{10, 10, 15}));
    EXPECT_DOUBLE_EQ(dose.spacing[0], 10.0);
    EXPECT_NEAR(dose.spacing[2], 5.0, 1e-12);
    EXPECT_DOUBLE_EQ(dose.origin[0], 189.43125);
    EXPECT_DOUBLE_EQ(dose.origin[2], -761.87);
    gdcm::ImageReader r;
    r.SetFileName(pydicom("rtdose.dcm").string().c_str());
    ASSERT_TRUE(r.Read());
    std::vector<std::uint32_t> stored(10 * 10 * 15);
    ASSERT_TRUE(r.GetImage().GetBuffer(reinterpret_cast<char*>(stored.data())));
    for (std::size_t i : {std::size_t(0), std::size_t(555), stored.size() - 1}) // float32: 7 digits
        EXPECT_NEAR(dose.data[i], stored[i] * 1e-6, 1e-6 * std::abs(stored[i] * 1e-6) + 1e-12) << i;
    ASSERT_FALSE(s.notes.empty());
    EXPECT_NE(s.notes.back().find("GridFrameOffsetVector"), std::string::npos);
}

TEST(DicomSeries, RejectsColourImages)
{
    LOBE_REQUIRE_PATH(pydicom("SC_rgb_rle.dcm"));
    expect_error<core::InvalidInputError>([] { io::read_dicom_series(pydicom("SC_rgb_rle.dcm")); },
                                          {"SC_rgb_rle.dcm", "colour"});
}

// ---- fabricated series: sorting and geometry ----------------------------------------------

TEST(DicomSeries, SortsShuffledSlicesAlongTheNormal)
{
    const auto dir = test::scratch_dir();
    // Write slice k at z = 10 + 2.5 k under names that sort in another order.
    const std::vector<int> name_order{3, 0, 4, 1, 2};
    std::vector<fs::path> files;
    for (int k = 0; k < 5; ++k) {
        SliceSpec s;
        s.position = ds_numbers({-10.0, 20.0, 10.0 + 2.5 * k});
        s.pixels = coded_pixels(s.columns, s.rows, k);
        files.push_back(dir / ("f" + std::to_string(name_order[static_cast<std::size_t>(k)]) + ".dcm"));
        write_dicom(files.back(), s);
    }
    for (const io::DicomSeries& s :
         {io::read_dicom_series(dir), io::read_dicom_files({files[2], files[0], files[4], files[1], files[3]})}) {
        const auto& img = as<std::int16_t>(s.image);
        EXPECT_EQ(img.size, (std::array<int, 3>{6, 5, 5}));
        // PixelSpacing 0.8 (between rows) \ 0.6 (between columns): x spacing is 0.6.
        EXPECT_DOUBLE_EQ(img.spacing[0], 0.6);
        EXPECT_DOUBLE_EQ(img.spacing[1], 0.8);
        EXPECT_NEAR(img.spacing[2], 2.5, 1e-12);
        EXPECT_DOUBLE_EQ(img.origin[2], 10.0);
        // Each voxel carries 1000 k + 10 j + i: slices in z order, rows and columns unflipped.
        for (int k = 0; k < 5; ++k)
            for (int j = 0; j < 5; ++j)
                for (int i = 0; i < 6; ++i)
                    ASSERT_EQ(img.at(i, j, k), 1000 * k + 10 * j + i) << i << " " << j << " " << k;
        ASSERT_EQ(s.files.size(), 5u);
        for (int k = 0; k < 5; ++k)
            EXPECT_EQ(s.files[static_cast<std::size_t>(k)], files[static_cast<std::size_t>(k)]);
    }
}

TEST(DicomSeries, TiltedOrientationGivesTheDirectionAndPositions)
{
    const auto dir = test::scratch_dir();
    // Rotation by 30 degrees about z, then 20 about x: row = R ex, column = R ey, normal = R ez.
    const double a = M_PI / 6, b = M_PI / 9;
    const core::Vec3 row{std::cos(a), std::sin(a) * std::cos(b), std::sin(a) * std::sin(b)};
    const core::Vec3 col{-std::sin(a), std::cos(a) * std::cos(b), std::cos(a) * std::sin(b)};
    const core::Vec3 normal = core::cross(row, col);
    const core::Vec3 p0{-50.25, 12.5, 100.0};
    const double dz = 3.0;
    // Slices written from the highest to the lowest position along the normal.
    for (int k = 0; k < 4; ++k) {
        const core::Vec3 p = p0 + normal * (dz * k);
        SliceSpec s;
        s.position = ds_numbers({p.x, p.y, p.z});
        s.orientation = ds_numbers({row.x, row.y, row.z, col.x, col.y, col.z});
        s.pixels = coded_pixels(s.columns, s.rows, k);
        write_dicom(dir / ("s" + std::to_string(9 - k) + ".dcm"), s);
    }
    const io::DicomSeries s = io::read_dicom_series(dir);
    const auto& img = as<std::int16_t>(s.image);
    // DS values carry 10 significant digits here, so geometry agrees to ~1e-8.
    const double tol = 1e-7;
    for (int r = 0; r < 3; ++r) {
        EXPECT_NEAR(img.direction[static_cast<std::size_t>(3 * r)], row[r], tol);
        EXPECT_NEAR(img.direction[static_cast<std::size_t>(3 * r + 1)], col[r], tol);
        EXPECT_NEAR(img.direction[static_cast<std::size_t>(3 * r + 2)], normal[r], tol);
    }
    EXPECT_NEAR(img.spacing[2], dz, tol);
    // Voxel (i, j, k) sits at p0 + i 0.6 row + j 0.8 col + k dz normal, and holds slice k.
    for (int k = 0; k < 4; ++k) {
        const core::Vec3 expected = p0 + row * (5 * 0.6) + col * (4 * 0.8) + normal * (k * dz);
        const core::Vec3 got = img.index_to_physical(5, 4, k);
        EXPECT_NEAR(core::distance(expected, got), 0.0, 1e-6) << k;
        EXPECT_EQ(img.at(5, 4, k), 1000 * k + 45);
    }
}

TEST(DicomSeries, ReadsAnEnhancedMultiFrameFile)
{
    const auto dir = test::scratch_dir();
    // Three frames whose per-frame positions are out of order (z = 4, 0, 2), with shared
    // orientation, pixel spacing and rescale in the functional groups, as Enhanced CT has.
    auto frame_group = [](double z) {
        gdcm::DataSet pos;
        put_text(pos, gdcm::Tag(0x0020, 0x0032), gdcm::VR::DS, ds_numbers({1.0, 2.0, z}));
        gdcm::DataSet fg;
        fg.Replace(sequence(gdcm::Tag(0x0020, 0x9113), {pos}));
        return fg;
    };
    gdcm::DataSet orient, measures, rescale, shared;
    put_text(orient, gdcm::Tag(0x0020, 0x0037), gdcm::VR::DS, "1\\0\\0\\0\\1\\0");
    put_text(measures, gdcm::Tag(0x0028, 0x0030), gdcm::VR::DS, "0.5\\0.25");
    put_text(rescale, gdcm::Tag(0x0028, 0x1052), gdcm::VR::DS, "-1024");
    put_text(rescale, gdcm::Tag(0x0028, 0x1053), gdcm::VR::DS, "1");
    shared.Replace(sequence(gdcm::Tag(0x0020, 0x9116), {orient}));
    shared.Replace(sequence(gdcm::Tag(0x0028, 0x9110), {measures}));
    shared.Replace(sequence(gdcm::Tag(0x0028, 0x9145), {rescale}));
    SliceSpec s;
    s.sop_class = "1.2.840.10008.5.1.4.1.1.2.1"; // Enhanced CT Image Storage
    s.frames = 3;
    s.position = s.orientation = s.pixel_spacing = "";
    for (int f = 0; f < 3; ++f) {
        const auto px = coded_pixels(s.columns, s.rows, f);
        s.pixels.insert(s.pixels.end(), px.begin(), px.end());
    }
    s.extra = {sequence(gdcm::Tag(0x5200, 0x9229), {shared}),
               sequence(gdcm::Tag(0x5200, 0x9230), {frame_group(4.0), frame_group(0.0), frame_group(2.0)})};
    write_dicom(dir / "enhanced.dcm", s);

    const io::DicomSeries r = io::read_dicom_series(dir / "enhanced.dcm");
    const auto& img = as<std::int16_t>(r.image);
    EXPECT_EQ(img.size, (std::array<int, 3>{6, 5, 3}));
    EXPECT_DOUBLE_EQ(img.spacing[0], 0.25);
    EXPECT_DOUBLE_EQ(img.spacing[1], 0.5);
    EXPECT_DOUBLE_EQ(img.spacing[2], 2.0);
    EXPECT_DOUBLE_EQ(img.origin[2], 0.0);
    // Sorted along z: frames 2 (z 0), 3 (z 2), 1 (z 4), each rescaled by -1024.
    EXPECT_EQ(img.at(3, 2, 0), 1000 * 1 + 23 - 1024);
    EXPECT_EQ(img.at(3, 2, 1), 1000 * 2 + 23 - 1024);
    EXPECT_EQ(img.at(3, 2, 2), 1000 * 0 + 23 - 1024);
}

// ---- rescaling ---------------------------------------------------------------------------------

TEST(DicomSeries, IntegralRescaleGivesInt16)
{
    const auto dir = test::scratch_dir();
    SliceSpec base;
    base.slope = "2";
    base.intercept = "-1000";
    write_stack(dir, 3, 0.0, 1.0, base);
    const io::DicomSeries s = io::read_dicom_series(dir);
    ASSERT_EQ(core::pixel_type(s.image), core::PixelType::Int16);
    const auto& img = as<std::int16_t>(s.image);
    // Integers throughout: exact.
    EXPECT_EQ(img.at(5, 4, 2), 2 * (2000 + 45) - 1000);
    EXPECT_EQ(img.at(0, 0, 0), -1000);
}

TEST(DicomSeries, FractionalRescaleGivesFloat32)
{
    const auto dir = test::scratch_dir();
    SliceSpec base;
    base.slope = "0.5";
    base.intercept = "-3.25";
    write_stack(dir, 3, 0.0, 1.0, base);
    const io::DicomSeries s = io::read_dicom_series(dir);
    ASSERT_EQ(core::pixel_type(s.image), core::PixelType::Float32);
    const auto& img = as<float>(s.image);
    // 0.5 and 3.25 are exact in binary and the values are small: exact in float32.
    EXPECT_EQ(img.at(5, 4, 2), 0.5f * (2000 + 45) - 3.25f);
    EXPECT_EQ(img.at(1, 0, 0), 0.5f * 1 - 3.25f);
}

TEST(DicomSeries, IntegralRescaleBeyondInt16GivesFloat32)
{
    const auto dir = test::scratch_dir();
    SliceSpec base;
    base.slope = "20";
    base.intercept = "0";
    write_stack(dir, 3, 0.0, 1.0, base); // 20 * 2045 = 40900 > 32767
    const io::DicomSeries s = io::read_dicom_series(dir);
    ASSERT_EQ(core::pixel_type(s.image), core::PixelType::Float32);
    EXPECT_EQ(as<float>(s.image).at(5, 4, 2), 40900.0f); // integers below 2^24 are exact
}

TEST(DicomSeries, EachSliceKeepsItsOwnRescale)
{
    const auto dir = test::scratch_dir();
    for (int k = 0; k < 3; ++k) {
        SliceSpec s;
        s.position = ds_numbers({0.0, 0.0, 1.5 * k});
        s.intercept = std::to_string(-1000 - k); // as PET and some CT series do
        s.slope = "1";
        s.pixels = coded_pixels(s.columns, s.rows, k);
        write_dicom(dir / ("s" + std::to_string(k) + ".dcm"), s);
    }
    const io::DicomSeries s = io::read_dicom_series(dir);
    const auto& img = as<std::int16_t>(s.image);
    for (int k = 0; k < 3; ++k)
        EXPECT_EQ(img.at(2, 1, k), 1000 * k + 12 - 1000 - k);
}

// ---- series selection ----------------------------------------------------------------------

TEST(DicomSeries, FolderWithSeveralSeriesNeedsAUid)
{
    const auto dir = test::scratch_dir();
    SliceSpec a, b;
    a.series_uid = "1.2.3.100";
    a.description = "arterial";
    b.series_uid = "1.2.3.200";
    b.description = "venous";
    b.modality = "CT";
    for (int k = 0; k < 3; ++k) {
        a.position = b.position = ds_numbers({0.0, 0.0, 2.0 * k});
        a.pixels = coded_pixels(6, 5, k);
        write_dicom(dir / ("a" + std::to_string(k) + ".dcm"), a);
        b.pixels = coded_pixels(6, 5, 10 + k);
        write_dicom(dir / ("b" + std::to_string(k) + ".dcm"), b);
    }
    write_dicom(dir / "b3.dcm", [&] {
        SliceSpec x = b;
        x.position = ds_numbers({0.0, 0.0, 6.0});
        return x;
    }());
    expect_error<core::InvalidInputError>([&] { io::read_dicom_series(dir); },
                                          {dir.string(), "2 DICOM series", "1.2.3.100", "1.2.3.200", "arterial",
                                           "venous", "series_uid", "3 slices", "4 slices"});
    io::DicomReadParams p;
    p.series_uid = "1.2.3.200";
    const io::DicomSeries s = io::read_dicom_series(dir, p);
    EXPECT_EQ(s.series_uid, "1.2.3.200");
    EXPECT_EQ(s.description, "venous");
    EXPECT_EQ(core::geometry(s.image).size[2], 4);
    EXPECT_EQ(as<std::int16_t>(s.image).at(0, 0, 0), 10000);
    p.series_uid = "9.9.9";
    expect_error<core::InvalidInputError>([&] { io::read_dicom_series(dir, p); }, {"9.9.9", "1.2.3.100"});

    const auto list = io::list_dicom_series(dir);
    ASSERT_EQ(list.size(), 2u);
    EXPECT_EQ(list[0].series_uid, "1.2.3.100");
    EXPECT_EQ(list[0].slices, 3);
    EXPECT_EQ(list[1].slices, 4);
    EXPECT_EQ(list[1].description, "venous");
    EXPECT_EQ(list[1].size, (std::array<int, 2>{6, 5}));
}

TEST(DicomSeries, RejectsMixedSeriesInAFileList)
{
    const auto dir = test::scratch_dir();
    SliceSpec a, b;
    a.series_uid = "1.2.3.1";
    b.series_uid = "1.2.3.2";
    b.position = "0\\0\\2";
    write_dicom(dir / "a.dcm", a);
    write_dicom(dir / "b.dcm", b);
    expect_error<core::InvalidInputError>(
        [&] {
            io::read_dicom_files({dir / "a.dcm", dir / "b.dcm"});
        },
        {"a.dcm", "1.2.3.1", "1.2.3.2"});
    io::DicomReadParams p;
    p.series_uid = "1.2.3.2";
    EXPECT_EQ(io::read_dicom_files({dir / "a.dcm", dir / "b.dcm"}, p).files, std::vector<fs::path>{dir / "b.dcm"});
}

TEST(DicomSeries, SkipsFilesThatAreNotDicomImages)
{
    const auto dir = test::scratch_dir();
    write_stack(dir, 3, 0.0, 2.0);
    std::ofstream(dir / "README") << "Exported by a PACS viewer.\n";
    std::ofstream(dir / "tiny") << "x";
    SliceSpec no_image; // e.g. a DICOMDIR or structured report: DICOM, but no pixels
    no_image.pixel_data = false;
    write_dicom(dir / "report.dcm", no_image);
    fs::create_directory(dir / "subfolder");
    const io::DicomSeries s = io::read_dicom_series(dir);
    EXPECT_EQ(core::geometry(s.image).size[2], 3);
    ASSERT_EQ(s.notes.size(), 1u);
    EXPECT_NE(s.notes[0].find("skipped 3 files"), std::string::npos) << s.notes[0];
    EXPECT_NE(s.notes[0].find("README"), std::string::npos) << s.notes[0];
}

// ---- bad input -------------------------------------------------------------------------------

TEST(DicomSeries, RejectsMissingAndEmptyInput)
{
    const auto dir = test::scratch_dir();
    expect_error<core::IoError>([&] { io::read_dicom_series(dir / "nowhere"); }, {"nowhere", "does not exist"});
    expect_error<core::IoError>([&] { io::read_dicom_series(dir); }, {dir.string(), "no DICOM image"});
    std::ofstream(dir / "notes.txt") << "not an image";
    expect_error<core::IoError>([&] { io::read_dicom_series(dir); }, {dir.string(), "no DICOM image", "1 files"});
    expect_error<core::IoError>([&] { io::read_dicom_series(dir / "notes.txt"); }, {"notes.txt", "not a DICOM file"});
    expect_error<core::IoError>([&] { io::read_dicom_files({dir / "notes.txt"}); }, {"notes.txt", "not a DICOM file"});
    expect_error<core::IoError>([&] { io::list_dicom_series(dir / "nowhere"); }, {"does not exist"});
    expect_error<core::InvalidInputError>([&] { io::read_dicom_files({}); }, {"empty"});
    SliceSpec no_image;
    no_image.pixel_data = false;
    write_dicom(dir / "report.dcm", no_image);
    expect_error<core::InvalidInputError>([&] { io::read_dicom_series(dir / "report.dcm"); },
                                          {"report.dcm", "without an image"});
}

TEST(DicomSeries, TruncatedSliceInAFolderIsFatal)
{
    const auto dir = test::scratch_dir();
    const auto files = write_stack(dir, 4, 0.0, 2.0);
    const auto bytes = read_bytes(files[2]);
    write_bytes(files[2], bytes, bytes.size() - 7);
    // Skipping it would silently leave a gap; the error names the file instead.
    expect_error<core::IoError>([&] { io::read_dicom_series(dir); }, {"slice2.dcm", "truncated"});
}

TEST(DicomSeries, RejectsDuplicatePositions)
{
    const auto dir = test::scratch_dir();
    write_stack(dir, 3, 0.0, 2.0);
    SliceSpec dup;
    dup.position = ds_numbers({-10.0, 20.0, 2.0}); // same as slice1
    write_dicom(dir / "slice9.dcm", dup);
    expect_error<core::InvalidInputError>([&] { io::read_dicom_series(dir); },
                                          {"slice1.dcm", "slice9.dcm", "same position", "duplicate"});
}

TEST(DicomSeries, RejectsNonUniformSpacing)
{
    const auto dir = test::scratch_dir();
    // z = 0, 2, 4, 8, 10: the slice at 6 is missing.
    for (int k : {0, 1, 2, 4, 5}) {
        SliceSpec s;
        s.position = ds_numbers({0.0, 0.0, 2.0 * k});
        write_dicom(dir / ("z" + std::to_string(2 * k) + ".dcm"), s);
    }
    expect_error<core::InvalidInputError>([&] { io::read_dicom_series(dir); },
                                          {"non-uniform", "z4.dcm", "z8.dcm", "4 mm apart", "2.5 mm"});
}

TEST(DicomSeries, AcceptsPositionsRoundedWithinTheTolerance)
{
    const auto dir = test::scratch_dir();
    // Spacing 0.625 written with two decimals (0, 0.63, 1.25, 1.88, 2.5): every slice within
    // 0.005 mm of the grid, under the 0.01 mm floor of the tolerance.
    const char* z[] = {"0", "0.63", "1.25", "1.88", "2.5"};
    for (int k = 0; k < 5; ++k) {
        SliceSpec s;
        s.position = std::string("0\\0\\") + z[k];
        write_dicom(dir / ("s" + std::to_string(k) + ".dcm"), s);
    }
    const io::DicomSeries s = io::read_dicom_series(dir);
    // The spacing is the mean over the stack: (2.5 - 0) / 4.
    EXPECT_DOUBLE_EQ(core::geometry(s.image).spacing[2], 0.625);
}

TEST(DicomSeries, RejectsSlicesThatDifferInOrientationSizeOrSpacing)
{
    {
        const auto dir = test::scratch_dir();
        write_stack(dir, 3, 0.0, 2.0);
        SliceSpec odd;
        odd.position = ds_numbers({-10.0, 20.0, 6.0});
        odd.orientation = "0\\1\\0\\1\\0\\0";
        write_dicom(dir / "slice3.dcm", odd);
        expect_error<core::InvalidInputError>(
            [&] { io::read_dicom_series(dir); },
            {"slice3.dcm", "ImageOrientationPatient 0\\1\\0\\1\\0\\0 differs", "slice0.dcm"});
    }
    {
        const auto dir = test::scratch_dir();
        write_stack(dir, 3, 0.0, 2.0);
        SliceSpec odd;
        odd.position = ds_numbers({-10.0, 20.0, 6.0});
        odd.columns = 7;
        write_dicom(dir / "slice3.dcm", odd);
        expect_error<core::InvalidInputError>([&] { io::read_dicom_series(dir); },
                                              {"slice3.dcm", "7 x 5", "6 x 5", "slice size"});
    }
    {
        const auto dir = test::scratch_dir();
        write_stack(dir, 3, 0.0, 2.0);
        SliceSpec odd;
        odd.position = ds_numbers({-10.0, 20.0, 6.0});
        odd.pixel_spacing = "0.9\\0.6";
        write_dicom(dir / "slice3.dcm", odd);
        expect_error<core::InvalidInputError>([&] { io::read_dicom_series(dir); }, {"slice3.dcm", "PixelSpacing"});
    }
}

TEST(DicomSeries, RejectsAShearedStack)
{
    const auto dir = test::scratch_dir();
    // Positions move 0.5 mm in x per slice while the normal is z: a gantry-tilted stack.
    for (int k = 0; k < 3; ++k) {
        SliceSpec s;
        s.position = ds_numbers({0.5 * k, 0.0, 2.0 * k});
        write_dicom(dir / ("s" + std::to_string(k) + ".dcm"), s);
    }
    expect_error<core::InvalidInputError>([&] { io::read_dicom_series(dir); },
                                          {"s1.dcm", "not stacked along their normal"});
}

TEST(DicomSeries, RejectsMissingPositionsInAVolume)
{
    const auto dir = test::scratch_dir();
    write_stack(dir, 2, 0.0, 2.0);
    SliceSpec s;
    s.position = "";
    write_dicom(dir / "slice2.dcm", s);
    expect_error<core::InvalidInputError>([&] { io::read_dicom_series(dir); },
                                          {"slice2.dcm", "ImagePositionPatient", "missing"});
}

TEST(DicomSeries, SingleImageWithoutGeometryGetsDefaults)
{
    const auto dir = test::scratch_dir();
    SliceSpec s; // a secondary capture: no position, orientation or pixel spacing
    s.sop_class = "1.2.840.10008.5.1.4.1.1.7";
    s.position = s.orientation = s.pixel_spacing = "";
    s.pixels = coded_pixels(6, 5, 0);
    write_dicom(dir / "sc.dcm", s);
    const io::DicomSeries r = io::read_dicom_series(dir / "sc.dcm");
    const auto& img = as<std::int16_t>(r.image);
    EXPECT_EQ(img.origin, (std::array<double, 3>{0, 0, 0}));
    EXPECT_EQ(img.spacing, (std::array<double, 3>{1, 1, 1}));
    EXPECT_EQ(img.at(5, 4, 0), 45);
    ASSERT_FALSE(r.notes.empty());
    EXPECT_NE(r.notes[0].find("assumed"), std::string::npos) << r.notes[0];
}

TEST(DicomSeries, RejectsAbsurdDimensionsBeforeAllocating)
{
    const auto dir = test::scratch_dir();
    SliceSpec s;
    s.frames = 1; // written below as 60000 frames of 60000 x 60000
    write_dicom(dir / "huge.dcm", s);
    gdcm::Reader r;
    r.SetFileName((dir / "huge.dcm").string().c_str());
    ASSERT_TRUE(r.Read());
    gdcm::DataSet& ds = r.GetFile().GetDataSet();
    put_us(ds, gdcm::Tag(0x0028, 0x0010), 60000);
    put_us(ds, gdcm::Tag(0x0028, 0x0011), 60000);
    put_text(ds, gdcm::Tag(0x0028, 0x0008), gdcm::VR::IS, "60000");
    gdcm::Writer w;
    w.SetFile(r.GetFile());
    w.SetFileName((dir / "huge.dcm").string().c_str());
    ASSERT_TRUE(w.Write());
    expect_error<core::InvalidInputError>([&] { io::read_dicom_series(dir / "huge.dcm"); },
                                          {"huge.dcm", "60000 x 60000 x 60000", "limit"});
}

TEST(DicomSeries, RejectsPixelDataShorterThanTheImage)
{
    const auto dir = test::scratch_dir();
    SliceSpec s;
    write_dicom(dir / "short.dcm", s);
    gdcm::Reader r;
    r.SetFileName((dir / "short.dcm").string().c_str());
    ASSERT_TRUE(r.Read());
    put_us(r.GetFile().GetDataSet(), gdcm::Tag(0x0028, 0x0010), 50); // 10 times the rows held
    gdcm::Writer w;
    w.SetFile(r.GetFile());
    w.SetFileName((dir / "short.dcm").string().c_str());
    ASSERT_TRUE(w.Write());
    expect_error<core::IoError>([&] { io::read_dicom_series(dir / "short.dcm"); },
                                {"short.dcm", "pixel data holds 60 bytes", "need 600"});
}

TEST(DicomSeries, ReadsTwelveBitPixelsWithBitsAboveHighBitSet)
{
    const auto dir = test::scratch_dir();
    // Signed 12-bit values in 16-bit cells whose top 4 bits hold garbage (as overlays once
    // did): -5, 2047, -2048, 0 must come out sign-extended from bit 11, then rescaled.
    SliceSpec s;
    s.columns = 4;
    s.rows = 1;
    s.bits_stored = 12;
    s.intercept = "-1024";
    s.slope = "1";
    for (int v : {-5, 2047, -2048, 0})
        s.pixels.push_back(static_cast<std::int16_t>(static_cast<std::uint16_t>((v & 0x0fff) | 0xa000)));
    write_dicom(dir / "twelve.dcm", s);
    const auto img = as<std::int16_t>(io::read_dicom_series(dir / "twelve.dcm").image);
    EXPECT_EQ(img.data, (core::BigVector<std::int16_t>{-5 - 1024, 2047 - 1024, -2048 - 1024, -1024}));
}

TEST(DicomSeries, RejectsACodestreamOfAnotherSizeThanTheHeader)
{
    LOBE_REQUIRE_PATH(pydicom("MR_small_jp2klossless.dcm"));
    const auto dir = test::scratch_dir();
    std::vector<char> bytes = read_bytes(pydicom("MR_small_jp2klossless.dcm"));
    // The JPEG 2000 SIZ segment (after FF4F FF51) says 64 x 64; make it 86 pixels wide. GDCM
    // would copy 86 x 64 decoded pixels into a 64 x 64 buffer.
    const std::string soc_siz("\xff\x4f\xff\x51", 4);
    const auto at = std::search(bytes.begin(), bytes.end(), soc_siz.begin(), soc_siz.end());
    ASSERT_NE(at, bytes.end());
    at[11] = 86; // low byte of Xsiz (big endian, bytes 8-11 after SOC)
    write_bytes(dir / "wide.dcm", bytes, bytes.size());
    expect_error<core::IoError>([&] { io::read_dicom_series(dir / "wide.dcm"); },
                                {"wide.dcm", "is 86 x 64", "64 x 64"});
}

TEST(DicomSeries, ReadsADeflatedDataSet)
{
    LOBE_REQUIRE_PATH(pydicom("image_dfl.dcm"));
    // Deflated Explicit VR Little Endian: the reader inflates the data set to check it, GDCM
    // reads it. A 512 x 512 8-bit secondary capture: values must equal GDCM's own decoding.
    const io::DicomSeries s = io::read_dicom_series(pydicom("image_dfl.dcm"));
    const auto& img = as<std::int16_t>(s.image);
    EXPECT_EQ(img.size, (std::array<int, 3>{512, 512, 1}));
    gdcm::ImageReader r;
    r.SetFileName(pydicom("image_dfl.dcm").string().c_str());
    ASSERT_TRUE(r.Read());
    std::vector<std::uint8_t> stored(512 * 512);
    ASSERT_TRUE(r.GetImage().GetBuffer(reinterpret_cast<char*>(stored.data())));
    EXPECT_TRUE(std::equal(stored.begin(), stored.end(), img.data.begin()));
}

TEST(DicomSeries, PassesOverAnUnreadableSeriesBesideTheImage)
{
    LOBE_REQUIRE_PATH(pydicom("SC_rgb_rle.dcm"));
    const auto dir = test::scratch_dir();
    write_stack(dir, 3, 0.0, 2.0);
    // A colour screenshot (e.g. a dose report) exported with the CT, in its own series.
    fs::copy_file(pydicom("SC_rgb_rle.dcm"), dir / "report.dcm");
    const io::DicomSeries s = io::read_dicom_series(dir);
    EXPECT_EQ(core::geometry(s.image).size[2], 3);
    ASSERT_EQ(s.notes.size(), 1u);
    EXPECT_NE(s.notes[0].find("passed over"), std::string::npos) << s.notes[0];
    EXPECT_NE(s.notes[0].find("colour"), std::string::npos) << s.notes[0];
    // Series are listed in the order of their first file's name: report.dcm, then slice*.dcm.
    const auto list = io::list_dicom_series(dir);
    ASSERT_EQ(list.size(), 2u);
    EXPECT_NE(list[0].problem.find("report.dcm"), std::string::npos) << list[0].problem;
    EXPECT_TRUE(list[1].problem.empty());
    EXPECT_EQ(list[1].slices, 3);
    // Asked for by its UID, the colour series is an error naming the file and the reason.
    io::DicomReadParams p;
    p.series_uid = list[0].series_uid;
    expect_error<core::InvalidInputError>([&] { io::read_dicom_series(dir, p); }, {"report.dcm", "colour"});
}
