// lio: inspect and convert images (MetaImage, DICOM series, NIfTI, lobe HDF5).
#include "common/cli.h"

#include "lobe/io/dicom.h"
#include "lobe/io/hdf5.h"
#include "lobe/io/image_io.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <iomanip>
#include <iostream>
#include <sstream>

using namespace lobe;

namespace {

// 3 decimals with trailing zeros dropped (but one kept): 0.9765625 -> "0.977", 2 -> "2.0".
std::string short_number(double v)
{
    std::ostringstream s;
    s << std::fixed << std::setprecision(3) << v;
    std::string t = s.str();
    while (t.size() > 2 && t.back() == '0' && t[t.size() - 2] != '.')
        t.pop_back();
    return t == "-0.0" ? "0.0" : t;
}

template <class A>
std::string joined(const A& values, const char* sep)
{
    std::string s;
    for (std::size_t i = 0; i < values.size(); ++i)
        s += (i ? sep : "") + short_number(static_cast<double>(values[i]));
    return s;
}

struct Loaded {
    core::AnyImage image;
    io::ImageFormat format;
    std::string detail; // e.g. the DICOM series
};

std::string uid_text(const std::string& uid) { return uid.empty() ? "(no SeriesInstanceUID)" : uid; }

// Reads any image; for DICOM, the series `series_uid` (empty: the only one), with its notes
// (skipped files, series passed over) as progress messages.
Loaded load(const std::filesystem::path& path, const std::string& series_uid, const tools::Progress& progress)
{
    const io::ImageFormat format = io::image_format(path);
    if (format == io::ImageFormat::Dicom) {
        io::DicomReadParams params;
        params.series_uid = series_uid;
        io::DicomSeries s = io::read_dicom_series(path, params);
        for (const auto& note : s.notes)
            progress.message(note);
        std::string detail = s.modality + " series " + uid_text(s.series_uid) + ", " + std::to_string(s.files.size()) + " files";
        if (!s.description.empty())
            detail += ", \"" + s.description + "\"";
        return {std::move(s.image), format, detail};
    }
    return {io::read_image(path), format, {}};
}

// A folder with several DICOM series: list them instead of choosing one.
bool list_series(const std::filesystem::path& path)
{
    if (io::image_format(path) != io::ImageFormat::Dicom)
        return false;
    const auto all = io::list_dicom_series(path);
    if (all.size() < 2)
        return false;
    std::cout << path.string() << " holds " << all.size() << " DICOM series; choose one with --series UID:\n";
    for (const auto& s : all)
        std::cout << "  " << uid_text(s.series_uid) << "  " << s.modality << "  " << s.size[0] << " x " << s.size[1]
                  << " x " << s.slices << (s.description.empty() ? "" : "  \"" + s.description + "\"")
                  << (s.problem.empty() ? "" : "  (unreadable: " + s.problem + ")") << "\n";
    return true;
}

int info(const std::filesystem::path& path, const std::string& series_uid, bool json, const tools::Progress& progress)
{
    if (series_uid.empty() && !json && list_series(path))
        return tools::kExitOk;
    const Loaded l = load(path, series_uid, progress);
    const core::ImageGeometry& g = core::geometry(l.image);
    const auto [lo, hi] = core::value_range(l.image);
    const char* type = core::pixel_type_name(core::pixel_type(l.image));
    if (json) {
        nlohmann::ordered_json j;
        j["file"] = path.string();
        j["format"] = io::format_name(l.format);
        if (!l.detail.empty())
            j["detail"] = l.detail;
        j["pixel_type"] = type;
        j["size"] = g.size;
        j["spacing"] = g.spacing;
        j["origin"] = g.origin;
        j["direction"] = g.direction;
        j["min"] = lo;
        j["max"] = hi;
        std::cout << j.dump(2) << "\n";
        return tools::kExitOk;
    }
    std::array<double, 3> extent{};
    for (int a = 0; a < 3; ++a)
        extent[static_cast<std::size_t>(a)] = g.size[static_cast<std::size_t>(a)] * g.spacing[static_cast<std::size_t>(a)];
    std::cout << "file:      " << path.string() << "\n"
              << "format:    " << io::format_name(l.format) << (l.detail.empty() ? "" : " (" + l.detail + ")") << "\n"
              << "type:      " << type << "\n"
              << "size:      " << g.size[0] << " x " << g.size[1] << " x " << g.size[2] << "\n"
              << "spacing:   " << joined(g.spacing, " x ") << " mm\n"
              << "origin:    " << joined(g.origin, " ") << " mm (LPS)\n"
              << "direction: " << joined(std::array<double, 3>{g.direction[0], g.direction[3], g.direction[6]}, " ")
              << " | " << joined(std::array<double, 3>{g.direction[1], g.direction[4], g.direction[7]}, " ") << " | "
              << joined(std::array<double, 3>{g.direction[2], g.direction[5], g.direction[8]}, " ") << " (axes)\n"
              << "extent:    " << joined(extent, " x ") << " mm\n"
              << "range:     " << lo << " .. " << hi << "\n";
    return tools::kExitOk;
}

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

    std::string info_path, series;
    bool json = false;
    auto* info_cmd = app.add_subcommand("info", "Print geometry, pixel type and intensity range of an image");
    info_cmd->add_option("PATH", info_path, "Image file or DICOM folder")->required();
    info_cmd->add_flag("--json", json, "Machine-readable output");
    info_cmd->add_option("--series", series, "DICOM: the SeriesInstanceUID to read when a folder holds several");

    std::string in, out, type, name = "image";
    auto* convert_cmd = app.add_subcommand("convert", "Convert an image; the output format follows OUT's extension");
    convert_cmd->add_option("IN", in, "Input image file or DICOM folder")->required();
    convert_cmd->add_option("OUT", out, "Output file (.mhd, .mha, .nii, .nii.gz, .h5)")->required();
    convert_cmd->add_option("--type", type, "Convert pixels to this type (rounding, saturating)")
        ->check(CLI::IsMember({"uint8", "int8", "int16", "uint16", "int32", "uint32", "float32", "float64"}));
    convert_cmd->add_option("--series", series, "DICOM: the SeriesInstanceUID to read when a folder holds several");
    convert_cmd->add_option("--name", name, "Name of the image in an HDF5 output (/images/NAME)")->capture_default_str();

    tools::RunRecord record(app, argc, argv);
    return tools::run_tool(app, argc, argv, [&] {
        const tools::Progress progress("lio", quiet);
        if (*info_cmd)
            return info(info_path, series, json, progress);
        auto& timings = record.timings;
        const Loaded l = timings.time("read", [&] { return load(in, series, progress); });
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
        progress.message("wrote " + out + " in " + short_number(timings.total()) + " s");
        return static_cast<int>(tools::kExitOk);
    });
}
