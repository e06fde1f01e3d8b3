#include "lmesh/input.h"

#include "lobe/core/any_image.h"
#include "lobe/core/errors.h"
#include "lobe/io/image_io.h"

#include <cmath>
#include <variant>

namespace lobe::lmesh {

LabelInput read_label_input(const std::filesystem::path& path, const std::string& name)
{
    LabelInput in;
    if (io::image_format(path) == io::ImageFormat::Hdf5) {
        io::Hdf5Reader reader(path);
        std::string item = name;
        if (item.empty()) {
            const auto all = reader.labels();
            if (all.size() != 1) {
                std::string list;
                for (const auto& n : all)
                    list += (list.empty() ? "" : ", ") + n;
                throw core::InvalidInputError(path.string() + ": " +
                                              (all.empty() ? std::string("has no label volume (/labels)")
                                                           : "holds several label volumes (" + list + "); choose one with --labels"));
            }
            item = all[0];
        }
        auto lv = reader.read_labels(item);
        in.labels = std::move(lv.image);
        in.table = std::move(lv.table);
        in.name = item;
        in.from_container = true;
        return in;
    }
    const core::AnyImage img = io::read_image(path);
    // Labels must be whole numbers in 0..255: anything else is not a label image.
    std::visit(
        [&](const auto& im) {
            for (auto v : im.data) {
                const double d = static_cast<double>(v);
                if (!(d >= 0 && d <= 255 && std::floor(d) == d))
                    throw core::InvalidInputError(path.string() + ": not a label image (value " + std::to_string(d) +
                                                  " is not an integer label in 0..255)");
            }
        },
        img);
    in.labels = core::convert_image<std::uint8_t>(img);
    in.name = path.stem().string();
    if (in.name.size() > 4 && in.name.substr(in.name.size() - 4) == ".nii")
        in.name = in.name.substr(0, in.name.size() - 4);
    return in;
}

std::string tissue_name(const io::LabelTable& table, int label)
{
    for (const auto& e : table)
        if (e.value == label)
            return e.name;
    switch (label) {
    case 1: return "liver";
    case 2: return "portal_vein";
    case 3: return "hepatic_veins";
    case 4: return "tumour";
    default: return "tissue_" + std::to_string(label);
    }
}

} // namespace lobe::lmesh
