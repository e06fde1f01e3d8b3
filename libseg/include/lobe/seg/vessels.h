#pragma once
//! \file
//! \brief Hepatic vessel segmentation inside a liver mask (seed thesis §5.3, spec §5.3): vessel
//! enhancement (multi-scale vesselness and directional sharpening along the vessel axis),
//! automatic seeds, Udupa-Samarasekera fuzzy connectedness that bridges gaps in contrast, 3-D
//! thinning into a centre-line graph with radii, branch points and branch levels, pruning of spurs
//! and noise, separation of the portal and hepatic venous trees, and the trunk names the thesis
//! uses (PV, RPV, LPV, RHV, MHV, LHV). Also the evaluation of a centre-line graph against a
//! reference graph (recall by branch level). docs/algorithms/vessels.md explains every choice.

#include "lobe/core/centreline_graph.h"
#include "lobe/core/image3d.h"
#include "lobe/seg/fuzzy_connectedness.h"
#include "lobe/seg/skeleton.h"
#include "lobe/seg/vesselness.h"

#include <cstddef>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace lobe::seg {

//! Tissue labels of the vessel trees (docs/file-format.md).
inline constexpr std::uint8_t kPortalVeinLabel = 2;
inline constexpr std::uint8_t kHepaticVeinLabel = 3;

//! Inputs of `segment_vessels`. `{}` is the documented default for contrast-enhanced CT in HU;
//! the `use_*` switches turn one stage off each for the ablation benchmark (bench/vessels).
struct VesselParams {
    double smoothing_mm = 0.7;      //!< Gaussian σ of the intensity the method reads [mm] (noise)
    double parenchyma_erosion_mm = 3.0; //!< parenchyma statistics and seeds come from the liver
                                    //!< shrunk by this (boundary partial volume stays out)

    bool use_vesselness = true;     //!< vesselness lifts thin tubes (feature = I + boost·V·C) and
                                    //!< gates the seeds; off: intensity alone
    VesselnessParams vesselness;
    double vesselness_boost = 0.5;  //!< the feature adds boost·V·C (C: vessel contrast) to the
                                    //!< intensity, so a thin tube dimmed by partial volume still
                                    //!< crosses the half-contrast level
    bool use_directional_sharpening = true; //!< average along the vessel axis, sharpen V
    DirectionalSharpeningParams sharpening;

    // Seeds.
    double seed_sigmas = 3.0;       //!< seed voxels are brighter than the parenchyma by this many σ
                                    //!< (of the smoothed parenchyma: 3.8 HU on the phantom, 13.6 on
                                    //!< the shared portal-venous scan, whose vessels lie 40 HU
                                    //!< above the liver and got no seed at 4 σ)
    double min_contrast = 20.0;     //!< ... and by at least this [image units, HU]: below it the
                                    //!< vessels are not visible and nothing is reported
    double seed_min_vesselness = 0.2; //!< ... and have at least this (sharpened) vesselness
    double seed_min_volume_ml = 0.05; //!< seed components smaller than this are noise [mL]

    // Fuzzy connectedness.
    bool use_fuzzy_connectedness = true; //!< off: plain region growing from the seeds over voxels
                                    //!< above the object level (no bridging)
    double link_threshold = 0.25;   //!< θ: voxels whose strength of connectedness to the seeds is
                                    //!< below this are not vessel; a gap whose affinity stays
                                    //!< above θ is bridged
    double object_level = 0.5;      //!< the vessel boundary: where the feature crosses this fraction
                                    //!< of the contrast above parenchyma (half maximum, the
                                    //!< partial-volume boundary of a blurred edge)
    double gradient_width_mm = 1.0; //!< h2's σ is C / this [image units per mm]: a step of the
                                    //!< full contrast over this width halves the affinity (about)
    int connectivity = 6;           //!< adjacency of the fuzzy connectedness (6 or 26)
    bool lookup_table = true;       //!< the lookup-table affinity (same result, ~2x faster)

    // Skeleton, graph and trees.
    bool use_pruning = true;        //!< off: spurs, junction clusters and small parts stay
    CentrelineParams centreline;
    bool bridge_gaps = true;        //!< join a tree part whose thick end lies inside the liver to
                                    //!< the nearest other tree (the thesis's "break point
                                    //!< connections"), and paint the bridge into the mask
    double max_gap_mm = 12.0;       //!< ... if the gap is at most this long
    //! A tree leaves the liver where its centre line comes within its radius + this of the liver
    //! surface (thinning stops about one radius short of a cut end) [mm]
    double root_surface_mm = 2.0;
    //! ... and only where it is at least this fraction of the thickest vessel found as thick: a
    //! tree's root is a trunk; a part that reaches the surface only with thin branches is a
    //! fragment cut off by a gap.
    double root_radius_fraction = 0.5;
    //! Two thick roots farther apart than this in one connected part are two trees that touch
    //! (the part is cut at the dimmest point of the path between them) [mm].
    double root_separation_mm = 30.0;
    double min_tree_length_mm = 15.0; //!< trees with less centre line are dropped [mm]
    //! A branch point counts for the branch level only if at least two of its children carry this
    //! much centre line each (with their subtrees), or none does: a short side twig on a trunk
    //! (noise the pruning kept) does not deepen the trunk's level [mm].
    double min_branch_mm = 10.0;
    //! Portal and hepatic trees are told apart by their intensity (portal brighter in the portal
    //! phase) when the two groups' mean intensities differ by at least this [image units];
    //! otherwise by anatomy (docs/algorithms/vessels.md).
    double tree_separation = 6.0;

