// lseg vessels: hepatic vessel trees inside the liver (lobe/seg/vessels.h).
#include "lseg/commands.h"
#include "lseg/structures.h"

#include "lobe/io/hdf5.h"
#include "lobe/io/image_io.h"
#include "lobe/seg/vessels.h"

#include <filesystem>
#include <memory>

namespace lobe::lseg {
namespace fs = std::filesystem;

namespace {

struct VesselOptions {
    fs::path image, out, labels_out, png_dir;
    std::string image_name = "image";
    LiverSource liver;
    bool no_vesselness = false, no_sharpening = false, no_fc = false, no_pruning = false, no_bridging = false;
    seg::VesselParams params;
};

int run_vessels(VesselOptions& o, const tools::Progress& progress, tools::RunRecord& record)
{
    auto& timings = record.timings;
    seg::VesselParams& p = o.params;
    p.use_vesselness = !o.no_vesselness;
    p.use_directional_sharpening = !o.no_sharpening;
    p.use_fuzzy_connectedness = !o.no_fc;
    p.use_pruning = !o.no_pruning;
    p.bridge_gaps = !o.no_bridging;

    const StructureInput in = read_structure_input(o.image, o.image_name, o.liver, progress, timings);
    const bool h5_input = in.h5_input;
    const core::ImageF& volume = in.volume;
    const core::LabelImage3D& liver = in.liver;
    const std::string& liver_from = in.liver_from;

    seg::VesselResult r;
    try {
        r = timings.time("vessels", [&] {
            return seg::segment_vessels(volume, liver, p, [&](const std::string& s) { progress.message(s); });
        });
    } catch (const core::InvalidInputError& e) {
        throw core::InvalidInputError(o.image.string() + ": " + e.what());
    }

    timings.time("write", [&] {
        io::Provenance prov = record.provenance();
        prov.parameters.emplace_back("liver_mask", liver_from);
        add_vessel_provenance(prov, r);
        io::Hdf5Writer h5(o.out);
        h5.write_image("image", in.source);
        h5.write_labels("liver", liver, {{1, "liver"}});
        h5.write_labels("vessels", r.labels, {{2, "portal_vein"}, {3, "hepatic_veins"}});
        h5.write_graph("vessels", r.graph);
        if (h5_input)
            h5.copy_provenance(io::Hdf5Reader(o.image));
        h5.write_provenance(prov);
        h5.commit();
        if (!o.labels_out.empty())
            io::write_image(o.labels_out, r.labels);
        if (!o.png_dir.empty())
            write_vessel_pictures(o.png_dir, "vessels", volume, liver, r);
    });
    progress.message(wrote_message(o.out, o.labels_out, o.png_dir));
    return tools::kExitOk;
}

} // namespace

Command add_vessels(CLI::App& lseg)
{
    auto o = std::make_shared<VesselOptions>();
    CLI::App* cmd = lseg.add_subcommand(
        "vessels", "Hepatic vessel trees inside the liver: vesselness and directional sharpening, fuzzy connectedness "
                   "from automatic seeds, 3-D thinning into a centre-line graph with radii and branch levels, portal and "
                   "hepatic trees (docs/algorithms/vessels.md). A scan without vessel contrast gives no vessels");
    cmd->add_option("IMAGE", o->image, "CT volume: MetaImage, NIfTI, DICOM folder, or a lobe .h5 (e.g. from lseg liver)")
        ->required();
    cmd->add_option("-o,--output", o->out, "Output container (.h5): image, labels/liver, labels/vessels, graphs/vessels")
        ->required();
    cmd->add_option("--image-name", o->image_name, "Image to read from a .h5 input")->capture_default_str();
    add_liver_options(cmd, o->liver);
    cmd->add_option("--labels-out", o->labels_out, "Also write the vessel labels (2 portal, 3 hepatic) as an image file");
    cmd->add_option("--png", o->png_dir, "Also write pictures (axial, coronal, the centre-line tree) into this folder");
    cmd->add_option("--min-contrast", o->params.min_contrast,
                    "Vessels must be at least this much brighter than the parenchyma [HU]; below it none are reported")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--seed-sigmas", o->params.seed_sigmas,
                    "Seeds are brighter than the parenchyma by this many of its (smoothed) standard deviations")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--link-threshold", o->params.link_threshold,
                    "Fuzzy-connectedness threshold θ: the weakest link a vessel path may have (0-1)")
        ->capture_default_str()
        ->check(CLI::Range(0.01, 0.99));
    cmd->add_flag("--no-vesselness", o->no_vesselness, "Ablation: intensity only, no vesselness");
    cmd->add_flag("--no-sharpening", o->no_sharpening, "Ablation: no averaging along the vessel axis");
    cmd->add_flag("--no-fc", o->no_fc, "Ablation: region growing at the half-contrast level instead of fuzzy connectedness");
    cmd->add_flag("--no-pruning", o->no_pruning, "Ablation: keep spurs, junction clusters and small parts");
    cmd->add_flag("--no-bridging", o->no_bridging, "Ablation: do not join parts cut off by a gap");
    return {cmd, [o](const tools::Progress& progress, tools::RunRecord& record) { return run_vessels(*o, progress, record); }};
}

} // namespace lobe::lseg
