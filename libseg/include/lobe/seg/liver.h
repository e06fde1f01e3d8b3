#pragma once
//! \file
//! \brief Automatic liver segmentation of a CT (or MRI) volume: the thesis's chapter 5 pipeline
//! (spec §5.1) around the CDSG snake. No clicks: the start slice and the patient's rotation come
//! from rotating template matching, a seed region from grid seeding, then CDSG segments the seed
//! slice and propagates slice by slice in both directions with the previous contour as template
//! (energy competition, directional sharpening), constrained by the K-means liver layer, the rib
//! cage ring and, when one is given, the trained shape memory; a 3-D pass smooths the stack and
//! applies the SLIVER07 convention. docs/algorithms/liver.md explains every step and choice.

#include "lobe/core/image3d.h"
#include "lobe/seg/bias_field.h"
#include "lobe/seg/dark_rim.h"
#include "lobe/seg/surface_lesions.h"
#include "lobe/seg/kmeans.h"
#include "lobe/seg/postprocess.h"
#include "lobe/seg/rib_cage.h"
#include "lobe/seg/shape_memory.h"
#include "lobe/seg/snake.h"
#include "lobe/seg/start_slice.h"

#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace lobe::seg {

//! What each slice of the propagation did (for reports, plots and the HDF5 provenance).
struct LiverSliceReport {
    int slice = -1;
    double area_mm2 = 0;        //!< area of the accepted contour
    int iterations = 0;         //!< level-set iterations of the snake
    bool converged = false;
    bool leak_stopped = false;  //!< the snake's leak stop ended it (SnakeResult::leak_stopped)
    bool competition_used = false;
    bool seed_window_widened = false; //!< the seed slice's contour reached its window's edge and
                                  //!< was segmented again on the whole slice (LiverParams::seed_window_mm)
    bool rejected = false;      //!< the shape memory rejected the snake's contour
    bool recovered = false;     //!< ... and its clip to the memory's envelope was accepted
    double shape_score = 0;     //!< the memory's score (<= 1 plausible; 0 without a memory)
    std::string shape_reason;   //!< why the memory rejected it
    double above_contact_mm2 = 0; //!< area kept out as lying above a dome contact found below
    double heart_mm2 = 0;         //!< area kept out as the heart model's (LiverParams::use_heart_model)
    double outside_fraction = 0;  //!< the contour's share outside the liver's grey levels
    bool not_liver = false;       //!< ... above LiverParams::tissue_stop_fraction: the slice is
                                  //!< dropped and the propagation in its direction ends
    double tissue_trim_mm2 = 0;   //!< area the tissue trim took out of the contour (the rest,
                                  //!< its liver-grey core, was kept: LiverParams::trim_at_tissue_stop)
    double vessel_cut_mm2 = 0;    //!< area of the pieces kept because a vessel cut them off
                                  //!< (LiverParams::keep_vessel_cut_pieces)
    double grown_pieces_mm2 = 0;  //!< area of the separate pieces dropped because they grew
                                  //!< (LiverParams::drop_growing_pieces)
    double seconds = 0;
};

//! The default per-slice snake of the liver pipeline: CDSG, energy competition Auto.
SnakeParams default_liver_snake();

//! The scanner a volume comes from: it decides how the pipeline reads its grey levels.
enum class Modality {
    Auto, //!< CT if at least `LiverParams::ct_air_fraction` of the voxels read below -500 (air
          //!< outside the body, lung, bowel gas in HU; an MR magnitude image has none), else MR
    Ct,   //!< Hounsfield units
    Mr,   //!< arbitrary units, read through `MrParams`
};

//! "CT" or "MR" ("auto" for Auto).
const char* modality_name(Modality modality);

