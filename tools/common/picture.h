#pragma once
//! \file
//! \brief PNG pictures of image slices with an optional label overlay, for every lobe tool.
//!
//! A slice is cut across the voxel axis nearest the view's normal (for an axial stack axial = k,
//! coronal = j, sagittal = i; a coronal stack's axial view cuts its j), windowed
//! (default W400/L40, soft tissue), resampled so that pixels are square in millimetres (CT
//! slices are often 2.5 mm apart against 0.7 mm in-plane), and shown in the radiological
//! convention for an LPS image: axial with the patient's right on the picture's left and anterior
//! at the top; coronal with superior at the top and the patient's right on the left; sagittal
//! with superior at the top and anterior on the left. Labels are drawn as translucent fills
//! and/or contour lines, one colour per label (default_label_colours()), with a legend of the
//! labels present and a caption. OpenCV does the drawing and PNG encoding, but stays out of
//! this header.

#include "lobe/core/any_image.h"
#include "lobe/core/image3d.h"
#include "lobe/core/types.h"

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace lobe::tools {

enum class SliceAxis { Axial, Coronal, Sagittal };

//! "axial", "coronal" or "sagittal".
const char* slice_axis_name(SliceAxis axis);

//! The voxel axis (0 = i, 1 = j, 2 = k) that a view of an image on `g` cuts across, along which
//! PictureParams::index counts: the axis nearest the view's normal (core::patient_axis_order).
int slice_voxel_axis(const core::ImageGeometry& g, SliceAxis axis);

//! Whether voxel axis `voxel_axis` of `g` runs against the patient axis it is nearest (a stack
//! stored feet first, a coronal series' columns to the feet).
bool axis_runs_backwards(const core::ImageGeometry& g, int voxel_axis);

//! A continuous voxel index along `voxel_axis` rounded to the nearest voxel, half-way cases
//! towards the patient's +axis whichever way the voxel axis runs: the same voxel for every
//! stored orientation, so pictures do not depend on it.
int patient_round(const core::ImageGeometry& g, int voxel_axis, double index);

//! The same for an axis of `size` voxels whose direction is known (`backwards` from
//! axis_runs_backwards), for loops that round many indices along one axis.
int patient_round(bool backwards, int size, double index);

//! The index of the largest of `counts` (per slice along a voxel axis), ties going to the first
//! in the patient's order (the last stored when the axis runs backwards).
int fullest_slice(const std::vector<std::size_t>& counts, bool backwards);

//! Where to look at a label volume, as PictureParams::index takes it: the axial slice holding the
//! most voxels labelled `fullest_from` or above (fullest_slice), and the coronal slice through the
//! centroid of those labelled `centred_from` or above (patient_round; -1, the middle slice, when
//! there are none). Either follows the patient's axes whatever the stored orientation.
struct LabelViews {
    int axial = 0;
    int coronal = -1;
};
LabelViews label_views(const core::LabelImage3D& labels, int fullest_from, int centred_from);

//! The view that cuts across voxel axis `voxel_axis` of `g`: the plane of a stored slice (a 2-D
//! result on slice k of a coronal stack is drawn in the coronal view).
SliceAxis view_across(const core::ImageGeometry& g, int voxel_axis);

//! The colour and legend name of one label value.
struct LabelColour {
    int label = 0;
    std::array<std::uint8_t, 3> rgb{255, 0, 0};
    std::string name;
};

//! The project palette: 1 liver (orange-brown), 2 portal vein (violet), 3 hepatic veins (blue),
//! 4 tumour (yellow), and the phantom's neighbour labels 10-26 (docs/phantom.md lists them).
const std::vector<LabelColour>& default_label_colours();

//! One label volume drawn over the slice.
struct Overlay {
    const core::LabelImage3D* labels = nullptr; //!< on the same grid as the image (checked)
    double fill_opacity = 0.35;                 //!< 0 = no fill, 1 = opaque
    int contour_px = 1;                         //!< contour line width [output pixels], 0 = none
    std::vector<LabelColour> colours;           //!< empty = default_label_colours(); labels
                                                //!< without a colour are not drawn
    bool legend = true;                         //!< list this overlay's labels present in the slice
};

//! What to draw.
struct PictureParams {
    SliceAxis axis = SliceAxis::Axial;
    int index = -1;            //!< voxel index along slice_voxel_axis(); -1 = the middle slice
    double window = 400;       //!< window width [image units, HU for CT]
    double level = 40;         //!< window centre
    double pixel_mm = 0;       //!< output pixel size [mm]; 0 = the finer in-plane spacing
    int max_side_px = 1600;    //!< the output is scaled down so that no side exceeds this
    core::Vec3 roi_lo{0, 0, 0}; //!< physical box [mm] limiting the picture to the part of the
    core::Vec3 roi_hi{0, 0, 0}; //!< slice inside it; roi_lo == roi_hi = the whole slice
    std::string caption;       //!< text under the picture; empty = none
    bool auto_caption = true;  //!< add "axial k=.. z=.. mm  W400/L40" to the caption
};

//! An 8-bit RGB picture, rows top to bottom, 3 bytes per pixel.
struct RgbImage {
    int width = 0;
    int height = 0;
    std::vector<std::uint8_t> rgb;
};

//! Renders one slice of `image` with `overlays` drawn in order.
//! \throw core::InvalidInputError if the index is outside the image or an overlay is on
//! another grid.
template <class T>
RgbImage render_slice(const core::Image3D<T>& image, const PictureParams& params,
                      const std::vector<Overlay>& overlays = {});

//! Same for any pixel type.
RgbImage render_slice(const core::AnyImage& image, const PictureParams& params,
                      const std::vector<Overlay>& overlays = {});

//! Writes a PNG atomically (temporary file, then rename). \throw core::IoError on failure.
void write_png(const std::filesystem::path& path, const RgbImage& picture);

//! render_slice + write_png.
template <class T>
void write_slice_png(const std::filesystem::path& path, const core::Image3D<T>& image,
                     const PictureParams& params, const std::vector<Overlay>& overlays = {})
{
    write_png(path, render_slice(image, params, overlays));
}

// Instantiated in picture.cpp for every pixel type of core::AnyImage.
extern template RgbImage render_slice(const core::Image3D<std::uint8_t>&, const PictureParams&, const std::vector<Overlay>&);
extern template RgbImage render_slice(const core::Image3D<std::int8_t>&, const PictureParams&, const std::vector<Overlay>&);
extern template RgbImage render_slice(const core::Image3D<std::int16_t>&, const PictureParams&, const std::vector<Overlay>&);
extern template RgbImage render_slice(const core::Image3D<std::uint16_t>&, const PictureParams&, const std::vector<Overlay>&);
extern template RgbImage render_slice(const core::Image3D<std::int32_t>&, const PictureParams&, const std::vector<Overlay>&);
extern template RgbImage render_slice(const core::Image3D<std::uint32_t>&, const PictureParams&, const std::vector<Overlay>&);
extern template RgbImage render_slice(const core::Image3D<float>&, const PictureParams&, const std::vector<Overlay>&);
extern template RgbImage render_slice(const core::Image3D<double>&, const PictureParams&, const std::vector<Overlay>&);

} // namespace lobe::tools
