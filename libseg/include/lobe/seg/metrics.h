#pragma once
//! \file
//! \brief Segmentation evaluation: Dice, Jaccard and the five SLIVER07 measures (Heimann et al.,
//! IEEE TMI 2009; seed thesis Appendix A) with the 0-100 SLIVER07 score.

#include "lobe/core/image3d.h"

#include <cstddef>

namespace lobe::seg {

//! Symmetric surface distances [mm] between the borders of two masks. A border voxel is an
//! object voxel with at least one of its 26 neighbours outside the object (voxels outside the
//! grid count as outside). Every border voxel of either mask contributes its distance to the
//! nearest border voxel of the other mask (exact Euclidean distance transform, anisotropic
//! spacing), and the three statistics are taken over that pooled set.
struct SurfaceDistances {
    double average = 0.0; //!< ASD: mean of the pooled distances [mm]
    double rms = 0.0;     //!< RMSD: square root of the mean squared distance [mm]
    double maximum = 0.0; //!< MaxD: Hausdorff distance between the borders [mm]
    std::size_t border_voxels_seg = 0; //!< border voxels of the segmentation
    std::size_t border_voxels_ref = 0; //!< border voxels of the reference
};

//! Everything `evaluate_segmentation` measures. Volumes in mL (1 mL = 1000 mm^3).
struct SegmentationMeasures {
    double dice = 0.0;    //!< 2|S∩R| / (|S|+|R|), 1 = perfect
    double jaccard = 0.0; //!< |S∩R| / |S∪R|, 1 = perfect
    double voe = 0.0;     //!< volumetric overlap error, (1 - jaccard) * 100 [%]
    double rvd = 0.0;     //!< signed relative volume difference, (|S| - |R|) / |R| * 100 [%]
    double abs_rvd = 0.0; //!< |rvd| [%], the SLIVER07 measure
    SurfaceDistances surface;
    double volume_seg_ml = 0.0;
    double volume_ref_ml = 0.0;
};

//! Compares segmentation `seg` with reference `ref` (non-zero = object) on the same grid.
//! \throw InvalidInputError if the grids differ, or if either mask is empty (every measure
//! would be undefined: say so rather than return a number).
SegmentationMeasures evaluate_segmentation(const core::LabelImage3D& seg, const core::LabelImage3D& ref);

//! The per-measure values an average human second rater reached in SLIVER07; each maps to a
//! score of 75. Defaults from Heimann et al. 2009 (see docs/algorithms/metrics.md).
struct SliverReference {
    double voe = 6.4;   //!< [%]
    double abs_rvd = 4.7; //!< [%]
    double asd = 1.0;   //!< [mm]
    double rmsd = 1.8;  //!< [mm]
    double maxd = 19.0; //!< [mm]
};

//! SLIVER07 scores: each measure maps linearly to max(0, 100 - 25 * value / reference).
struct SliverScore {
    double voe = 0.0, abs_rvd = 0.0, asd = 0.0, rmsd = 0.0, maxd = 0.0;
    double total = 0.0; //!< mean of the five scores
};

SliverScore sliver_score(const SegmentationMeasures& m, const SliverReference& reference = {});

} // namespace lobe::seg
