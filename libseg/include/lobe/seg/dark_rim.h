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
    double touching_min_smoothing_px = 0.5; //!< the pixels touching the body are kept (a boundary pixel
                                        //!< half object, half darker tissue reads below the level after the
                                        //!< smoothing) only where the smoothing's sigma spans at least this many
                                        //!< pixels; on coarser pixels (3 mm at 1 mm) it barely mixes a pixel with
                                        //!< its neighbours, and a rim pixel below the half-way level is mostly
                                        //!< darker tissue. 0 = always kept
    double body_depth_voxels = 2.0;     //!< the object's body in a slice: its non-dark pieces reaching
                                        //!< more than this many pixels from their edge (not the thin partial-
                                        //!< volume sliver between a dark layer and a bright rib)
    int sectors = 8;                    //!< the darker tissue is measured per angular sector of each slice
                                        //!< (around the mask's centroid); 0 = one neighbour for the volume
    int sector_min_voxels = 20;         //!< a sector with fewer darker ring pixels takes the volume's
};

//! What `trim_dark_rim` returns.
struct DarkRimResult {
    core::LabelImage3D mask; //!< the input mask less the dark rim (0/1)
    double level = 0;        //!< the volume's level (a sector with its own darker tissue has its own)
    double neighbour = 0;    //!< the median of the darker tissue outside the mask
    std::size_t removed = 0; //!< voxels dropped
    bool applied = false;    //!< false: no darker tissue outside the mask, nothing done
    bool touching_kept = true; //!< the dark pixels touching the body were kept (the smoothing spans
                             //!< touching_min_smoothing_px pixels); false: judged like the rest
};

//! Drops, on every axial slice of `mask` (non-zero = object), the voxels darker than the level
//! (smoothed grey level) that are not among the 8 neighbours of the slice's body (its non-dark
//! pieces deeper than `body_depth_voxels`; the neighbours count only where `smoothing_mm` spans
//! `touching_min_smoothing_px` pixels), in 8-connected pieces that reach the mask's outside in
//! the slice and are at most 2 x `max_half_thickness_mm` thick, or thicker but no brighter on
//! average than the volume's neighbour (the surroundings' fat, lung or gas, not a lesion), and the
//! pieces of the mask that this cuts off from the body. The level is
//! `min(low, median − level × (median − neighbour))`, the neighbour being the median of the
//! smoothed grey levels below `low` in a ring of `ring_voxels` pixels outside the mask: per
//! angular sector of each slice where the sector's ring holds `sector_min_voxels` such pixels,
//! else over the whole volume (`DarkRimResult::level` and `neighbour` are the volume's). `median`
//! is the object's grey level and `low` the low end of its band (below it a voxel is not
//! object-like), both in `image` units. \throw InvalidInputError for a mask not on the image's
//! grid, non-finite median or low, low above median, or parameters out of range (level in (0, 1],
//! ring_voxels >= 1, max_half_thickness_mm > 0, smoothing_mm, touching_min_smoothing_px and
//! body_depth_voxels >= 0, sectors >= 0, sector_min_voxels >= 1).
DarkRimResult trim_dark_rim(const core::ImageF& image, const core::LabelImage3D& mask, double median, double low,
                            const DarkRimParams& params = {});

} // namespace lobe::seg
