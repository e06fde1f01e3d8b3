// Segmentation measures on shapes whose values are known: counted overlaps, concentric spheres,
// a one-voxel shift; the SLIVER07 score mapping; and the errors.
#include "lobe/seg/metrics.h"

#include "common/expect_error.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace lobe;

namespace {

core::ImageGeometry grid(int nx, int ny, int nz, double hx, double hy, double hz)
{
    core::ImageGeometry g;
    g.size = {nx, ny, nz};
    g.spacing = {hx, hy, hz};
    return g;
}

// Voxels [lo, lo + n) along each axis set to `value`.
void fill_box(core::LabelImage3D& m, std::array<int, 3> lo, std::array<int, 3> n, std::uint8_t value = 1)
{
    for (int k = lo[2]; k < lo[2] + n[2]; ++k)
        for (int j = lo[1]; j < lo[1] + n[1]; ++j)
            for (int i = lo[0]; i < lo[0] + n[0]; ++i)
                m.at(i, j, k) = value;
}

core::LabelImage3D sphere(const core::ImageGeometry& g, const core::Vec3& c, double r)
{
    core::LabelImage3D m(g, 0);
    for (int k = 0; k < g.size[2]; ++k)
        for (int j = 0; j < g.size[1]; ++j)
            for (int i = 0; i < g.size[0]; ++i) {
                const double dx = i * g.spacing[0] - c.x, dy = j * g.spacing[1] - c.y, dz = k * g.spacing[2] - c.z;
                m.at(i, j, k) = dx * dx + dy * dy + dz * dz <= r * r ? 1 : 0;
            }
    return m;
}

} // namespace

// Two cubes of 10^3 and 8^3 voxels overlapping in 7 x 6 x 8: every overlap measure is a ratio
// of voxel counts, so it must match to rounding (1e-12).
TEST(Metrics, OffsetCubesGiveCountedOverlap)
{
    const auto g = grid(30, 30, 30, 0.7, 0.8, 1.5);
    core::LabelImage3D seg(g, 0), ref(g, 0);
    fill_box(seg, {5, 5, 5}, {10, 10, 10}, 255); // any non-zero value is object
    fill_box(ref, {8, 9, 5}, {8, 8, 8});
    const double s = 1000, r = 512, both = 7 * 6 * 8;
    const auto m = seg::evaluate_segmentation(seg, ref);
    EXPECT_NEAR(m.dice, 2 * both / (s + r), 1e-12);
    EXPECT_NEAR(m.jaccard, both / (s + r - both), 1e-12);
    EXPECT_NEAR(m.voe, 100 * (1 - both / (s + r - both)), 1e-10);
    EXPECT_NEAR(m.rvd, 100 * (s - r) / r, 1e-10);
    EXPECT_NEAR(m.abs_rvd, 100 * (s - r) / r, 1e-10);
    const double voxel_ml = 0.7 * 0.8 * 1.5 / 1000;
    EXPECT_NEAR(m.volume_seg_ml, s * voxel_ml, 1e-12);
    EXPECT_NEAR(m.volume_ref_ml, r * voxel_ml, 1e-12);
    // Border voxels, counted: a cube of n^3 has n^3 - (n-2)^3.
    EXPECT_EQ(m.surface.border_voxels_seg, 1000u - 512u);
    EXPECT_EQ(m.surface.border_voxels_ref, 512u - 216u);

    const auto swapped = seg::evaluate_segmentation(ref, seg); // RVD is signed, the rest symmetric
    EXPECT_NEAR(swapped.rvd, 100 * (r - s) / s, 1e-10);
    EXPECT_NEAR(swapped.dice, m.dice, 1e-12);
    EXPECT_NEAR(swapped.surface.average, m.surface.average, 1e-9);
    EXPECT_NEAR(swapped.surface.maximum, m.surface.maximum, 1e-9);
}

TEST(Metrics, IdenticalMasksArePerfect)
{
    const auto g = grid(20, 18, 12, 0.7, 0.7, 2.5);
    const auto s = sphere(g, {7, 6, 15}, 5);
    const auto m = seg::evaluate_segmentation(s, s);
    EXPECT_EQ(m.dice, 1.0);
    EXPECT_EQ(m.jaccard, 1.0);
    EXPECT_EQ(m.voe, 0.0);
    EXPECT_EQ(m.rvd, 0.0);
    EXPECT_EQ(m.surface.average, 0.0);
    EXPECT_EQ(m.surface.rms, 0.0);
    EXPECT_EQ(m.surface.maximum, 0.0);
    EXPECT_EQ(seg::sliver_score(m).total, 100.0);
}

// Borders use the 26-neighbourhood (8 in 2-D) and the grid's outside counts as outside: the centre of a
// 3^3 cube is interior, and a cube filling its 4^3 grid is border but for its 2^3 core.
TEST(Metrics, BorderIsTwentySixConnectedAndTheGridEndsTheObject)
{
    core::LabelImage3D m(grid(5, 5, 5, 1, 1, 1), 0);
    fill_box(m, {1, 1, 1}, {3, 3, 3});
    EXPECT_EQ(seg::evaluate_segmentation(m, m).surface.border_voxels_seg, 26u);
    const core::LabelImage3D full(grid(4, 4, 4, 1, 1, 1), 1);
    EXPECT_EQ(seg::evaluate_segmentation(full, full).surface.border_voxels_ref, 64u - 8u);
    // A 2-D image has no neighbours across its plane: a 5 x 5 square has a border of 16.
    core::LabelImage3D flat(grid(9, 9, 1, 1, 1, 1), 0);
    fill_box(flat, {2, 2, 0}, {5, 5, 1});
    EXPECT_EQ(seg::evaluate_segmentation(flat, flat).surface.border_voxels_seg, 16u);
}

