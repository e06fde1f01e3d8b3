#include "lseg/structures.h"

#include "common/picture.h"
#include "lseg/input.h"
#include "lseg/shape_file.h"

#include "lobe/core/any_image.h"
#include "lobe/seg/liver.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <iomanip>
#include <map>
#include <memory>
#include <sstream>

namespace lobe::lseg {
namespace fs = std::filesystem;

std::string fixed(double v, int digits)
{
    std::ostringstream s;
    s << std::fixed << std::setprecision(digits) << v;
    return s.str();
}

void add_liver_options(CLI::App* cmd, LiverSource& source)
{
    cmd->add_option("--liver", source.liver,
                    "Liver mask on the image's grid (MetaImage, NIfTI, or a .h5 from `lseg liver`); without it an .h5 "
                    "input's labels/liver is used, else the automatic liver pipeline runs");
    cmd->add_option("--liver-name", source.liver_name, "Label volume of a .h5 --liver (or input) holding the liver")
        ->capture_default_str();
    cmd->add_option("--liver-label", source.liver_labels,
                    "Values of --liver counted as liver, comma separated (default: every non-zero value; 1,2,3,4 "
                    "for lphantom's labels.mhd)")
        ->delimiter(',');
    cmd->add_option("--shape", source.shape, "Shape memory (`lseg train`) for the automatic liver pipeline");
    cmd->add_option_function<std::string>(
           "--modality", [&source](const std::string& m) { source.force_ct = m == "ct"; },
           "auto: refuse a volume that reads as MR (under 0.1 % of its voxels below -500), since the vessel and "
           "tumour finders are calibrated for contrast CT in HU | ct: run them on it anyway")
        ->check(CLI::IsMember({"auto", "ct"}))
        ->default_str("auto");
}

namespace {

core::LabelImage3D mask_of(const core::AnyImage& image, const std::vector<long long>& labels)
{
    return std::visit(
        [&](const auto& im) {
            core::LabelImage3D m(im.geometry(), 0);
            for (std::size_t i = 0; i < im.data.size(); ++i) {
                const auto v = static_cast<double>(im.data[i]);
                bool on = labels.empty() && v != 0 && !std::isnan(v);
                for (long long l : labels)
                    on = on || v == static_cast<double>(l);
                m.data[i] = on ? 1 : 0;
            }
            return m;
        },
        image);
}

bool has_item(const io::Hdf5Reader& h5, const std::string& name)
{
    const auto labels = h5.labels();
    return std::find(labels.begin(), labels.end(), name) != labels.end();
}

} // namespace

bool has_labels(const fs::path& path, const std::string& name)
{
    return io::image_format(path) == io::ImageFormat::Hdf5 && has_item(io::Hdf5Reader(path), name);
}

core::LabelImage3D read_mask(const fs::path& path, const std::string& h5_name, const core::ImageGeometry& image,
                             const std::string& what)
{
    const std::string item = io::image_format(path) == io::ImageFormat::Hdf5 ? "labels/" + h5_name : "";
    core::LabelImage3D m = mask_of(read_any(path, item), {});
    if (!core::same_grid(m, image))
        throw core::InvalidInputError(path.string() + ": the " + what + " mask is not on the image's grid");
    return m;
}

core::Vec3 parse_point(const std::string& text)
{
    core::Vec3 p;
    char c1 = 0, c2 = 0;
    std::istringstream s(text);
    if (!(s >> p.x >> c1 >> p.y >> c2 >> p.z) || c1 != ',' || c2 != ',' || !s.eof() || !std::isfinite(p.x) ||
        !std::isfinite(p.y) || !std::isfinite(p.z))
        throw CLI::ValidationError("--seed", "'" + text + "' is not a point x,y,z in mm");
    return p;
}

std::vector<core::Vec3> parse_points(const std::vector<std::string>& texts)
{
    std::vector<core::Vec3> points;
    for (const auto& t : texts)
        points.push_back(parse_point(t));
    return points;
}

StructureInput read_structure_input(const fs::path& image, const std::string& image_name, const LiverSource& source,
                                    const tools::Progress& progress, tools::Timings& timings)
{
    StructureInput in;
    in.h5_input = io::image_format(image) == io::ImageFormat::Hdf5;
    in.source = timings.time("read image", [&] { return read_any(image, in.h5_input ? image_name : ""); });
    in.volume = core::convert_image<float>(in.source);
    // An MR has no HU: the finders' contrast and fluid thresholds would mean nothing on it.
    if (!source.force_ct && seg::detect_modality(in.volume) == seg::Modality::Mr)
        throw core::InvalidInputError(image.string() +
                                      ": reads as MR (fewer than 0.1 % of its voxels below -500 HU); the vessel and "
                                      "tumour finders are calibrated for contrast-enhanced CT in HU (give --modality "
                                      "ct to run them on it anyway)");
    in.liver = obtain_liver(image, in.volume, source, progress, timings, in.liver_from);
    progress.message("liver mask: " + in.liver_from);
    return in;
}

core::LabelImage3D obtain_liver(const fs::path& image_path, const core::ImageF& image, const LiverSource& source,
                                const tools::Progress& progress, tools::Timings& timings, std::string& how)
{
    fs::path from = source.liver;
    if (from.empty() && io::image_format(image_path) == io::ImageFormat::Hdf5 &&
        has_item(io::Hdf5Reader(image_path), source.liver_name))
        from = image_path;
    if (!from.empty()) {
        const std::string item = io::image_format(from) == io::ImageFormat::Hdf5 ? "labels/" + source.liver_name : "";
        core::LabelImage3D m = timings.time("read liver", [&] { return mask_of(read_any(from, item), source.liver_labels); });
        if (!core::same_grid(m, image))
            throw core::InvalidInputError(from.string() + ": the liver mask is not on the grid of " + image_path.string());
        if (std::none_of(m.data.begin(), m.data.end(), [](std::uint8_t v) { return v != 0; }))
            throw core::InvalidInputError(from.string() + ": the liver mask is empty" +
                                          (source.liver_labels.empty() ? "" : " (no voxel has the --liver-label values)"));
        how = from == image_path ? "labels/" + source.liver_name + " of the input" : from.string();
        return m;
    }
    std::unique_ptr<seg::ShapeMemory> memory;
    if (!source.shape.empty())
        memory = std::make_unique<seg::ShapeMemory>(timings.time("read shape memory", [&] { return read_shape_memory(source.shape); }));
    progress.message("no liver mask given: running the automatic liver pipeline");
    seg::LiverResult r;
    try {
        r = timings.time("liver", [&] {
            return seg::segment_liver(image, {}, memory.get(), [&](const std::string& s) { progress.message(s); });
        });
    } catch (const core::InvalidInputError& e) {
        throw core::InvalidInputError(image_path.string() + ": " + e.what());
    }
    progress.message("liver: " + fixed(r.volume_ml, 1) + " mL");
    how = "automatic (lseg liver)";
    return r.mask;
}

const io::LabelTable& tissue_table()
{
    static const io::LabelTable t{{1, "liver"}, {2, "portal_vein"}, {3, "hepatic_veins"}, {4, "tumour"}};
    return t;
}

void add_vessel_provenance(io::Provenance& prov, const seg::VesselResult& r)
{
    auto param = [&](const std::string& k, const std::string& v) { prov.parameters.emplace_back("vessels." + k, v); };
    param("found", r.found ? "true" : "false");
    param("message", r.message);
    param("parenchyma", fixed(r.parenchyma, 2));
    param("parenchyma_sigma", fixed(r.parenchyma_sigma, 2));
    param("vessel_intensity", fixed(r.vessel_intensity, 2));
    param("contrast", fixed(r.contrast, 2));
    param("seed_voxels", std::to_string(r.seed_voxels));
    param("portal_ml", fixed(r.portal_ml, 3));
    param("hepatic_ml", fixed(r.hepatic_ml, 3));
    param("trees", std::to_string(r.trees.size()));
    param("segments", std::to_string(r.graph.edges.size()));
    int levels = 0;
    for (const auto& e : r.graph.edges)
        levels = std::max(levels, static_cast<int>(e.level));
    param("branch_levels", std::to_string(levels));
    param("separated_by", r.found ? (r.separated_by_contrast ? "contrast" : "anatomy") : "");
    param("gaps_bridged", std::to_string(r.bridges));
    param("tree_contacts_cut", std::to_string(r.trees_cut));
    for (std::size_t t = 0; t < r.trees.size(); ++t) {
        const auto& tr = r.trees[t];
        param("tree" + std::to_string(t), std::string(tr.label == seg::kPortalVeinLabel ? "portal" : "hepatic") +
                                              (tr.name.empty() ? "" : " " + tr.name) + ", " + fixed(tr.centreline_mm, 1) +
                                              " mm of centre line, " + std::to_string(tr.edges) + " segments, " +
                                              std::to_string(tr.max_level) + " levels, mean " +
                                              fixed(tr.mean_intensity, 1));
    }
    for (const auto& [name, seconds] : r.timings)
        prov.timings.emplace_back("vessels." + name, seconds);
}

void add_tumour_provenance(io::Provenance& prov, const seg::TumourResult& r)
{
    auto param = [&](const std::string& k, const std::string& v) { prov.parameters.emplace_back("tumours." + k, v); };
    param("found", r.found ? "true" : "false");
    param("message", r.message);
    param("parenchyma", fixed(r.parenchyma, 2));
    param("parenchyma_sigma", fixed(r.parenchyma_sigma, 2));
    param("threshold", fixed(r.threshold, 2));
    std::string centres;
    for (double c : r.layer_centres)
        centres += (centres.empty() ? "" : ",") + fixed(c, 1);
    param("layer_centres", centres);
    param("count", std::to_string(r.tumours.size()));
    double total = 0;
    for (std::size_t t = 0; t < r.tumours.size(); ++t) {
        const auto& tr = r.tumours[t];
        total += tr.volume_ml;
        param("tumour" + std::to_string(t), fixed(tr.volume_ml, 3) + " mL at (" + fixed(tr.centroid.x, 1) + ", " +
                                                fixed(tr.centroid.y, 1) + ", " + fixed(tr.centroid.z, 1) + ") mm, contrast " +
                                                fixed(tr.contrast, 1) + (tr.touches_surface ? ", at the surface" : "") +
                                                (tr.from_seed ? ", from a seed" : ""));
    }
    param("volume_ml", fixed(total, 3));
    for (const auto& [name, seconds] : r.timings)
        prov.timings.emplace_back("tumours." + name, seconds);
}

void write_tumour_pictures(const fs::path& dir, const std::string& prefix, const core::ImageF& image,
                           const core::LabelImage3D& liver, const seg::TumourResult& r)
{
    fs::create_directories(dir);
    tools::Overlay ov;
    ov.labels = &r.mask;
    ov.fill_opacity = 0.25;
    ov.contour_px = 2;
    ov.colours = {{seg::kTumourLabel, {255, 235, 0}, "tumour"}};
    tools::Overlay lov;
    lov.labels = &liver;
    lov.fill_opacity = 0.0;
    lov.colours = {{1, {214, 128, 52}, "liver"}};
    const int a = tools::slice_voxel_axis(image, tools::SliceAxis::Axial); // the stack's axis for z
    for (std::size_t t = 0; t < r.tumours.size() && t < 3; ++t) {
        const core::Vec3 c = image.physical_to_index(r.tumours[t].centroid);
        tools::PictureParams pp;
        pp.index = std::clamp(tools::patient_round(image, a, c[a]), 0, image.size[static_cast<std::size_t>(a)] - 1);
        pp.caption = "lseg tumours: " + fixed(r.tumours[t].volume_ml, 2) + " mL, " + fixed(r.tumours[t].contrast, 0) +
                     " HU against the parenchyma" + (r.tumours[t].touches_surface ? ", at the surface" : "");
        tools::write_slice_png(dir / (prefix + "-" + std::to_string(t + 1) + ".png"), image, pp, {lov, ov});
    }
}

void write_vessel_pictures(const fs::path& dir, const std::string& prefix, const core::ImageF& image,
                           const core::LabelImage3D& liver, const seg::VesselResult& r)
{
    fs::create_directories(dir);
    // The views follow the patient's axes whatever the stored orientation: the axial view cuts
    // voxel axis `ax`, the coronal view (and the tree's projection) voxel axis `co`; `rest` is the third.
    const int ax = tools::slice_voxel_axis(image, tools::SliceAxis::Axial);
    const int co = tools::slice_voxel_axis(image, tools::SliceAxis::Coronal);
    const int rest = 3 - ax - co;
    const auto n_of = [&image](int a) { return image.size[static_cast<std::size_t>(a)]; };
    // Where the vessels are: the axial slice holding most of them, and their centroid.
    const tools::LabelViews at = tools::label_views(r.labels, 1, 1);
    tools::Overlay ov;
    ov.labels = &r.labels;
    ov.fill_opacity = 0.55;
    ov.colours = {{2, {170, 70, 255}, "portal vein"}, {3, {40, 140, 255}, "hepatic veins"}};
    tools::Overlay lov;
    lov.labels = &liver;
    lov.fill_opacity = 0.0;
    lov.colours = {{1, {214, 128, 52}, "liver"}};
    const std::string caption = "lseg vessels: portal " + fixed(r.portal_ml, 1) + " mL, hepatic " + fixed(r.hepatic_ml, 1) + " mL";
    const std::pair<tools::SliceAxis, int> views[] = {{tools::SliceAxis::Axial, at.axial}, {tools::SliceAxis::Coronal, at.coronal}};
    for (const auto& [axis, index] : views) {
        tools::PictureParams pp;
        pp.axis = axis;
        pp.index = index;
        pp.caption = caption;
        tools::write_slice_png(dir / (prefix + "-" + tools::slice_axis_name(axis) + ".png"), image, pp, {lov, ov});
    }

    // The tree: a coronal maximum-intensity projection of the liver (along voxel axis `co`) with
    // the centre lines drawn in the colour of their branch level.
    core::ImageGeometry g = image.geometry();
    g.size[static_cast<std::size_t>(co)] = 1;
    core::ImageF mip(g, -1000.f);
    core::LabelImage3D lines(g, 0);
    const auto flat = [co](int i, int j, int k) {
        std::array<int, 3> q{i, j, k};
        q[static_cast<std::size_t>(co)] = 0;
        return q;
    };
    for (int k = 0; k < image.size[2]; ++k)
        for (int j = 0; j < image.size[1]; ++j)
            for (int i = 0; i < image.size[0]; ++i)
                if (liver.at(i, j, k)) {
                    const auto q = flat(i, j, k);
                    mip.at(q[0], q[1], q[2]) = std::max(mip.at(q[0], q[1], q[2]), image.at(i, j, k));
                }
    const std::array<bool, 3> backwards{tools::axis_runs_backwards(image, 0), tools::axis_runs_backwards(image, 1),
                                        tools::axis_runs_backwards(image, 2)};
    for (const auto& e : r.graph.edges)
        for (std::size_t p = 0; p + 1 < e.points.size(); ++p) {
            const core::Vec3 a = image.physical_to_index(e.points[p]), b = image.physical_to_index(e.points[p + 1]);
            const int steps = 1 + static_cast<int>(std::ceil(std::max(std::abs(b[ax] - a[ax]), std::abs(b[rest] - a[rest]))));
            for (int s = 0; s <= steps; ++s) {
                const double t = double(s) / steps;
                std::array<int, 3> q{0, 0, 0};
                for (int d : {ax, rest})
                    q[static_cast<std::size_t>(d)] = tools::patient_round(backwards[static_cast<std::size_t>(d)],
                                                                          n_of(d), a[d] + (b[d] - a[d]) * t);
                if (q[static_cast<std::size_t>(ax)] >= 0 && q[static_cast<std::size_t>(ax)] < n_of(ax) &&
                    q[static_cast<std::size_t>(rest)] >= 0 && q[static_cast<std::size_t>(rest)] < n_of(rest))
                    lines.at(q[0], q[1], q[2]) = static_cast<std::uint8_t>(std::clamp(static_cast<int>(e.level), 1, 5));
            }
        }
    tools::Overlay tov;
    tov.labels = &lines;
    tov.fill_opacity = 1.0;
    tov.contour_px = 0;
    tov.colours = {{1, {230, 40, 40}, "level 1 (trunks)"},
                   {2, {255, 150, 0}, "level 2"},
                   {3, {60, 200, 60}, "level 3"},
                   {4, {0, 200, 230}, "level 4"},
                   {5, {230, 0, 230}, "level 5+"}};
    tools::PictureParams pp;
    pp.axis = tools::SliceAxis::Coronal;
    pp.index = 0;
    pp.auto_caption = false;
    pp.window = 250; // the projection holds the brightest liver voxels: vessels over parenchyma
    pp.level = 120;
    pp.pixel_mm = 0.5;
    pp.max_side_px = 1200;
    // Crop to the liver, 5 mm around it.
    core::Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    for (int k = 0; k < mip.size[2]; ++k)
        for (int j = 0; j < mip.size[1]; ++j)
            for (int i = 0; i < mip.size[0]; ++i) {
                if (!(mip.at(i, j, k) > -1000.f))
                    continue;
                std::array<int, 3> far{i, j, k};
                far[static_cast<std::size_t>(co)] = n_of(co) - 1;
                for (const core::Vec3& q : {image.index_to_physical(i, j, k), image.index_to_physical(far[0], far[1], far[2])})
                    for (int d = 0; d < 3; ++d) {
                        lo[d] = std::min(lo[d], q[d] - 5);
                        hi[d] = std::max(hi[d], q[d] + 5);
                    }
            }
    if (lo.x < hi.x) {
        pp.roi_lo = lo;
        pp.roi_hi = hi;
    }
    pp.caption = "lseg vessels: centre lines by branch level over a coronal MIP of the liver";
    tools::write_slice_png(dir / (prefix + "-tree.png"), mip, pp, {tov});
}

std::string wrote_message(const std::filesystem::path& out, const std::filesystem::path& labels_out,
                          const std::filesystem::path& png_dir)
{
    return "wrote " + out.string() + (labels_out.empty() ? "" : ", " + labels_out.string()) +
           (png_dir.empty() ? "" : ", pictures in " + png_dir.string());
}

} // namespace lobe::lseg
