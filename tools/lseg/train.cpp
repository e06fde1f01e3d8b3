// lseg train: builds the shape memory (docs/algorithms/shape_memory.md) from image/label pairs.
#include "lseg/commands.h"
#include "lseg/shape_file.h"

#include "lobe/io/image_io.h"
#include "lobe/seg/shape_memory.h"

#include <iomanip>
#include <memory>
#include <sstream>

namespace lobe::lseg {
namespace fs = std::filesystem;

namespace {

struct TrainOptions {
    std::vector<fs::path> images, labels;
    std::vector<long long> label_values; //!< empty = every non-zero voxel
    fs::path out;
    seg::ShapeTrainParams params;
};

core::LabelImage3D liver_mask(const fs::path& path, const std::vector<long long>& values)
{
    const auto img = core::convert_image<std::int32_t>(io::read_image(path));
    core::LabelImage3D m(img.geometry(), 0);
    std::size_t n = 0;
    for (std::size_t i = 0; i < m.data.size(); ++i) {
        bool in = img.data[i] != 0;
        if (!values.empty()) {
            in = false;
            for (long long v : values)
                in = in || img.data[i] == v;
        }
        m.data[i] = in ? 1 : 0;
        n += m.data[i];
    }
    if (n == 0) {
        std::string sel = "non-zero";
        if (!values.empty()) {
            sel = "label";
            for (std::size_t i = 0; i < values.size(); ++i)
                sel += (i ? "," : " ") + std::to_string(values[i]);
        }
        throw core::InvalidInputError(path.string() + ": no liver voxels (" + sel + ")");
    }
    return m;
}

int run_train(const TrainOptions& o, const tools::Progress& progress, tools::RunRecord& record)
{
    if (o.images.size() != o.labels.size())
        throw core::InvalidInputError("give one --labels per --image (" + std::to_string(o.images.size()) +
                                      " images, " + std::to_string(o.labels.size()) + " label volumes)");
    auto& timings = record.timings;
    std::vector<core::ImageF> images;
    std::vector<core::LabelImage3D> masks;
    for (std::size_t v = 0; v < o.images.size(); ++v) {
        images.push_back(timings.time("read " + std::to_string(v + 1), [&] {
            return core::convert_image<float>(io::read_image(o.images[v]));
        }));
        masks.push_back(liver_mask(o.labels[v], o.label_values));
        if (!core::same_grid(images.back(), masks.back()))
            throw core::InvalidInputError(o.labels[v].string() + ": not on the grid of " + o.images[v].string());
        progress.message("read " + o.images[v].filename().string() + " + " + o.labels[v].filename().string());
    }
    std::vector<const core::ImageF*> ip;
    std::vector<const core::LabelImage3D*> mp;
    for (std::size_t v = 0; v < images.size(); ++v) {
        ip.push_back(&images[v]);
        mp.push_back(&masks[v]);
    }
    const seg::ShapeMemory m = timings.time("train", [&] { return seg::train_shape_memory(ip, mp, o.params); });
    std::ostringstream msg;
    msg << std::fixed << std::setprecision(1) << m.volumes << " volumes, " << m.slices << " liver slices, "
        << m.transitions << " transitions; liver " << m.intensity.modality << " median " << m.intensity.quantiles[2]
        << " (IQR " << m.intensity.quantiles[1] << ".." << m.intensity.quantiles[3] << ")";
    progress.message(msg.str());
    timings.time("write", [&] {
        io::Provenance p = record.provenance();
        for (std::size_t v = 0; v < o.images.size(); ++v) {
            p.parameters.emplace_back("training." + std::to_string(v + 1) + ".image", o.images[v].string());
            p.parameters.emplace_back("training." + std::to_string(v + 1) + ".labels", o.labels[v].string());
        }
        write_shape_memory(o.out, m, p);
    });
    progress.message("wrote " + o.out.string());
    return tools::kExitOk;
}

} // namespace

Command add_train(CLI::App& lseg)
{
    auto o = std::make_shared<TrainOptions>();
    CLI::App* cmd = lseg.add_subcommand(
        "train", "Build the shape memory (slice-to-slice shape limits and liver intensity) from image/label "
                 "pairs (docs/algorithms/shape_memory.md)");
    cmd->add_option("--image", o->images, "Training image (repeat: one per --labels); any image format")
        ->required()
        ->check(CLI::ExistingPath);
    cmd->add_option("--labels", o->labels, "Label volume of the matching --image")->required()->check(CLI::ExistingPath);
    cmd->add_option("--label", o->label_values, "Label values that are liver (default: every non-zero voxel; "
                                                "the phantom: 1,2,3,4)")
        ->delimiter(',');
    cmd->add_option("-o,--output", o->out, "Shape memory file (.h5)")->required();
    cmd->add_option("--modality", o->params.modality, "Recorded with the intensity statistics")
        ->capture_default_str();
    cmd->add_option("--quantile", o->params.quantile, "Quantile of the per-bin rates (1 = maximum)")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 1.0));
    cmd->add_option("--margin", o->params.margin, "Tolerance factor on the learnt rates")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    return {cmd, [o](const tools::Progress& progress, tools::RunRecord& record) {
                return run_train(*o, progress, record);
            }};
}

} // namespace lobe::lseg