// Concentric spheres of radii 10 and 14 mm: every border point of one is 4 mm from the other's
// sphere. Each voxelised border lies within one voxel of its sphere (a border voxel is inside,
// and within one voxel diagonal of an outside voxel), and the two borders are offset in the same
// direction, so the pooled mean and the maximum stay within one voxel (1.2 mm, the largest
// spacing) of 4 mm.
TEST(Metrics, ConcentricSpheresAreTheirRadiiApart)
{
    const auto g = grid(44, 44, 44, 0.8, 1.0, 1.2);
    const core::Vec3 c{17.5, 21.6, 25.9};
    const auto inner = sphere(g, c, 10.0), outer = sphere(g, c, 14.0);
    const auto m = seg::evaluate_segmentation(inner, outer);
    EXPECT_NEAR(m.surface.average, 4.0, 1.2);
    EXPECT_NEAR(m.surface.rms, 4.0, 1.2);
    EXPECT_NEAR(m.surface.maximum, 4.0, 1.2);
    EXPECT_GE(m.surface.rms, m.surface.average); // RMS >= mean, always
    EXPECT_GE(m.surface.maximum, m.surface.rms);
    // Volumes of the spheres, to the voxelisation's few per cent.
    EXPECT_NEAR(m.volume_ref_ml, 4.0 / 3.0 * 3.14159265358979 * 14 * 14 * 14 / 1000, 0.03 * 11.5);
    EXPECT_NEAR(m.rvd, 100 * (1000.0 / 2744.0 - 1), 3.0);
}

// A box shifted by one voxel along z (2.5 mm) against x and y of 0.7 mm: every border voxel has
// a border voxel of the other box at most one slice away and one exactly one slice away, so
// the Hausdorff distance is the z spacing (exact, float rounding only: 1e-6).
TEST(Metrics, OneVoxelShiftAlongTheCoarseAxisIsItsSpacing)
{
    const auto g = grid(20, 20, 14, 0.7, 0.7, 2.5);
    core::LabelImage3D seg(g, 0), ref(g, 0);
    fill_box(ref, {4, 5, 3}, {10, 10, 6});
    fill_box(seg, {4, 5, 4}, {10, 10, 6});
    const auto m = seg::evaluate_segmentation(seg, ref);
    EXPECT_NEAR(m.surface.maximum, 2.5, 1e-6);
    EXPECT_NEAR(m.dice, 5.0 / 6.0, 1e-12); // 5 of 6 slices shared
    EXPECT_GT(m.surface.average, 0.0);
    EXPECT_LT(m.surface.average, 2.5);
}

// The mapping max(0, 100 - 25 value / reference): the reference value scores 75, zero 100,
// four times the reference or more 0; the total is the mean. Exact arithmetic on these values.
TEST(Metrics, SliverScoreMapping)
{
    seg::SegmentationMeasures m;
    const seg::SliverReference ref;
    m.voe = ref.voe;
    m.abs_rvd = ref.abs_rvd;
    m.surface.average = ref.asd;
    m.surface.rms = ref.rmsd;
    m.surface.maximum = ref.maxd;
    auto s = seg::sliver_score(m);
    EXPECT_DOUBLE_EQ(s.voe, 75);
    EXPECT_DOUBLE_EQ(s.abs_rvd, 75);
    EXPECT_DOUBLE_EQ(s.asd, 75);
    EXPECT_DOUBLE_EQ(s.rmsd, 75);
    EXPECT_DOUBLE_EQ(s.maxd, 75);
    EXPECT_DOUBLE_EQ(s.total, 75);

    EXPECT_DOUBLE_EQ(seg::sliver_score(seg::SegmentationMeasures{}).total, 100);

    m.voe = 1000; // large: clamped at 0
    m.surface.maximum = 2 * ref.maxd; // 50
    s = seg::sliver_score(m);
    EXPECT_DOUBLE_EQ(s.voe, 0);
    EXPECT_DOUBLE_EQ(s.maxd, 50);
    EXPECT_DOUBLE_EQ(s.total, (0 + 75 + 75 + 75 + 50) / 5.0);

    seg::SliverReference custom;
    custom.asd = 2.0;
    m.surface.average = 1.0;
    EXPECT_DOUBLE_EQ(seg::sliver_score(m, custom).asd, 87.5);
    custom.rmsd = 0;
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::sliver_score(m, custom), "RMSD", "positive");
}

TEST(Metrics, DefaultReferenceIsHeimann2009)
{
    const seg::SliverReference ref;
    EXPECT_EQ(ref.voe, 6.4);
    EXPECT_EQ(ref.abs_rvd, 4.7);
    EXPECT_EQ(ref.asd, 1.0);
    EXPECT_EQ(ref.rmsd, 1.8);
    EXPECT_EQ(ref.maxd, 19.0);
}

TEST(Metrics, MismatchedGridsAndEmptyMasksAreRejected)
{
    const auto g = grid(8, 8, 8, 1, 1, 1);
    core::LabelImage3D a(g, 0);
    fill_box(a, {2, 2, 2}, {3, 3, 3});
    auto g2 = g;
    g2.size[2] = 9;
    core::LabelImage3D b(g2, 1);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evaluate_segmentation(a, b), "same grid", "8 x 8 x 9");
    auto g3 = g;
    g3.spacing[0] = 1.5;
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evaluate_segmentation(a, core::LabelImage3D(g3, 1)),
                      "same grid");
    const core::LabelImage3D empty(g, 0);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evaluate_segmentation(empty, a), "segmentation", "empty");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evaluate_segmentation(a, empty), "reference", "empty");
    core::LabelImage3D truncated = a;
    truncated.data.resize(100);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::evaluate_segmentation(truncated, a), "segmentation", "100");
}
