// lseg bias: divides an MR volume's smooth shading out (docs/algorithms/bias_field.md) and writes
// the corrected image and the field, so that both can be looked at before the liver is segmented.
#include "lseg/commands.h"
#include "lseg/input.h"

#include "lobe/seg/bias_field.h"
#include "lobe/seg/liver.h"

#include <iomanip>
#include <memory>
#include <sstream>

namespace lobe::lseg {
namespace fs = std::filesystem;

namespace {

struct BiasOptions {
    fs::path image, out, corrected_out, field_out;
    std::string image_name = "image";
    std::string modality = "auto";
    seg::BiasFieldParams params;
};

int run_bias(const BiasOptions& o, const tools::Progress& progress, tools::RunRecord& record)
{
    auto& timings = record.timings;
    const core::ImageF volume =
        timings.time("read image", [&] { return core::convert_image<float>(read_any(o.image, o.image_name)); });
    // A CT's grey levels are Hounsfield units, the same everywhere: a fitted field would only
    // distort them. Auto refuses what reads as CT (air below -500, as `lseg liver` decides).
    if (o.modality == "auto" && seg::detect_modality(volume) == seg::Modality::Ct)
        throw core::InvalidInputError(o.image.string() +
                                      ": reads as CT (voxels below -500: air in HU); a bias field is an MR's "
                                      "(--modality mr to correct it anyway)");
    progress.message("estimating the bias field of " + std::to_string(volume.size[0]) + " x " +
                     std::to_string(volume.size[1]) + " x " + std::to_string(volume.size[2]) + " voxels");
    seg::BiasFieldResult r;
    try {
        r = timings.time("bias field", [&] { return seg::correct_bias_field(volume, o.params); });
    } catch (const core::InvalidInputError& e) {
        throw core::InvalidInputError(o.image.string() + ": " + e.what());
    }
    if (r.samples == 0)
        throw core::InvalidInputError(o.image.string() + ": too few tissue voxels (above " +
                                      std::to_string(o.params.tissue_fraction) +
                                      " of the 99th percentile) to fit a field");
    std::ostringstream msg;
    msg << std::setprecision(3) << "gain " << r.min_gain << " to " << r.max_gain << " over " << r.samples
        << " tissue samples, " << r.iterations << " iterations" << (r.converged ? "" : " (not converged)");
    progress.message(msg.str());

    timings.time("write", [&] {
        io::Provenance prov = record.provenance();
        prov.parameters.emplace_back("result.min_gain", std::to_string(r.min_gain));
        prov.parameters.emplace_back("result.max_gain", std::to_string(r.max_gain));
        prov.parameters.emplace_back("result.iterations", std::to_string(r.iterations));
        prov.parameters.emplace_back("result.converged", r.converged ? "true" : "false");
        prov.parameters.emplace_back("result.samples", std::to_string(r.samples));
        io::Hdf5Writer h5(o.out);
        h5.write_image("image", r.corrected);
        h5.write_image("bias_field", r.field);
        h5.write_provenance(prov);
        h5.commit();
        if (!o.corrected_out.empty())
            io::write_image(o.corrected_out, r.corrected);
        if (!o.field_out.empty())
            io::write_image(o.field_out, r.field);
    });
    progress.message("wrote " + o.out.string());
    return tools::kExitOk;
}

} // namespace

Command add_bias(CLI::App& lseg)
{
    auto o = std::make_shared<BiasOptions>();
    CLI::App* cmd = lseg.add_subcommand(
        "bias", "MR shading correction: K-means tissue classes and a smooth multiplicative field, divided out "
                "(docs/algorithms/bias_field.md; `lseg liver` does this itself on MR)");
    cmd->add_option("IMAGE", o->image, "Volume: MetaImage, NIfTI, DICOM folder, or a lobe .h5 (see --image-name)")
        ->required();
    cmd->add_option("-o,--output", o->out, "Output container (.h5): images/image (corrected), images/bias_field")
        ->required();
    cmd->add_option("--image-name", o->image_name, "Image to read from a .h5 input")->capture_default_str();
    cmd->add_option("--modality", o->modality,
                    "auto: refuse a volume that reads as CT (air below -500) | mr: correct whatever it holds")
        ->check(CLI::IsMember({"auto", "mr"}))
        ->capture_default_str();
    cmd->add_option("--corrected", o->corrected_out, "Also write the corrected image (e.g. .mhd)");
    cmd->add_option("--field", o->field_out, "Also write the field b (the image divided by it is the corrected one)");
    cmd->add_option("--degree", o->params.degree, "Total degree of the polynomial log b")
        ->capture_default_str()
        ->check(CLI::Range(0, 4));
    cmd->add_option("--classes", o->params.classes, "K-means tissue classes")
        ->capture_default_str()
        ->check(CLI::Range(1, 16));
    cmd->add_option("--tissue-fraction", o->params.tissue_fraction,
                    "Tissue: voxels above this fraction of the 99th percentile")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 1.0));
    return {cmd, [o](const tools::Progress& progress, tools::RunRecord& record) { return run_bias(*o, progress, record); }};
}

} // namespace lobe::lseg
