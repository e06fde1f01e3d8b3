#pragma once
//! \file
//! \brief The outside peer of the bias-field benchmark: ITK 5.2's N4 (Tustison et al. 2010,
//! `itk::N4BiasFieldCorrectionImageFilter`). This header is ITK-free so that bias_bench.cpp
//! never sees ITK; only n4_peer.cpp includes ITK. ITK is used in bench/ only, never by a lobe
//! library.

#include "lobe/core/image3d.h"

#include <string>
#include <vector>

namespace lobe::bench {

//! itk::MultiThreaderBase::SetGlobalDefaultNumberOfThreads(n) (and the global maximum), so
//! that every filter created afterwards uses n threads.
void n4_set_threads(int n);

//! A typical N4 setup (the one ITK's N4 example and most pipelines use), with the tissue mask
//! made by lobe's rule so that both methods see the same voxels.
struct N4Params {
    double tissue_fraction = 0.1; //!< mask: voxels above this fraction of the 99th percentile
                                  //!< (libseg's BiasFieldParams::tissue_fraction)
    int shrink = 2;               //!< ShrinkImageFilter factor on every axis before fitting
    std::vector<unsigned> iterations{50, 50, 50, 50}; //!< per fitting level (4 levels)
    double convergence = 0.001;   //!< N4's convergence threshold
    // Everything else at N4's defaults: spline order 3, 4 control points per axis, 200
    // histogram bins, FWHM 0.15, Wiener noise 0.01.
};

//! One N4 run. `field` is b on the full grid (exp of the B-spline log field evaluated there),
//! `corrected` = image / b; the field's scale is N4's own (only its shape is meaningful).
struct N4Run {
    core::ImageF corrected;
    core::ImageF field;
    double seconds = 0.0;         //!< wall time of the whole call (mask, shrink, N4, full-grid field)
    double fit_seconds = 0.0;     //!< N4's Update() alone
    std::vector<int> level_iterations; //!< iterations N4 ran at each fitting level
    double last_convergence = 0.0; //!< N4's convergence measure at its last iteration
    std::size_t mask_voxels = 0;  //!< tissue voxels on the full grid
    std::string notes;
};

//! Runs N4 on `image` (3-D). \throw std::runtime_error when ITK fails.
N4Run n4_correct(const core::ImageF& image, const N4Params& params = {});

} // namespace lobe::bench
