#pragma once
//! \file
//! \brief Active-contour segmentation under one API: the CDSG snake (thesis §4.10, eq. 4.29) and
//! its two baselines, the GGVF geometric snake (eq. 4.14 with |∇φ|) and the geodesic active
//! contour (Caselles et al. 1997, eq. 4.11) without GVF. The snake starts inside the object
//! (thesis L3170) and expands. Works on a 2-D slice (size[2] == 1) or a 3-D volume.

#include "lobe/core/image3d.h"
#include "lobe/seg/dsg.h"
#include "lobe/seg/edge_map.h"
#include "lobe/seg/gvf.h"
#include "lobe/seg/level_set.h"

namespace lobe::seg {

enum class SnakeMethod {
    Cdsg, //!< chessboard-distance pressure outside δ1 + band-limited DSG/GGVF inside δ1
    Ggvf, //!< GGVF over the whole image, normalised, advecting the contour (+ curvature)
    Gac,  //!< geodesic active contour: g (κ + v0) |∇φ| + ∇g·∇φ
};

//! Energy competition (thesis §4.6) needs a template (normally the previous slice's contour).
enum class CompetitionMode {
    Off,  //!< G = 1 always
    On,   //!< G = 0.3 from the start
    Auto, //!< the thesis's rule: run with G = 1; if the result leaves the AOI, repeat once with G = 0.3
};

//! How the chessboard distance drives the CDSG contour outside δ1 (spec §4.11, both readings).
enum class PressureMode {
    Scalar, //!< a normal speed: constant outward pressure outside δ1, handed over to the field inside
    Vector, //!< -∇D_Ch joined to the DSG field into one advection field
};

struct CdsgParams {
    int edge_band = 1;              //!< δ1: voxels within this chessboard distance of an edge get the DSG/GGVF field
    BinaryEdgeParams edges;         //!< binary edge map feeding the chessboard distance
    PressureMode pressure_mode = PressureMode::Scalar;
    double pressure = 1.0;          //!< pressure speed outside δ1 [mm per unit time]
    double pressure_stopping_k = 0.005; //!< the pressure is scaled by g_k = 1/(1+(|∇I|/k)^2) so that
                                    //!< edges missing from the binary map still slow it; 0 = constant
                                    //!< pressure (the thesis's reading)
    double pressure_stopping_power = 2.0; //!< the exponent of |∇I|/k in that stopping function
    bool directional_sharpening = true; //!< use DSG when a template is given (else plain GGVF in δ1)
    DsgParams dsg;
};

//! Inputs of `segment_snake`. Defaults are the ones docs/segmentation.md justifies.
struct SnakeParams {
    SnakeMethod method = SnakeMethod::Cdsg;
    EdgeMapParams edge;             //!< windowing, smoothing, stopping function g
    GvfParams gvf;                  //!< GGVF for the Ggvf baseline (full image) and CDSG (inside δ1, fewer iterations)
    int band_gvf_iterations = 40;   //!< GGVF iterations inside δ1 for CDSG
    CdsgParams cdsg;
    double curvature_weight = 0.05; //!< ε: curvature term weight [mm^2 per unit time] (spacing 1 mm)
    double gac_pressure = 1.0;      //!< v0 of the geodesic active contour
    double gac_stopping_k = 0.005;  //!< k of the GAC stopping function (sharper than the CDSG default)
    //! The level set, with a convergence tolerance of 2 % of the contour's voxels changing side
    //! per check (on a noisy weak edge a few voxels flicker for ever) and the leak stop on: four
    //! checks of rising growth after the front had slowed to a quarter of its peak end the run
    //! at the slowest state (docs/segmentation.md, "Leak stop").
    LevelSetParams level_set = [] {
        LevelSetParams p;
        p.convergence_tolerance = 0.02;
        p.leak_checks = 4;
        return p;
    }();
    CompetitionMode competition = CompetitionMode::Auto;
    double aoi_width_mm = 6.0;      //!< AOI: voxels within this distance of the template's boundary
    double aoi_leave_fraction = 0.05; //!< Auto: repeat when more than this fraction of the result's
                                    //!< boundary lies outside the AOI
    //! Auto: what the repeat keeps of the first run. The repeat lifts every edge in the AOI, the
    //! object's interior ones too, and stops a voxel or more inside the first run's edge all round;
    //! it is trusted only to cut the first run's leak: the result is the first run's mask within
    //! this many voxels (chessboard distance) of the repeat's. -1: the repeat's mask as it is
    //! (the thesis's rule). docs/algorithms/liver.md, "What energy competition's repeat keeps".
    int repeat_keep_voxels = 1;
};

//! What `segment_snake` returns.
struct SnakeResult {
    core::LabelImage3D mask;    //!< 1 inside the final contour
    core::ImageF phi;           //!< the final level set (after a trimmed repeat: the signed distance
                                //!< to the trimmed mask)
    int iterations = 0;         //!< level-set iterations (of the last run when competition repeated)
    int reinitialisations = 0;  //!< ... and re-initialisations of φ among them
    bool converged = false;
    bool leak_stopped = false;  //!< the leak stop ended the run: the contour is the one before the
                                //!< leak spread (converged is false; LevelSetParams::leak_checks)
    bool competition_used = false; //!< true if G = 0.3 was in force for the returned result
    int runs = 1;               //!< 1, or 2 when the Auto rule repeated the segmentation
    double field_seconds = 0.0; //!< edge map, distances and vector fields
    double evolve_seconds = 0.0; //!< level-set evolution
};

//! Segments `image` (raw intensities, e.g. HU; windowed by params.edge.window) starting from the
//! contour of `init` (non-zero = inside). `templ` (may be null) is the expected shape, normally
//! the previous slice's result: it defines the AOI for energy competition and the preferred edge
//! directions for DSG. `region` (may be null) confines the pressure: outside it the pressure is
//! zero and the front is moved only by curvature and the edge field, so it stops at the region's
//! border (the liver pipeline can pass the slice's liver-like layer). \throw InvalidInputError on
//! grid mismatch, an empty or full `init`, or non-finite image values.
SnakeResult segment_snake(const core::ImageF& image, const core::LabelImage3D& init, const SnakeParams& params = {},
                          const core::LabelImage3D* templ = nullptr, const core::LabelImage3D* region = nullptr);

//! The edge snap: a short, pressure-free run that moves a converged contour on to the ridge of
//! the edge map. CDSG's pressure is damped by a sharp stopping function a few voxels before an
//! edge and its field acts only within δ1 of the ridge, so a front settles 1-2 voxels inside the
//! ridge between the two (docs/segmentation.md, "The edge snap"). Here the band-limited GGVF
//! field acts within `band` voxels (chessboard) of the thinned binary edges; where no edge is that
//! near, only the curvature term moves the contour.
struct SnapParams {
    int band = 3;        //!< chessboard distance of the field's reach [voxels], > CdsgParams::edge_band
    int iterations = 20; //!< level-set iterations (the field moves the front about 1 voxel per 2)
    int gvf_iterations = 10; //!< GGVF iterations in the band (its field there is mostly ∇f's; 40 gain nothing)
    //! The gate: a voxel the snap adds stays only if its smoothed intensity lies at least this far
    //! (as a fraction) from the intensity two voxels outwards to the one two voxels inwards along
    //! the contour's normal; 0 = no gate. 0.5 is the half-way crossing of the edge's profile, the
    //! boundary of a blurred step: where the surroundings fall off gradually (soft tissue, then
    //! fat) the gradient's ridge lies outside it and the field alone overshoots.
    double gate_level = 0.5;
};

//! Snaps the contour of `mask` to the edges of `image` (raw intensities, windowed and smoothed
//! by params.edge; the binary edges and GGVF are CDSG's). Returns the snapped mask and φ;
//! `converged` is the run's own convergence test. 	hrow InvalidInputError on a grid mismatch,
//! an empty or full mask, non-finite values, a band or iteration count below 1, or a gate_level
//! outside [0, 1].
SnakeResult snap_to_edges(const core::ImageF& image, const core::LabelImage3D& mask, const SnakeParams& params = {},
                          const SnapParams& snap = {});

} // namespace lobe::seg
