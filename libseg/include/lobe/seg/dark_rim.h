#pragma once
//! \file
//! \brief The dark rim: a pass over a stacked slice-by-slice segmentation that drops the layers
//! of darker tissue its contour holds along its rim. A contour that crosses a weak edge into a
//! thin layer of another tissue (the diaphragm and intercostal muscle between the liver and the
//! ribs, 40-50 HU darker than an enhanced liver) stops only at the next strong edge (the ribs),
//! and carries the layer on from slice to slice. See docs/algorithms/liver.md, "The dark rim".

#include "lobe/core/image3d.h"

#include <cstddef>

namespace lobe::seg {

//! Inputs of `trim_dark_rim`. `{}` is the documented default.
struct DarkRimParams {
    double level = 0.5;                 //!< a voxel is dark below this fraction of the way from the object's
                                        //!< median down to the median of the darker tissue outside it: the
                                        //!< half-way level is where a blurred step between the two crosses
    int ring_voxels = 3;                //!< the darker tissue is sampled in this many pixels outside the mask
    double max_half_thickness_mm = 5.0; //!< thicker dark pieces are kept: a lesion of 1 cm or more
                                        //!< at the surface (liver under SLIVER07) is not a layer of muscle
    double smoothing_mm = 1.0;          //!< Gaussian sigma of the grey levels, in plane (as the snakes see them)
    double body_depth_voxels = 2.0;     //!< the object's body in a slice: its non-dark pieces reaching
                                        //!< more than this many pixels from their edge (not the thin partial-
                                        //!< volume sliver between a dark layer and a bright rib)
};

//! What `trim_dark_rim` returns.
struct DarkRimResult {
    core::LabelImage3D mask; //!< the input mask less the dark rim (0/1)
    double level = 0;        //!< the smoothed grey level below which a voxel was dark
    double neighbour = 0;    //!< the median of the darker tissue outside the mask
    std::size_t removed = 0; //!< voxels dropped
    bool applied = false;    //!< false: no darker tissue outside the mask, nothing done
};

//! Drops, on every axial slice of `mask` (non-zero = object), the voxels whose smoothed grey
//! level lies below `DarkRimResult::level` and which are not among the 8 neighbours of the
//! slice's body (its non-dark pieces deeper than `body_depth_voxels`), in 8-connected pieces that
//! reach the mask's outside in the slice and are at most 2 x `max_half_thickness_mm` thick, and
//! the pieces of the mask that this cuts off from the body. The level is
//! `min(low, median − level × (median − neighbour))`, neighbour being the median of the smoothed
//! grey levels below `low` in a ring of `ring_voxels` pixels outside the mask over all slices.
//! `median` is the object's grey level and `low` the low end of its band (below it a voxel is not
//! object-like), both in `image` units. The pixels touching the object are kept: partial volume
//! lies there. \throw InvalidInputError for a mask not on the image's grid, non-finite median or
//! low, low above median, or parameters out of range (level in (0, 1], ring_voxels >= 1,
//! max_half_thickness_mm > 0, smoothing_mm and body_depth_voxels >= 0).
DarkRimResult trim_dark_rim(const core::ImageF& image, const core::LabelImage3D& mask, double median, double low,
                            const DarkRimParams& params = {});

} // namespace lobe::seg
