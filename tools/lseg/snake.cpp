// lseg snake: one active contour (CDSG, GGVF or GAC) on a slice or a volume.
#include "common/files.h"
#include "common/picture.h"
#include "lseg/commands.h"
#include "lseg/input.h"

#include "lobe/io/hdf5.h"
#include "lobe/io/image_io.h"
#include "lobe/io/metaimage.h"
#include "lobe/seg/level_set.h"
#include "lobe/seg/snake.h"

#include <filesystem>
#include <iomanip>
#include <memory>
#include <sstream>

namespace lobe::lseg {
namespace fs = std::filesystem;

namespace {

struct SnakeOptions {
    fs::path image, init, templ, out, mask_out, png;
    std::string image_name = "ct";
    int init_label = -1, template_label = -1;
    std::vector<std::vector<double>> seeds;
    double seed_radius_mm = 5.0;
    std::string method = "cdsg";      // kept as typed, so the provenance records the name
    std::string competition = "auto";
    int slice = -1;
    bool volume = false;
    bool require_convergence = false;
    seg::SnakeParams params;
    std::vector<double> window{params.edge.window.level, params.edge.window.width};
};

//! A mask from a label image: `label` < 0 means every non-zero voxel.
core::LabelImage3D read_mask(const fs::path& path, int label, const std::string& h5_name)
{
    const auto img = core::convert_image<std::int32_t>(read_any(path, h5_name));
    core::LabelImage3D m(img.geometry(), 0);
    std::size_t count = 0;
    for (std::size_t i = 0; i < m.data.size(); ++i) {
        m.data[i] = (label < 0 ? img.data[i] != 0 : img.data[i] == label) ? 1 : 0;
        count += m.data[i];
    }
    if (count == 0)
        throw core::InvalidInputError(path.string() + ": the mask is empty" +
                                      (label >= 0 ? " (no voxel has label " + std::to_string(label) + ")" : ""));
    return m;
}

template <class T>
core::Image3D<T> maybe_slice(const core::Image3D<T>& img, int k, const fs::path& path)
{
    if (k < 0)
        return img;
    try {
        return core::axial_slice(img, k);
    } catch (const core::InvalidInputError& e) {
        throw core::InvalidInputError(path.string() + ": " + e.what());
    }
}

int run_snake(SnakeOptions& o, const tools::Progress& progress, tools::RunRecord& record)
{
    auto& timings = record.timings;
    o.params.method = o.method == "cdsg" ? seg::SnakeMethod::Cdsg
                      : o.method == "ggvf" ? seg::SnakeMethod::Ggvf
                                           : seg::SnakeMethod::Gac;
    o.params.competition = o.competition == "off" ? seg::CompetitionMode::Off
                           : o.competition == "on" ? seg::CompetitionMode::On
                                                   : seg::CompetitionMode::Auto;
    o.params.edge.window = {o.window[0], o.window[1]};

    const core::ImageF volume = timings.time("read image", [&] {
        return core::convert_image<float>(read_any(o.image, o.image_name));
    });
    const bool is3d = volume.size[2] > 1;
    if (is3d && o.slice < 0 && !o.volume)
        throw core::InvalidInputError(o.image.string() + " is a volume of " + std::to_string(volume.size[2]) +
                                      " slices: choose --slice K or --3d");
    const core::ImageF image = maybe_slice(volume, o.volume ? -1 : o.slice, o.image);

    core::LabelImage3D init;
    if (!o.init.empty()) {
        init = maybe_slice(read_mask(o.init, o.init_label, "labels/truth"), o.volume ? -1 : o.slice, o.init);
        if (!core::same_grid(init, image))
            throw core::InvalidInputError(o.init.string() + ": the initial mask is not on the image's grid");
    } else {
        std::vector<core::Vec3> seeds;
        for (const auto& s : o.seeds) {
            // Seeds are voxel indices of the input; on a slice the k index must be that slice.
            if (o.slice >= 0 && static_cast<int>(std::lround(s[2])) != o.slice)
                throw core::InvalidInputError("seed (" + std::to_string(s[0]) + "," + std::to_string(s[1]) + "," +
                                              std::to_string(s[2]) + ") is not on slice " + std::to_string(o.slice));
            seeds.push_back({s[0], s[1], o.slice >= 0 ? 0.0 : s[2]});
        }
        const core::ImageF phi = seg::level_set_from_seeds(image.geometry(), seeds, o.seed_radius_mm);
        init = core::LabelImage3D(image.geometry(), 0);
        for (std::size_t i = 0; i < init.data.size(); ++i)
            init.data[i] = phi.data[i] < 0 ? 1 : 0;
    }
    std::unique_ptr<core::LabelImage3D> templ;
    if (!o.templ.empty()) {
        templ = std::make_unique<core::LabelImage3D>(
            maybe_slice(read_mask(o.templ, o.template_label, "labels/truth"), o.volume ? -1 : o.slice, o.templ));
        if (!core::same_grid(*templ, image))
            throw core::InvalidInputError(o.templ.string() + ": the template is not on the image's grid");
    }

    progress.message("segmenting " + std::to_string(image.size[0]) + " x " + std::to_string(image.size[1]) +
                     " x " + std::to_string(image.size[2]) + " voxels");
    const seg::SnakeResult r = timings.time("segment", [&] { return seg::segment_snake(image, init, o.params, templ.get()); });

    std::size_t inside = 0;
    for (auto v : r.mask.data)
        inside += v;
    const double voxel_ml = image.spacing[0] * image.spacing[1] * image.spacing[2] / 1000.0;
    std::ostringstream msg;
    msg << std::fixed << std::setprecision(3)
        << (r.converged ? "converged" : r.leak_stopped ? "stopped at a leak (not converged)" : "did NOT converge") << " after "
        << r.iterations << " iterations, " << r.reinitialisations << " re-initialisations (" << r.runs << (r.runs == 1 ? " run" : " runs")
        << (r.competition_used ? ", energy competition on" : "") << "); fields " << r.field_seconds
        << " s, evolution " << r.evolve_seconds << " s; " << std::setprecision(1) << static_cast<double>(inside) * voxel_ml << " mL";
    progress.message(msg.str());

    timings.time("write", [&] {
        io::Provenance prov = record.provenance();
        prov.timings.emplace_back("snake.fields", r.field_seconds);
        prov.timings.emplace_back("snake.evolution", r.evolve_seconds);
        prov.parameters.emplace_back("result.converged", r.converged ? "true" : "false");
        prov.parameters.emplace_back("result.iterations", std::to_string(r.iterations));
        prov.parameters.emplace_back("result.reinitialisations", std::to_string(r.reinitialisations));
        prov.parameters.emplace_back("result.leak_stopped", r.leak_stopped ? "true" : "false");
        prov.parameters.emplace_back("result.runs", std::to_string(r.runs));
        prov.parameters.emplace_back("result.competition_used", r.competition_used ? "true" : "false");
        io::Hdf5Writer h5(o.out);
        h5.write_image("image", image);
        h5.write_labels("snake", r.mask, {{1, "object"}});
        h5.write_image("phi", r.phi);
        h5.write_provenance(prov);
        h5.commit();
        if (!o.mask_out.empty())
            io::write_image(o.mask_out, r.mask);
        if (!o.png.empty()) {
            tools::PictureParams pp;
            pp.index = 0;
            pp.level = o.window[0];
            pp.window = o.window[1];
            pp.caption = "lseg snake --method " + o.method +
                         (o.slice >= 0 ? ", slice " + std::to_string(o.slice) + " of " + o.image.filename().string() : "");
            tools::Overlay ov;
            ov.labels = &r.mask;
            ov.fill_opacity = 0.25;
            ov.colours = {{1, {255, 200, 0}, "snake"}};
            if (o.volume) // the middle slice of the volume
                pp.index = image.size[2] / 2;
            // The plane of the stored slices (coronal for a slice of a coronal series).
            pp.axis = tools::view_across(image, 2);
            tools::write_slice_png(o.png, image, pp, {ov});
        }
    });
    progress.message("wrote " + o.out.string() + (o.mask_out.empty() ? "" : ", " + o.mask_out.string()) +
                     (o.png.empty() ? "" : ", " + o.png.string()));
    if (!r.converged && o.require_convergence)
        return tools::kExitAlgorithm;
    return tools::kExitOk;
}

} // namespace

Command add_snake(CLI::App& lseg)
{
    auto o = std::make_shared<SnakeOptions>();
    CLI::App* cmd = lseg.add_subcommand(
        "snake", "Active-contour segmentation from an initial mask or seed points: CDSG (default), or the GGVF "
                 "geometric snake or geodesic active contour baselines (docs/segmentation.md)");
    cmd->add_option("IMAGE", o->image, "Image: MetaImage, NIfTI, DICOM folder, or a lobe .h5 (see --image-name)")
        ->required();
    cmd->add_option("-o,--output", o->out, "Output container (.h5): image, labels/snake, phi, provenance")->required();
    auto* init = cmd->add_option("--init", o->init, "Initial mask (inside the object); any image format");
    cmd->add_option("--init-label", o->init_label, "Use this label of --init (default: every non-zero voxel)");
    auto* seed = cmd->add_option("--seed", o->seeds, "Seed voxel index i,j,k inside the object (repeatable: "
                                                     "several contours)")
                     ->delimiter(',')
                     ->expected(3)
                     ->allow_extra_args(false);
    cmd->add_option("--seed-radius", o->seed_radius_mm, "Radius of the ball around each seed [mm]")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    init->excludes(seed);
    cmd->add_option("--image-name", o->image_name, "Image to read from a .h5 input")->capture_default_str();
    cmd->add_option("--method", o->method, "cdsg | ggvf | gac")
        ->check(CLI::IsMember({"cdsg", "ggvf", "gac"}))
        ->capture_default_str();
    auto* slice = cmd->add_option("--slice", o->slice, "Segment axial slice K of a volume (2-D)")
                      ->check(CLI::NonNegativeNumber);
    auto* vol = cmd->add_flag("--3d", o->volume, "Segment the whole volume in 3-D");
    slice->excludes(vol);
    cmd->add_option("--template", o->templ, "Expected shape (e.g. the neighbouring slice's result): enables "
                                            "energy competition and directional sharpening");
    cmd->add_option("--template-label", o->template_label, "Use this label of --template (default: non-zero)");
    cmd->add_option("--competition", o->competition, "Energy competition with a template: off | on | auto")
        ->check(CLI::IsMember({"off", "on", "auto"}))
        ->capture_default_str();
    cmd->add_option("--window", o->window, "Intensity window level,width [HU]")
        ->delimiter(',')
        ->expected(2)
        ->capture_default_str();
    cmd->add_option("--sigma", o->params.edge.sigma_mm, "Pre-smoothing sigma [mm]")->capture_default_str();
    cmd->add_option("--curvature", o->params.curvature_weight, "Curvature weight epsilon")->capture_default_str();
    cmd->add_option("--edge-band", o->params.cdsg.edge_band, "CDSG delta1: GVF band around edges [voxels]")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--max-iterations", o->params.level_set.max_iterations, "Bound on level-set iterations")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    cmd->add_option("--leak-checks", o->params.level_set.leak_checks,
                    "Leak stop: rising growth at this many checks after the front slowed ends the run at its "
                    "slowest state; 0 = off")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--mask", o->mask_out, "Also write the mask as an image (e.g. .mhd for 3D Slicer)");
    cmd->add_option("--png", o->png, "Also write a picture of the contour on the slice (PNG)");
    cmd->add_flag("--require-convergence", o->require_convergence,
                  "Exit with code 3 if the contour did not converge (the result is written either way)");
    return {cmd, [o, init, seed](const tools::Progress& progress, tools::RunRecord& record) -> int {
                if (init->count() == 0 && seed->count() == 0)
                    throw CLI::ValidationError("--init/--seed", "give an initial mask (--init) or seeds (--seed)");
                return run_snake(*o, progress, record);
            }};
}

} // namespace lobe::lseg