//! How `segment_liver` reads an MR volume (docs/algorithms/liver.md, "MRI"): the seed is found
//! on the MR's own grey levels, then the whole volume is mapped by `mr_liver_contrast` and the
//! CT pipeline runs on the map, without the start slice (its heart template is a CT's) and the
//! rib cage (MR shows no bright bone).
struct MrParams {
    double body_fraction = 0.25;     //!< the seed's body: above this fraction of the volume's 99th
                                     //!< percentile (in T1 the bright fat under the skin closes it)
    double liver_lo_fraction = 0.08; //!< the liver's plausible grey levels: this fraction of the
    double liver_hi_fraction = 0.6;  //!< 99th percentile to this one (T1: air and lung below,
                                     //!< fat above; the CT path's 40-200 HU)
    double acceptance_sigma = 2.0;   //!< seed cells within this many noise sd of the liver's grey
                                     //!< level (MR shading spreads the liver's cell means; 1 sd, the
                                     //!< CT default, found 4.9 cm2 of cells on mr-small)
    double noise_hu = 30.0;          //!< the map scales the liver's noise sd to this many pseudo-HU:
                                     //!< twice a contrast CT's liver noise, so that a T1 neighbour
                                     //!< darker than the liver by about 5 sd (the wall muscles)
                                     //!< reads below 0, as fat does in CT (chosen on mr-small, the
                                     //!< one MR at hand: docs/algorithms/liver.md, "MRI")
    bool bias_correction = false;    //!< divide out the coil's shading first (`correct_bias_field`);
                                     //!< off: on mr-small, whose liver shows little shading, the
                                     //!< score falls 16.5 -> 13.8 (docs/algorithms/bias_field.md)
    BiasFieldParams bias;            //!< ... with these parameters
};

//! Auto's rule: CT if at least `ct_air_fraction` of the voxels read below -500.
//! \throw core::InvalidInputError for an empty image or a fraction outside (0, 1].
Modality detect_modality(const core::ImageF& volume, double ct_air_fraction = 1e-3);

//! The liver-contrast image of an MR volume: 100 - (noise_hu / liver_sigma) |v - liver_value|,
//! floored at -1000. The liver reads about 100 with noise_hu spread, and every other tissue,
//! darker (muscle, kidney, spleen, fluid in T1) or brighter (fat), reads lower, as the tissues
//! around the liver do in a contrast CT's liver window. \throw core::InvalidInputError for a
//! non-finite liver value or a liver_sigma or noise_hu that is not positive.
core::ImageF mr_liver_contrast(const core::ImageF& mr, double liver_value, double liver_sigma, double noise_hu);

