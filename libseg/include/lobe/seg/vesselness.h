#pragma once
//! \file
//! \brief Enhancement of tubular structures: the multi-scale Hessian vesselness of Frangi et al.
//! (MICCAI 1998), with the vessel axis at every voxel, and the directional sharpening the seed
//! thesis asks of CDSG for vessels ("enhance the contrast of vessels along their axial
//! directions", spec §5.3): averaging along the local axis, then the thesis's monotone
//! tan∘tan∘tan sharpening kernel (dsg.h). See docs/algorithms/vessels.md.

#include "lobe/core/image3d.h"
#include "lobe/seg/vector_field.h"

#include <vector>

namespace lobe::seg {

//! Inputs of `vesselness`.
struct VesselnessParams {
    //! Gaussian σ of each scale [mm]. A bright cylinder of radius r gives its strongest
    //! σ²-normalised response at its centre for σ = r/√2 (docs/algorithms/vessels.md), so these
    //! cover radii of about 1.4-5.7 mm.
    std::vector<double> scales_mm{1.0, 1.6, 2.5, 4.0};
    double alpha = 0.5;       //!< Frangi's α: sensitivity to R_A = |λ2|/|λ3| (plate vs line)
    double beta = 0.5;        //!< Frangi's β: sensitivity to R_B = |λ1|/√|λ2 λ3| (blob vs line)
    //! Frangi's c in image units (HU for CT) on the σ²-normalised Hessian: structures whose
    //! Hessian norm is well below c (noise) get a low response. <= 0: half the 99.9th percentile
    //! of the norm over the ROI, per scale (Frangi's "half the maximum", made robust to a few
    //! very bright voxels).
    double structureness = 0.0;
    bool bright = true;       //!< bright tubes on a darker background (contrast-enhanced vessels)
};

//! What `vesselness` returns, on the input's grid.
struct VesselnessResult {
    core::ImageF vesselness;  //!< max over the scales, in [0, 1]; 0 outside the ROI
    core::ImageF scale_mm;    //!< σ of the scale that gave the maximum [mm]; 0 where vesselness is 0
    //! Unit vessel direction (the Hessian eigenvector of the smallest |λ| at the best scale),
    //! components along the image axes i, j, k in physical units (a step of t mm along it moves
    //! t·axis[a]/spacing[a] voxels along axis a); zero where vesselness is 0.
    VectorField axis;
    std::vector<double> structureness; //!< the c used at each scale
};

//! Multi-scale vesselness of `image` (e.g. HU). Only voxels where `roi` is non-zero (all when it
//! is null) are computed; the smoothing still sees the image around them. Derivatives are in mm
//! with the true spacing, so anisotropic voxels are handled (coarsely along a thick-slice axis).
//! \throw InvalidInputError on an invalid grid, a data size that does not match it, an ROI on
//! another grid, non-finite values in the ROI's box, or parameters out of range (no scale, a
//! scale <= 0, α or β <= 0).
VesselnessResult vesselness(const core::ImageF& image, const VesselnessParams& params = {},
                            const core::LabelImage3D* roi = nullptr);

//! Inputs of `directional_sharpening`.
struct DirectionalSharpeningParams {
    double half_length_mm = 1.5; //!< the average runs over ± this along the vessel axis [mm]
    double step_mm = 0.0;        //!< sample spacing along the axis [mm]; <= 0: the finest spacing
    double min_vesselness = 0.02; //!< voxels with less vesselness keep their value
    //! The thesis's safe tan∘tan∘tan kernel (sharpen_kernel in dsg.h) applied to the axially
    //! averaged vesselness: argument scale in (0, 0.7873); <= 0 (the default) leaves it linear.
    //! At 0.75 (DSG's edge-map default) it crushes the mid-range responses of thin vessels
    //! (a tube with V = 0.5 keeps 0.10) and cost 20 % of the 4th-level centre line on the
    //! phantom (docs/algorithms/vessels.md, bench/vessels).
    double sharpen_max = 0.0;
};

//! What `directional_sharpening` returns.
struct DirectionalSharpeningResult {
    core::ImageF intensity;   //!< the image averaged along each voxel's vessel axis (unchanged
                              //!< where vesselness < min_vesselness)
    core::ImageF vesselness;  //!< the vesselness averaged the same way, then sharpened, in [0, 1]
};

//! Enhances vessels along their axial directions: each voxel with a vessel axis takes the mean of
//! `image` and of `v.vesselness` sampled (trilinearly) along that axis over ±half_length_mm.
//! Noise falls by about √(samples) along a vessel, whose profile is constant along its axis,
//! while the cross-section (the boundary) is not blurred; a short gap in contrast is partly
//! filled from both sides. \throw InvalidInputError if the grids differ or params are invalid.
DirectionalSharpeningResult directional_sharpening(const core::ImageF& image, const VesselnessResult& v,
                                                   const DirectionalSharpeningParams& params = {});

} // namespace lobe::seg
