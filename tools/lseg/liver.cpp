// lseg liver: the automatic liver pipeline (lobe/seg/liver.h) on a CT or MRI volume.
#include "common/background.h"
#include "common/files.h"
#include "common/picture.h"
#include "lseg/commands.h"
#include "lseg/input.h"
#include "lseg/shape_file.h"

#include "lobe/io/hdf5.h"
#include "lobe/io/image_io.h"
#include "lobe/seg/liver.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iomanip>
#include <memory>
#include <sstream>
#include <vector>

namespace lobe::lseg {
namespace fs = std::filesystem;

namespace {

struct LiverOptions {
    fs::path image, out, mask_out, png_dir, shape;
    std::string image_name = "ct";
    std::string convention = "sliver07";
    std::string modality = "auto";
    bool no_start_slice = false, no_competition = false, no_kmeans = false, no_rib_cage = false,
         no_shape_memory = false, no_3d_pass = false, no_dome_contact = false, layer_stop = false, bias_field = false,
         envelope_stop = false, no_tissue_stop = false, no_edge_snap = false, no_piece_growth = false,
         no_vessel_inlets = false, no_dark_rim = false, no_heart_model = false,
         no_surface_lesions = false, no_vessel_cut_pieces = false, no_tissue_trim = false, no_wall_margin = false,
         no_seed_window_widening = false, no_repeat_trim = false, no_iteration_scaling = false,
         dark_rim_keep_touching = false, no_snap_scaling = false;
    seg::LiverParams params;
};

std::string fixed(double v, int digits)
{
    std::ostringstream s;
    s << std::fixed << std::setprecision(digits) << v;
    return s.str();
}

//! Axial, coronal and sagittal pictures through the liver's centroid. The views follow the
//! patient's axes whatever the stored orientation (a coronal series is drawn as an axial one).
void write_pictures(const fs::path& dir, const core::ImageF& image, const seg::LiverResult& r)
{
    fs::create_directories(dir);
    const core::LabelImage3D& mask = r.mask;
    double ci = 0, cj = 0, ck = 0, n = 0;
    for (int k = 0; k < mask.size[2]; ++k)
        for (int j = 0; j < mask.size[1]; ++j)
            for (int i = 0; i < mask.size[0]; ++i)
                if (mask.at(i, j, k)) {
                    ci += i;
                    cj += j;
                    ck += k;
                    n += 1;
                }
    // Rounded the patient's way: the same slice whichever way an axis runs.
    const int centre[3] = {tools::patient_round(image, 0, ci / n), tools::patient_round(image, 1, cj / n),
                           tools::patient_round(image, 2, ck / n)};
    const auto through_centre = [&](tools::SliceAxis axis) {
        return std::pair{axis, centre[tools::slice_voxel_axis(image, axis)]};
    };
    tools::Overlay ov;
    ov.labels = &mask;
    ov.fill_opacity = 0.25;
    ov.colours = {{1, {255, 200, 0}, "liver"}};
    const std::pair<tools::SliceAxis, int> views[] = {through_centre(tools::SliceAxis::Axial),
                                                      through_centre(tools::SliceAxis::Coronal),
                                                      through_centre(tools::SliceAxis::Sagittal)};
    // An MR has no HU: its window spans the 1st to the 99th percentile of a strided sample.
    double window = tools::PictureParams{}.window, level = tools::PictureParams{}.level;
    if (r.modality == seg::Modality::Mr) {
        std::vector<float> sample;
        for (std::size_t i = 0; i < image.data.size(); i += 1 + image.data.size() / 100000)
            sample.push_back(image.data[i]);
        std::sort(sample.begin(), sample.end());
        const double lo = sample[sample.size() / 100], hi = sample[sample.size() * 99 / 100];
        window = std::max(hi - lo, 1.0);
        level = 0.5 * (lo + hi);
    }
    for (const auto& [axis, index] : views) {
        tools::PictureParams pp;
        pp.window = window;
        pp.level = level;
        pp.axis = axis;
        pp.index = index;
        pp.caption = "lseg liver: " + fixed(r.volume_ml, 0) + " mL";
        tools::write_slice_png(dir / (std::string("liver-") + tools::slice_axis_name(axis) + ".png"), image, pp, {ov});
    }
}

int run_liver(LiverOptions& o, const tools::Progress& progress, tools::RunRecord& record)
{
    auto& timings = record.timings;
    seg::LiverParams& p = o.params;
    p.use_start_slice = !o.no_start_slice;
    p.use_kmeans = !o.no_kmeans;
    p.use_rib_cage = !o.no_rib_cage;
    p.use_shape_memory = !o.no_shape_memory;
    p.use_3d_pass = !o.no_3d_pass;
    p.use_dome_contact = !o.no_dome_contact;
    p.use_tissue_stop = !o.no_tissue_stop;
    p.trim_at_tissue_stop = !o.no_tissue_trim;
    p.use_edge_snap = !o.no_edge_snap;
    p.drop_growing_pieces = !o.no_piece_growth;
    p.keep_vessel_cut_pieces = !o.no_vessel_cut_pieces;
    p.fill_vessel_inlets = !o.no_vessel_inlets;
    p.trim_dark_rim = !o.no_dark_rim;
    p.fill_surface_lesions = !o.no_surface_lesions;
    if (o.no_wall_margin)
        p.wall_margin_mm = 0.0;
    p.use_heart_model = !o.no_heart_model;
    p.widen_seed_window = !o.no_seed_window_widening;
    p.layer_holds_pressure = o.layer_stop;
    p.envelope_holds_pressure = o.envelope_stop;
    p.mr.bias_correction = o.bias_field;
    if (o.no_competition)
        p.snake.competition = seg::CompetitionMode::Off;
    if (o.no_repeat_trim)
        p.snake.repeat_keep_voxels = -1;
    if (o.no_iteration_scaling)
        p.propagation_reference_pixel_mm = 0.0;
    if (o.dark_rim_keep_touching)
        p.dark_rim.touching_min_smoothing_px = 0.0;
    if (o.no_snap_scaling)
        p.snap_reference_pixel_mm = 0.0;
    p.post.convention =
        o.convention == "parenchyma" ? seg::LiverConvention::Parenchyma : seg::LiverConvention::Sliver07;
    p.modality = o.modality == "ct" ? seg::Modality::Ct : o.modality == "mr" ? seg::Modality::Mr : seg::Modality::Auto;

    // The container keeps the image in its own type (a CT stays int16, half the bytes of float).
    core::AnyImage source = timings.time("read image", [&] { return read_any(o.image, o.image_name); });
    const core::ImageF volume = core::convert_image<float>(source);
    std::unique_ptr<seg::ShapeMemory> memory;
    if (!o.shape.empty())
        memory = std::make_unique<seg::ShapeMemory>(
            timings.time("read shape memory", [&] { return read_shape_memory(o.shape); }));

    // The container is opened now and the image written into it beside the segmentation, on the
    // time the segmentation's threads leave idle (its serial steps): on a 512 x 512 x 200 CT the
    // compressed write took 1.3 s after the segmentation (docs/benchmarks.md). The main thread
    // touches the writer again only after the image is written; a failed run still removes the
    // temporary (the work is waited for first, then the writer's destructor runs).
    io::Hdf5Writer h5(o.out);
    double image_write_seconds = 0.0;
    tools::BackgroundWork image_written([&] {
        const auto t0 = std::chrono::steady_clock::now();
        h5.write_image("image", source);
        source = core::AnyImage(); // written: its 100 MB (512 x 512 x 200 int16) not beside the segmentation's peak
        image_write_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    });

    progress.message("segmenting the liver in " + std::to_string(volume.size[0]) + " x " +
                     std::to_string(volume.size[1]) + " x " + std::to_string(volume.size[2]) + " voxels");
    seg::LiverResult r;
    try {
        r = timings.time("segment", [&] {
            return seg::segment_liver(volume, p, memory.get(), [&](const std::string& s) { progress.message(s); });
        });
    } catch (const core::InvalidInputError& e) {
        throw core::InvalidInputError(o.image.string() + ": " + e.what());
    }
    int rejected = 0, recovered = 0, bounded = 0, above_contact = 0;
    std::string not_liver, grown, vessel_cut, trimmed;
    for (const auto& s : r.slices) {
        if (s.not_liver)
            not_liver += (not_liver.empty() ? "" : ",") + std::to_string(s.slice);
        if (s.grown_pieces_mm2 > 0)
            grown += (grown.empty() ? "" : ",") + std::to_string(s.slice);
        if (s.vessel_cut_mm2 > 0)
            vessel_cut += (vessel_cut.empty() ? "" : ",") + std::to_string(s.slice);
        if (s.tissue_trim_mm2 > 0)
            trimmed += (trimmed.empty() ? "" : ",") + std::to_string(s.slice);
        above_contact += s.above_contact_mm2 > 0;
        rejected += s.rejected;
        recovered += s.recovered;
        bounded += !s.converged && !s.leak_stopped;
    }
    progress.message("liver: " + fixed(r.volume_ml, 1) + " mL on slices " + std::to_string(r.first_slice) + ".." +
                     std::to_string(r.last_slice) + " (" + std::to_string(r.slices.size()) + " slices segmented, " +
                     std::to_string(rejected) + " rejected by the shape memory)");

    timings.time("write", [&] {
        image_written.wait(); // rethrows a failed image write
        io::Provenance prov = record.provenance();
        for (const auto& [name, seconds] : r.timings)
            prov.timings.emplace_back("liver." + name, seconds);
        prov.timings.emplace_back("write image (beside segment)", image_write_seconds);
        auto param = [&](const std::string& k, const std::string& v) { prov.parameters.emplace_back(k, v); };
        param("result.volume_ml", fixed(r.volume_ml, 3));
        param("result.modality", seg::modality_name(r.modality));
        param("result.first_slice", std::to_string(r.first_slice));
        param("result.last_slice", std::to_string(r.last_slice));
        param("result.seed_slice", std::to_string(r.seed_slice));
        param("result.start_slice.found", r.start.found ? "true" : "false");
        param("result.start_slice", std::to_string(r.start.slice));
        param("result.rotation_deg", fixed(r.start.rotation_deg, 1));
        param("result.start_slice.message", r.start.message);
        param("result.seed.message", r.seed.message);
        param("result.seed_window_widened",
              std::any_of(r.slices.begin(), r.slices.end(),
                          [](const seg::LiverSliceReport& s) { return s.seed_window_widened; })
                  ? "true"
                  : "false");
        param("result.liver_value", fixed(r.seed.liver_value, 1));
        param("result.slices_segmented", std::to_string(r.slices.size()));
        param("result.slices_rejected", std::to_string(rejected));
        param("result.slices_recovered", std::to_string(recovered));
        param("result.slices_iteration_bound", std::to_string(bounded));
        param("result.propagation_iterations", std::to_string(r.propagation_iterations));
        param("result.snap_band", std::to_string(r.snap_band));
        param("result.snap_iterations", std::to_string(r.snap_iterations));
        param("result.slices_above_contact", std::to_string(above_contact));
        param("result.tissue_stop_slices", not_liver);
        param("result.tissue_trim_slices", trimmed);
        param("result.grown_piece_slices", grown);
        param("result.vessel_cut_piece_slices", vessel_cut);
        param("result.vessel_inlet_voxels", std::to_string(r.vessel_inlet_voxels));
        param("result.dark_rim_voxels", std::to_string(r.dark_rim_voxels));
        param("result.heart_model_voxels", std::to_string(r.heart_model_voxels));
        param("result.surface_lesion_voxels", std::to_string(r.surface_lesion_voxels));
        param("result.wall_margin_voxels", std::to_string(r.wall_margin_voxels));
        param("result.dark_rim_level", fixed(r.dark_rim_level, 1));
        param("result.dark_rim_neighbour", fixed(r.dark_rim_neighbour, 1));
        param("result.dark_rim_touching_kept", r.dark_rim_touching_kept ? "true" : "false");
        if (r.bias_corrected)
            param("result.bias_field.gain", fixed(r.bias_min_gain, 3) + " to " + fixed(r.bias_max_gain, 3));
        const bool ct = r.modality == seg::Modality::Ct; // MR runs without the start slice and the rib cage
        param(
            "components",
            std::string(p.use_start_slice && ct ? "start-slice " : "") + (ct ? "" : "mr-contrast-map ") +
                (r.bias_corrected ? "bias-field " : "") + (p.use_kmeans ? "kmeans " : "") +
                (p.layer_clip_sigmas > 0 ? "layer-clip " : "") +
                (p.use_rib_cage && ct ? "rib-cage " : "") + (memory && p.use_shape_memory ? "shape-memory " : "") +
                (p.use_dome_contact ? "dome-contact " : "") + (p.use_heart_model && ct ? "heart-model " : "") +
                (p.use_tissue_stop ? "tissue-stop " : "") +
                (p.use_tissue_stop && p.trim_at_tissue_stop ? "tissue-trim " : "") + (p.use_edge_snap ? "edge-snap " : "") +
                (p.drop_growing_pieces ? "piece-growth " : "") +
                (p.keep_vessel_cut_pieces ? "vessel-cut-pieces " : "") + (p.trim_dark_rim ? "dark-rim " : "") +
                (p.fill_vessel_inlets && p.post.convention == seg::LiverConvention::Sliver07 ? "vessel-inlets " : "") +
                (p.fill_surface_lesions && p.post.convention == seg::LiverConvention::Sliver07 ? "surface-lesions "
                                                                                                 : "") +
                (p.use_3d_pass ? "3d-pass " : "") + (p.propagation_reference_pixel_mm > 0 ? "iteration-scaling " : "") +
                (p.use_edge_snap && p.snap_reference_pixel_mm > 0 ? "snap-scaling " : "") +
                (p.use_rib_cage && ct && p.wall_margin_mm > 0 ? "wall-margin " : "") + (p.layer_holds_pressure ? "layer-stop " : "") +
                (p.snake.competition == seg::CompetitionMode::Off ? ""
                 : p.snake.repeat_keep_voxels >= 0                ? "competition repeat-trim"
                                                                  : "competition"));
        h5.write_labels("liver", r.mask, {{1, "liver"}});
        h5.write_labels("liver_slices", r.stacked, {{1, "liver (slice by slice, before the 3-D pass)"}});
        h5.write_provenance(prov);
        h5.commit();
        if (!o.mask_out.empty())
            io::write_image(o.mask_out, r.mask);
        if (!o.png_dir.empty())
            write_pictures(o.png_dir, volume, r);
    });
    progress.message("wrote " + o.out.string() + (o.mask_out.empty() ? "" : ", " + o.mask_out.string()) +
                     (o.png_dir.empty() ? "" : ", pictures in " + o.png_dir.string()));
    return tools::kExitOk;
}

} // namespace

Command add_liver(CLI::App& lseg)
{
    auto o = std::make_shared<LiverOptions>();
    CLI::App* cmd = lseg.add_subcommand(
        "liver", "Automatic liver segmentation of a CT (or MRI) volume, no clicks: rotating template start slice, "
                 "grid seed, CDSG slice by slice with K-means layers, rib cage and shape memory, 3-D pass "
                 "(docs/algorithms/liver.md)");
    cmd->add_option("IMAGE", o->image, "Volume: MetaImage, NIfTI, DICOM folder, or a lobe .h5 (see --image-name)")
        ->required();
    cmd->add_option("-o,--output", o->out,
                    "Output container (.h5): image, labels/liver, labels/liver_slices, provenance")
        ->required();
    cmd->add_option("--image-name", o->image_name, "Image to read from a .h5 input")->capture_default_str();
    cmd->add_option("--mask", o->mask_out,
                    "Also write the liver mask as an image (e.g. .mhd or .nii.gz for 3D Slicer)");
    cmd->add_option("--png", o->png_dir,
                    "Also write axial, coronal and sagittal pictures of the contour into this folder");
    cmd->add_option("--shape", o->shape, "Shape memory trained by `lseg train` (without it: a fixed growth bound)");
    cmd->add_option("--convention", o->convention,
                    "sliver07: vessels, tumours and the enclosed IVC are liver | parenchyma: they are not")
        ->check(CLI::IsMember({"sliver07", "parenchyma"}))
        ->capture_default_str();
    cmd->add_option(
           "--modality", o->modality,
           "auto: CT if at least 0.1 % of the voxels read as air (below -500), else MR | ct: HU | mr: the MR path "
           "(seed on the MR's grey levels, then the liver-contrast map; no start slice, no rib cage)")
        ->check(CLI::IsMember({"auto", "ct", "mr"}))
        ->capture_default_str();
    cmd->add_option("--mr-noise", o->params.mr.noise_hu,
                    "MR path: the liver's noise sd in the liver-contrast map, in pseudo-HU (larger: neighbours "
                    "a few sd from the liver's grey level read darker; docs/algorithms/liver.md, \"MRI\")")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    cmd->add_flag("--bias-field", o->bias_field,
                  "MR path: divide out the coil's shading before the seed, for a scan whose liver is visibly "
                  "brighter on one side (docs/algorithms/bias_field.md)");
    cmd->add_flag("--no-start-slice", o->no_start_slice, "Ablation: no rotating-template start slice");
    cmd->add_flag("--no-competition", o->no_competition, "Ablation: no energy competition between slices");
    cmd->add_flag("--no-repeat-trim", o->no_repeat_trim,
                  "Ablation: energy competition's repeat replaces the first run's contour (the thesis's rule) "
                  "instead of only cutting where that left the previous slice's band");
    cmd->add_flag("--no-kmeans", o->no_kmeans,
                  "Ablation: a fixed band around the seed's grey level, not K-means layers");
    cmd->add_flag("--no-rib-cage", o->no_rib_cage, "Ablation: no rib cage ring");
    cmd->add_flag("--no-shape-memory", o->no_shape_memory, "Ablation: ignore --shape");
    cmd->add_flag("--no-3d-pass", o->no_3d_pass, "Ablation: keep the slice-by-slice stack");
    cmd->add_flag(
        "--no-dome-contact", o->no_dome_contact,
        "Ablation: going up, do not close the columns above a dome contact (the flat diaphragm under the heart)");
    cmd->add_flag("--no-tissue-stop", o->no_tissue_stop,
                  "Ablation: do not end the propagation at a slice whose contour lies mostly outside the liver's "
                  "grey levels");
    cmd->add_option("--tissue-stop", o->params.tissue_stop_fraction,
                    "End the propagation at a slice whose contour lies for more than this fraction outside the "
                    "liver's grey levels")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 1.0));
    cmd->add_flag("--no-tissue-trim", o->no_tissue_trim,
                  "Ablation: at the tissue stop, end the propagation instead of keeping the contour's liver-grey "
                  "core");
    cmd->add_option("--tissue-trim-keep", o->params.tissue_trim_keep,
                    "Tissue trim: go on with the contour's liver-grey core if it keeps at least this fraction of the "
                    "contour")
        ->capture_default_str()
        ->check(CLI::Range(0.01, 1.0));
    cmd->add_flag("--no-vessel-inlets", o->no_vessel_inlets,
                  "Ablation: do not add the contrast-filled vessels open to the liver's surface in a slice (SLIVER07 "
                  "convention only)");
    cmd->add_option("--vessel-inlet-closing", o->params.vessel_inlet_closing_mm,
                    "Vessel inlets: radius of the per-slice closing that bridges their mouths [mm]")
        ->capture_default_str()
        ->check(CLI::Range(0.1, 50.0));
    cmd->add_flag("--no-heart-model", o->no_heart_model,
                  "Ablation: do not close the heart (its blood pool followed down from the start slice, dilated by "
                  "the myocardium) to the upward propagation");
    cmd->add_option("--heart-wall", o->params.heart_wall_mm, "Heart model: myocardium thickness [mm]")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 50.0));
    cmd->add_flag("--no-surface-lesions", o->no_surface_lesions,
                  "Ablation: do not add the hypodense lesions in the notches of the liver's surface (SLIVER07 "
                  "convention only)");
    cmd->add_option("--surface-lesion-closing", o->params.surface_lesions.closing_mm,
                    "Surface lesions: radius of the per-slice closing that bridges their notches [mm]")
        ->capture_default_str()
        ->check(CLI::Range(0.1, 50.0));
    cmd->add_flag("--no-wall-margin", o->no_wall_margin,
                  "Ablation: keep the voxels just inside the ribs (the diaphragm and intercostal layer)");
    cmd->add_option("--wall-margin", o->params.wall_margin_mm,
                    "Wall margin: drop the voxels within this distance inside the rib cage ring [mm]")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 30.0));
    cmd->add_flag("--no-dark-rim", o->no_dark_rim,
                  "Ablation: keep the layers of darker tissue along the contour's rim (the diaphragm between the "
                  "liver and the ribs)");
    cmd->add_option("--dark-rim-level", o->params.dark_rim.level,
                    "Dark rim: drop rim voxels darker than this fraction of the way from the liver's grey level down "
                    "to the darker tissue outside the contour")
        ->capture_default_str()
        ->check(CLI::Range(0.05, 1.0));
    cmd->add_flag("--dark-rim-keep-touching", o->dark_rim_keep_touching,
                  "Ablation: the dark rim keeps the dark pixels touching the liver whatever the pixel size (by "
                  "default only where its 1 mm smoothing spans half a pixel: pixels up to 2 mm)");
    cmd->add_flag("--no-piece-growth", o->no_piece_growth,
                  "Ablation: keep the separate pieces of a contour that grow past the liver's widest slice");
    cmd->add_option("--layer-clip", o->params.layer_clip_sigmas,
                    "Each propagated slice's snake starts from the previous contour's pieces only where they lie "
                    "within the liver's grey levels under the seed slice's contour (median +- this many robust sd); "
                    "0 = off")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 100.0));
    cmd->add_option("--piece-growth", o->params.piece_growth_limit,
                    "Drop a separate piece past the widest slice whose area exceeds this many times its predecessors'")
        ->capture_default_str()
        ->check(CLI::Range(1.0, 100.0));
    cmd->add_option("--piece-lineage-growth", o->params.piece_lineage_limit,
                    "Drop a separate piece past the widest slice that, since it split off, grew this many times as "
                    "much as the largest piece")
        ->capture_default_str()
        ->check(CLI::Range(1.0, 100.0));
    cmd->add_flag("--no-vessel-cut-pieces", o->no_vessel_cut_pieces,
                  "Ablation: drop the pieces of the previous contour that a vessel cut off (as any small piece "
                  "inside it)");
    cmd->add_option("--vessel-cut-reach", o->params.vessel_cut_reach_mm,
                    "Vessel-cut pieces: the tissue between a piece and the kept ones within this many mm of both "
                    "must read brighter than the liver's band")
        ->capture_default_str()
        ->check(CLI::Range(0.5, 50.0));
    cmd->add_option("--vessel-cut-midline-reach", o->params.vessel_cut_midline_reach_mm,
                    "Vessel-cut pieces: a piece with no tissue within --vessel-cut-reach of both is judged on the "
                    "midline of its narrowest gap if that lies within this many mm of both; 0 = never")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 50.0));
    cmd->add_flag("--no-edge-snap", o->no_edge_snap,
                  "Ablation: stack the snake's contours as they are, not moved on to the edge ridge");
    cmd->add_option("--snap-band", o->params.snap.band,
                    "Edge snap: the field reaches this many voxels (chessboard) from an edge, on 0.7 mm pixels "
                    "(scaled to the pixel unless --no-snap-scaling)")
        ->capture_default_str()
        ->check(CLI::Range(1, 20));
    cmd->add_option("--snap-iterations", o->params.snap.iterations,
                    "Edge snap: level-set iterations, on 0.7 mm pixels (scaled to the pixel unless --no-snap-scaling)")
        ->capture_default_str()
        ->check(CLI::Range(1, 1000));
    cmd->add_flag("--no-snap-scaling", o->no_snap_scaling,
                  "Ablation: the edge snap's band and iterations in voxels as given, whatever the pixel size");
    cmd->add_flag("--layer-stop", o->layer_stop,
                  "Experiment: the snake's pressure acts only inside the liver-like layer on propagated slices");
    cmd->add_flag("--envelope-stop", o->envelope_stop,
                  "Experiment: the snake's pressure acts only inside the growth envelope on propagated slices");
    cmd->add_option("--max-iterations", o->params.propagation_max_iterations,
                    "Level-set iteration bound on a propagated slice of 0.7 mm pixels (scaled by 0.7 mm over the "
                    "volume's pixel: 47 at 3 mm)")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    cmd->add_flag("--no-iteration-scaling", o->no_iteration_scaling,
                  "Ablation: the same iteration bound on every pixel size, instead of the same front travel in mm");
    cmd->add_option("--seed-window", o->params.seed_window_mm,
                    "The seed slice's snake sees the seed's box widened by this [mm]")
        ->capture_default_str()
        ->check(CLI::Range(5.0, 500.0));
    cmd->add_flag("--no-seed-window-widening", o->no_seed_window_widening,
                  "Ablation: keep the seed slice's contour when it reaches its window's edge, instead of segmenting "
                  "the seed slice again on the whole slice");
    cmd->add_option("--max-growth", o->params.max_growth_per_mm,
                    "Without a shape memory: how far the contour may move out between slices, per mm of slice gap")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    cmd->add_option("--growth-slack", o->params.growth_slack_mm,
                    "Without a shape memory: added to the growth bound on every slice, whatever the slice gap [mm]")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 20.0));
    cmd->add_option("--smoothing", o->params.post.smoothing_mm,
                    "3-D pass: Gaussian sigma of the volume-preserving smoothing [mm]; 0 = none")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--ivc-closing", o->params.post.concavity_closing_mm,
                    "3-D pass, sliver07: radius of the per-slice closing that adds the IVC's concavity [mm]; 0 = none")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    return {cmd,
            [o](const tools::Progress& progress, tools::RunRecord& record) { return run_liver(*o, progress, record); }};
}

} // namespace lobe::lseg
