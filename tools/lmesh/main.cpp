// lmesh: label volume -> multi-tissue tetrahedral mesh, tissue surfaces and quality report.
#include "common/cli.h"
#include "common/files.h"
#include "lmesh/input.h"
#include "lmesh/pictures.h"
#include "lmesh/report.h"

#include "lobe/core/errors.h"
#include "lobe/io/hdf5.h"
#include "lobe/io/surface.h"
#include "lobe/mesh/quality.h"
#include "lobe/mesh/surface.h"
#include "lobe/mesh/tetrahedralize.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>

using namespace lobe;
namespace fs = std::filesystem;

namespace {

struct Options {
    fs::path input, output, png_dir, report, export_dir;
    std::string labels_name, mesh_name = "liver", export_format = "stl";
    std::vector<int> tissues;
    std::vector<std::string> tissue_sizes, tissue_distances;
    std::vector<double> roi, roi_box;
    double roi_size = 0;
    bool perturb = false, no_exude = false, no_peel = false, no_repair = false, no_improve = false, no_slivers = false;
    int smooth = 10;
    mesh::MeshParams params;
};

// "L:MM" -> (label, size).
mesh::TissueSize parse_tissue_size(const std::string& s, const std::string& option)
{
    const auto colon = s.find(':');
    try {
        if (colon == std::string::npos)
            throw std::invalid_argument("no colon");
        return {std::stoi(s.substr(0, colon)), std::stod(s.substr(colon + 1))};
    } catch (const std::exception&) {
        throw CLI::ValidationError(option, "expected LABEL:MM, got '" + s + "'");
    }
}

std::string clean_name(std::string s)
{
    for (auto& c : s)
        if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '-' && c != '.')
            c = '_';
    return s;
}

std::string fixed(double v, int digits = 1)
{
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", digits, v);
    return buf;
}

