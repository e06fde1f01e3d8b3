#include "lobe/core/image3d.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>

using namespace lobe::core;

namespace {
ImageGeometry rotated()
{
    ImageGeometry g;
    g.size = {10, 20, 5};
    g.spacing = {0.5, 0.75, 2.5};
    g.origin = {-100.0, 50.0, -300.0};
    const double a = 0.4;
    // Rotation about z: axis 0 = (cos a, sin a, 0), axis 1 = (-sin a, cos a, 0), axis 2 = z.
    g.direction = {std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a), 0, 0, 0, 1};
    return g;
}
} // namespace

TEST(Image3D, IndexIsXFastest)
{
    ImageGeometry g;
    g.size = {4, 3, 2};
    Image3D<int> img(g, 0);
    EXPECT_EQ(img.data.size(), 24u);
    EXPECT_EQ(img.index(1, 0, 0), 1u);
    EXPECT_EQ(img.index(0, 1, 0), 4u);
    EXPECT_EQ(img.index(0, 0, 1), 12u);
    img.at(3, 2, 1) = 7;
    EXPECT_EQ(img.data.back(), 7);
    EXPECT_TRUE(img.contains(3, 2, 1));
    EXPECT_FALSE(img.contains(4, 0, 0));
    EXPECT_FALSE(img.contains(0, -1, 0));
}

TEST(Image3D, PhysicalPositionFollowsItk)
{
    const auto g = rotated();
    // Voxel (0,0,0) sits at the origin.
    const Vec3 p0 = g.index_to_physical(0, 0, 0);
    EXPECT_DOUBLE_EQ(p0.x, -100.0);
    EXPECT_DOUBLE_EQ(p0.y, 50.0);
    // One step along i moves spacing[0] mm along axis 0 (the first column of the direction).
    const Vec3 d = g.index_to_physical(1, 0, 0) - p0;
    EXPECT_NEAR(d.x, 0.5 * std::cos(0.4), 1e-12);
    EXPECT_NEAR(d.y, 0.5 * std::sin(0.4), 1e-12);
    EXPECT_NEAR(norm(g.index_to_physical(0, 0, 3) - p0), 7.5, 1e-12);
    // physical_to_index inverts it to rounding error.
    const Vec3 ijk{3.25, 17.5, 4.0};
    const Vec3 back = g.physical_to_index(g.index_to_physical(ijk));
    EXPECT_NEAR(back.x, ijk.x, 1e-10);
    EXPECT_NEAR(back.y, ijk.y, 1e-10);
    EXPECT_NEAR(back.z, ijk.z, 1e-10);
}

TEST(Image3D, GeometryProblemsAreNamed)
{
    auto g = rotated();
    EXPECT_EQ(geometry_problem(g), "");
    g.spacing[1] = 0;
    EXPECT_NE(geometry_problem(g).find("spacing along axis 1"), std::string::npos);
    g = rotated();
    g.spacing[2] = std::nan("");
    EXPECT_NE(geometry_problem(g).find("spacing along axis 2"), std::string::npos);
    g = rotated();
    g.size[0] = 0;
    EXPECT_NE(geometry_problem(g).find("size along axis 0"), std::string::npos);
    g = rotated();
    g.direction = {1, 1, 0, 0, 0, 0, 0, 0, 1}; // axes 0 and 1 equal: singular
    EXPECT_NE(geometry_problem(g).find("singular"), std::string::npos);
    g = rotated();
    g.direction[0] = 2.0;
    EXPECT_NE(geometry_problem(g).find("unit vector"), std::string::npos);
    try {
        validate_geometry(g, "scan.mhd");
        FAIL();
    } catch (const InvalidInputError& e) {
        EXPECT_NE(std::string(e.what()).find("scan.mhd"), std::string::npos);
    }
}

TEST(Image3D, SameGridComparesWithinTolerance)
{
    const auto a = rotated();
    auto b = a;
    EXPECT_TRUE(same_grid(a, b));
    b.origin[0] += 5e-5; // below the default 1e-4 mm
    EXPECT_TRUE(same_grid(a, b));
    b.origin[0] += 1e-3;
    EXPECT_FALSE(same_grid(a, b));
    b = a;
    b.size[2] = 6;
    EXPECT_FALSE(same_grid(a, b));
    b = a;
    b.direction[1] = -b.direction[1];
    EXPECT_FALSE(same_grid(a, b));
}

