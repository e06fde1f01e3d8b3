#pragma once
//! \file
//! \brief Gradient vector flow (Xu & Prince 1998) and generalised GVF (Xu & Prince 1998b):
//! over the whole image (the baseline the thesis beats) and band-limited to the voxels of a mask
//! (the δ1 band around edges that CDSG uses).

#include "lobe/core/image3d.h"
#include "lobe/seg/vector_field.h"

#include <cstdint>

namespace lobe::seg {

enum class GvfModel {
    Gvf,  //!< h = μ, p = |∇f|^2 (thesis's explicit iteration, Xu & Prince GVF.m)
    Ggvf, //!< h = exp(-(|∇f|/K)^2), p = 1 - h (thesis eq. 4.13)
};

//! Inputs of `gradient_vector_flow`. Works in index units (grid spacing 1): the edge map f is
//! normalised to [0,1], so μ and K need no rescaling with spacing. Explicit scheme, 5-point
//! (2-D) or 7-point (3-D) Laplacian with mirrored borders.
struct GvfParams {
    GvfModel model = GvfModel::Ggvf;
    double mu = 0.2;          //!< GVF regularisation μ (Xu & Prince default)
    double k = 0.05;          //!< GGVF K in h = exp(-(|∇f|/K)^2), for f in [0,1]
    double time_step = 1.0;   //!< Δt; reduced automatically to 0.999 / max(2·dim·h + p), the bound at
                              //!< which each step is a weighted average (so |v| ≤ max|∇f|)
    int iterations = 0;       //!< 0 = the thesis's minimum, (1/3) of the longest in-plane row
    double tolerance = 0.0;   //!< stop early when max |Δv| per iteration < tolerance (0 = never)
};

//! What `gradient_vector_flow` returns.
struct GvfResult {
    VectorField field;    //!< the GVF/GGVF field v (index units)
    int iterations = 0;   //!< iterations run
    double last_change = 0.0; //!< max |Δv| in the last iteration
};

//! GVF/GGVF of edge map `edge` over the whole grid.
GvfResult gradient_vector_flow(const core::ImageF& edge, const GvfParams& params = {});

//! Band-limited GVF/GGVF: the diffusion runs only on voxels where `band` is non-zero. The field
//! starts as ∇f there and is zero outside; the band's border is a zero-flux boundary (a
//! neighbour outside the band counts as equal to the centre). Cost is proportional to the
//! band size, not the image. \throw InvalidInputError if the grids differ.
GvfResult gradient_vector_flow(const core::ImageF& edge, const core::LabelImage3D& band, const GvfParams& params = {});

} // namespace lobe::seg
