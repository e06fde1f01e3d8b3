// Format dispatch: every writable format round-trips through read_image/write_image.
#include "lobe/io/image_io.h"

#include "common/test_data.h"

#include <gtest/gtest.h>

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
