#pragma once
//! \file
//! \brief Edge maps and stopping functions for active contours: intensity windowing, Gaussian
//! smoothing, gradients, the normalised edge map f for GVF/DSG, the stopping function g, the
//! binary edge map for the chessboard distance, and energy-competition re-weighting.
//! 2-D images (size[2] == 1) are handled in-plane; 3-D images in 3-D.

#include "lobe/core/image3d.h"
#include "lobe/seg/vector_field.h"

namespace lobe::seg {

//! Maps intensities (e.g. HU) through a window to [0, 1]: values below level - width/2 give 0,
//! above level + width/2 give 1. Default: the thesis's abdominal window W400 / L70 (spec §9.1).
struct IntensityWindow {
    double level = 70.0;  //!< window centre [HU]
    double width = 400.0; //!< window width [HU]
};
core::ImageF apply_window(const core::ImageF& image, const IntensityWindow& window = {});

//! Gaussian smoothing with standard deviation `sigma_mm` [mm] per axis (spacing-aware); only
//! in-plane for a 2-D image. sigma_mm <= 0 returns a copy.
core::ImageF gaussian_smooth(const core::ImageF& image, double sigma_mm);

//! Central-difference gradient in physical units (per mm) along the index axes; one-sided at
//! the borders. The k component is zero for a 2-D image.
VectorField gradient(const core::ImageF& image);

//! |v| per voxel.
core::ImageF magnitude(const VectorField& v);

//! Inputs of `edge_map`.
struct EdgeMapParams {
    IntensityWindow window;  //!< applied first (set width <= 0 to skip: image already in [0,1])
    double sigma_mm = 1.0;   //!< pre-smoothing σ [mm] (spec §9.1: about 1 px)
    double stopping_k = 0.05; //!< g = 1 / (1 + (|∇I_σ| / k)^2), |∇I_σ| in window units per mm
};

//! What `edge_map` returns: the images every snake needs, on the input grid.
struct EdgeMapResult {
    core::ImageF intensity;          //!< windowed, smoothed image in [0, 1]
    core::ImageF gradient_magnitude; //!< |∇I_σ| [1/mm]
    core::ImageF edge;               //!< f = gradient magnitude normalised to [0, 1] (the GVF edge map)
    core::ImageF stopping;           //!< g in (0, 1], ~0 on edges, 1 in flat regions
    double scale = 1.0;              //!< the robust maximum (99.9th percentile of the non-zero
                                     //!< |∇I_σ|) that normalises f; f is clamped to [0, 1]
};
EdgeMapResult edge_map(const core::ImageF& image, const EdgeMapParams& params = {});

//! Hysteresis thresholds on the normalised edge map f: voxels with f >= high are edges, and
//! voxels with f >= low connected (26-neighbourhood in 3-D, 8 in 2-D) to them.
struct BinaryEdgeParams {
    double low = 0.05;
    double high = 0.15;
};
//! The binary edge map that seeds the chessboard distance (1 = edge).
core::LabelImage3D binary_edges(const core::ImageF& edge, const BinaryEdgeParams& params = {});

//! Hysteresis thresholds raised above the noise: f's median over the image is the gradient of
//! noise in flat regions (most of an image is flat), and Canny's rule of thumb puts the
//! thresholds a few noise levels up: low = max(base.low, factor * median), high =
//! max(base.high, 2 * factor * median, low). Without noise the configured thresholds stand.
BinaryEdgeParams noise_adapted(const core::ImageF& edge, const BinaryEdgeParams& base, double noise_factor);

//! Energy-competition weight G when competition is on (thesis L3273-3295; 0.2 is too low).
inline constexpr float kCompetitionOn = 0.3f;

//! Energy competition: f' = f inside the area of interest (`aoi` non-zero), G * f outside it.
//! G = 1 leaves f unchanged. \throw InvalidInputError if the grids differ.
core::ImageF energy_competition(const core::ImageF& edge, const core::LabelImage3D& aoi, float weight);

} // namespace lobe::seg
