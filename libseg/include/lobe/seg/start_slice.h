#pragma once
//! \file
//! \brief Steps 1-5 of the automatic liver pipeline (spec §5.1): the start slice and the axial
//! rotation of the patient by rotational template matching against a heart/lung template with a
//! weighted normalised cross-correlation, then a conservative seed region inside the liver from
//! homogeneous liver-like grid cells. See docs/algorithms/start_slice.md.
//!
//! Conventions: the volume's third axis must be the craniocaudal axis (axial slices); positions
//! are handled in physical LPS millimetres through the image direction, so flipped axes work
//! (+x = patient left, +y = posterior, +z = superior; "caudal" = towards smaller z).

#include "lobe/core/image3d.h"
#include "lobe/core/types.h"

#include <string>
#include <vector>

namespace lobe::seg {

//! Inputs of `find_start_slice`. Defaults are for CT in HU.
struct StartSliceParams {
    double pixel_mm = 4.0;           //!< working pixel size: slices are area-averaged to it
    double max_rotation_deg = 30.0;  //!< rotations searched: [-max, +max]
    double rotation_step_deg = 3.0;  //!< fine angular step on the start slice (the estimate is
                                     //!< then refined by a parabola through the best three)
    double coarse_step_deg = 10.0;   //!< angular step of the per-slice search over all slices
    double lung_value = -900.0;      //!< grey level mapped to 0 (air/lung); the feature image is
                                     //!< f = clamp((v - lung_value) / (tissue_value - lung_value), 0, 1)
    double tissue_value = -100.0;    //!< grey level mapped to 1 (fat and all soft tissue)
    double template_scale = 1.0;     //!< scales the template's millimetre layout (body size)
    double min_score = 0.55;         //!< a slice "shows the heart and both lungs" if its best
                                     //!< weighted NCC reaches max(min_score, relative_score * best)
    double relative_score = 0.9;     //!< see min_score
};

//! What `find_start_slice` returns.
struct StartSliceResult {
    bool found = false;              //!< a heart/lung slice was found
    int slice = -1;                  //!< the start slice: the most caudal slice of the run of
                                     //!< matching slices around the best one (just above the liver)
    double rotation_deg = 0.0;       //!< axial rotation of the patient: positive turns +x (patient
                                     //!< left) towards +y (posterior); for an identity direction that
                                     //!< is clockwise on screen (i right, j down), i.e. the negative
                                     //!< of cv::getRotationMatrix2D's angle
    double score = 0.0;              //!< weighted NCC of the template on `slice` at rotation_deg
    core::Vec3 heart_centre;         //!< continuous voxel index of the matched heart centre on `slice`
    std::vector<double> slice_scores;//!< best score per slice over positions and coarse angles
    std::string message;             //!< why not found (also set when found, as a summary)
};

//! Finds the start slice (the most caudal slice showing the heart between both lungs) and the
//! axial rotation. Needs no training data: the template is built in code (see the doc).
//! Returns found = false with a message when no slice matches (e.g. an abdominal-only volume).
//! \throw core::InvalidInputError for an invalid image, mismatched data size, invalid params,
//! or a volume whose third axis is not craniocaudal.
StartSliceResult find_start_slice(const core::ImageF& hu_volume, const StartSliceParams& params = {});

//! The weighted normalised cross-correlation used above, exposed for testing and plots:
//! R = Σ w (f - f̄_w)(t - t̄_w) / sqrt(Σ w (f - f̄_w)² · Σ w (t - t̄_w)²), with weighted means
//! f̄_w = Σ w f / Σ w. Returns 0 when either weighted variance is ~0 (a flat window).
//! `f`, `t`, `w` hold `n` values each; w >= 0. \throw core::InvalidInputError otherwise.
double weighted_ncc(const float* f, const float* t, const float* w, std::size_t n);

//! The same for three contiguous containers of floats (std::vector, an image's data) of one
//! size. \throw core::InvalidInputError if the sizes differ or a weight is negative.
template <class F, class T, class W>
double weighted_ncc(const F& f, const T& t, const W& w)
{
    if (f.size() != t.size() || f.size() != w.size())
        throw core::InvalidInputError("weighted_ncc: f, t and w must have the same size (" + std::to_string(f.size()) +
                                      ", " + std::to_string(t.size()) + ", " + std::to_string(w.size()) + ")");
    return weighted_ncc(f.data(), t.data(), w.data(), f.size());
}

//! The synthetic heart/lung template as the matcher sees it, rasterised on a square grid of
//! `pixel_mm` pixels centred on the heart, rotated by `rotation_deg` (same sign as
//! StartSliceResult::rotation_deg) with the in-plane axes +x right, +y down: `value` in [0, 1]
//! (0 = lung) and the weight map k(x, y) (0 outside the support). Both have size[2] == 1.
struct HeartLungTemplate {
    core::ImageF value;
    core::ImageF weight;
};
HeartLungTemplate heart_lung_template(double pixel_mm, double rotation_deg = 0.0, double scale = 1.0);

//! Inputs of `seed_liver`. Grey-level defaults are CT HU; for a normalised MR image set
//! body_threshold, liver_range and max_cell_sd to the image's scale.
struct LiverSeedParams {
    double cell_mm = 6.0;              //!< grid cell size (thesis: a grid excludes lung vessels)
    double body_threshold = -400.0;    //!< body = largest component above this, holes filled
    double liver_range_lo = 40.0;      //!< plausible liver grey levels: the liver value is the
    double liver_range_hi = 200.0;     //!< mode of homogeneous cell means inside this range
    double max_cell_sd = 40.0;         //!< a cell is never homogeneous above this sd
    double homogeneity_factor = 1.6;   //!< homogeneous: sd <= factor * (25th percentile of the
                                       //!< candidate cells' sd), the pixel-noise estimate
    double acceptance_sigma = 1.0;     //!< accept cells with |mean - liver_value| <= this * noise sd
    double wall_margin_mm = 15.0;      //!< cells at least this deep inside the body
    double search_depth_mm = 150.0;    //!< with a start slice: slices at most this far below it
    double min_depth_mm = 40.0;        //!< ... and at least this far (the heart sits in the dome
                                       //!< there, behind a contact the snake may cross), when the
                                       //!< volume reaches that deep
    double min_area_mm2 = 1500.0;      //!< smaller seeds are rejected (kidney, bowel, noise)
    double max_body_fraction = 0.6;    //!< larger seeds are rejected (no contrast: constant image)
    int erode_cells = 1;               //!< erosion of the accepted group, in cells (conservative)
};

//! What `seed_liver` returns.
struct LiverSeedResult {
    bool found = false;
    int slice = -1;                    //!< slice index of the seed in the input volume
    core::LabelImage3D mask;           //!< the seed (1) on `slice`: a one-slice image with that
                                       //!< slice's geometry (size[2] == 1); empty when not found
    double liver_value = 0.0;          //!< estimated liver grey level (HU for CT)
    double liver_sigma = 0.0;          //!< estimated pixel noise sd inside the liver
    double area_mm2 = 0.0;             //!< seed area
    bool used_start_slice = false;     //!< the search was below a found start slice (else: the
                                       //!< whole volume, the patient's right half of the body)
    std::string message;               //!< why not found, or how it was found
};

//! Seeds the liver: on the slices below the start slice (or all slices when `start.found` is
//! false), on the patient's right (of the heart, or of the body's centre) and in front of the
//! back muscles, keeps the grid cells whose grey level is homogeneous and equal to the estimated
//! liver value, and returns the largest connected group of them on the slice where it is largest.
//! \throw core::InvalidInputError for an invalid image or params.
LiverSeedResult seed_liver(const core::ImageF& hu_volume, const StartSliceResult& start,
                           const LiverSeedParams& params = {});

} // namespace lobe::seg