    bool keep_images = false;       //!< also return the enhanced images (for inspection)
};

//! One vessel tree found.
struct VesselTreeReport {
    int label = 0;                  //!< kPortalVeinLabel or kHepaticVeinLabel
    std::string name;               //!< trunk name ("PV", "RHV", ...), empty if unknown
    int root_node = -1;             //!< node of the result's graph
    double volume_ml = 0;           //!< voxels of the mask assigned to this tree
    double centreline_mm = 0;       //!< total edge length
    double mean_intensity = 0;      //!< along the thick part of the centre line
    int edges = 0;
    int max_level = 0;
};

//! What `segment_vessels` returns.
struct VesselResult {
    core::LabelImage3D labels;      //!< 0, kPortalVeinLabel, kHepaticVeinLabel on the input grid
    core::CentrelineGraph graph;    //!< levels, labels and trunk names set
    bool found = false;             //!< false: no vessel contrast (labels all 0, graph empty)
    std::string message;            //!< one line: what was found, or why nothing was
    double parenchyma = 0;          //!< median parenchyma intensity (smoothed)
    double parenchyma_sigma = 0;    //!< its robust σ
    double vessel_intensity = 0;    //!< estimated from the seeds
    double contrast = 0;            //!< vessel_intensity - parenchyma
    std::size_t seed_voxels = 0;
    int seed_components = 0;
    bool separated_by_contrast = false; //!< portal/hepatic decided by intensity (else anatomy)
    int bridges = 0;                //!< gaps bridged in the graph
    int trees_cut = 0;              //!< touching trees separated
    double portal_ml = 0, hepatic_ml = 0;
    std::vector<VesselTreeReport> trees;
    CentrelineStats centreline;
    std::vector<std::pair<std::string, double>> timings; //!< seconds per stage

    // With keep_images (else empty), on the input grid, 0 outside the liver's box:
    core::ImageF vesselness;        //!< the (sharpened) vesselness in [0, 1]
    core::ImageF feature;           //!< the feature fuzzy connectedness reads (image units)
    core::ImageF connectedness;     //!< strength of connectedness to the seeds in [0, 1]
    core::LabelImage3D seeds;       //!< 1 = seed voxel
};

//! Called with a one-line progress message.
using VesselProgress = std::function<void(const std::string&)>;

//! Segments the hepatic vessels of `image` (CT in HU) inside `liver` (non-zero = liver, including
//! its vessels, as the SLIVER07 reference and `segment_liver` give it). No clicks. Runs on the
//! volume reordered onto the patient frame (core::patient_axis_order), so every storage of the
//! same scan (reversed axes, a coronal stack) gives the same trees; the images are on `image`'s grid.
//! \throw InvalidInputError on grids that differ, an empty liver, non-finite values in the liver's
//! box, or invalid parameters.
VesselResult segment_vessels(const core::ImageF& image, const core::LabelImage3D& liver, const VesselParams& params = {},
                             const VesselProgress& progress = {});

//! Recall of one branch level (or all, level 0) of a reference centre-line graph.
struct LevelRecall {
    int level = 0;
    int label = 0;                  //!< 0 = both trees
    std::size_t samples = 0;        //!< reference samples (every 1 mm, inside the region)
    std::size_t found = 0;          //!< of them, within tolerance of the segmented centre lines
    std::size_t labelled_right = 0; //!< of those, whose nearest segmented edge has the same label
    double recall() const { return samples ? double(found) / double(samples) : 0.0; }
};

//! What `evaluate_centrelines` returns.
struct CentrelineEvaluation {
    std::vector<LevelRecall> by_level;       //!< both trees, per reference level (ascending)
    std::vector<LevelRecall> by_tree_level;  //!< per label and level
    LevelRecall overall;                     //!< every reference sample
    double precision = 0;  //!< fraction of segmented centre line within tolerance of the reference
    double level_agreement = 0; //!< of the found samples, how many have the same level in both
};

//! Inputs of `evaluate_centrelines`.
struct CentrelineMatchParams {
    double sample_mm = 1.0;       //!< reference and segmented lines are sampled this densely
    double min_tolerance_mm = 2.0; //!< a reference sample is found if a segmented centre line passes
                                  //!< within max(its radius, this) of it
};

//! Compares a segmented centre-line graph with a reference (e.g. lphantom's truth). Only
//! reference samples whose voxel is non-zero in `region` count (null: all), so that the parts of
//! a trunk outside the liver do not; segmented samples count for precision wherever they are.
CentrelineEvaluation evaluate_centrelines(const core::CentrelineGraph& segmented, const core::CentrelineGraph& reference,
                                          const core::LabelImage3D* region = nullptr,
                                          const CentrelineMatchParams& params = {});

} // namespace lobe::seg