//! Inputs of `segment_liver`. `{}` is the documented default; each `use_*` switch turns one
//! component off for the ablation chart (bench/seg/liver_bench).
struct LiverParams {
    SnakeParams snake = default_liver_snake(); //!< per-slice CDSG
    double erosion_mm = 2.0;        //!< the previous slice's contour shrinks by this before it
                                    //!< starts the next slice's snake (snakes expand)
    double layer_alpha = 2.5;       //!< liver-like band: estimated liver grey ± alpha * sigma
    //! The layer clip: a propagated slice's snake starts from the previous contour's kept pieces
    //! only where they lie within the seed contour's band (median ± this many robust sd, as the
    //! tissue stop reads it); the pieces themselves are judged on the whole K-means layer, which
    //! is 2.4-4.4 times wider and holds the partial volume with fat and the brighter neighbours
    //! touching the liver (the IVC, a kidney's pole, the stomach). 0 = off
    //! (docs/algorithms/liver.md, "The layer clip").
    double layer_clip_sigmas = 2.5;
    double min_area_mm2 = 100.0;    //!< stop rule: a slice whose liver is smaller ends the liver
    double min_seed_area_mm2 = 25.0; //!< pieces of the shrunk contour smaller than this are dropped
    double keep_piece_fraction = 0.2; //!< pieces of the cut previous contour smaller than this
                                    //!< fraction of the largest piece do not start the next snake
    double rim_piece_fraction = 0.25; //!< ... unless at least this fraction of their border lies
                                    //!< on the previous contour's rim (a lobe along the surface,
                                    //!< not an organ enclosed by edges that touches it at a notch)
    bool keep_vessel_cut_pieces = true; //!< ... and pieces that a vessel cut off (the tissue
                                    //!< between them and the kept pieces reads brighter than the
                                    //!< tissue stop's band) start it too
    double vessel_cut_reach_mm = 8.0; //!< that tissue: within this of both (half the widest vein)
    double vessel_cut_midline_reach_mm = 16.0; //!< a piece with no such tissue (a wide vein between
                                    //!< widened edge lines) is judged on the midline of its
                                    //!< narrowest gap if that lies within this of both; 0: never
    bool exclude_dropped_pieces = true; //!< the dropped pieces (organs that took the liver's
                                    //!< place) are also kept out of the slice's contour
    double max_growth_per_mm = 1.3; //!< without a shape memory, the contour moves out at most
                                    //!< this many mm per mm of slice gap, plus growth_slack_mm
                                    //!< (4.75 mm at 2.5 mm slices, 2.8 mm at 1 mm); a leak is cut there
    double growth_slack_mm = 1.5;   //!< the part of the bound that does not scale with the slice
                                    //!< gap (the snake's own error, partial volume)
    double window_margin_mm = 10.0; //!< the snake sees the previous contour's box widened by
                                    //!< window_growth_per_mm * dz + this
    double window_growth_per_mm = 1.6; //!< (apart from the growth bound: the window's size sets
                                    //!< the edge thresholds, so it is kept as it was tuned)
    double seed_window_mm = 60.0;   //!< ... and the seed's box widened by this on the seed slice
    bool widen_seed_window = true;  //!< a seed contour that reaches its window's edge is
                                    //!< segmented again on the whole slice (on every phantom the
                                    //!< window cut the left lobe; docs/algorithms/liver.md)
    double seed_window_hold = 0.9;  //!< ... kept only if it holds this share of the window's
                                    //!< contour (else the window's stands)
    int propagation_max_iterations = 200; //!< level-set bound on a propagated slice of
                                    //!< propagation_reference_pixel_mm pixels (the front travels
                                    //!< only erosion_mm + the growth bound)
    double propagation_reference_pixel_mm = 0.7; //!< the bound is scaled by this over the in-plane
                                    //!< pixel: the front moves about a fixed fraction of a pixel
                                    //!< per iteration, so the same travel in mm takes fewer
                                    //!< iterations on coarser pixels (200 at 0.7 mm, 47 at 3 mm;
                                    //!< propagation_iteration_bound); 0 = the bound as it is
    bool layer_holds_pressure = false; //!< on a propagated slice the snake's pressure acts only
                                    //!< inside the liver-like layer; off: it lost 19 points on a
                                    //!< phantom by following the kidney (docs/algorithms/liver.md)
    //! The tissue stop, at the liver's ends: a propagated slice whose contour lies for more than
    //! this fraction outside the liver's grey levels (the seed's mean ± tissue_stop_sigmas sd, on
    //! the slice smoothed with sigma 1 mm) has left the liver (bowel, kidney, fat): it is dropped
    //! and the propagation in that direction ends. 0.35: every liver slice of the labelled inputs
    //! stays under 0.25 (docs/algorithms/liver.md, "The tissue stop").
    bool use_tissue_stop = true;
    double tissue_stop_fraction = 0.35;
    double tissue_stop_sigmas = 2.5;
    //! Before the tissue stop ends a direction, the contour is trimmed to its liver-grey core:
    //! the pixels inside the band, opened by tissue_trim_opening_px pixels (the speckle and the
    //! thin bridges the band test leaves go). If the core keeps at least tissue_trim_keep of the
    //! contour and covers at least tissue_trim_min_area_fraction of the largest slice's area, it
    //! is the slice's contour and the propagation goes on: a leak carried down from the slices
    //! above (fat, the gallbladder fossa) pushed the fraction up, not the liver's end. Otherwise
    //! the slice is dropped as before. The area bound keeps the trim off the liver's tips, where a
    //! neighbour of the liver's grey (a kidney) is as large as the liver's last slices and would
    //! be followed (docs/algorithms/liver.md, "The tissue trim").
    bool trim_at_tissue_stop = true;
    double tissue_trim_keep = 0.4;
    double tissue_trim_min_area_fraction = 0.1;
    int tissue_trim_opening_px = 2;
    //! Vessel inlets (SLIVER07 convention only): after the propagation, on each slice, the voxels
    //! a closing of the contour with radius vessel_inlet_closing_mm adds and whose grey level
    //! (smoothed, sigma 1 mm) lies above the liver's band by more than vessel_inlet_sigmas sd are
    //! contrast-filled vessels open to the surface in that slice (hepatic veins running to the
    //! IVC): they are liver (docs/algorithms/liver.md, "Vessel inlets").
    bool fill_vessel_inlets = true;
    double vessel_inlet_closing_mm = 7.0;
    double vessel_inlet_sigmas = 2.5;
    //! The dark rim: after the propagation, the layers of darker tissue the contours hold along
    //! their rim (the diaphragm and intercostal muscle between the liver and the ribs, crossed at
    //! a weak edge and carried from slice to slice) are dropped by `trim_dark_rim`, with the
    //! tissue stop's band as the liver's grey level (docs/algorithms/liver.md, "The dark rim").
    bool trim_dark_rim = true;
    DarkRimParams dark_rim;
    //! Surface lesions (SLIVER07: tumours inside the liver are liver): a hypodense lesion at the
    //! liver's surface is a notch the contour runs round (the thesis's tumour next to the ribs).
    //! After the dark rim, `fill_surface_lesions` adds the thick pieces that a per-slice closing
    //! bridges between the dark rim's level and the band's low end (darker than liver, not as dark
    //! as what surrounds it), outside the heart model (docs/algorithms/liver.md, "Surface
    //! lesions"). SLIVER07 only.
    bool fill_surface_lesions = true;
    SurfaceLesionParams surface_lesions;
    //! Growing pieces: past the liver's widest slice (the slice's area below 0.9 of the largest so
    //! far) its cross-sections shrink towards the dome and the tip, so a separate piece of the
    //! contour (not the largest, and not touching the previous slice's largest piece) whose area
    //! exceeds piece_growth_limit times that of the previous slice's pieces it overlaps is not
    //! liver (the heart wall carried up beside the dome): it is dropped
    //! (docs/algorithms/liver.md, "Growing pieces"). Such a piece is also dropped when, since it
    //! split off, its area has grown more than piece_lineage_limit times as much as the largest
    //! piece's (area ratios): on thin slices a kidney carried along grows by a few per cent a
    //! slice while the liver beside it shrinks.
    bool drop_growing_pieces = true;
    double piece_growth_limit = 1.15;
    double piece_lineage_limit = 1.3;
    //! The edge snap: each slice's accepted contour is moved on to the edge ridge by a short
    //! pressure-free run (`snap_to_edges`) before it is stacked; the propagation goes on from the
    //! unsnapped contour. Without it CDSG leaves the contour 1-2 voxels inside the ridge
    //! (docs/algorithms/liver.md, "The edge snap").
    bool use_edge_snap = true;
    SnapParams snap;                //!< band and iterations as on snap_reference_pixel_mm pixels
    //! The edge snap's reach is in voxels (its band, and its iterations, which move the front about
    //! a voxel per two): `snap.band` and `snap.iterations` are set on pixels of this size and
    //! scaled by it over the in-plane pixel, rounded, at least 1 (3 and 20 at 0.7 mm, 2 and 14 at
    //! 0.98 mm, 1 and 5 at 3 mm; liver_snap_params). 0 = in voxels as given
    //! (docs/algorithms/liver.md, "The edge snap's reach in mm").
    double snap_reference_pixel_mm = 0.7;
    bool envelope_holds_pressure = false; //!< experiment: on a propagated slice the pressure acts
                                          //!< only inside the growth envelope (the shape memory's, or
                                          //!< max_growth_per_mm), so the front stops at it
    bool parallel_directions = true; //!< propagate up and down on two threads
    //! The dome contact (docs/algorithms/liver.md, "The dome contact"): going up, a column of the
    //! liver whose next slice is a thin z-valley (the diaphragm and pericardium between the dome
    //! and the heart, too flat to be an edge in an axial slice) is closed to the liver above it.
    bool use_dome_contact = true;
    //! The heart model (docs/algorithms/liver.md, "The heart model"): with a start slice, the
    //! heart's blood pool (brighter than the liver's band by vessel_inlet_sigmas sd, at most
    //! heart_max_hu) is found nearest the template's heart centre (within heart_search_mm) and
    //! followed down while its pieces keep heart_min_area_mm2 and heart_min_area_fraction of its
    //! largest area; dilated in 3-D by heart_wall_mm, it is closed to the upward propagation.
    bool use_heart_model = true;
    double heart_wall_mm = 10.0;
    double heart_max_hu = 400.0;
    double heart_search_mm = 40.0;
    double heart_min_area_mm2 = 800.0;
    double heart_min_area_fraction = 0.15;
    double contact_smoothing_mm = 1.5;     //!< in-plane box half-width before the valley test
    double contact_sigmas = 3.0;           //!< a valley is deeper than this many robust sd of the valley
                                           //!< depth over the liver's columns ...
    double contact_min_dip = 5.0;          //!< ... and than this [image units, HU]
    double contact_closing_mm = 2.0;       //!< the valley pixels are closed into a sheet with this radius
    double contact_min_area_mm2 = 150.0;   //!< smaller pieces of the sheet are ignored (noise specks, more of
                                           //!< them at thick slices); a ring broken by noise keeps its fragments
    double contact_heart_radius_mm = 70.0; //!< a sheet counts only if its centroid lies within this
                                           //!< in-plane distance of the heart centre found on the start
                                           //!< slice: the contact is the heart's base, and without a start
                                           //!< slice (or in propagate_liver) no contact is sought