TEST(Image3D, AxialSliceKeepsItsPlaceInSpace)
{
    ImageGeometry g;
    g.size = {3, 2, 4};
    g.spacing = {0.5, 0.7, 2.5};
    g.origin = {10, 20, 30};
    g.direction = {1, 0, 0, 0, 0, -1, 0, 1, 0}; // axis k along +y, axis j along -z
    Image3D<int> img(g);
    for (std::size_t i = 0; i < img.data.size(); ++i)
        img.data[i] = static_cast<int>(i);
    const auto s = axial_slice(img, 2);
    EXPECT_EQ(s.size, (std::array<int, 3>{3, 2, 1}));
    // Voxel (i, j, 0) of the slice is voxel (i, j, 2) of the volume, at the same position.
    for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 3; ++i) {
            EXPECT_EQ(s.at(i, j, 0), img.at(i, j, 2));
            const auto a = s.index_to_physical(i, j, 0), b = img.index_to_physical(i, j, 2);
            EXPECT_NEAR(a.x, b.x, 1e-12);
            EXPECT_NEAR(a.y, b.y, 1e-12);
            EXPECT_NEAR(a.z, b.z, 1e-12);
        }
    EXPECT_THROW(axial_slice(img, 4), InvalidInputError);
    EXPECT_THROW(axial_slice(img, -1), InvalidInputError);
}

// Any set of axes turned round: every voxel keeps its value and its physical position, the
// turned axes' directions are negated and the others kept; twice is the identity (the origin to
// rounding, as above).
TEST(Image3D, FlipAxesKeepsEveryVoxelInPlace)
{
    Image3D<int> img(rotated(), 0);
    for (std::size_t i = 0; i < img.data.size(); ++i)
        img.data[i] = static_cast<int>(i);
    for (const std::array<bool, 3> turn : {std::array<bool, 3>{true, false, false}, {false, true, false},
                                           {true, true, false}, {true, true, true}}) {
        const Image3D<int> f = flip_axes(img, turn);
        ASSERT_EQ(f.size, img.size);
        EXPECT_EQ(f.spacing, img.spacing);
        for (int a = 0; a < 3; ++a) {
            const double s = turn[std::size_t(a)] ? -1.0 : 1.0;
            EXPECT_NEAR(f.axis(a).x, s * img.axis(a).x, 1e-12);
            EXPECT_NEAR(f.axis(a).y, s * img.axis(a).y, 1e-12);
            EXPECT_NEAR(f.axis(a).z, s * img.axis(a).z, 1e-12);
        }
        for (int k = 0; k < img.size[2]; ++k)
            for (int j = 0; j < img.size[1]; j += 3)
                for (int i = 0; i < img.size[0]; i += 2) {
                    const int it = turn[0] ? img.size[0] - 1 - i : i, jt = turn[1] ? img.size[1] - 1 - j : j,
                              kt = turn[2] ? img.size[2] - 1 - k : k;
                    EXPECT_EQ(f.at(it, jt, kt), img.at(i, j, k));
                    const Vec3 a = img.index_to_physical(i, j, k), b = f.index_to_physical(it, jt, kt);
                    EXPECT_NEAR(a.x, b.x, 1e-9);
                    EXPECT_NEAR(a.y, b.y, 1e-9);
                    EXPECT_NEAR(a.z, b.z, 1e-9);
                }
        const Image3D<int> back = flip_axes(f, turn);
        EXPECT_EQ(back.data, img.data);
        EXPECT_EQ(back.direction, img.direction);
        for (std::size_t a = 0; a < 3; ++a)
            EXPECT_NEAR(back.origin[a], img.origin[a], 1e-9);
    }
}

