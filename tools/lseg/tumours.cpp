// lseg tumours: liver tumours from K-means layers, or from seed points (lobe/seg/tumours.h).
#include "lseg/commands.h"
#include "lseg/structures.h"

#include "lobe/io/hdf5.h"
#include "lobe/io/image_io.h"
#include "lobe/seg/tumours.h"

#include <filesystem>
#include <memory>

namespace lobe::lseg {
namespace fs = std::filesystem;

namespace {

struct TumourOptions {
    fs::path image, out, labels_out, png_dir, vessels;
    std::string image_name = "image";
    LiverSource liver;
    std::vector<std::string> seeds;
    bool cdsg = false;
    seg::TumourParams params;
};

int run_tumours(TumourOptions& o, const tools::Progress& progress, tools::RunRecord& record)
{
    auto& timings = record.timings;
    const std::vector<core::Vec3> seeds = parse_points(o.seeds);
    o.params.use_cdsg = o.cdsg;

    const StructureInput in = read_structure_input(o.image, o.image_name, o.liver, progress, timings);
    const bool h5_input = in.h5_input;
    const core::ImageF& volume = in.volume;
    const core::LabelImage3D& liver = in.liver;
    const std::string& liver_from = in.liver_from;
    // Vessels are left out of the clustering when known: --vessels, or labels/vessels of an .h5 input.
    core::LabelImage3D vessels;
    std::string vessels_from = "none";
    if (!o.vessels.empty()) {
        vessels = timings.time("read vessels", [&] { return read_mask(o.vessels, "vessels", volume, "vessel"); });
        vessels_from = o.vessels.string();
    } else if (h5_input && has_labels(o.image, "vessels")) {
        vessels = timings.time("read vessels", [&] { return read_mask(o.image, "vessels", volume, "vessel"); });
        vessels_from = "labels/vessels of the input";
    }

    seg::TumourResult r;
    try {
        r = timings.time("tumours", [&] {
            return seg::segment_tumours(volume, liver, vessels.data.empty() ? nullptr : &vessels, o.params, seeds,
                                        [&](const std::string& s) { progress.message(s); });
        });
    } catch (const core::InvalidInputError& e) {
        throw core::InvalidInputError(o.image.string() + ": " + e.what());
    }

    timings.time("write", [&] {
        io::Provenance prov = record.provenance();
        prov.parameters.emplace_back("liver_mask", liver_from);
        prov.parameters.emplace_back("vessel_mask", vessels_from);
        add_tumour_provenance(prov, r);
        io::Hdf5Writer h5(o.out);
        h5.write_image("image", in.source);
        h5.write_labels("liver", liver, {{1, "liver"}});
        h5.write_labels("tumours", r.mask, {{seg::kTumourLabel, "tumour"}});
        if (h5_input)
            h5.copy_provenance(io::Hdf5Reader(o.image));
        h5.write_provenance(prov);
        h5.commit();
        if (!o.labels_out.empty())
            io::write_image(o.labels_out, r.mask);
        if (!o.png_dir.empty())
            write_tumour_pictures(o.png_dir, "tumour", volume, liver, r);
    });
    progress.message(wrote_message(o.out, o.labels_out, o.png_dir));
    return tools::kExitOk;
}

} // namespace

Command add_tumours(CLI::App& lseg)
{
    auto o = std::make_shared<TumourOptions>();
    CLI::App* cmd = lseg.add_subcommand(
        "tumours", "Liver tumours: the hypodense K-means layer inside the liver, multiple, lobular and satellite tumours "
                   "and tumours at the liver's surface; or one tumour per --seed point (docs/algorithms/tumours.md)");
    cmd->add_option("IMAGE", o->image, "CT volume: MetaImage, NIfTI, DICOM folder, or a lobe .h5 (e.g. from lseg liver)")
        ->required();
    cmd->add_option("-o,--output", o->out, "Output container (.h5): image, labels/liver, labels/tumours")->required();
    cmd->add_option("--image-name", o->image_name, "Image to read from a .h5 input")->capture_default_str();
    add_liver_options(cmd, o->liver);
    cmd->add_option("--vessels", o->vessels,
                    "Vessel mask left out of the clustering (non-zero = vessel; a .h5's labels/vessels); default: an .h5 "
                    "input's labels/vessels if any");
    cmd->add_option("--seed", o->seeds,
                    "Semi-automatic: a point x,y,z [mm, LPS] inside a tumour; repeat for several tumours; only the "
                    "seeded tumours are segmented");
    cmd->add_flag("--cdsg", o->cdsg, "Refine each tumour with the CDSG snake (off by default: see the algorithm notes)");
    cmd->add_option("--min-contrast", o->params.min_contrast,
                    "A tumour layer lies at least this much below the parenchyma [HU]")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--min-volume", o->params.min_volume_ml, "Smaller tumours are ignored [mL]")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--labels-out", o->labels_out, "Also write the tumour labels (4) as an image file");
    cmd->add_option("--png", o->png_dir, "Also write an axial picture through each of the three largest tumours");
    return {cmd, [o](const tools::Progress& progress, tools::RunRecord& record) { return run_tumours(*o, progress, record); }};
}

} // namespace lobe::lseg
