#pragma once
//! \file
//! \brief Liver tumour segmentation (seed thesis §5.2, spec §5.2): multi-layer K-means inside the
//! liver finds the hypodense tumour layer, whose components (multiple, lobular, satellite tumours,
//! and tumours touching the liver surface) initialise the CDSG active contour, one box per tumour.
//! A semi-automatic mode takes one seed point per tumour instead. See docs/algorithms/tumours.md.

#include "lobe/core/image3d.h"
#include "lobe/core/types.h"
#include "lobe/seg/kmeans.h"
#include "lobe/seg/snake.h"

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace lobe::seg {

//! Tissue label of tumours (docs/file-format.md).
inline constexpr std::uint8_t kTumourLabel = 4;

//! Inputs of `segment_tumours`. `{}` is the documented default for contrast-enhanced CT in HU.
struct TumourParams {
    double smoothing_mm = 1.5;        //!< σ of the smoothing inside the liver (normalised convolution,
                                      //!< so nothing outside the liver is averaged in) [mm]
    double vessel_margin_mm = 1.0;    //!< the vessels (when given) grown by this are left out [mm]
    double surface_rim_mm = 1.0;      //!< the liver's outer voxel layer and what lies within this of
                                      //!< its outside are left out (partial volume with what is
                                      //!< outside), and given back to a tumour that reaches them [mm]
    KMeansParams kmeans = [] {
        KMeansParams k;
        k.clusters = 4;               //!< tumour, parenchyma (maybe split in two), vessels
        return k;
    }();
    //! A K-means layer is a tumour layer if its centre lies below the parenchyma's (the most
    //! populous layer) by at least max(min_contrast, contrast_sigmas × the parenchyma's σ).
    double min_contrast = 8.0;        //!< [image units, HU]
    double contrast_sigmas = 4.0;
    //! ... and a component whose median lies more than this below the parenchyma is not tumour
    //! but fluid, bile or fat: a simple cyst (0-20 HU), or a neighbour a leaky liver mask took in
    //! (the gallbladder) [image units, HU]
    double max_contrast = 70.0;
    double min_volume_ml = 0.1;       //!< smaller components are noise [mL]
    double min_thickness_mm = 2.0;    //!< components thinner than twice this (the largest distance
                                      //!< from inside to their border) are partial-volume sheets
                                      //!< along the liver surface or a fissure [mm]
    //! Refine each component with the CDSG snake started from it (shrunk by init_erosion_mm).
    //! Off by default: on the phantom the K-means component already lies on the half-contrast edge;
    //! the snake shrinks small tumours (satellite Dice 0.92 -> 0.76) and leaks out of the lobular
    //! one on coarse or noisy grids (0.96 -> 0.72); docs/algorithms/tumours.md has the table.
    bool use_cdsg = false;
    SnakeParams snake;                //!< the snake; its window is set from the layers (see .md)
    double box_margin_mm = 8.0;       //!< the snake runs in the component's box grown by this [mm]
    double init_erosion_mm = 1.0;     //!< the component shrinks by this before it starts the snake
                                      //!< (snakes expand) [mm]
    double max_growth_mm = 4.0;       //!< the snake's result is kept within this of the component
                                      //!< (a leak through a weak edge is cut there) [mm]
    double seed_radius_mm = 3.0;      //!< semi-automatic: the tumour's grey level is measured in a
                                      //!< ball of this radius around each seed [mm]
    double max_seed_extent_mm = 80.0; //!< ... and its region may not reach farther from the seed [mm]
};

//! One tumour found.
struct TumourReport {
    core::Vec3 centroid;              //!< [mm]
    double volume_ml = 0;
    double mean_intensity = 0;        //!< in the (unsmoothed) image
    double contrast = 0;              //!< mean_intensity - parenchyma
    bool touches_surface = false;     //!< reaches the liver's surface
    bool from_seed = false;           //!< semi-automatic
    int snake_iterations = 0;
    bool snake_converged = false;
};

//! What `segment_tumours` returns.
struct TumourResult {
    core::LabelImage3D mask;          //!< kTumourLabel in tumours, 0 elsewhere, on the input grid
    std::vector<TumourReport> tumours; //!< largest first
    bool found = false;
    std::string message;              //!< one line: what was found, or why nothing was
    double parenchyma = 0;            //!< centre of the parenchyma layer (smoothed)
    double parenchyma_sigma = 0;
    double threshold = 0;             //!< voxels below this (smoothed) formed the tumour layer
    std::vector<double> layer_centres; //!< the K-means centres
    std::vector<std::pair<std::string, double>> timings; //!< seconds per stage
};

//! Called with a one-line progress message.
using TumourProgress = std::function<void(const std::string&)>;

//! Segments the tumours of `image` (CT in HU) inside `liver` (non-zero = liver including its
//! tumours and vessels). `vessels` (may be null; non-zero = vessel) is left out of the clustering.
//! With `seeds` (physical points [mm], each inside a tumour) only the seeded tumours are returned
//! (semi-automatic); without, every tumour layer component is (automatic).
//! \throw InvalidInputError on grids that differ, an empty liver, non-finite values in the liver,
//! a seed outside the liver, or invalid parameters.
TumourResult segment_tumours(const core::ImageF& image, const core::LabelImage3D& liver,
                             const core::LabelImage3D* vessels = nullptr, const TumourParams& params = {},
                             const std::vector<core::Vec3>& seeds = {}, const TumourProgress& progress = {});

} // namespace lobe::seg
