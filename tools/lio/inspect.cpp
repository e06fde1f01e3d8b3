#include "lio/inspect.h"

#include "lobe/core/image3d.h"
#include "lobe/io/dicom.h"
#include "lobe/io/hdf5.h"
#include "lobe/io/nifti.h"

#include <nlohmann/json.hpp>

#include <array>
#include <iomanip>
#include <iostream>
#include <sstream>

namespace lobe::lio {
namespace {

} // namespace

std::string short_number(double v)
{
    std::ostringstream s;
    s << std::fixed << std::setprecision(3) << v;
    std::string t = s.str();
    while (t.size() > 2 && t.back() == '0' && t[t.size() - 2] != '.')
        t.pop_back();
    return t == "-0.0" ? "0.0" : t;
}

namespace {

template <class A>
std::string joined(const A& values, const char* sep)
{
    std::string s;
    for (std::size_t i = 0; i < values.size(); ++i)
        s += (i ? sep : "") + short_number(static_cast<double>(values[i]));
    return s;
}

std::string uid_text(const std::string& uid) { return uid.empty() ? "(no SeriesInstanceUID)" : uid; }

// Where each voxel axis runs, by the patient direction it is nearest (core::patient_axis_order):
// "LPS" for a DICOM-style axial stack, "RAS" for NIfTI's, "LIP" for a coronal series stored head
// first, and which plane the stored slices (the third axis) lie in.
struct Orientation {
    std::string code;
    std::string slices;
};

Orientation orientation(const core::ImageGeometry& g)
{
    const core::AxisOrder to_voxel = core::patient_axis_order(g).inverse(); // voxel axis -> patient axis
    Orientation o;
    for (std::size_t a = 0; a < 3; ++a)
        o.code += (to_voxel.flip[a] ? "RAI" : "LPS")[to_voxel.from[a]];
    static const char* kPlane[3] = {"sagittal", "coronal", "axial"}; // slices across x, y, z
    o.slices = kPlane[to_voxel.from[2]];
    return o;
}

} // namespace

Loaded load(const std::filesystem::path& path, const Selection& selection, const tools::Progress& progress)
{
    const io::ImageFormat format = io::image_format(path);
    if (selection.volume >= 0) {
        if (format != io::ImageFormat::Nifti)
            throw core::InvalidInputError(path.string() + ": --volume chooses a volume of a NIfTI series; this is " +
                                          io::format_name(format));
        io::NiftiReadParams params;
        params.volume = selection.volume;
        return {io::read_nifti(path, params), format, "volume " + std::to_string(selection.volume)};
    }
    if (format == io::ImageFormat::Hdf5)
        return {io::read_hdf5_image(path, selection.item), format, selection.item};
    if (format == io::ImageFormat::Dicom) {
        io::DicomReadParams params;
        params.series_uid = selection.series_uid;
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

namespace {

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

// A NIfTI series of several volumes: say what it holds instead of choosing one.
bool list_volumes(const std::filesystem::path& path, bool json)
{
    if (io::image_format(path) != io::ImageFormat::Nifti)
        return false;
    const io::NiftiHeader h = io::read_nifti_header(path);
    if (h.volumes < 2)
        return false;
    const core::ImageGeometry& g = h.geometry;
    if (json) {
        nlohmann::ordered_json j;
        j["file"] = path.string();
        j["format"] = "NIfTI";
        j["volumes"] = h.volumes;
        j["size"] = g.size;
        j["spacing"] = g.spacing;
        j["pixel_type"] = core::pixel_type_name(h.pixel_type);
        std::cout << j.dump(2) << "\n";
        return true;
    }
    std::cout << path.string() << " is a series of " << h.volumes << " volumes of " << g.size[0] << " x " << g.size[1]
              << " x " << g.size[2] << " " << core::pixel_type_name(h.pixel_type) << " voxels (" << joined(g.spacing, " x ")
              << " mm); choose one with --volume K (0.." << h.volumes - 1 << ")\n";
    return true;
}

// An HDF5 container with more than one image or label volume: list what it holds.
bool list_container(const std::filesystem::path& path, bool json)
{
    if (io::image_format(path) != io::ImageFormat::Hdf5)
        return false;
    const io::Hdf5Reader h5(path);
    const auto images = h5.images(), labels = h5.labels();
    if (images.size() + labels.size() == 1)
        return false;
    nlohmann::ordered_json j;
    j["file"] = path.string();
    j["format"] = "HDF5";
    j["lobe_version"] = h5.lobe_version();
    j["created"] = h5.created();
    auto describe = [](const std::string& name, const io::ImageInfo& i) {
        return nlohmann::ordered_json{{"name", name}, {"pixel_type", core::pixel_type_name(i.pixel_type)},
                                      {"size", i.geometry.size}, {"spacing", i.geometry.spacing}};
    };
    for (const auto& n : images)
        j["images"].push_back(describe(n, h5.image_info(n)));
    for (const auto& n : labels)
        j["labels"].push_back(describe(n, h5.label_info(n)));
    j["surfaces"] = h5.surfaces();
    j["meshes"] = h5.tet_meshes();
    for (const auto& p : h5.provenance())
        j["history"].push_back({{"tool", p.tool}, {"started", p.started}, {"command_line", p.command_line}});
    if (json) {
        std::cout << j.dump(2) << "\n";
        return true;
    }
    std::cout << "file:      " << path.string() << "\n"
              << "format:    HDF5 (lobe container written by lobe " << h5.lobe_version() << " at " << h5.created()
              << "; choose an image with --item NAME)\n";
    for (const char* kind : {"images", "labels"})
        for (const auto& e : j.value(kind, nlohmann::ordered_json::array()))
            std::cout << kind << ":    " << e["name"].get<std::string>() << "  "
                      << e["pixel_type"].get<std::string>() << "  " << e["size"][0] << " x " << e["size"][1] << " x "
                      << e["size"][2] << "  " << joined(e["spacing"].get<std::array<double, 3>>(), " x ") << " mm\n";
    for (const auto& s : h5.surfaces())
        std::cout << "surface:   " << s << "\n";
    for (const auto& m : h5.tet_meshes())
        std::cout << "mesh:      " << m << "\n";
    for (const auto& e : j.value("history", nlohmann::ordered_json::array()))
        std::cout << "history:   " << e["started"].get<std::string>() << "  " << e["command_line"].get<std::string>()
                  << "\n";
    return true;
}

} // namespace

int info(const std::filesystem::path& path, const Selection& selection, bool json, const tools::Progress& progress)
{
    if (selection.series_uid.empty() && !json && list_series(path))
        return tools::kExitOk;
    if (selection.item.empty() && list_container(path, json))
        return tools::kExitOk;
    if (selection.volume < 0 && list_volumes(path, json))
        return tools::kExitOk;
    const Loaded l = load(path, selection, progress);
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
        const Orientation o = orientation(g);
        j["orientation"] = o.code;
        j["slices"] = o.slices;
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
              << "axes to:   " << orientation(g).code << ", " << orientation(g).slices << " slices\n"
              << "extent:    " << joined(extent, " x ") << " mm\n"
              << "range:     " << lo << " .. " << hi << "\n";
    return tools::kExitOk;
}

} // namespace lobe::lio
