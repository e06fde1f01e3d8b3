#include "lobe/core/any_image.h"

#include <gtest/gtest.h>

using namespace lobe::core;

TEST(AnyImage, ReportsTypeAndGeometry)
{
    ImageGeometry g;
    g.size = {2, 2, 1};
    g.spacing = {0.5, 0.5, 1};
    AnyImage img = make_image(PixelType::Int16, g);
    EXPECT_EQ(pixel_type(img), PixelType::Int16);
    EXPECT_EQ(pixel_size(PixelType::Int16), 2);
    EXPECT_STREQ(pixel_type_name(PixelType::Float32), "float32");
    EXPECT_EQ(geometry(img).spacing[0], 0.5);
    EXPECT_EQ(std::get<ImageI16>(img).data.size(), 4u);
}

TEST(AnyImage, ConvertRoundsAndSaturates)
{
    ImageGeometry g;
    g.size = {5, 1, 1};
    Image3D<float> f(g);
    f.data = {-1e6f, -0.5f, 2.5f, 3.6f, 1e6f};
    const auto s = convert_image<std::int16_t>(f);
    // nearbyint rounds half to even: -0.5 -> 0 (as -0), 2.5 -> 2; out-of-range values clamp.
    EXPECT_EQ(s.data, (BigVector<std::int16_t>{-32768, 0, 2, 4, 32767}));
    const auto u = convert_image<std::uint8_t>(s);
    EXPECT_EQ(u.data, (BigVector<std::uint8_t>{0, 0, 2, 4, 255}));
    Image3D<std::uint32_t> big(g, 4000000000u);
    EXPECT_EQ(convert_image<std::int32_t>(big).data[0], 2147483647);
    EXPECT_EQ(saturate_cast<std::uint8_t>(std::nan("")), 0);
    // Same type: an exact copy.
    EXPECT_EQ(convert_image<float>(f).data, f.data);
}

TEST(AnyImage, ValueRange)
{
    ImageGeometry g;
    g.size = {3, 1, 1};
    Image3D<double> d(g);
    d.data = {2.0, -7.5, 4.0};
    const auto [lo, hi] = value_range(d);
    EXPECT_EQ(lo, -7.5);
    EXPECT_EQ(hi, 4.0);
}
