// tools/common/picture.h: the views follow the patient's axes whatever the stored orientation.
#include "common/picture.h"

#include "common/orientation.h"

#include "lobe/core/image3d.h"

#include <gtest/gtest.h>

#include <cstdint>

using namespace lobe;

namespace {

// A small axial volume, anisotropic, every voxel distinct, with a label volume over part of it.
struct Axial {
    core::ImageF image;
    core::LabelImage3D labels;
    Axial()
    {
        core::ImageGeometry g;
        g.size = {23, 17, 9};
        g.spacing = {0.8, 0.8, 2.5};
        g.origin = {-10, 20, -30};
        image = core::ImageF(g, 0.f);
        labels = core::LabelImage3D(g, 0);
        for (int k = 0; k < g.size[2]; ++k)
            for (int j = 0; j < g.size[1]; ++j)
                for (int i = 0; i < g.size[0]; ++i) {
                    image.at(i, j, k) = float((i * 37 + j * 11 + k * 101) % 400 - 160);
                    labels.at(i, j, k) = (i - 11) * (i - 11) + (j - 8) * (j - 8) < 30 + 4 * k ? 1 : 0;
                }
    }
};

} // namespace

TEST(Picture, ViewsCutTheVoxelAxisNearestTheirNormal)
{
    const Axial a;
    EXPECT_EQ(tools::slice_voxel_axis(a.image, tools::SliceAxis::Axial), 2);
    EXPECT_EQ(tools::slice_voxel_axis(a.image, tools::SliceAxis::Coronal), 1);
    EXPECT_EQ(tools::slice_voxel_axis(a.image, tools::SliceAxis::Sagittal), 0);
    // Stored as a coronal series: rows along x, columns to the feet, slices to the back.
    const core::ImageF c = core::reorder_axes(a.image, test::coronal_storage());
    EXPECT_EQ(tools::slice_voxel_axis(c, tools::SliceAxis::Axial), 1);
    EXPECT_EQ(tools::slice_voxel_axis(c, tools::SliceAxis::Coronal), 2);
    EXPECT_EQ(tools::slice_voxel_axis(c, tools::SliceAxis::Sagittal), 0);
    EXPECT_EQ(tools::view_across(c, 2), tools::SliceAxis::Coronal); // the plane of its stored slices
    EXPECT_EQ(tools::view_across(a.image, 2), tools::SliceAxis::Axial);
    EXPECT_FALSE(tools::axis_runs_backwards(c, 0));
    EXPECT_TRUE(tools::axis_runs_backwards(c, 1)); // to the feet
    EXPECT_FALSE(tools::axis_runs_backwards(c, 2));
}

TEST(Picture, RoundingAndTiesFollowThePatientNotTheStorage)
{
    const Axial a;
    const core::ImageF c = core::reorder_axes(a.image, test::coronal_storage());
    // z index 3.5 of the axial grid (9 slices) is 8 - 3.5 = 4.5 along the coronal stack's j:
    // both round towards the head, to axial slice 4, which the stack holds at j = 8 - 4.
    EXPECT_EQ(tools::patient_round(a.image, 2, 3.5), 4);
    EXPECT_EQ(tools::patient_round(c, 1, 4.5), 4);
    EXPECT_EQ(tools::patient_round(c, 1, 4.4), 4);
    EXPECT_EQ(tools::patient_round(c, 1, 4.6), 5);
    // The form for loops along one axis, its direction given: the same voxels.
    for (const double x : {4.4, 4.5, 4.6})
        EXPECT_EQ(tools::patient_round(true, c.size[1], x), tools::patient_round(c, 1, x)) << x;
    EXPECT_EQ(tools::patient_round(false, a.image.size[2], 3.5), 4);
    // The fullest of tied slices: the first in the patient's order.
    const std::vector<std::size_t> counts{1, 3, 3, 2};
    EXPECT_EQ(tools::fullest_slice(counts, false), 1);
    EXPECT_EQ(tools::fullest_slice(counts, true), 2);
    EXPECT_EQ(tools::fullest_slice({}, true), 0);
}

TEST(Picture, ACoronalStackIsDrawnAsItsAxialCopy)
{
    // Each view of the stack, at the voxel index holding the same slice, is the axial copy's
    // picture pixel for pixel (captions off: they name the stored index).
    const Axial a;
    const core::AxisOrder order = test::coronal_storage();
    const core::ImageF c = core::reorder_axes(a.image, order);
    const core::LabelImage3D cl = core::reorder_axes(a.labels, order);
    for (tools::SliceAxis view : {tools::SliceAxis::Axial, tools::SliceAxis::Coronal, tools::SliceAxis::Sagittal}) {
        const int axial_axis = tools::slice_voxel_axis(a.image, view), stored_axis = tools::slice_voxel_axis(c, view);
        const int n = a.image.size[static_cast<std::size_t>(axial_axis)];
        for (int index : {0, n / 2, n - 1}) {
            tools::PictureParams pp;
            pp.axis = view;
            pp.auto_caption = false;
            pp.index = index;
            tools::Overlay ov;
            ov.labels = &a.labels;
            const tools::RgbImage want = tools::render_slice(a.image, pp, {ov});
            pp.index = tools::axis_runs_backwards(c, stored_axis) ? n - 1 - index : index;
            ov.labels = &cl;
            const tools::RgbImage got = tools::render_slice(c, pp, {ov});
            EXPECT_EQ(got.width, want.width) << tools::slice_axis_name(view) << " " << index;
            EXPECT_EQ(got.height, want.height) << tools::slice_axis_name(view) << " " << index;
            EXPECT_TRUE(got.rgb == want.rgb) << tools::slice_axis_name(view) << " " << index;
        }
    }
}
