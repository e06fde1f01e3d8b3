#pragma once
//! \file
//! \brief The outside peer of the active-contour benchmark: ITK 5.2 (Debian's
//! libinsighttoolkit5-dev). This header is ITK-free so that seg_bench.cpp never sees ITK;
//! only itk_peer.cpp includes ITK. ITK is used in bench/ only, never by a lobe library.
//!
//! Every function takes lobe images (2-D when size[2] == 1, then run with itk::Image<., 2>;
//! otherwise 3-D) and returns lobe images on the same grid.

#include "lobe/core/image3d.h"

#include <cstddef>
#include <string>

namespace lobe::bench {

//! itk::MultiThreaderBase::SetGlobalDefaultNumberOfThreads(n) (and the global maximum), so
//! that every filter created afterwards uses n threads.
void itk_set_threads(int n);

//! Voxels of `mask` whose Euclidean distance [mm] to the nearest voxel outside the mask is
//! greater than `distance_mm` (in-plane for a 2-D image). Uses ITK's SignedMaurerDistanceMap
//! (exact EDT, anisotropic spacing). Setup only: never timed.
core::LabelImage3D erode_by_distance(const core::LabelImage3D& mask, double distance_mm);

//! One ITK segmentation run, with the same fields the CSV has.
struct ItkRun {
    core::LabelImage3D mask;     //!< 1 where the final level set is < 0
    double field_seconds = 0.0;  //!< smoothing, gradient, speed (and GVF) images
    double evolve_seconds = 0.0; //!< signed-distance initial level set + level-set filter
    double total_seconds = 0.0;  //!< wall time of the whole call
    int iterations = 0;          //!< level-set iterations (GVF iterations for a field-only run)
    bool converged = false;      //!< the level-set filter stopped on its RMS criterion before the cap
    std::string notes;           //!< parameters actually used (sigmoid alpha/beta, ...)
};

//! The geodesic active contour pipeline of ITK's GeodesicActiveContourImageFilter example, on
//! the intensity-windowed image:
//!   clamp to the window → CurvatureAnisotropicDiffusion → GradientMagnitudeRecursiveGaussian
//!   → Sigmoid (alpha, beta from gradient statistics) → GeodesicActiveContourLevelSetImageFilter
//! starting from the signed distance of `init` (SignedMaurerDistanceMap, zero level half a
//! voxel outside the mask's border voxels) instead of fast marching, so that the start is the
//! same as lobe's snakes get.
struct ItkGacParams {
    double window_level = 70.0;   //!< same window as libseg's EdgeMapParams (W400 / L70)
    double window_width = 400.0;
    int diffusion_iterations = 5; //!< the ITK example's values
    double diffusion_conductance = 9.0;
    double diffusion_time_step = 0.125; //!< reduced to ITK's stability bounds when larger: min spacing / 2^(dim+1), 0.5 / 2^dim
    double sigma_mm = 1.0;        //!< GradientMagnitudeRecursiveGaussian sigma (libseg's edge sigma too)
    //! Sigmoid statistics as in the ITK Software Guide: K1 ≈ gradient magnitude on the edges the
    //! contour must stop at, K2 ≈ gradient magnitude inside the object; alpha = (K2 - K1) / 6,
    //! beta = (K1 + K2) / 2. Estimated without the reference: K2 = mean inside `init`, K1 = the
    //! `k1_percentile` of the gradient magnitude in the shell 0 < d <= shell_mm outside `init`.
    //! 0.6 and propagation 1 were chosen on the benchmark's own 2-D inputs (bench/seg/README.md):
    //! the example's propagation 2 with a 90th percentile leaked (Dice 0.63 on phantom k59).
    double k1_percentile = 0.60;
    double shell_mm = 20.0;
    //! The mask whose inside and shell give K2 and K1 (null: `init`). A seeded start's ball
    //! lies deep inside the liver, so its shell holds no edge: the seeded rows pass the eroded
    //! reference here, i.e. the sigmoid of the unseeded run on the same slice.
    const core::LabelImage3D* statistics_mask = nullptr;
    double propagation_scaling = 1.0; //!< the ITK example uses 2 (see k1_percentile)
    double curvature_scaling = 1.0;   //!< the ITK example's values
    double advection_scaling = 1.0;
    //! The example's 0.02 stops a 3-D front after 31 iterations while it still moves (phantom
    //! volume: Dice 0.72, barely past the initial mask); 0.005 lets it reach the edges.
    double max_rms_error = 0.005;
    int iterations = 800;
};
ItkRun itk_gac(const core::ImageF& image, const core::LabelImage3D& init, const ItkGacParams& params = {});

//! ITK's GradientVectorFlowImageFilter (Xu & Prince GVF, μ = noise level) on the gradient of the
//! edge map f = |∇(G_σ * I_windowed)| / max, in index units (the Laplacian ignores spacing,
//! as the filter assumes), for `iterations` iterations. With `snake`, the normalised field then
//! drives ITK's level-set solver (GeodesicActiveContourLevelSetImageFilter with the advection
//! image replaced by the GVF field, no propagation, curvature weighted by the sigmoid speed
//! of itk_gac); otherwise only the field is computed and timed (mask left empty).
struct ItkGvfParams {
    double window_level = 70.0;
    double window_width = 400.0;
    double sigma_mm = 1.0;
    double mu = 0.2;              //!< GVF regularisation (Xu & Prince default; libseg's too)
    int iterations = 171;         //!< set to the iteration count of libseg's GGVF baseline
    bool snake = true;
    double curvature_scaling = 0.2;
    double advection_scaling = 1.0;
    double max_rms_error = 0.005;
    int snake_iterations = 800;
    ItkGacParams speed;           //!< how the curvature speed (sigmoid) is made
};
ItkRun itk_gvf(const core::ImageF& image, const core::LabelImage3D& init, const ItkGvfParams& params = {});

//! Independent cross-check of the libseg metrics: Dice and the average symmetric surface
//! distance with 8-neighbour (2-D) / 26-neighbour (3-D) borders, exact EDT (ITK Maurer).
struct CrossCheck {
    double dice = 0.0;
    double asd_mm = 0.0;
    std::size_t border_seg = 0;
    std::size_t border_ref = 0;
};
CrossCheck cross_check(const core::LabelImage3D& seg, const core::LabelImage3D& ref);

} // namespace lobe::bench
