#pragma once
//! \file
//! \brief The rib-cage ring (thesis L4700-4711, Fig 5.26; spec §5.1 step 7): bone is binarised,
//! the bone of neighbouring slices is overlapped so the separate rib sections form one ring, a
//! closed curve is laid along the ribs' inner surface (the "nearest whole rib shape"), and the
//! edge map is enhanced in a band just inside it, so that a snake does not leak into the
//! subcostal tissue and between the ribs. See docs/algorithms/rib_cage.md.
//!
//! Axial slices are assumed (size[2] slices of an LPS volume, rotation already corrected as in
//! the thesis); the ring is built per slice in the physical plane (anisotropic spacing allowed).

#include "lobe/core/image3d.h"

#include <cstdint>
#include <vector>

namespace lobe::seg {

//! Inputs of `rib_cage`.
struct RibCageParams {
    double bone_hu = 200.0;       //!< bone threshold [HU] (cortex ~900, marrow ~230; cartilage ~120
                                  //!< is below it on purpose: its gaps are bridged)
    int slices_to_combine = 4;    //!< slices whose bone is overlapped (thesis: 4), centred on the
                                  //!< slice: k - (n-1)/2 .. k + n/2, clipped to the volume
    double enhance_width_mm = 3.0; //!< width of the band inside the ring (the `ring` output) [mm]
    double wall_width_mm = 0.0;   //!< width of the `wall` band inside the ring [mm]; 0: none
    double body_hu = -400.0;      //!< the body is the largest region above this [HU], holes filled
    int angles = 360;             //!< rays cast from the body's centroid (angular resolution)
    double max_gap_deg = 40.0;    //!< angular gaps without bone up to this are bridged by linear
                                  //!< interpolation of the ring radius (intercostal spaces,
                                  //!< cartilage); wider gaps are left unconstrained
    double min_coverage = 0.5;    //!< a slice is valid when bone or bridged gaps cover at least
                                  //!< this fraction of the full turn
    double median_deg = 7.0;      //!< circular median filter of the ring radius over this angle
                                  //!< [degrees], removing single-ray spikes
    double min_bone_area_mm2 = 15.0; //!< bone components (of the overlapped slices) smaller than
                                  //!< this are dropped: noise specks in contrast vessels, calcifications
    double max_depth_mm = 60.0;   //!< a ray's bone counts only within this depth below the skin:
                                  //!< ribs lie under the body wall, so deeper bone in an open sector
                                  //!< (vessels, bowel contrast) cannot pull the ring into the organs
};

//! The ring of one slice in polar form about the body's centroid (physical in-plane offsets).
struct RibRing {
    double centre_i = 0.0, centre_j = 0.0; //!< the centroid [continuous voxel indices]
    std::vector<float> radius_mm;          //!< per ray (angle 2π a / angles, from +i towards +j)
    std::vector<std::uint8_t> supported;   //!< per ray: 1 bone, 2 bridged gap, 0 unconstrained
};

//! What `rib_cage` returns, on the input grid.
struct RibCageResult {
    core::LabelImage3D inside;    //!< 1 inside the rib cage; on invalid slices 1 everywhere (no
                                  //!< constraint), and beyond wide gaps 1 up to the image border
    core::LabelImage3D ring;      //!< 1 in the band of `enhance_width_mm` just inside the ring,
                                  //!< where the ring is supported by bone or a bridged gap
    core::LabelImage3D wall;      //!< 1 within `wall_width_mm` inside the ring where it is supported
                                  //!< (the body wall: intercostal muscle and diaphragm); all 0
                                  //!< when wall_width_mm is 0
    std::vector<std::uint8_t> valid; //!< per slice: 1 if a ring could be formed
    std::vector<double> coverage; //!< per slice: fraction of the turn covered by bone or bridged gaps
    std::vector<RibRing> rings;   //!< per slice (empty rays when no body was found)
};

//! Builds the rib-cage ring of every axial slice of `hu_volume` (HU). Slices with too little rib
//! (below the rib cage, an MRI, a tiny field of view) get valid = 0 and constrain nothing.
//! \throw InvalidInputError on an invalid grid, non-finite parameters or out-of-range values
//! (NaN voxels are treated as not bone and not body).
RibCageResult rib_cage(const core::ImageF& hu_volume, const RibCageParams& params = {});

//! Raises an edge map (values in [0, 1], 1 = strong edge, e.g. EdgeMapResult::edge) on the ring:
//! f' = min(1, (1 + gain) f) where `ring` is non-zero. Existing edges (the weak liver/subcostal
//! boundary) get stronger; flat regions stay flat (no edge is invented). Works on a slice or a
//! volume. \throw InvalidInputError if the grids differ or gain is negative or not finite.
core::ImageF enhance_rib_edges(const core::ImageF& edge, const core::LabelImage3D& ring, double gain = 1.0);

//! Sets the voxels of `image` outside the rib cage (`inside` == 0) to `background` (e.g. the low
//! end of the intensity window), so that any method working on the image sees a strong boundary
//! along the ribs' inner surface. Works on a slice or a volume.
//! \throw InvalidInputError if the grids differ.
core::ImageF mask_outside_rib_cage(const core::ImageF& image, const core::LabelImage3D& inside, float background);

} // namespace lobe::seg
