#pragma once
//! \file
//! \brief MR intensity inhomogeneity (bias field) correction by K-means classes and a smooth
//! multiplicative field (thesis §5.3.4 handles shading with "multi-layer K-means with an adaptive
//! contrast parameter", spec §5.1 step 6; this is that idea with the field made explicit). The
//! image is modelled as v(x) = b(x) · t(x), t piecewise constant per tissue class, b a smooth
//! positive field with log b a low-degree polynomial in millimetres. Alternating: classify
//! log v − log b by 1-D K-means (`kmeans_layers`), fit log b to log v − (class mean) by robust
//! least squares, until the field stops changing. See docs/algorithms/bias_field.md.

#include "lobe/core/image3d.h"

#include <cstddef>

namespace lobe::seg {

//! Inputs of `correct_bias_field`. The defaults are the ones docs/algorithms/bias_field.md
//! justifies.
struct BiasFieldParams {
    int degree = 2;               //!< total degree of the polynomial log b (0..4); 2: a field
                                  //!< that bends once across the body, as a coil's falloff does
    int classes = 4;              //!< K tissue classes of the log intensity (T1 body: fluid,
                                  //!< muscle, liver and spleen, fat)
    double tissue_fraction = 0.1; //!< tissue: voxels above this fraction of the 99th percentile
                                  //!< (air and noise below carry no field)
    int max_iterations = 50;      //!< alternations of classify and fit
    double tolerance = 1e-3;      //!< converged when log b changes by less than this anywhere
                                  //!< on the tissue (0.1 % of the intensity)
    double outlier_sigmas = 2.5;  //!< residuals beyond this many robust sd (partial volume,
                                  //!< vessels, a class the model lacks) are left out of the fit
    std::size_t max_samples = 200000; //!< the fit uses at most this many tissue voxels (a regular
                                  //!< subsample); the field is evaluated on every voxel
};

//! What `correct_bias_field` returns.
struct BiasFieldResult {
    core::ImageF corrected;       //!< v / b (voxels outside the tissue are divided too)
    core::ImageF field;           //!< b, with geometric mean 1 over the tissue samples, so the
                                  //!< corrected image keeps the input's scale
    int iterations = 0;
    bool converged = false;       //!< false: max_iterations reached (the last field is returned)
    std::size_t samples = 0;      //!< tissue voxels in the fit
    double min_gain = 1.0;        //!< the range of b over the tissue samples
    double max_gain = 1.0;
};

//! Estimates and divides out a smooth multiplicative field. A volume with too few tissue voxels
//! for the polynomial (fewer than 20 per term) is returned unchanged with b = 1 and converged =
//! false (nothing to fit is no error: the caller decides).
//! \throw core::InvalidInputError on an empty grid, non-finite values, or parameters out of range.
BiasFieldResult correct_bias_field(const core::ImageF& image, const BiasFieldParams& params = {});

} // namespace lobe::seg