// Axes that change place too (a coronal stack: rows along x, columns to the feet, slices to the
// back): every voxel keeps its value and physical position, and the patient frame's order found
// from the stored grid's directions takes it back to the axial grid exactly (its data, and its
// geometry to rounding).
TEST(Image3D, ReorderAxesToThePatientFrame)
{
    Image3D<int> img(rotated(), 0);
    for (std::size_t i = 0; i < img.data.size(); ++i)
        img.data[i] = static_cast<int>(i);
    EXPECT_TRUE(patient_axis_order(img).identity()); // rotated 0.4 rad about z: still nearest LPS
    AxisOrder coronal;
    coronal.from = {0, 2, 1};
    coronal.flip = {false, true, false};
    const Image3D<int> c = reorder_axes(img, coronal);
    EXPECT_EQ(c.size, (std::array<int, 3>{10, 5, 20}));
    EXPECT_EQ(c.spacing, (std::array<double, 3>{0.5, 2.5, 0.75}));
    EXPECT_NEAR(c.axis(1).z, -1.0, 1e-12);
    for (int k = 0; k < c.size[2]; k += 3)
        for (int j = 0; j < c.size[1]; ++j)
            for (int i = 0; i < c.size[0]; i += 2) {
                const int io = i, jo = k, ko = img.size[2] - 1 - j;
                EXPECT_EQ(c.at(i, j, k), img.at(io, jo, ko));
                const Vec3 a = img.index_to_physical(io, jo, ko), b = c.index_to_physical(i, j, k);
                EXPECT_NEAR(a.x, b.x, 1e-9);
                EXPECT_NEAR(a.y, b.y, 1e-9);
                EXPECT_NEAR(a.z, b.z, 1e-9);
            }
    const AxisOrder back = patient_axis_order(c);
    EXPECT_EQ(back.from, (std::array<int, 3>{0, 2, 1}));
    EXPECT_EQ(back.flip, (std::array<bool, 3>{false, false, true}));
    const Image3D<int> axial = reorder_axes(c, back);
    EXPECT_EQ(axial.size, img.size);
    EXPECT_EQ(axial.data, img.data);
    for (std::size_t e = 0; e < 9; ++e)
        EXPECT_NEAR(axial.direction[e], img.direction[e], 1e-12);
    for (std::size_t a = 0; a < 3; ++a)
        EXPECT_NEAR(axial.origin[a], img.origin[a], 1e-9);
    EXPECT_EQ(reorder_axes(c, coronal.inverse()).data, img.data);
    // index_of maps a continuous index the same way as the voxels.
    const Vec3 q = back.index_of(Vec3{3.0, 1.5, 7.0}, c.size);
    EXPECT_NEAR(q.x, 3.0, 1e-12);
    EXPECT_NEAR(q.y, 7.0, 1e-12);
    EXPECT_NEAR(q.z, img.size[2] - 1 - 1.5, 1e-12);
}

// Every voxel keeps its value and its physical position; twice is the identity (the origin to
// rounding: two sums of (n - 1) * spacing along the axis and back).
TEST(Image3D, ReverseSlicesKeepsEveryVoxelInPlace)
{
    Image3D<int> img(rotated(), 0);
    for (std::size_t i = 0; i < img.data.size(); ++i)
        img.data[i] = static_cast<int>(i);
    const Image3D<int> rev = reverse_slices(img);
    ASSERT_EQ(rev.size, img.size);
    EXPECT_EQ(rev.spacing, img.spacing);
    EXPECT_NEAR(rev.axis(2).z, -1.0, 1e-12); // the third axis turns round
    EXPECT_NEAR(rev.axis(0).x, img.axis(0).x, 1e-12);
    for (int k = 0; k < img.size[2]; ++k)
        for (int j = 0; j < img.size[1]; j += 7)
            for (int i = 0; i < img.size[0]; i += 3) {
                const int kr = img.size[2] - 1 - k;
                EXPECT_EQ(rev.at(i, j, kr), img.at(i, j, k));
                const Vec3 a = img.index_to_physical(i, j, k), b = rev.index_to_physical(i, j, kr);
                EXPECT_NEAR(a.x, b.x, 1e-9);
                EXPECT_NEAR(a.y, b.y, 1e-9);
                EXPECT_NEAR(a.z, b.z, 1e-9);
            }
    const Image3D<int> back = reverse_slices(rev);
    EXPECT_EQ(back.data, img.data);
    EXPECT_EQ(back.direction, img.direction);
    for (std::size_t a = 0; a < 3; ++a)
        EXPECT_NEAR(back.origin[a], img.origin[a], 1e-9);
}
