// lseg all: the liver, its vessels and its tumours in one label volume (0 background, 1 liver
// parenchyma, 2 portal vein, 3 hepatic veins, 4 tumour), with volumes, the vessel graph and pictures.
#include "lseg/commands.h"
#include "lseg/structures.h"

#include "common/picture.h"

#include "lobe/io/hdf5.h"
#include "lobe/io/image_io.h"
#include "lobe/seg/tumours.h"
#include "lobe/seg/vessels.h"

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <memory>

namespace lobe::lseg {
namespace fs = std::filesystem;

namespace {

struct AllOptions {
    fs::path image, out, labels_out, png_dir;
    std::string image_name = "image";
    LiverSource liver;
    std::vector<std::string> seeds;
    seg::VesselParams vessels;
    seg::TumourParams tumours;
};

int run_all(AllOptions& o, const tools::Progress& progress, tools::RunRecord& record)
{
    auto& timings = record.timings;
    const std::vector<core::Vec3> seeds = parse_points(o.seeds);

    const StructureInput in = read_structure_input(o.image, o.image_name, o.liver, progress, timings);
    const bool h5_input = in.h5_input;
    const core::ImageF& volume = in.volume;
    const core::LabelImage3D& liver = in.liver;
    const std::string& liver_from = in.liver_from;

    seg::VesselResult vr;
    seg::TumourResult tr;
    try {
        vr = timings.time("vessels", [&] {
            return seg::segment_vessels(volume, liver, o.vessels, [&](const std::string& s) { progress.message("vessels: " + s); });
        });
        tr = timings.time("tumours", [&] {
            return seg::segment_tumours(volume, liver, vr.found ? &vr.labels : nullptr, o.tumours, seeds,
                                        [&](const std::string& s) { progress.message("tumours: " + s); });
        });
    } catch (const core::InvalidInputError& e) {
        throw core::InvalidInputError(o.image.string() + ": " + e.what());
    }

    // One label volume: tumour over vessels over parenchyma (a vessel inside a tumour is the
    // tumour's, as in lphantom's truth).
    core::LabelImage3D tissues(liver.geometry(), 0);
    std::size_t count[5] = {0, 0, 0, 0, 0};
    for (std::size_t u = 0; u < tissues.data.size(); ++u) {
        std::uint8_t v = liver.data[u] ? 1 : 0;
        if (vr.labels.data[u])
            v = vr.labels.data[u];
        if (tr.mask.data[u])
            v = seg::kTumourLabel;
        tissues.data[u] = v;
        ++count[v];
    }
    const double voxel_ml = volume.spacing[0] * volume.spacing[1] * volume.spacing[2] / 1000.0;
    const double liver_ml = static_cast<double>(count[1] + count[2] + count[3] + count[4]) * voxel_ml;
    const char* names[5] = {"", "liver_parenchyma", "portal_vein", "hepatic_veins", "tumour"};

    timings.time("write", [&] {
        io::Provenance prov = record.provenance();
        prov.parameters.emplace_back("liver_mask", liver_from);
        prov.parameters.emplace_back("volume_ml.liver", fixed(liver_ml, 3));
        for (int l = 1; l <= 4; ++l)
            prov.parameters.emplace_back(std::string("volume_ml.") + names[l], fixed(static_cast<double>(count[l]) * voxel_ml, 3));
        add_vessel_provenance(prov, vr);
        add_tumour_provenance(prov, tr);
        io::Hdf5Writer h5(o.out);
        h5.write_image("image", in.source);
        h5.write_labels("tissues", tissues, tissue_table());
        h5.write_graph("vessels", vr.graph);
        if (h5_input)
            h5.copy_provenance(io::Hdf5Reader(o.image));
        h5.write_provenance(prov);
        h5.commit();
        if (!o.labels_out.empty())
            io::write_image(o.labels_out, tissues);
        if (!o.png_dir.empty()) {
            fs::create_directories(o.png_dir);
            tools::Overlay ov;
            ov.labels = &tissues;
            ov.fill_opacity = 0.3;
            // The axial slice with the most vessel and tumour voxels, and a coronal slice through
            // the liver's centre.
            const tools::LabelViews at = tools::label_views(tissues, 2, 1);
            const std::pair<tools::SliceAxis, int> views[] = {{tools::SliceAxis::Axial, at.axial},
                                                              {tools::SliceAxis::Coronal, at.coronal}};
            for (const auto& [axis, index] : views) {
                tools::PictureParams pp;
                pp.axis = axis;
                pp.index = index;
                pp.caption = "lseg all: liver " + fixed(liver_ml, 0) + " mL, portal " + fixed(static_cast<double>(count[2]) * voxel_ml, 1) +
                             ", hepatic " + fixed(static_cast<double>(count[3]) * voxel_ml, 1) + ", tumour " +
                             fixed(static_cast<double>(count[4]) * voxel_ml, 1) + " mL";
                tools::write_slice_png(o.png_dir / (std::string("all-") + tools::slice_axis_name(axis) + ".png"), volume, pp, {ov});
            }
            if (vr.found)
                write_vessel_pictures(o.png_dir, "vessels", volume, liver, vr);
            write_tumour_pictures(o.png_dir, "tumour", volume, liver, tr);
        }
    });

    // The volumes on stdout (the result; progress is on stderr).
    std::cout << "structure          volume_ml\n";
    std::cout << "liver              " << fixed(liver_ml, 2) << "\n";
    for (int l = 1; l <= 4; ++l) {
        std::string name = names[l];
        name.resize(19, ' ');
        std::cout << name << fixed(static_cast<double>(count[l]) * voxel_ml, 2) << "\n";
    }
    std::cout << "vessels: " << vr.message << "\ntumours: " << tr.message << "\n";
    progress.message(wrote_message(o.out, o.labels_out, o.png_dir));
    return tools::kExitOk;
}

} // namespace

Command add_all(CLI::App& lseg)
{
    auto o = std::make_shared<AllOptions>();
    CLI::App* cmd = lseg.add_subcommand(
        "all", "The liver (automatic unless --liver), its vessels and its tumours in one label volume: 0 background, "
               "1 liver parenchyma, 2 portal vein, 3 hepatic veins, 4 tumour; volumes in mL, the vessel graph, pictures");
    cmd->add_option("IMAGE", o->image, "CT volume: MetaImage, NIfTI, DICOM folder, or a lobe .h5 (e.g. from lseg liver)")
        ->required();
    cmd->add_option("-o,--output", o->out, "Output container (.h5): image, labels/tissues, graphs/vessels, provenance")
        ->required();
    cmd->add_option("--image-name", o->image_name, "Image to read from a .h5 input")->capture_default_str();
    add_liver_options(cmd, o->liver);
    cmd->add_option("--seed", o->seeds, "Semi-automatic tumours: a point x,y,z [mm] inside each tumour (repeat)");
    cmd->add_option("--labels-out", o->labels_out, "Also write the tissue labels as an image file (e.g. .nii.gz)");
    cmd->add_option("--png", o->png_dir, "Also write pictures (axial, coronal, the vessel tree, each tumour) into this folder");
    return {cmd, [o](const tools::Progress& progress, tools::RunRecord& record) { return run_all(*o, progress, record); }};
}

} // namespace lobe::lseg
