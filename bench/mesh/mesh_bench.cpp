// Meshing benchmark (issue 6): lobe's mesh_labels on CGAL's labelled liver (INRIMAGE) and on an
// lphantom volume, against Debian's tetgen on the same surfaces, in one run; one line per run,
// and optionally a CSV for the charts (bench/mesh/plot_mesh_bench.py). Results: docs/benchmarks.md.
//   mesh_bench [--liver LIVER.inr.gz] [--csv OUT.csv] [--no-sweep] [--roi-only]
//   (default liver: ../shared/data/liver-labels-inr/liver.inr.gz)
#include "tetgen_peer.h"

#include "lobe/mesh/quality.h"
#include "lobe/mesh/tetrahedralize.h"
#include "lobe/io/inrimage.h"
#include "lphantom/phantom.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

using namespace lobe;

namespace {

// The INRIMAGE's label values (0/85/127/255) to lobe tissues: the most frequent non-zero value
// is the liver (1), the others 2, 3 in increasing value.
core::LabelImage3D remap(core::LabelImage3D img, std::string& mapping)
{
    std::array<std::int64_t, 256> count{};
    for (auto v : img.data)
        ++count[v];
    std::vector<int> values;
    for (int v = 1; v < 256; ++v)
        if (count[static_cast<std::size_t>(v)] > 0)
            values.push_back(v);
    const int liver = *std::max_element(values.begin(), values.end(), [&](int a, int b) { return count[a] < count[b]; });
    std::array<std::uint8_t, 256> to{};
    to[static_cast<std::size_t>(liver)] = 1;
    std::uint8_t next = 2;
    for (int v : values)
        if (v != liver)
            to[static_cast<std::size_t>(v)] = next++;
    for (int v : values)
        mapping += std::to_string(v) + "->" + std::to_string(to[static_cast<std::size_t>(v)]) + "(" +
                   std::to_string(count[static_cast<std::size_t>(v)]) + " voxels) ";
    for (auto& v : img.data)
        v = to[v];
    return img;
}

// The centroid of label 1's voxels [mm]: the region of interest's centre.
core::Vec3 liver_centroid(const core::LabelImage3D& img)
{
    core::Vec3 sum;
    double n = 0;
    for (int k = 0; k < img.size[2]; ++k)
        for (int j = 0; j < img.size[1]; ++j)
            for (int i = 0; i < img.size[0]; ++i)
                if (img.at(i, j, k) == 1) {
                    sum += img.index_to_physical(i, j, k);
                    n += 1;
                }
    return sum / n;
}

struct Row {
    std::string scene, mesher, config;
    double k = 0; // resolution factor of the sweep (0: not in the sweep)
    int threads = 1;
    std::size_t tets = 0;
    double seconds = 0, min_dihedral = 0, combined_min = 0, combined_mean = 0, below = 0;
    std::size_t below_10deg = 0; // tets whose smallest dihedral angle is below 10 degrees
    double roi_below = -1; // % of the tets inside the region of interest below 0.3; -1: none
    std::size_t roi_tets = 0, roi_low = 0;      // tets inside the ROI, and of them below 0.3
    double roi_worst = 0, roi_min_dihedral = 0; // worst combined and smallest dihedral angle [deg] there
    double improve_seconds = -1; // the ROI quality pass's share of `seconds`; -1: did not run
    std::string volumes;   // label:ratio;...
};

std::vector<Row> rows;

void print(const Row& r)
{
    std::printf("%-8s %-20s %-38s thr %d: %8zu tets %7.2f s  dihedral >= %5.2f (%zu < 10)  combined min %.3f mean %.3f "
                "<0.3 %5.1f%%",
                r.scene.c_str(), r.mesher.c_str(), r.config.c_str(), r.threads, r.tets, r.seconds, r.min_dihedral,
                r.below_10deg, r.combined_min, r.combined_mean, r.below);
    if (r.roi_below >= 0)
        std::printf(" (ROI %.1f%% = %zu of %zu, worst %.3f, dihedral >= %.2f)", r.roi_below, r.roi_low, r.roi_tets,
                    r.roi_worst, r.roi_min_dihedral);
    if (r.improve_seconds >= 0)
        std::printf(" (improve %.2f s)", r.improve_seconds);
    std::printf("  volumes %s\n", r.volumes.c_str());
    std::fflush(stdout);
}

void fill_quality(Row& row, const core::TetMesh& m, const mesh::RegionOfInterest* roi)
{
    const auto q = mesh::evaluate_quality(m);
    const auto& comb = q.all.measures[static_cast<int>(mesh::Measure::Combined)];
    row.tets = m.tets.size();
    row.min_dihedral = q.all.min_dihedral_deg;
    row.below_10deg = static_cast<std::size_t>(
        std::count_if(q.min_dihedral_deg.begin(), q.min_dihedral_deg.end(), [](double a) { return a < 10; }));
    row.combined_min = comb.min;
    row.combined_mean = comb.mean;
    row.below = 100.0 * double(comb.bands[0]) / double(comb.count);
    if (roi && roi->kind == mesh::RegionOfInterest::Kind::Spheres) {
        const auto& per = q.per_tet[static_cast<int>(mesh::Measure::Combined)];
        std::size_t in = 0, low = 0;
        row.roi_worst = 1e300;
        row.roi_min_dihedral = 180;
        for (std::size_t t = 0; t < m.tets.size(); ++t) {
            const auto& c = m.tets[t];
            const core::Vec3 cen = (m.vertices[c[0]] + m.vertices[c[1]] + m.vertices[c[2]] + m.vertices[c[3]]) / 4;
            if (core::distance(cen, roi->centres[0]) <= roi->radius) {
                ++in;
                low += per[t] < 0.3;
                row.roi_worst = std::min(row.roi_worst, per[t]);
                row.roi_min_dihedral = std::min(row.roi_min_dihedral, q.min_dihedral_deg[t]);
            }
        }
        row.roi_below = in ? 100.0 * double(low) / double(in) : 0.0;
        row.roi_tets = in;
        row.roi_low = low;
    }
}

mesh::MeshResult run_lobe(const std::string& scene, const core::LabelImage3D& labels, const mesh::MeshParams& p,
                          const std::string& config, double k)
{
    const auto t0 = std::chrono::steady_clock::now();
    auto r = mesh::mesh_labels(labels, p);
    Row row;
    row.scene = scene;
    row.mesher = "lobe";
    row.config = config;
    row.k = k;
    row.threads = r.threads;
    row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    fill_quality(row, r.mesh, &p.roi);
    if (const auto& sl = r.slivers; sl.ran)
        std::printf("         sliver pass: %.2f s, below %.0f deg %lld -> %lld, worst %.2f -> %.2f deg; %lld 2-3 flips, %lld "
                    "edge removals, %lld interface flips (%.2f mm^3), %lld moves, %lld surface moves (%.2f mm^3), %lld "
                    "vertices inserted\n",
                    sl.seconds, sl.goal, static_cast<long long>(sl.below_before), static_cast<long long>(sl.below_after),
                    sl.worst_before, sl.worst_after, static_cast<long long>(sl.flips23),
                    static_cast<long long>(sl.edge_removals), static_cast<long long>(sl.interface_flips),
                    sl.interface_flip_volume, static_cast<long long>(sl.vertex_moves),
                    static_cast<long long>(sl.surface_moves), sl.surface_move_volume,
                    static_cast<long long>(sl.vertices_inserted));
    if (const auto& im = r.improvement; im.ran) {
        row.improve_seconds = im.seconds;
        std::printf("         ROI pass: below 0.3 %lld -> %lld (of which %lld with 4 vertices on surfaces, %lld with a face "
                    "on one), worst %.3f -> %.3f; %lld 2-3 flips, %lld edge removals, %lld moves, %lld surface moves, %lld "
                    "interface flips, %lld vertices inserted, %d rounds\n",
                    static_cast<long long>(im.below_before), static_cast<long long>(im.below_after),
                    static_cast<long long>(im.below_after_pinned), static_cast<long long>(im.below_after_surface_face),
                    im.worst_before, im.worst_after, static_cast<long long>(im.flips23),
                    static_cast<long long>(im.edge_removals), static_cast<long long>(im.vertex_moves),
                    static_cast<long long>(im.surface_moves), static_cast<long long>(im.interface_flips),
                    static_cast<long long>(im.vertices_inserted), im.rounds);
    }
    for (const auto& t : r.tissues) {
        if (t.components == 0)
            continue; // a label dropped as specks
        char buf[64];
        std::snprintf(buf, sizeof buf, "%s%d:%.3f(%d/%d)", row.volumes.empty() ? "" : ";", t.label,
                      t.label_volume > 0 ? t.mesh_volume / t.label_volume : 0.0, t.components_meshed, t.components);
        row.volumes += buf;
    }
    print(row);
    rows.push_back(row);
    return r;
}

// tetgen on lobe's boundary and interface faces of `r`: the same surfaces, volumes against the
// same label volumes.
void run_tetgen(const std::string& scene, const mesh::MeshResult& r, const std::string& switches,
                const std::string& config, double k)
{
    const auto dir = std::filesystem::temp_directory_path() / ("lobe_mesh_bench_" + scene);
    const auto t = bench::run_tetgen(r.mesh, switches, dir);
    if (!t.ok) {
        std::printf("%-8s tetgen -%s failed: %s\n", scene.c_str(), switches.c_str(), t.message.c_str());
        return;
    }
    Row row;
    row.scene = scene;
    row.mesher = "tetgen -" + switches;
    row.config = config;
    row.k = k;
    row.seconds = t.seconds;
    fill_quality(row, t.mesh, nullptr);
    for (const auto& tr : r.tissues) {
        if (tr.components == 0)
            continue;
        double v = 0;
        for (std::size_t i = 0; i < t.mesh.tets.size(); ++i)
            if (t.mesh.tet_labels[i] == tr.label)
                v += core::signed_volume(t.mesh, i);
        char buf[64];
        std::snprintf(buf, sizeof buf, "%s%d:%.3f", row.volumes.empty() ? "" : ";", tr.label,
                      tr.label_volume > 0 ? v / tr.label_volume : 0.0);
        row.volumes += buf;
    }
    print(row);
    rows.push_back(row);
    std::filesystem::remove_all(dir);
}

bool have_tetgen()
{
    return std::system("command -v tetgen > /dev/null 2>&1") == 0;
}

} // namespace

