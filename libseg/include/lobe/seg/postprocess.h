#pragma once
//! \file
//! \brief The 3-D pass over the stacked slice-by-slice liver result: keep the largest
//! component, fill what the chosen convention counts as liver (SLIVER07: enclosed vessels and
//! tumours, and the inferior vena cava in the liver's Omega concavity), and smooth the jagged
//! stack in 3-D while keeping its volume. See docs/algorithms/postprocess.md.

#include "lobe/core/image3d.h"

#include <cstddef>

namespace lobe::seg {

//! What the output counts as liver.
enum class LiverConvention {
    Sliver07,   //!< SLIVER07 reference: internal vessels, tumours and the enclosed IVC are liver
    Parenchyma, //!< smoothing only: holes (vessels, tumours) and the IVC concavity stay outside
};

//! Inputs of `postprocess_liver`.
struct PostprocessParams {
    double smoothing_mm = 2.0;   //!< Gaussian sigma of the 3-D smoothing [mm], the same in mm on
                                 //!< every axis (anisotropic spacing honoured); <= 0: no smoothing
    bool preserve_volume = true; //!< threshold the smoothed mask at the level that keeps its voxel
                                 //!< count (else at 0.5, which shaves convex parts)
    LiverConvention convention = LiverConvention::Sliver07;
    bool keep_largest_component = true; //!< drop every 3-D component (26-connected) but the largest
    bool fill_holes = true;      //!< Sliver07 only: fill holes per axial slice and in 3-D
    double concavity_closing_mm = 7.0; //!< Sliver07 only: radius of the per-slice closing that
                                       //!< bridges the neck of an Omega concavity (IVC); necks
                                       //!< narrower than about twice it are bridged; <= 0: off
};

//! Statistics of a postprocess run (for logs and the driver's provenance).
struct PostprocessResult {
    core::LabelImage3D mask;          //!< 0/1 on the input's grid
    std::size_t voxels_in = 0;        //!< non-zero input voxels
    std::size_t removed_components = 0; //!< voxels dropped with the smaller components
    std::size_t filled_holes = 0;     //!< voxels added by hole filling
    std::size_t filled_concavities = 0; //!< voxels added by the concavity (IVC) filling
    double threshold = 0.5;           //!< level the smoothed mask was cut at
    double seconds = 0.0;
};

//! Runs the 3-D pass on a stacked mask (non-zero = liver). An all-zero mask comes back as an
//! all-zero mask. \throw InvalidInputError for an invalid geometry or a data size that does not
//! match it, or a negative/NaN parameter.
PostprocessResult postprocess_liver_full(const core::LabelImage3D& stacked, const PostprocessParams& params = {});

//! `postprocess_liver_full(stacked, params).mask`.
core::LabelImage3D postprocess_liver(const core::LabelImage3D& stacked, const PostprocessParams& params = {});

} // namespace lobe::seg
