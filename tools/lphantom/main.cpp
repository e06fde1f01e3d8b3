// lphantom: writes the synthetic patient (ct.mhd, labels.mhd, truth.json, optional PNGs).
#include "common/cli.h"
#include "common/files.h"
#include "common/picture.h"
#include "lphantom/phantom.h"
#include "lphantom/truth_json.h"

#include "lobe/io/hdf5.h"
#include "lobe/io/metaimage.h"


#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <set>
#include <sstream>
#include <unistd.h>

using namespace lobe;
namespace fs = std::filesystem;

namespace {

// The pictures docs/phantom.md shows: axial slices through each feature, one coronal, one
// sagittal, each with and without the label overlay.
void write_pictures(const fs::path& dir, const phantom::PhantomResult& r, double pixel_mm)
{
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec || !fs::is_directory(dir))
        throw core::IoError("cannot create the picture folder '" + dir.string() + "'" + (ec ? ": " + ec.message() : ""));
    struct View {
        std::string name;
        tools::SliceAxis axis;
        std::string landmark;
    };
    const std::vector<View> views = {
        {"axial-heart-lungs", tools::SliceAxis::Axial, "heart_lungs"},
        {"axial-heart-contact", tools::SliceAxis::Axial, "heart_liver_contact"},
        {"axial-ivc-omega", tools::SliceAxis::Axial, "ivc_omega"},
        {"axial-fissures", tools::SliceAxis::Axial, "even_fissure"},
        {"axial-tumours", tools::SliceAxis::Axial, "tumour_lobular"},
        {"axial-boundary-tumour", tools::SliceAxis::Axial, "tumour_boundary"},
        {"axial-kidney-contact", tools::SliceAxis::Axial, "kidney_liver_contact"},
        {"coronal", tools::SliceAxis::Coronal, "tumour_lobular"},
        {"sagittal", tools::SliceAxis::Sagittal, "kidney_liver_contact"},
    };
    std::set<std::pair<int, int>> done;
    for (const auto& v : views) {
        const phantom::Landmark* lm = nullptr;
        for (const auto& l : r.truth.landmarks)
            if (l.name == v.landmark) lm = &l;
        if (!lm) continue; // e.g. no tumours
        const int a = v.axis == tools::SliceAxis::Axial ? 2 : (v.axis == tools::SliceAxis::Coronal ? 1 : 0);
        tools::PictureParams pp;
        pp.axis = v.axis;
        pp.index = lm->index[static_cast<std::size_t>(a)];
        if (pp.index < 0 || pp.index >= r.ct.size[static_cast<std::size_t>(a)]) continue; // outside a small grid
        if (!done.insert({a, pp.index}).second) continue; // e.g. two features in one slice
        pp.pixel_mm = pixel_mm;
        // the body, not the air around it
        pp.roi_lo = {-172, -128, -1e4};
        pp.roi_hi = {172, 114, 1e4};
        pp.caption = "lphantom " + v.name;
        tools::write_slice_png(dir / ("phantom-" + v.name + ".png"), r.ct, pp);
        tools::Overlay o;
        o.labels = &r.labels;
        tools::write_slice_png(dir / ("phantom-" + v.name + "-labels.png"), r.ct, pp, {o});
    }
}

} // namespace

