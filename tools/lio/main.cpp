// lio: inspect and convert images (MetaImage, DICOM series, NIfTI, lobe HDF5).
#include "common/cli.h"
#include "lio/inspect.h"

#include "lobe/io/hdf5.h"
#include "lobe/io/image_io.h"


using namespace lobe;

namespace {

template <class T>
core::AnyImage as(const core::AnyImage& img)
{
    return core::convert_image<T>(img);
}

core::AnyImage cast_to(const core::AnyImage& img, const std::string& type)
{
    if (type.empty()) return img;
    if (type == "uint8") return as<std::uint8_t>(img);
    if (type == "int8") return as<std::int8_t>(img);
    if (type == "int16") return as<std::int16_t>(img);
    if (type == "uint16") return as<std::uint16_t>(img);
    if (type == "int32") return as<std::int32_t>(img);
    if (type == "uint32") return as<std::uint32_t>(img);
    if (type == "float32") return as<float>(img);
    return as<double>(img);
}

} // namespace

int main(int argc, char** argv)
{
    CLI::App app{"lio: print what an image holds, and convert between MetaImage (.mhd/.mha), DICOM "
                 "(a folder or .dcm; read only), NIfTI (.nii/.nii.gz) and lobe HDF5 (.h5)",
                 "lio"};
    bool quiet = false;
    tools::add_common_options(app, quiet);
    app.require_subcommand(1);
    app.fallthrough(); // --quiet may follow the subcommand (subcommands inherit this)

    std::string info_path;
    lio::Selection selection;
    bool json = false;
    auto* info_cmd = app.add_subcommand("info", "Print geometry, pixel type and intensity range of an image");
    info_cmd->add_option("PATH", info_path, "Image file or DICOM folder")->required();
    info_cmd->add_flag("--json", json, "Machine-readable output");
    const auto add_selection = [&selection](CLI::App* cmd) {
        cmd->add_option("--series", selection.series_uid, "DICOM: the SeriesInstanceUID to read when a folder holds several");
        cmd->add_option("--item", selection.item, "HDF5: the image or label volume to read when a container holds several");
        cmd->add_option("--volume", selection.volume, "NIfTI: the volume (0-based) to read from a 4-D series")
            ->check(CLI::NonNegativeNumber);
    };
    add_selection(info_cmd);

    std::string in, out, type, name = "image";
    auto* convert_cmd = app.add_subcommand("convert", "Convert an image; the output format follows OUT's extension");
    convert_cmd->add_option("IN", in, "Input image file or DICOM folder")->required();
    convert_cmd->add_option("OUT", out, "Output file (.mhd, .mha, .nii, .nii.gz, .h5)")->required();
    convert_cmd->add_option("--type", type, "Convert pixels to this type (rounding, saturating)")
        ->check(CLI::IsMember({"uint8", "int8", "int16", "uint16", "int32", "uint32", "float32", "float64"}));
    add_selection(convert_cmd);
    convert_cmd->add_option("--name", name, "Name of the image in an HDF5 output (/images/NAME)")->capture_default_str();

    tools::RunRecord record(app, argc, argv);
    return tools::run_tool(app, argc, argv, [&] {
        const tools::Progress progress("lio", quiet);
        if (*info_cmd)
            return lio::info(info_path, selection, json, progress);
        auto& timings = record.timings;
        const lio::Loaded l = timings.time("read", [&] { return lio::load(in, selection, progress); });
        progress.message("read " + in + " (" + io::format_name(l.format) + ")");
        const core::AnyImage converted = cast_to(l.image, type);
        if (io::image_format(out) != io::ImageFormat::Hdf5) {
            timings.time("write", [&] { io::write_image(out, converted); });
        } else {
            // An HDF5 output records this run (and the history of an HDF5 input) as provenance.
            io::Hdf5Writer writer(out);
            timings.time("write", [&] { writer.write_image(name, converted); });
            if (l.format == io::ImageFormat::Hdf5)
                writer.copy_provenance(io::Hdf5Reader(in));
            writer.write_provenance(record.provenance());
            writer.commit();
        }
        progress.message("wrote " + out + " in " + lio::short_number(timings.total()) + " s");
        return static_cast<int>(tools::kExitOk);
    });
}
