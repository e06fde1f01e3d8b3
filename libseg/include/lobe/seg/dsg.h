#pragma once
//! \file
//! \brief Directional sharpened GVF (DSG, thesis §4.9): weak edges whose orientation matches a
//! template contour are boosted by a steerable directional derivative, the compensated edge map
//! is sharpened by a safe monotone kernel and a Laplacian, and GGVF runs on the result inside δ1.

#include "lobe/core/image3d.h"
#include "lobe/seg/gvf.h"
#include "lobe/seg/vector_field.h"

namespace lobe::seg {

//! Inputs of the DSG edge enhancement.
struct DsgParams {
    double gain = 1.0;            //!< A: weight of the directional compensation Λ relative to Γ
    double neighbourhood_mm = 3.0; //!< radius over which the local gradient energy Γ_{x0y0ϑ0} is averaged [mm]
    double sharpen_max = 0.75;    //!< the tan∘tan∘tan kernel's argument is scaled to [0, sharpen_max]
                                  //!< (below the pole at 0.7873, where the kernel is monotone)
    bool laplacian_sharpening = true; //!< f~ = f_H - ∇²f_H
};

//! Directionally compensated, sharpened edge map F_ϑ = Γ_ϑ · f~_H, normalised to [0, 1].
//! `edge` is the normalised edge map f; `direction` holds, per voxel, the preferred unit edge
//! normal (from the template contour: the gradient of its signed distance); where `direction`
//! is zero the voxel gets no compensation. Compensation: the steerable form of the thesis's
//! f_u^2 - f_v^2 (spec §4.9.4) as a gain, F = (1 + A c) f~_H with c = <(n·∇f)^2> / <|∇f|^2>
//! averaged over a Gaussian window of σ = neighbourhood_mm / 2 (c = cos² of the angle between
//! the edge normal and n); docs/algorithms/dsg.md says why a gain and not a sum.
//! \throw InvalidInputError if the grids differ.
core::ImageF dsg_edge_map(const core::ImageF& edge, const VectorField& direction, const DsgParams& params = {});

//! The safe monotone replacement for H = tan(tan(tan(x))): x is mapped to [0, sharpen_max]
//! first, so H is finite, increasing and convex; the result is rescaled to [0, 1].
double sharpen_kernel(double x, double sharpen_max = 0.75);

} // namespace lobe::seg