int main(int argc, char** argv)
{
    CLI::App app{"lphantom: writes a synthetic portal-venous abdominal CT with known ground truth\n"
                 "(ct.mhd in HU, labels.mhd, truth.json) into OUT_DIR. See docs/phantom.md.",
                 "lphantom"};
    phantom::PhantomParams p;
    fs::path out_dir, png_dir;
    double png_pixel_mm = 0;
    std::vector<int> size;
    std::vector<double> spacing;
    bool quiet = false, no_tumours = false, no_vessels = false, compress = false;
    app.add_option("OUT_DIR", out_dir, "Output folder (created if missing)")->required();
    app.add_option("--size", size, "Voxels along x,y,z [default 512,512,80; with only --spacing: the default field of view]")
        ->delimiter(',')->expected(3);
    app.add_option("--spacing", spacing, "Voxel size x,y,z in mm, or one value for all axes [default 0.7,0.7,2.5]")
        ->delimiter(',')->expected(1, 3);
    app.add_option("--noise", p.noise_sigma_hu, "Gaussian noise sigma [HU]")->capture_default_str();
    app.add_option("--blur", p.blur_sigma_mm, "Gaussian PSF sigma [mm]")->capture_default_str();
    app.add_option("--seed", p.seed, "Noise seed (the anatomy does not depend on it)")->capture_default_str();
    app.add_option("--fissure-width", p.fissure_width_voxels, "Even fissure width [voxels], 0 = none")->capture_default_str();
    app.add_option("--odd-fissure-width", p.odd_fissure_width_voxels, "Second fissure width [voxels], 0 = none")
        ->capture_default_str();
    app.add_flag("--no-tumours", no_tumours, "Leave out the tumours");
    app.add_flag("--no-vessels", no_vessels, "Leave out the portal and hepatic venous trees");
    app.add_flag("--compress", compress, "zlib-compress the MetaImage data (.zraw)");
    app.add_option("--png", png_dir, "Also write PNG slices through each feature into this folder");
    app.add_option("--png-pixel", png_pixel_mm, "Pixel size of the pictures [mm]; 0 = the in-plane spacing")
        ->check(CLI::NonNegativeNumber);
    tools::add_common_options(app, quiet);

    tools::RunRecord record(app, argc, argv);
    return tools::run_tool(app, argc, argv, [&]() -> int {
        const tools::Progress progress("lphantom", quiet);
        if (spacing.size() == 2) {
            std::cerr << "lphantom: error: invalid option: --spacing takes 1 or 3 values, not 2\n";
            return tools::kExitUsage;
        }
        if (spacing.size() == 1) spacing.assign(3, spacing[0]);
        if (spacing.size() == 3) p.spacing = {spacing[0], spacing[1], spacing[2]};
        if (size.size() == 3) p.size = {size[0], size[1], size[2]};
        else if (spacing.size() == 3 && phantom::params_problem(p).find("spacing") == std::string::npos)
            p.size = phantom::size_for_spacing(p.spacing);
        p.tumours = !no_tumours;
        p.vessels = !no_vessels;
        const std::string problem = phantom::params_problem(p);
        if (!problem.empty()) {
            std::cerr << "lphantom: error: invalid option: " << problem << "\n";
            return tools::kExitUsage;
        }

        // Stage everything in a hidden folder inside OUT_DIR and move it into place at the end,
        // so that a failed run leaves no half-written set of files.
        std::error_code ec;
        const bool created = !fs::exists(out_dir, ec);
        fs::create_directories(out_dir, ec);
        if (ec || !fs::is_directory(out_dir))
            throw core::IoError("cannot create the output folder '" + out_dir.string() + "'" +
                                (ec ? ": " + ec.message() : ": not a folder"));
        const fs::path stage = out_dir / (".lphantom-" + std::to_string(::getpid()));
        fs::create_directories(stage, ec);
        if (ec)
            throw core::IoError("cannot write into '" + out_dir.string() + "': " + ec.message());
        struct Cleanup { // on failure also removes an output folder this run created (if empty)
            fs::path stage, out;
            bool created, done = false;
            ~Cleanup()
            {
                std::error_code e;
                fs::remove_all(stage, e);
                if (!done && created) fs::remove(out, e);
            }
        } cleanup{stage, out_dir, created};

        progress.message("generating " + std::to_string(p.size[0]) + " x " + std::to_string(p.size[1]) + " x " +
                         std::to_string(p.size[2]) + " voxels");
        tools::Timings& timings = record.timings;
        const phantom::PhantomResult r = timings.time("generate", [&] { return phantom::generate_phantom(p); });
        io::MetaImageWriteParams wp;
        wp.compress = compress;
        timings.time("write images", [&] {
            io::write_metaimage(stage / "ct.mhd", r.ct, wp);
            io::write_metaimage(stage / "labels.mhd", r.labels, wp);
        });
        if (!png_dir.empty()) {
            progress.message("writing pictures into " + png_dir.string());
            timings.time("write pictures", [&] { write_pictures(png_dir, r, png_pixel_mm); });
        }
        tools::write_file_atomically(stage / "truth.json", phantom::truth_json(p, r, io::join_command_line(argc, argv), timings).dump(2) + "\n");
        // The pipeline's first container: CT, ground-truth labels with their names, provenance.
        timings.time("write container", [&] {
            io::Hdf5Writer h5(stage / "phantom.h5");
            h5.write_image("ct", r.ct);
            io::LabelTable table;
            for (const auto& l : phantom::label_table())
                table.push_back({l.label, l.name});
            h5.write_labels("truth", r.labels, table);
            h5.write_provenance(record.provenance());
            h5.commit();
        });
        for (const auto& e : fs::directory_iterator(stage))
            tools::move_file(e.path(), out_dir / e.path().filename());
        cleanup.done = true;
        std::ostringstream msg;
        msg << std::fixed << std::setprecision(1) << "wrote " << (out_dir / "ct.mhd").string()
            << ", labels.mhd, truth.json, phantom.h5; liver " << r.truth.liver_volume_ml << " mL; generated in "
            << timings.entries().front().second << " s";
        progress.message(msg.str());
        return tools::kExitOk;
    });
}
