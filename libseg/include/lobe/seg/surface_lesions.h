#pragma once
//! \file
//! \brief Surface lesions: a pass over a stacked slice-by-slice segmentation that adds the
//! lesions its contour ran round at the object's surface. A hypodense lesion that reaches the
//! liver's surface is, in an axial slice, a notch in the outline: the snake stops at the lesion's
//! edge and the lesion's outer face is the liver's surface, so no hole filling reaches it (the
//! thesis's "tumour next to the ribs"). Under SLIVER07 it is liver. See
//! docs/algorithms/liver.md, "Surface lesions".

#include "lobe/core/image3d.h"

#include <cstddef>
#include <string>

namespace lobe::seg {

//! Inputs of `fill_surface_lesions`. `{}` is the documented default.
struct SurfaceLesionParams {
    double closing_mm = 15.0;   //!< radius of the per-slice closing that bridges a lesion's notch
    double core_mm = 2.5;       //!< a piece's core is what survives an in-plane opening of this radius
    double min_ml = 0.5;        //!< a piece is added when its core holds at least this volume ...
    double core_fraction = 0.5; //!< ... and this fraction of the piece: a lesion is a thick blob, the
                                //!< partial volume a closing bridges in the outline's notches is thin
    double smoothing_mm = 1.0;  //!< Gaussian sigma of the grey levels, in plane (as the snakes see them)
};

//! What `fill_surface_lesions` returns.
struct SurfaceLesionResult {
    core::LabelImage3D mask; //!< the input mask with the lesions added (0/1)
    std::size_t added = 0;   //!< voxels added
};

//! Adds to `mask` (non-zero = object) the lesions in the notches of its outline. On every axial
//! slice the candidates are the voxels that a closing of the slice's mask with a disc of
//! `closing_mm` adds, whose smoothed grey level lies in [lo, hi) (darker than the object, not as
//! dark as what surrounds it) and which are not in `exclude` (null: nothing excluded). The
//! candidates' 3-D pieces (26-connected) whose core, what survives an in-plane opening with a disc
//! of `core_mm`, holds at least `min_ml` and `core_fraction` of the piece are added. The closing
//! and the opening are discs in mm of the slice's mean pixel size. \throw InvalidInputError for a
//! mask or exclusion not on the image's grid, non-finite lo or hi or lo >= hi, or parameters out of
//! range (closing_mm, core_mm > 0, min_ml, smoothing_mm >= 0, core_fraction in [0, 1], all finite).
SurfaceLesionResult fill_surface_lesions(const core::ImageF& image, const core::LabelImage3D& mask, double lo,
                                         double hi, const core::LabelImage3D* exclude = nullptr,
                                         const SurfaceLesionParams& params = {});

//! Throws InvalidInputError, naming `who`, if `params` is out of the range `fill_surface_lesions`
//! accepts (so that a caller can refuse it before its own work).
void check_surface_lesion_params(const SurfaceLesionParams& params, const std::string& who);

} // namespace lobe::seg