    // The pipeline's components (segment_liver); each can be switched off for the ablation.
    bool use_start_slice = true;    //!< rotating template: the heart/lung slice bounds the seed search
    bool use_kmeans = true;         //!< the liver-like band is the K-means liver layer (else seed
                                    //!< mean ± layer_alpha sigma)
    bool use_rib_cage = true;       //!< the image outside the rib ring is set to rib_background_hu
    bool use_shape_memory = true;   //!< check each slice against the memory, when one is given
    bool use_3d_pass = true;        //!< smooth the stack, fill holes, apply the convention
    double rib_background_hu = -100.0; //!< what lies outside the rib cage becomes (fat)
    //! The wall margin: after the 3-D pass, the voxels within this distance inside the rib cage
    //! ring, where bone or a bridged gap supports it, are dropped (0: off; needs the rib cage).
    //! The ring is the ribs' inner surface, and between it and the liver lie the diaphragm's
    //! costal part and the innermost intercostal layer, tissue of the liver's grey level in a
    //! non-contrast or thick-slice scan (docs/algorithms/liver.md, "The wall margin").
    double wall_margin_mm = 6.0;
    int min_slices = 5;             //!< fewer slices: refuse (a volume, not a slice, is needed)
    Modality modality = Modality::Auto; //!< CT, MR, or detected (detect_modality)
    double ct_air_fraction = 1e-3;      //!< Auto: CT if at least this fraction of voxels is below -500
    MrParams mr;                        //!< used when the volume is MR
    StartSliceParams start;
    LiverSeedParams seed;
    KMeansParams kmeans;
    LayerParams layer;
    RibCageParams ribs;
    //! The 3-D pass. Unlike `postprocess_liver`'s own default, the driver adds no IVC concavity
    //! (`concavity_closing_mm` = 0): the IVC is then in the mask only where the liver encloses it
    //! in a slice, the strict SLIVER07 reading. Every reference measured (phantom truth, ct-dicom,
    //! ct-small) excludes a half-enclosed IVC; closing it in cost 4-6 score points on each.
    PostprocessParams post = [] {
        PostprocessParams p;
        p.concavity_closing_mm = 0.0;
        return p;
    }();
};