int main(int argc, char** argv)
{
    std::filesystem::path inr = LOBE_SOURCE_DIR "/../shared/data/liver-labels-inr/liver.inr.gz", csv;
    bool sweep = true, roi_only = false;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--liver") && i + 1 < argc)
            inr = argv[++i];
        else if (!std::strcmp(argv[i], "--csv") && i + 1 < argc)
            csv = argv[++i];
        else if (!std::strcmp(argv[i], "--no-sweep"))
            sweep = false;
        else if (!std::strcmp(argv[i], "--roi-only")) {
            roi_only = true;
            sweep = false;
        } else {
            std::fprintf(stderr, "usage: mesh_bench [--liver LIVER.inr.gz] [--csv OUT.csv] [--no-sweep] [--roi-only]\n");
            return 1;
        }
    }
    std::vector<std::pair<std::string, core::LabelImage3D>> scenes;
    if (std::filesystem::exists(inr)) {
        std::string mapping;
        scenes.emplace_back("cgal", remap(std::get<core::LabelImage3D>(io::read_inrimage(inr)), mapping));
        const auto& g = scenes.back().second;
        std::printf("cgal liver: %s %d x %d x %d voxels of %.3f x %.3f x %.3f mm; labels %s\n", inr.string().c_str(),
                    g.size[0], g.size[1], g.size[2], g.spacing[0], g.spacing[1], g.spacing[2], mapping.c_str());
    } else {
        std::printf("%s absent: the CGAL liver is skipped\n", inr.string().c_str());
    }
    phantom::PhantomParams pp;
    scenes.emplace_back("phantom", phantom::generate_phantom(pp).labels);
    const bool tetgen = have_tetgen();
    if (!tetgen)
        std::printf("tetgen not found (bash scripts/install-deps.sh --bench): the peer is skipped\n");

    // The table: the issue's ~50 k configuration and its neighbours.
    struct Config {
        std::string what;
        double size, cf;
        std::vector<mesh::TissueSize> sizes;
        int threads;
        bool roi, peer;
        bool improve = true;  // MeshParams::improve.enabled (acts only with a ROI)
        bool perturb = false; // CGAL's perturber (the default until the sliver pass)
        bool slivers = true;  // MeshParams::slivers.enabled
        double vessel_distance = 0; // the vessels' boundary tolerance [mm]; 0 = the default
    };
    const std::vector<mesh::TissueSize> small = {{2, 3}, {3, 3}, {4, 5}};
    const std::vector<Config> configs = {
        {"size 7.5, cf 2", 7.5, 2, {}, 2, false, false},
        {"size 10, vessels 3, tumours 5, cf 2", 10, 2, small, 2, false, false},
        {"size 10, vessels 3, tumours 5, cf 2", 10, 2, small, 1, false, true},
        {"same, CGAL's perturber instead of the sliver pass", 10, 2, small, 1, false, false, true, true, false},
        {"same, CGAL's perturber and the sliver pass", 10, 2, small, 1, false, false, true, true, true},
        {"same, neither (exuder only)", 10, 2, small, 1, false, false, true, false, false},
        {"same, vessels' boundary tolerance 0.5 mm", 10, 2, small, 1, false, false, true, false, true, 0.5},
        {"same, vessels' boundary tolerance 0.5 mm", 10, 2, small, 2, false, false, true, false, true, 0.5},
        {"same, ROI r 15 mm size 2, no ROI pass", 10, 2, small, 1, true, false, false},
        {"same, ROI r 15 mm size 2", 10, 2, small, 1, true, false, true},
        {"size 10, vessels 3, tumours 5, cf 1", 10, 1, small, 2, false, false},
    };
    for (const auto& [scene, labels] : scenes) {
        const core::Vec3 centre = liver_centroid(labels);
        for (const auto& c : configs) {
            if (roi_only && !c.roi)
                continue;
            mesh::MeshParams p;
            p.improve.enabled = c.improve;
            p.perturb = c.perturb;
            p.slivers.enabled = c.slivers;
            p.size = c.size;
            p.curvature_factor = c.cf;
            p.tissue_sizes = c.sizes;
            if (c.vessel_distance > 0)
                for (auto& t : p.tissue_sizes)
                    if (t.label == 2 || t.label == 3)
                        t.facet_distance = c.vessel_distance;
            p.threads = c.threads;
            if (c.roi) {
                p.roi.kind = mesh::RegionOfInterest::Kind::Spheres;
                p.roi.centres = {centre};
                p.roi.radius = 15;
                p.roi.size = 2;
            }
            try {
                const auto r = run_lobe(scene, labels, p, c.what, 0);
                if (c.peer && tetgen) {
                    run_tetgen(scene, r, "pq1.9AYQ", c.what, 0);
                    run_tetgen(scene, r, "pq1.414AYQ", c.what, 0);
                }
            } catch (const std::exception& e) {
                std::printf("%-8s %-40s failed: %s\n", scene.c_str(), c.what.c_str(), e.what());
            }
        }
    }
    // The sweep for the charts: one resolution factor k scales every size and the curvature
    // factor (size 10k, vessels 3k, tumours 5k, cf 2k), serial so that runs repeat; tetgen on
    // each mesh's surfaces.
    if (sweep)
        for (const auto& [scene, labels] : scenes) {
            std::vector<double> ks = {2, 1.4, 1, 0.7};
            if (scene == "phantom")
                ks.push_back(0.5);
            for (double k : ks) {
                mesh::MeshParams p;
                p.size = 10 * k;
                p.curvature_factor = 2 * k;
                p.tissue_sizes = {{2, 3 * k}, {3, 3 * k}, {4, 5 * k}};
                p.threads = 1;
                char what[64];
                std::snprintf(what, sizeof what, "sweep k %.1f", k);
                try {
                    const auto r = run_lobe(scene, labels, p, what, k);
                    if (tetgen) {
                        run_tetgen(scene, r, "pq1.9AYQ", what, k);
                        run_tetgen(scene, r, "pq1.414AYQ", what, k);
                    }
                } catch (const std::exception& e) {
                    std::printf("%-8s %-40s failed: %s\n", scene.c_str(), what, e.what());
                }
            }
        }
    if (!csv.empty()) {
        std::ofstream o(csv);
        o << "scene,mesher,config,k,threads,tets,seconds,min_dihedral_deg,tets_below_10deg,combined_min,combined_mean,"
             "combined_below_0.3_pct,roi_below_0.3_pct,volume_ratios\n";
        for (const auto& r : rows)
            o << r.scene << ',' << r.mesher << ",\"" << r.config << "\"," << r.k << ',' << r.threads << ',' << r.tets << ','
              << r.seconds << ',' << r.min_dihedral << ',' << r.below_10deg << ',' << r.combined_min << ',' << r.combined_mean << ',' << r.below
              << ',' << (r.roi_below >= 0 ? std::to_string(r.roi_below) : "") << ',' << r.volumes << '\n';
        std::printf("wrote %s\n", csv.string().c_str());
    }
    return 0;
}