int run(Options& o, const tools::Progress& progress, tools::RunRecord& record)
{
    auto& timings = record.timings;
    auto& p = o.params;
    p.tissues = o.tissues;
    for (const auto& s : o.tissue_sizes)
        p.tissue_sizes.push_back(parse_tissue_size(s, "--tissue-size"));
    for (const auto& s : o.tissue_distances) {
        const auto d = parse_tissue_size(s, "--tissue-distance");
        auto it = std::find_if(p.tissue_sizes.begin(), p.tissue_sizes.end(), [&](const auto& t) { return t.label == d.label; });
        if (it == p.tissue_sizes.end())
            p.tissue_sizes.push_back({d.label, 0, d.size});
        else
            it->facet_distance = d.size;
    }
    if (!o.roi.empty()) {
        p.roi.kind = mesh::RegionOfInterest::Kind::Spheres;
        p.roi.centres = {{o.roi[0], o.roi[1], o.roi[2]}};
        p.roi.radius = o.roi[3];
    } else if (!o.roi_box.empty()) {
        p.roi.kind = mesh::RegionOfInterest::Kind::Box;
        p.roi.box_lo = {o.roi_box[0], o.roi_box[1], o.roi_box[2]};
        p.roi.box_hi = {o.roi_box[3], o.roi_box[4], o.roi_box[5]};
    }
    p.roi.size = o.roi_size;
    p.perturb = o.perturb;
    p.exude = !o.no_exude;
    p.peel_slivers = !o.no_peel;
    p.repair_manifold = !o.no_repair;
    p.improve.enabled = !o.no_improve;
    p.slivers.enabled = !o.no_slivers;
    p.progress = [&](const std::string& s) { progress.message(s); };

    const auto t0 = std::chrono::steady_clock::now();
    const lmesh::LabelInput in = timings.time("read", [&] { return lmesh::read_label_input(o.input, o.labels_name); });
    progress.message("meshing " + o.input.string() + (in.from_container ? " /labels/" + in.name : "") + ": " +
                     std::to_string(in.labels.size[0]) + " x " + std::to_string(in.labels.size[1]) + " x " +
                     std::to_string(in.labels.size[2]) + " voxels");
    mesh::MeshResult res;
    try {
        res = timings.time("mesh", [&] { return mesh::mesh_labels(in.labels, p); });
    } catch (const core::InvalidInputError& e) {
        throw core::InvalidInputError(o.input.string() + ": " + e.what());
    }
    for (const auto& w : res.warnings)
        progress.message("warning: " + w);
    const mesh::MeshQuality q = timings.time("quality", [&] { return mesh::evaluate_quality(res.mesh); });
    std::vector<std::pair<int, std::string>> names;
    for (const auto& t : res.tissues)
        names.emplace_back(t.label, clean_name(lmesh::tissue_name(in.table, t.label)));
    std::vector<mesh::TissueSurface> surfaces;
    lmesh::Report report;
    timings.time("surfaces", [&] {
        surfaces = mesh::tissue_surfaces(res.mesh);
        for (const auto& s : surfaces) {
            std::string name = "outer";
            for (const auto& [l, n] : names)
                if (l == s.label)
                    name = n;
            report.surfaces.push_back({s.label, name, mesh::check_surface(s.surface)});
        }
    });
    report.input = o.input.string();
    report.result = &res;
    report.quality = &q;
    report.names = names;
    report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    timings.time("write", [&] {
        io::Provenance prov = record.provenance();
        auto param = [&](const std::string& k, const std::string& v) { prov.parameters.emplace_back(k, v); };
        param("result.tets", std::to_string(res.mesh.tets.size()));
        param("result.vertices", std::to_string(res.mesh.vertices.size()));
        param("result.element_size_mm", fixed(res.size, 3));
        param("result.threads", std::to_string(res.threads));
        param("result.padded", res.padded ? "true" : "false");
        param("result.min_dihedral_deg", fixed(q.all.min_dihedral_deg, 2));
        param("result.min_combined", fixed(q.all.measures[static_cast<int>(mesh::Measure::Combined)].min, 4));
        for (const auto& t : res.tissues) {
            const std::string k = "result." + clean_name(lmesh::tissue_name(in.table, t.label));
            param(k + ".label_volume_mm3", fixed(t.label_volume));
            param(k + ".mesh_volume_mm3", fixed(t.mesh_volume));
            param(k + ".tets", std::to_string(t.tets));
            param(k + ".pieces_meshed", std::to_string(t.components_meshed) + "/" + std::to_string(t.components));
        }
        if (const auto& sl = res.slivers; sl.ran) {
            // The sliver pass runs inside "mesh"; its own time and outcome.
            param("result.slivers.seconds", fixed(sl.seconds, 3));
            param("result.slivers.below_goal_before", std::to_string(sl.below_before));
            param("result.slivers.below_goal_after", std::to_string(sl.below_after));
            param("result.slivers.min_dihedral_before_deg", fixed(sl.worst_before, 2));
            param("result.slivers.min_dihedral_after_deg", fixed(sl.worst_after, 2));
            param("result.slivers.changes", std::to_string(sl.flips23 + sl.edge_removals + sl.vertex_moves +
                                                           sl.vertices_inserted + sl.interface_flips + sl.surface_moves));
            param("result.slivers.interface_flips", std::to_string(sl.interface_flips));
            param("result.slivers.interface_flip_volume_mm3", fixed(sl.interface_flip_volume, 4));
            param("result.slivers.surface_moves", std::to_string(sl.surface_moves));
            param("result.slivers.surface_move_volume_mm3", fixed(sl.surface_move_volume, 4));
        }
        if (const auto& im = res.improvement; im.ran) {
            param("result.improve.interface_flips", std::to_string(im.interface_flips));
            param("result.improve.surface_moves", std::to_string(im.surface_moves));
            // The ROI quality pass runs inside "mesh"; its own time and outcome.
            param("result.improve.seconds", fixed(im.seconds, 3));
            param("result.improve.rounds", std::to_string(im.rounds));
            param("result.improve.flips23", std::to_string(im.flips23));
            param("result.improve.edge_removals", std::to_string(im.edge_removals));
            param("result.improve.vertex_moves", std::to_string(im.vertex_moves));
            param("result.improve.roi_tets", std::to_string(im.tets_in_region_after));
            param("result.improve.roi_below_0.3_before", std::to_string(im.below_before));
            param("result.improve.roi_below_0.3_after", std::to_string(im.below_after));
            param("result.improve.roi_below_0.3_after_on_surfaces", std::to_string(im.below_after_pinned));
            param("result.improve.vertices_inserted", std::to_string(im.vertices_inserted));
            param("result.improve.roi_min_combined_before", fixed(im.worst_before, 4));
            param("result.improve.roi_min_combined_after", fixed(im.worst_after, 4));
        }
        param("result.warnings", std::to_string(res.warnings.size()));
        std::vector<io::ElementArray> arrays;
        for (int i = 0; i < mesh::kMeasureCount; ++i)
            arrays.push_back({mesh::measure_name(static_cast<mesh::Measure>(i)), q.per_tet[static_cast<std::size_t>(i)], ""});
        arrays.push_back({"min_dihedral_angle", q.min_dihedral_deg, "degree"});
        arrays.push_back({"max_dihedral_angle", q.max_dihedral_deg, "degree"});
        arrays.push_back({"radius_edge_ratio", q.radius_edge_ratio, ""});
        io::LabelTable table;
        for (const auto& [l, n] : names)
            table.push_back({l, n});
        io::Hdf5Writer h5(o.output);
        if (in.from_container)
            h5.copy_provenance(io::Hdf5Reader(o.input));
        h5.write_labels(clean_name(in.name), in.labels, in.table);
        h5.write_tet_mesh(o.mesh_name, res.mesh, arrays, table);
        for (std::size_t i = 0; i < surfaces.size(); ++i)
            h5.write_surface(report.surfaces[i].name, surfaces[i].surface);
        h5.write_provenance(prov);
        h5.commit();
        if (!o.report.empty()) {
            tools::write_file_atomically(o.report, lmesh::report_json(report).dump(2) + "\n");
            fs::path txt = o.report;
            txt.replace_extension(".txt");
            tools::write_file_atomically(txt, lmesh::report_text(report));
        }
        if (!o.export_dir.empty()) {
            fs::create_directories(o.export_dir);
            for (std::size_t i = 0; i < surfaces.size(); ++i) {
                mesh::TaubinParams tp;
                tp.iterations = o.smooth;
                io::write_surface(o.export_dir / (report.surfaces[i].name + "." + o.export_format),
                                  mesh::taubin_smooth(surfaces[i].surface, tp));
            }
        }
    });
    if (!o.png_dir.empty()) {
        timings.time("pictures", [&] {
            core::Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
            for (const auto& v : res.mesh.vertices)
                for (int a = 0; a < 3; ++a) {
                    lo[a] = std::min(lo[a], v[a]);
                    hi[a] = std::max(hi[a], v[a]);
                }
            core::Vec3 centre = (lo + hi) / 2;
            if (!o.roi.empty())
                centre = {o.roi[0], o.roi[1], o.roi[2]};
            else if (!o.roi_box.empty())
                centre = core::Vec3{o.roi_box[0] + o.roi_box[3], o.roi_box[1] + o.roi_box[4], o.roi_box[2] + o.roi_box[5]} / 2;
            lmesh::write_mesh_pictures(o.png_dir, res.mesh, q, centre, names);
        });
    }
    if (!progress.quiet())
        std::fputs(lmesh::report_text(report).c_str(), stderr);
    progress.message("wrote " + o.output.string() + (o.report.empty() ? "" : ", " + o.report.string()) +
                     (o.png_dir.empty() ? "" : ", pictures in " + o.png_dir.string()));
    return tools::kExitOk;
}

} // namespace