//! The level-set bound on a propagated slice of a volume whose in-plane pixels are `pixel_x_mm` x
//! `pixel_y_mm`: `propagation_max_iterations` x `propagation_reference_pixel_mm` / (their
//! geometric mean), rounded, at least 1 (`propagation_max_iterations` itself when the reference
//! is 0). Too coarse a bound leaves the front short of the liver's edge; on 3 mm pixels 200
//! iterations let it creep 4 times as far in mm as on the 0.7 mm pixels the bound was set on,
//! into the wall muscle (docs/algorithms/liver.md, "The iteration bound in mm"). \throw
//! InvalidInputError for a bound below 1, a negative or non-finite reference, or pixels not
//! finite and > 0.
int propagation_iteration_bound(const LiverParams& params, double pixel_x_mm, double pixel_y_mm);

//! The edge snap's parameters on pixels of `pixel_x_mm` x `pixel_y_mm`: `params.snap` with its band
//! and iterations scaled by `snap_reference_pixel_mm` over the pixel (the geometric mean),
//! rounded, at least 1 (as given when the reference is 0). \throw InvalidInputError for a band or
//! iteration count below 1, a negative or non-finite reference, or pixels not finite and > 0.
SnapParams liver_snap_params(const LiverParams& params, double pixel_x_mm, double pixel_y_mm);

