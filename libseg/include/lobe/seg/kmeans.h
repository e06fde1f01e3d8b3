#pragma once
//! \file
//! \brief Multi-layer K-means (thesis §5.3.4, eqs 5.2 and 5.4; spec §5.1 step 6): 1-D intensity
//! clustering of a slice or volume into K region layers (fat, muscle, liver-like, vessels, bone...),
//! and the mask of one layer with an acceptance band μ ± α·σ, re-clustered inside the layer when
//! it holds two separable tissues (the "multi-layer" refinement). See docs/algorithms/kmeans.md.

#include "lobe/core/image3d.h"

#include <cstddef>
#include <vector>

namespace lobe::seg {

//! Inputs of `kmeans_layers`.
struct KMeansParams {
    int clusters = 4;          //!< K, "a small constant number" (thesis L4380); 1..64
    int max_iterations = 100;  //!< Lloyd iterations (each costs O(bins), not O(pixels)); from the
                               //!< exact solution Lloyd stops after one
    double tolerance = 1e-4;   //!< converged when no centre moves more than this [image units]
    int bins = 4096;           //!< histogram bins over [min, max] of the clustered values; a bin's
                               //!< values go to one cluster, so a centre is off by < 1 bin width
                               //!< at most (in practice far less); 16..65536
    //! Initial centres (e.g. the previous slice's `centres`, the thesis's per-slice adaptation,
    //! L4506-4514): Lloyd from them, a local optimum. Empty (default): the global optimum of J on
    //! the histogram by dynamic programming (deterministic). Otherwise its size must be `clusters`.
    std::vector<double> seeds;
};

//! What `kmeans_layers` returns. Clusters are sorted by ascending centre. A cluster that ends
//! empty is dropped, so when the values have fewer than K distinct levels (e.g. a constant
//! image) `centres.size()` is smaller than `clusters`.
struct KMeansResult {
    std::vector<double> centres;     //!< mean of each layer's values, ascending
    std::vector<double> sigmas;      //!< standard deviation of each layer's values
    std::vector<std::size_t> counts; //!< voxels per layer
    std::vector<double> thresholds;  //!< layer j (0-based) holds values in [thresholds[j-1],
                                     //!< thresholds[j]): midpoints of consecutive centres (size K-1)
    core::LabelImage3D layers;       //!< 0 outside the ROI, 1..K = layer index by ascending centre
    double objective = 0.0;          //!< J of eq 5.2: Σ_j Σ_{n∈S_j} (x_n − μ_j)^2
    int iterations = 0;
    bool converged = false;
};

//! Clusters the intensities of `image` (every voxel, or those where `roi` is non-zero) into K
//! layers minimising J (eq 5.2) on a fine histogram: exactly by 1-D dynamic programming, or by
//! Lloyd from `params.seeds`; voxels are then labelled by the midpoints of the final centres. A 3-D image is clustered as one set of voxels; for the thesis's per-slice
//! adaptation call it per axial slice, seeding each slice with the previous slice's centres.
//! \throw InvalidInputError on an invalid grid, NaN or infinite values among the clustered
//! voxels, an ROI on another grid or empty, or parameters out of range.
KMeansResult kmeans_layers(const core::ImageF& image, const KMeansParams& params = {},
                           const core::LabelImage3D* roi = nullptr);

//! Inputs of `layer_mask`.
struct LayerParams {
    //! α of eq 5.4 as the spec reads it (§9, point 13): the acceptance band of the chosen layer is
    //! μ ± α·σ. 2 keeps ~95 % of a Gaussian tissue.
    double alpha = 2.0;
    //! Multi-layer refinement: the chosen layer is split by 2-means when its two halves are
    //! separable, i.e. Ashman's D = √2 |μ1 − μ2| / √(σ1² + σ2²) exceeds this (D > 2: a clean
    //! bimodal split; a single Gaussian cut in two gives D = 2.67, hence 3), and the sub-layer
    //! nearest the target is kept. Repeated up to `max_depth`.
    double split_separation = 3.0;
    double min_split_fraction = 0.05; //!< a split is accepted only if each part holds >= this fraction
    int max_depth = 2;                //!< refinement levels (0 = no refinement)
    double min_sigma = 0.0;           //!< floor on σ [image units], e.g. the noise level, so that a
                                      //!< nearly constant layer still gets a band
};

//! What `layer_mask` returns.
struct LayerResult {
    core::LabelImage3D mask; //!< 1 where the value lies in [low, high] (and inside the ROI of `km`)
    int layer = 0;           //!< 1-based layer of `km` nearest the target
    int depth = 0;           //!< refinement levels applied (0: the K-means layer itself)
    double centre = 0.0;     //!< μ of the (sub-)layer the band is built on
    double sigma = 0.0;      //!< σ of that (sub-)layer (after `min_sigma`)
    double low = 0.0;        //!< μ − α σ
    double high = 0.0;       //!< μ + α σ
};

//! The mask of the layer whose centre is nearest `target_value` (e.g. the liver's expected grey
//! value), widened or narrowed to the acceptance band μ ± α·σ, after the multi-layer refinement.
//! `km` must come from `kmeans_layers(image, ...)` on the same grid.
//! \throw InvalidInputError on a grid mismatch, an empty `km`, a non-finite target or bad params.
LayerResult layer_mask(const core::ImageF& image, const KMeansResult& km, double target_value,
                       const LayerParams& params = {});

} // namespace lobe::seg