int main(int argc, char** argv)
{
    CLI::App app{"lmesh: multi-tissue tetrahedral mesh (CGAL Mesh_3), tissue surfaces and element quality "
                 "from a label volume (docs/algorithms/meshing.md, docs/algorithms/mesh_quality.md)",
                 "lmesh"};
    bool quiet = false;
    tools::add_common_options(app, quiet);
    Options o;
    auto& p = o.params;
    app.add_option("INPUT", o.input, "Label volume: a lobe .h5 (see --labels) or a label image (.mhd, .nii.gz, .inr.gz)")
        ->required()
        ->check(CLI::ExistingPath);
    app.add_option("-o,--output", o.output, "Output container (.h5): labels, /meshes/NAME with quality, /surfaces/TISSUE")
        ->required();
    app.add_option("--labels", o.labels_name, "Label volume to read from a .h5 input (default: its only one)");
    app.add_option("--name", o.mesh_name, "Name of the mesh in the output")->capture_default_str();
    app.add_option("--tissues", o.tissues, "Labels to mesh, e.g. 1,2,3,4 (default: every label 1-9 present)")
        ->delimiter(',');
    app.add_option("--size", p.size, "Element size [mm]: bound on tet circumradius and surface facet size (0 = 3 voxels)")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    app.add_option("--tissue-size", o.tissue_sizes, "Per-tissue size LABEL:MM, e.g. 2:1.5 (repeatable)")->delimiter(',');
    app.add_option("--tissue-distance", o.tissue_distances,
                   "Per-tissue boundary tolerance LABEL:MM (default: the smaller of the curvature factor's and "
                   "--distance-per-size x the tissue's size)")
        ->delimiter(',');
    app.add_option("--distance-per-size", p.distance_per_size,
                   "Default boundary tolerance of a tissue as a fraction of its element size")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    auto* roi = app.add_option("--roi", o.roi, "Region of interest: a ball x,y,z,r [mm] where the mesh is fine")
                    ->delimiter(',')
                    ->expected(4);
    auto* roi_box = app.add_option("--roi-box", o.roi_box, "Region of interest: a box x0,y0,z0,x1,y1,z1 [mm]")
                        ->delimiter(',')
                        ->expected(6);
    roi->excludes(roi_box);
    app.add_option("--roi-size", o.roi_size, "Element size inside the region of interest [mm] (0 = size / 3)")
        ->check(CLI::NonNegativeNumber);
    app.add_option("--curvature-factor", p.curvature_factor, "Boundary size / radius of curvature (thesis: 1.0)")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    app.add_option("--radius-edge", p.radius_edge_ratio, "Bound on tet circumradius / shortest edge")
        ->check(CLI::Range(1.0, 10.0))
        ->capture_default_str();
    app.add_option("--facet-angle", p.facet_angle, "Lower bound on surface facet angles [deg]")
        ->check(CLI::Range(1.0, 30.0))
        ->capture_default_str();
    app.add_option("--grading", p.grading, "Max size ratio between neighbours around the region of interest")
        ->check(CLI::Range(1.05, 4.0))
        ->capture_default_str();
    app.add_option("--sliver-bound", p.sliver_bound, "Perturb/exude target: smallest dihedral angle [deg]")
        ->check(CLI::Range(0.0, 30.0))
        ->capture_default_str();
    app.add_flag("--perturb", o.perturb,
                 "Run CGAL's sliver perturbation before the exuder (slow; the sliver pass does its work by default)");
    app.add_flag("--no-exude", o.no_exude, "Skip CGAL's sliver exudation");
    app.add_flag("--no-peel", o.no_peel, "Keep the flat tets on the outer boundary (see docs/algorithms/meshing.md)");
    app.add_flag("--no-repair", o.no_repair, "Keep tissues that touch themselves along an edge or at a vertex");
    app.add_flag("--no-improve", o.no_improve,
                 "Skip the quality improvement on the combined measure inside the region of interest (flips and "
                 "smoothing inside each tissue; runs only with --roi or --roi-box)");
    app.add_flag("--no-slivers", o.no_slivers,
                 "Skip the sliver pass after CGAL's optimisers (flips, smoothing and insertion on the tets whose "
                 "smallest dihedral angle is below --sliver-target)");
    app.add_option("--sliver-target", p.slivers.target,
                   "Smallest dihedral angle [deg] below which the sliver pass works on a tet (it aims for 10)")
        ->check(CLI::Range(10.0, 30.0))
        ->capture_default_str();
    app.add_option("--improve-target", p.improve.target,
                   "Combined measure below which the region of interest's tets are worked on")
        ->check(CLI::Range(0.0, 1.0))
        ->capture_default_str();
    app.add_flag("--lloyd", p.lloyd, "Lloyd smoothing before perturb/exude (slow)");
    app.add_flag("--odt", p.odt, "ODT smoothing before perturb/exude (slow)");
    app.add_option("--threads", p.threads, "Threads (0 = all cores, CGAL parallel mode; 1 = serial, repeatable)")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    app.add_option("--seed", p.seed, "Seed of CGAL's random generator")->capture_default_str();
    app.add_option("--max-tets", p.max_tets, "Refuse requests estimated above this many tets")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    app.add_option("--min-piece", p.min_component_voxels, "Pieces with fewer voxels are specks: relabelled and reported")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    app.add_option("--export", o.export_dir, "Also export each tissue surface (Taubin-smoothed) into this folder");
    app.add_option("--format", o.export_format, "Export format")
        ->check(CLI::IsMember({"stl", "obj", "ply", "gltf", "glb"}))
        ->capture_default_str();
    app.add_option("--smooth", o.smooth, "Taubin iterations for exported surfaces")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    app.add_option("--png", o.png_dir, "Write pictures (cuts by tissue and quality, histograms) into this folder");
    app.add_option("--report", o.report, "Write the quality report as JSON (and text beside it, .txt)");

    tools::RunRecord record(app, argc, argv);
    return tools::run_tool(app, argc, argv, [&] {
        const tools::Progress progress("lmesh", quiet);
        return run(o, progress, record);
    });
}