//! What `segment_liver` returns.
struct LiverResult {
    core::LabelImage3D mask;        //!< 1 = liver, on the input's grid
    core::LabelImage3D stacked;     //!< the slice-by-slice result before the 3-D pass
    StartSliceResult start;         //!< the rotating template's answer
    LiverSeedResult seed;           //!< the seed region
    int seed_slice = -1;            //!< where the propagation started
    Modality modality = Modality::Ct; //!< how the volume was read (never Auto)
    bool bias_corrected = false;      //!< MR: a bias field was divided out before the seed
    double bias_min_gain = 1.0;       //!< ... its range over the tissue (1, 1 when none)
    double bias_max_gain = 1.0;
    int first_slice = -1;           //!< lowest k with liver
    int last_slice = -1;            //!< highest k with liver
    double volume_ml = 0;
    std::size_t vessel_inlet_voxels = 0;  //!< voxels added by LiverParams::fill_vessel_inlets
    std::size_t dark_rim_voxels = 0;      //!< voxels dropped by LiverParams::trim_dark_rim
    std::size_t heart_model_voxels = 0;   //!< voxels of the heart model (LiverParams::use_heart_model)
    std::size_t surface_lesion_voxels = 0; //!< voxels added by LiverParams::fill_surface_lesions
    std::size_t wall_margin_voxels = 0;   //!< voxels dropped by LiverParams::wall_margin_mm
    int propagation_iterations = 0;       //!< the level-set bound the propagated slices had
    int snap_band = 0, snap_iterations = 0; //!< the edge snap's reach on this grid (0: no snap)
    double dark_rim_level = 0;            //!< ... below this smoothed grey level (0: not applied)
    double dark_rim_neighbour = 0;        //!< ... set from this median of the darker tissue outside
    bool dark_rim_touching_kept = true;   //!< ... keeping the dark pixels touching the liver (pixels up to 2 mm)
    std::vector<LiverSliceReport> slices; //!< one per segmented slice, ascending k
    std::vector<std::pair<std::string, double>> timings; //!< seconds per stage
};

//! Called with a one-line progress message ("slice 40/80 ...").
using LiverProgress = std::function<void(const std::string&)>;

//! Propagates a liver contour through `hu` (the CT in HU, or a normalised MRI) from the one-slice
//! mask `seed` (size[2] == 1, on slice `seed_slice`), which must lie inside the liver: CDSG
//! segments the seed slice, then every next slice from the previous contour, in both directions,
//! until the stop rule ends the liver. Any axis may be reversed (see segment_liver); the seed is
//! on `hu`'s grid. \throw InvalidInputError on a seed off the grid or empty, or a volume whose
//! slices are not axial (its seed slice would not be an axial one).
LiverResult propagate_liver(const core::ImageF& hu, const core::LabelImage3D& seed, int seed_slice,
                            const LiverParams& params = {}, const LiverProgress& progress = {});

//! The whole pipeline: start slice, seed, rib cage, propagation with K-means layers and the
//! shape memory (may be null), 3-D pass. `hu` is a CT in HU or an MR in its own units
//! (`LiverParams::modality`). \throw LiverNotFoundError when no liver is found (with
//! the reason), InvalidInputError for an image it cannot take (too few slices, non-finite).
//! The volume may be stored with any of its axes reversed (slices from head to feet, rows or
//! columns as in NIfTI's RAS) or in another plane (a coronal stack): it is segmented on a copy
//! whose axes run along the patient frame (LPS, core::patient_axis_order) and the result mapped
//! back to `hu`'s grid (the masks, the heart centre; a slice index counts along `hu`'s axis that
//! runs along the body; the seed stays on its axial slice's own grid when `hu` is not axial), so
//! every such storage of the same voxels gives the same liver.
LiverResult segment_liver(const core::ImageF& hu, const LiverParams& params = {}, const ShapeMemory* memory = nullptr,
                          const LiverProgress& progress = {});

//! No liver in the volume (or none the pipeline can find): the message says why.
class LiverNotFoundError : public core::InvalidInputError {
public:
    using core::InvalidInputError::InvalidInputError;
};

} // namespace lobe::seg
