#pragma once
//! \file
//! \brief Shape memory: slice-to-slice statistics of the liver learnt from labelled volumes,
//! used while propagating a contour slice by slice to reject a candidate that departs grossly
//! from the expected shape (a leak into the heart, kidney, subcostal tissue or stomach, or a
//! collapse) and to recover from it (the plausible envelope). It also holds the liver's
//! intensity statistics, which the pipeline uses to pick the liver's K-means layer.
//! See docs/algorithms/shape_memory.md.
//!
//! What is learnt needs no position along the liver (unknown while propagating): for every pair
//! of consecutive liver slices, in both directions, the change from the previous slice to the
//! next one per mm of z, binned by the previous slice's equivalent radius sqrt(area / pi) (the
//! one thing the driver knows: small slices near the dome and the tip change fastest) and by the
//! phase rho = previous area / largest area met so far in the propagation direction (past the
//! widest slice, rho < 1, the liver shrinks and a growth is suspect; rho ~ 1 while it grows).

#include "lobe/core/image3d.h"

#include <array>
#include <cstddef>
#include <string>
#include <vector>

namespace lobe::seg {

//! Levels of the intensity quantiles stored in IntensityStats::quantiles.
inline constexpr std::array<double, 5> kIntensityQuantileLevels{0.05, 0.25, 0.50, 0.75, 0.95};

//! Intensity of the image inside the (slightly eroded) liver masks, pooled over the volumes.
struct IntensityStats {
    std::string modality = "CT"; //!< as given to training ("CT": values are HU)
    std::size_t voxels = 0;      //!< voxels the statistics are taken over
    double mean = 0.0;
    double sd = 0.0;
    std::array<double, 5> quantiles{}; //!< at kIntensityQuantileLevels
};

//! Learnt slice-to-slice limits for previous slices whose equivalent radius is in
//! [radius_min_mm, radius_max_mm) and whose phase rho is in [rho_min, rho_max). Rates are per
//! mm of z; all are "high quantile" values (ShapeTrainParams::quantile) of the training
//! transitions, made non-increasing with the radius and non-decreasing with rho (a smaller
//! slice, or one nearer the widest, is never held to a stricter limit).
struct ShapeStep {
    double radius_min_mm = 0.0;
    double radius_max_mm = 0.0;     //!< +infinity for the last bin
    double rho_min = 0.0;
    double rho_max = 0.0;           //!< +infinity for the last phase (rho is at most 1)
    std::size_t transitions = 0;    //!< training transitions whose previous slice fell in this bin
    double outward_per_mm = 0.0;    //!< max outward boundary motion / dz: the farthest candidate
                                    //!< pixel from the previous mask [mm/mm]
    double envelope_per_mm = 0.0;   //!< 95th percentile of the new pixels' distance from the
                                    //!< previous mask / dz: the envelope's radius rate, robust to
                                    //!< a lobe's thin edge appearing (which the max is not)
    double inward_per_mm = 0.0;     //!< max inward motion / dz: the farthest previous pixel from
                                    //!< the candidate [mm/mm]
    double growth_per_mm = 0.0;     //!< ln(A_next / A_prev) / dz over growing transitions [1/mm]
    double shrink_per_mm = 0.0;     //!< ln(A_prev / A_next) / dz over shrinking transitions [1/mm]
    double centroid_per_mm = 0.0;   //!< in-plane centroid shift / dz [mm/mm]
    double dice_min = 1.0;          //!< lowest Dice of the two slices seen (information only)
};

//! What training learns. A plain struct: the driver may edit the tolerances.
struct ShapeMemory {
    int volumes = 0;               //!< volumes trained on
    std::size_t slices = 0;        //!< liver slices (non-empty) in them
    std::size_t transitions = 0;   //!< ordered pairs of consecutive liver slices (both directions)
    std::vector<ShapeStep> steps;  //!< phase-major (all radii of the first phase, then the next),
                                   //!< radius and phase increasing
    double margin = 1.25;          //!< allowed = margin * rate * dz + allowance
    double allowance_px = 1.5;     //!< discretisation allowance [pixels of the checked slice]
    double volume_ml_min = 0.0, volume_ml_max = 0.0;         //!< liver volumes seen [mL]
    double extent_mm_min = 0.0, extent_mm_max = 0.0;         //!< z extents (first..last slice) [mm]
    double max_area_mm2_min = 0.0, max_area_mm2_max = 0.0;   //!< largest slice area per volume [mm^2]
    IntensityStats intensity;
};

//! Inputs of `train_shape_memory`.
struct ShapeTrainParams {
    //! Bin edges of the previous slice's equivalent radius [mm]; the last bin is open-ended.
    std::vector<double> radius_edges_mm{0, 10, 20, 30, 40, 50, 60, 70, 80, 100};
    //! Bin edges of the phase rho = previous area / largest area so far; the last is open-ended.
    std::vector<double> rho_edges{0, 0.5, 0.8, 0.95};
    double quantile = 1.0;         //!< of the per-bin rates; 1 = the maximum (few volumes: a high
                                   //!< quantile is the maximum anyway)
    double envelope_quantile = 0.9; //!< of the per-bin envelope rates (a leak-cutting envelope,
                                    //!< not a verdict: a few true pixels outside are acceptable)
    double margin = 1.25;          //!< copied to ShapeMemory::margin
    double allowance_px = 1.5;     //!< copied to ShapeMemory::allowance_px
    std::string modality = "CT";   //!< recorded with the intensity statistics
    int intensity_erosion_px = 1;  //!< in-plane erosion of the mask before the intensity statistics
                                   //!< (keeps partial-volume boundary voxels out); 0 = none
};

//! Learns the shape memory from images and their 0/1 liver masks (non-zero = liver), pairwise
//! on the same grid. Masks with one liver slice contribute no transitions. Transitions are
//! between axial slices whatever the stored orientation (a coronal stack is read on its axial
//! grid, core::patient_axis_order).
//! \throw InvalidInputError for no volumes, different list sizes, a null pointer, a mask not on
//! its image's grid, an empty mask (naming its index), or no transition at all.
ShapeMemory train_shape_memory(const std::vector<const core::ImageF*>& images,
                               const std::vector<const core::LabelImage3D*>& liver_masks,
                               const ShapeTrainParams& params = {});

//! The verdict on a candidate slice, with what was measured and what was allowed.
struct ShapeCheck {
    bool plausible = false;
    double score = 0.0;        //!< max over the criteria of measured / allowed; <= 1 plausible
    std::string reason;        //!< empty when plausible, else the worst criterion in words
    int bin = 0;               //!< index of the ShapeStep used
    double rho = 1.0;          //!< phase used: area_previous / largest area so far
    // measured
    double area_previous_mm2 = 0.0, area_mm2 = 0.0;
    double log_area_ratio = 0.0;   //!< ln(area / area_previous); -inf for an empty candidate
    double outward_mm = 0.0;       //!< farthest candidate pixel from the previous mask
    double inward_mm = 0.0;        //!< farthest previous pixel from the candidate
    double centroid_shift_mm = 0.0;
    double dice = 0.0;             //!< of the two slices
    // allowed at this dz
    double allowed_outward_mm = 0.0, allowed_inward_mm = 0.0;
    double allowed_growth = 0.0, allowed_shrink = 0.0; //!< bounds on +/- log_area_ratio
    double allowed_centroid_shift_mm = 0.0;
};

//! Checks candidate slice k+1 against the accepted slice k (both one-slice masks on the same
//! 2-D grid, size[2] == 1, non-zero = liver) `dz_mm` apart. `largest_area_mm2` is the largest
//! slice area accepted so far in this propagation direction (0 = unknown: rho = 1, the most
//! permissive phase). An empty candidate is implausible
//! (reason "empty"). \throw InvalidInputError if the grids differ, a mask is not one slice, the
//! previous mask is empty, dz_mm is not positive, or the memory has no steps.
ShapeCheck check_slice(const ShapeMemory& memory, const core::LabelImage3D& previous,
                       const core::LabelImage3D& candidate, double dz_mm, double largest_area_mm2 = 0.0);

//! Where slice k+1 may lie: the previous mask dilated by margin * envelope_per_mm * dz +
//! allowance (exact Euclidean distance in mm). Built from the 95th percentile of the boundary
//! motion rather than its maximum, so it holds >= 99 % of a true next slice while cutting most
//! of a leak. A driver clips a leaking candidate to it. Same checks.
core::LabelImage3D plausible_envelope(const ShapeMemory& memory, const core::LabelImage3D& previous, double dz_mm,
                                      double largest_area_mm2 = 0.0);

//! What slice k+1 should contain: the previous mask eroded by the allowed inward motion at
//! dz_mm (may be empty near the liver's ends). A driver can fall back to it after a collapse.
core::LabelImage3D plausible_core(const ShapeMemory& memory, const core::LabelImage3D& previous, double dz_mm,
                                  double largest_area_mm2 = 0.0);

} // namespace lobe::seg
