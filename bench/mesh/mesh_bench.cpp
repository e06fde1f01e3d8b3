// Meshing benchmark (issue 6): lobe's mesh_labels on CGAL's labelled liver (INRIMAGE) and on an
// lphantom volume, over a few parameter sets; one line per run. Results: docs/benchmarks.md.
//   mesh_bench [LIVER.inr.gz]   (default ../shared/data/liver-labels-inr/liver.inr.gz)
#include "inrimage.h"
#include "tetgen_peer.h"

#include "lobe/mesh/quality.h"
#include "lobe/mesh/tetrahedralize.h"
#include "lphantom/phantom.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <cstdlib>
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

mesh::MeshResult run(const char* scene, const core::LabelImage3D& labels, const mesh::MeshParams& p, const char* what)
{
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = mesh::mesh_labels(labels, p);
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const auto q = mesh::evaluate_quality(r.mesh);
    const auto& comb = q.all.measures[static_cast<int>(mesh::Measure::Combined)];
    std::printf("%-8s %-44s threads %d: %7zu tets %6.2f s  dihedral %5.2f-%6.2f deg  combined min %.3f mean %.3f "
                "<0.3 %5.1f%%  volumes",
                scene, what, r.threads, r.mesh.tets.size(), secs, q.all.min_dihedral_deg, q.all.max_dihedral_deg,
                comb.min, comb.mean, 100.0 * double(comb.bands[0]) / double(comb.count));
    for (const auto& t : r.tissues)
        std::printf(" %d:%.3f(%d/%d)", t.label, t.label_volume > 0 ? t.mesh_volume / t.label_volume : 0.0,
                    t.components_meshed, t.components);
    int big_missed = 0;
    for (const auto& c : r.components)
        big_missed += c.voxels >= 100 && !c.meshed;
    std::printf("  pieces>=100 unmeshed %d\n", big_missed);
    std::fflush(stdout);
    return r;
}

// tetgen on lobe's boundary and interface faces of `r`: the same surfaces, volumes against the
// same label volumes.
void run_tetgen_peer(const char* scene, const mesh::MeshResult& r, const std::string& switches)
{
    const auto dir = std::filesystem::temp_directory_path() / ("lobe_mesh_bench_" + std::string(scene));
    const auto t = bench::run_tetgen(r.mesh, switches, dir);
    if (!t.ok) {
        std::printf("%-8s tetgen -%-36s failed: %s\n", scene, switches.c_str(), t.message.c_str());
        return;
    }
    const auto q = mesh::evaluate_quality(t.mesh);
    const auto& comb = q.all.measures[static_cast<int>(mesh::Measure::Combined)];
    std::printf("%-8s tetgen -%-36s threads 1: %7zu tets %6.2f s  dihedral %5.2f-%6.2f deg  combined min %.3f mean %.3f "
                "<0.3 %5.1f%%  volumes",
                scene, switches.c_str(), t.mesh.tets.size(), t.seconds, q.all.min_dihedral_deg, q.all.max_dihedral_deg,
                comb.min, comb.mean, 100.0 * double(comb.bands[0]) / double(comb.count));
    for (const auto& tr : r.tissues) {
        double v = 0;
        for (std::size_t i = 0; i < t.mesh.tets.size(); ++i)
            if (t.mesh.tet_labels[i] == tr.label)
                v += core::signed_volume(t.mesh, i);
        std::printf(" %d:%.3f", tr.label, tr.label_volume > 0 ? v / tr.label_volume : 0.0);
    }
    std::printf("\n");
    std::fflush(stdout);
    std::filesystem::remove_all(dir);
}

} // namespace

int main(int argc, char** argv)
{
    const std::filesystem::path inr = argc > 1 ? argv[1] : LOBE_SOURCE_DIR "/../shared/data/liver-labels-inr/liver.inr.gz";
    struct Config {
        const char* what;
        double size, cf;
        std::vector<mesh::TissueSize> sizes;
        int threads;
    };
    const std::vector<Config> configs = {
        {"size 7.5, cf 2", 7.5, 2, {}, 2},
        {"size 10, vessels 3, tumours 5, cf 2", 10, 2, {{2, 3}, {3, 3}, {4, 5}}, 2},
        {"size 10, vessels 3, tumours 5, cf 2", 10, 2, {{2, 3}, {3, 3}, {4, 5}}, 1},
        {"size 10, vessels 3, tumours 5, cf 1", 10, 1, {{2, 3}, {3, 3}, {4, 5}}, 2},
    };
    std::vector<std::pair<std::string, core::LabelImage3D>> scenes;
    if (std::filesystem::exists(inr)) {
        std::string mapping;
        scenes.emplace_back("cgal", remap(bench::read_inrimage(inr), mapping));
        const auto& g = scenes.back().second;
        std::printf("cgal liver: %s %d x %d x %d voxels of %.3f x %.3f x %.3f mm; labels %s\n", inr.string().c_str(),
                    g.size[0], g.size[1], g.size[2], g.spacing[0], g.spacing[1], g.spacing[2], mapping.c_str());
    } else {
        std::printf("%s absent: the CGAL liver is skipped\n", inr.string().c_str());
    }
    phantom::PhantomParams pp;
    scenes.emplace_back("phantom", phantom::generate_phantom(pp).labels);
    for (const auto& [scene, labels] : scenes)
        for (const auto& c : configs) {
            mesh::MeshParams p;
            p.size = c.size;
            p.curvature_factor = c.cf;
            p.tissue_sizes = c.sizes;
            p.threads = c.threads;
            try {
                const auto r = run(scene.c_str(), labels, p, c.what);
                // The peer on the surfaces of the 50 k-class configuration (serial).
                if (c.threads == 1 && std::system("command -v tetgen > /dev/null 2>&1") == 0) {
                    run_tetgen_peer(scene.c_str(), r, "pq1.9AYQ");
                    run_tetgen_peer(scene.c_str(), r, "pq1.414AYQ");
                }
            } catch (const std::exception& e) {
                std::printf("%-8s %-44s failed: %s\n", scene.c_str(), c.what, e.what());
            }
        }
    return 0;
}
