// lseg eval SEG REF: Dice, Jaccard and the five SLIVER07 measures of a segmentation against a
// reference, with the SLIVER07 score (docs/algorithms/metrics.md).
#include "lseg/commands.h"

#include "lobe/io/hdf5.h"
#include "lobe/io/image_io.h"
#include "lobe/seg/metrics.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

namespace lobe::lseg {
namespace {

struct EvalOptions {
    std::string seg, ref;
    bool json = false;
    std::vector<long long> label, ref_label; //!< empty = every non-zero voxel
    int slice = -1;                          //!< compare axial slice K of any volume input
    std::string seg_name;                    //!< label volume of a SEG container with several
};

std::string label_text(const std::vector<long long>& labels)
{
    if (labels.empty())
        return "non-zero";
    std::string s = labels.size() == 1 ? "label " : "labels ";
    for (std::size_t i = 0; i < labels.size(); ++i)
        s += (i ? "," : "") + std::to_string(labels[i]);
    return s;
}

// One input: its file, which voxels are the object, and the mask.
struct Input {
    std::string path;
    std::vector<long long> labels;
    core::LabelImage3D mask;
    std::size_t voxels = 0;

    std::string selection() const { return label_text(labels); }
};


// The object voxels of an image of any pixel type, compared in the file's own type (a uint8
// conversion would saturate label 300 into 255). NaN is background.
core::LabelImage3D object_mask(const core::AnyImage& image, const std::vector<long long>& labels, std::size_t& voxels)
{
    return std::visit(
        [&](const auto& im) {
            core::LabelImage3D m;
            static_cast<core::ImageGeometry&>(m) = im;
            m.data.resize(im.data.size());
            voxels = 0;
            for (std::size_t i = 0; i < im.data.size(); ++i) {
                const auto v = static_cast<double>(im.data[i]);
                bool on = labels.empty() && v != 0 && !std::isnan(v);
                for (long long l : labels)
                    on = on || v == static_cast<double>(l);
                m.data[i] = on ? 1 : 0;
                voxels += on;
            }
            return m;
        },
        image);
}

// A container's label volume when it holds exactly one (lseg snake writes an image, the mask
// and phi); otherwise any image format through libio.
core::AnyImage read_input(const std::string& path, const std::string& name = {})
{
    if (io::image_format(path) == io::ImageFormat::Hdf5) {
        const io::Hdf5Reader h5(path);
        if (!name.empty())
            return h5.read_labels(name).image;
        if (h5.labels().size() == 1)
            return h5.read_labels(h5.labels().front()).image;
        return io::read_hdf5_image(path);
    }
    return io::read_image(path);
}

Input load(const std::string& path, const std::vector<long long>& labels, int slice, tools::Timings& timings,
           const tools::Progress& progress, const std::string& name = {})
{
    Input in{path, labels, {}, 0};
    core::AnyImage image = timings.time("read " + path, [&] { return read_input(path, name); });
    std::visit([&](const auto& im) { core::validate_geometry(im, path); }, image);
    if (slice >= 0)
        image = std::visit(
            [&](const auto& im) -> core::AnyImage {
                if (im.size[2] == 1)
                    return im; // already a slice
                try {
                    return core::axial_slice(im, slice);
                } catch (const core::InvalidInputError& e) {
                    throw core::InvalidInputError(path + ": " + e.what());
                }
            },
            image);
    in.mask = object_mask(image, labels, in.voxels);
    if (in.voxels == 0)
        throw core::InvalidInputError(path + ": the object is empty (no voxel is " + label_text(labels) +
                                      (slice >= 0 ? " in slice " + std::to_string(slice) : "") +
                                      "); nothing to evaluate");
    progress.message("read " + path + ": " + std::to_string(in.voxels) + " object voxels (" + in.selection() + ")");
    return in;
}

std::string geometry_text(const core::ImageGeometry& g)
{
    std::ostringstream s;
    s << g.size[0] << " x " << g.size[1] << " x " << g.size[2] << " voxels of " << g.spacing[0] << " x "
      << g.spacing[1] << " x " << g.spacing[2] << " mm at (" << g.origin[0] << ", " << g.origin[1] << ", "
      << g.origin[2] << ")";
    return s.str();
}

std::string fixed(double v, int digits)
{
    std::ostringstream s;
    s << std::fixed << std::setprecision(digits) << v;
    return s.str();
}

void print_table(const Input& seg, const Input& ref, const seg::SegmentationMeasures& m, const seg::SliverScore& s,
                 const seg::SliverReference& r)
{
    std::cout << "segmentation  " << seg.path << " (" << seg.selection() << "): " << seg.voxels << " voxels, "
              << fixed(m.volume_seg_ml, 2) << " mL, " << m.surface.border_voxels_seg << " border voxels\n"
              << "reference     " << ref.path << " (" << ref.selection() << "): " << ref.voxels << " voxels, "
              << fixed(m.volume_ref_ml, 2) << " mL, " << m.surface.border_voxels_ref << " border voxels\n\n";
    const auto row = [](const std::string& name, const std::string& value, const std::string& reference,
                        const std::string& score) {
        std::ostringstream line;
        line << std::left << std::setw(12) << name << std::right << std::setw(10) << value << std::setw(12)
             << reference << std::setw(8) << score;
        std::string text = line.str();
        text.erase(text.find_last_not_of(' ') + 1);
        std::cout << text << "\n";
    };
    row("measure", "value", "human ref", "score");
    row("Dice", fixed(m.dice, 4), "", "");
    row("Jaccard", fixed(m.jaccard, 4), "", "");
    row("VOE [%]", fixed(m.voe, 2), fixed(r.voe, 1), fixed(s.voe, 1));
    row("|RVD| [%]", fixed(m.abs_rvd, 2), fixed(r.abs_rvd, 1), fixed(s.abs_rvd, 1));
    row("ASD [mm]", fixed(m.surface.average, 2), fixed(r.asd, 1), fixed(s.asd, 1));
    row("RMSD [mm]", fixed(m.surface.rms, 2), fixed(r.rmsd, 1), fixed(s.rmsd, 1));
    row("MaxD [mm]", fixed(m.surface.maximum, 2), fixed(r.maxd, 1), fixed(s.maxd, 1));
    row("SLIVER07", "", "", fixed(s.total, 1));
    std::cout << "(signed RVD " << fixed(m.rvd, 2) << " %; a score of 75 is the average human second rater's)\n";
}

nlohmann::ordered_json to_json(const Input& seg, const Input& ref, const seg::SegmentationMeasures& m,
                               const seg::SliverScore& s, const seg::SliverReference& r)
{
    const auto input = [](const Input& in, double ml, std::size_t border) {
        return nlohmann::ordered_json{{"file", in.path},
                                      {"labels", in.labels.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(in.labels)},
                                      {"voxels", in.voxels},
                                      {"volume_ml", ml},
                                      {"border_voxels", border}};
    };
    nlohmann::ordered_json j;
    j["segmentation"] = input(seg, m.volume_seg_ml, m.surface.border_voxels_seg);
    j["reference"] = input(ref, m.volume_ref_ml, m.surface.border_voxels_ref);
    j["grid"] = {{"size", seg.mask.size}, {"spacing", seg.mask.spacing}};
    j["dice"] = m.dice;
    j["jaccard"] = m.jaccard;
    j["voe_percent"] = m.voe;
    j["rvd_percent"] = m.rvd;
    j["abs_rvd_percent"] = m.abs_rvd;
    j["asd_mm"] = m.surface.average;
    j["rmsd_mm"] = m.surface.rms;
    j["maxd_mm"] = m.surface.maximum;
    j["score"] = {{"voe", s.voe}, {"abs_rvd", s.abs_rvd}, {"asd", s.asd},
                  {"rmsd", s.rmsd}, {"maxd", s.maxd},       {"total", s.total}};
    j["human_reference"] = {{"voe_percent", r.voe}, {"abs_rvd_percent", r.abs_rvd}, {"asd_mm", r.asd},
                            {"rmsd_mm", r.rmsd},    {"maxd_mm", r.maxd},            {"source", "Heimann et al., IEEE TMI 2009"}};
    return j;
}

} // namespace

Command add_eval(CLI::App& lseg)
{
    auto o = std::make_shared<EvalOptions>();
    CLI::App* cmd = lseg.add_subcommand(
        "eval", "Compare a segmentation with a reference on the same grid: Dice, Jaccard, VOE, |RVD|, ASD, RMSD, "
                "MaxD and the SLIVER07 score (100 = perfect, 75 = an average human second rater)");
    cmd->add_option("SEG", o->seg, "Segmentation (.mhd, .mha, .nii, .nii.gz, .h5 or a DICOM folder)")->required();
    cmd->add_option("REF", o->ref, "Reference segmentation on the same grid")->required();
    cmd->add_flag("--json", o->json, "Machine-readable output");
    cmd->add_option("--seg-name", o->seg_name, "Label volume of a SEG container holding several (e.g. liver for "
                                               "lseg liver's output)");
    cmd->add_option("--label", o->label, "The object is this value (or these, comma-separated) in SEG "
                                         "[default: every non-zero voxel]")
        ->delimiter(',');
    cmd->add_option("--ref-label", o->ref_label, "The object is this value (or these, e.g. 1,2,3,4 for the "
                                                 "phantom's liver with its vessels and tumours) in REF [default: every non-zero voxel]")
        ->delimiter(',');
    cmd->add_option("--slice", o->slice, "Compare axial slice K of every input that is a volume (e.g. a 2-D "
                                         "lseg snake result against a reference volume)")
        ->check(CLI::NonNegativeNumber);
    return {cmd, [o](const tools::Progress& progress, tools::RunRecord& record) -> int {
                auto& timings = record.timings;
                const Input seg = load(o->seg, o->label, o->slice, timings, progress, o->seg_name);
                const Input ref = load(o->ref, o->ref_label, o->slice, timings, progress);
                if (!core::same_grid(seg.mask, ref.mask))
                    throw core::InvalidInputError(o->seg + " and " + o->ref +
                                                  " are not on the same grid: " + geometry_text(seg.mask) + " vs " +
                                                  geometry_text(ref.mask) + " (resample one onto the other first)");
                const auto m = timings.time("evaluate", [&] { return seg::evaluate_segmentation(seg.mask, ref.mask); });
                const seg::SliverReference reference;
                const seg::SliverScore score = seg::sliver_score(m, reference);
                progress.message("read and evaluated in " + fixed(timings.total(), 2) + " s");
                if (o->json)
                    std::cout << to_json(seg, ref, m, score, reference).dump(2) << "\n";
                else
                    print_table(seg, ref, m, score, reference);
                return static_cast<int>(tools::kExitOk);
            }};
}

} // namespace lobe::lseg
