#pragma once
// The outside peer of the meshing benchmark: Debian's `tetgen` program on the same
// reconstructed surfaces (lobe's tissue boundaries and interfaces, one PLC with a region
// point per tissue), run as a separate process through files.

#include "lobe/core/errors.h"
#include "lobe/core/tet_mesh.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace lobe::bench {

struct TetgenRun {
    core::TetMesh mesh;
    double seconds = 0; //!< the tetgen process, wall clock
    bool ok = false;
    std::string message;
};

//! Meshes the PLC made of `m`'s boundary and interface faces with `tetgen <switches>`.
inline TetgenRun run_tetgen(const core::TetMesh& m, const std::string& switches, const std::filesystem::path& dir)
{
    namespace fs = std::filesystem;
    TetgenRun out;
    // Faces with one tet, or two tets of different labels: the PLC's facets.
    std::map<std::array<std::int32_t, 3>, std::vector<std::size_t>> sides;
    const int f[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
    for (std::size_t t = 0; t < m.tets.size(); ++t)
        for (const auto& i : f) {
            std::array<std::int32_t, 3> k{m.tets[t][i[0]], m.tets[t][i[1]], m.tets[t][i[2]]};
            std::sort(k.begin(), k.end());
            sides[k].push_back(t);
        }
    std::vector<std::array<std::int32_t, 3>> facets;
    std::set<std::int32_t> used;
    for (const auto& [k, s] : sides)
        if (s.size() == 1 || m.tet_labels[s[0]] != m.tet_labels[s[1]]) {
            facets.push_back(k);
            used.insert(k.begin(), k.end());
        }
    std::map<std::int32_t, std::int32_t> index;
    for (auto v : used)
        index.emplace(v, static_cast<std::int32_t>(index.size()));
    fs::create_directories(dir);
    const fs::path smesh = dir / "plc.smesh";
    {
        std::ofstream o(smesh);
        o.precision(17);
        o << index.size() << " 3 0 0\n";
        for (const auto& [v, i] : index)
            o << i << ' ' << m.vertices[v].x << ' ' << m.vertices[v].y << ' ' << m.vertices[v].z << '\n';
        o << facets.size() << " 0\n";
        for (const auto& k : facets)
            o << "3 " << index[k[0]] << ' ' << index[k[1]] << ' ' << index[k[2]] << '\n';
        o << "0\n";
        // One region point per piece (tets of one label joined through faces): the centroid of
        // its largest tet, so that every piece gets its label in tetgen's output.
        std::vector<std::size_t> parent(m.tets.size());
        for (std::size_t t = 0; t < parent.size(); ++t)
            parent[t] = t;
        auto find = [&](std::size_t x) {
            while (parent[x] != x)
                x = parent[x] = parent[parent[x]];
            return x;
        };
        for (const auto& [k, s] : sides)
            if (s.size() == 2 && m.tet_labels[s[0]] == m.tet_labels[s[1]])
                parent[find(s[0])] = find(s[1]);
        std::map<std::size_t, std::pair<double, core::Vec3>> pieces;
        std::map<std::size_t, int> piece_label;
        for (std::size_t t = 0; t < m.tets.size(); ++t) {
            const double v = core::signed_volume(m, t);
            const std::size_t root = find(t);
            auto& r = pieces[root];
            piece_label[root] = m.tet_labels[t];
            if (v > r.first) {
                const auto& q = m.tets[t];
                r = {v, (m.vertices[q[0]] + m.vertices[q[1]] + m.vertices[q[2]] + m.vertices[q[3]]) / 4};
            }
        }
        std::map<std::size_t, std::pair<int, core::Vec3>> region;
        for (const auto& [root, r] : pieces)
            region[root] = {piece_label[root], r.second};
        o << region.size() << '\n';
        int i = 0;
        for (const auto& [root, r] : region)
            o << i++ << ' ' << r.second.x << ' ' << r.second.y << ' ' << r.second.z << ' ' << r.first << " -1\n";
    }
    const std::string cmd = "tetgen -" + switches + " " + smesh.string() + " > " + (dir / "tetgen.log").string() + " 2>&1";
    const auto t0 = std::chrono::steady_clock::now();
    const int rc = std::system(cmd.c_str());
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (rc != 0) {
        out.message = "tetgen exited with " + std::to_string(rc) + " (see " + (dir / "tetgen.log").string() + ")";
        return out;
    }
    std::ifstream node(dir / "plc.1.node"), ele(dir / "plc.1.ele");
    std::size_t n = 0, dim = 0, na = 0, nb = 0;
    node >> n >> dim >> na >> nb;
    out.mesh.vertices.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        std::size_t id;
        node >> id >> out.mesh.vertices[i].x >> out.mesh.vertices[i].y >> out.mesh.vertices[i].z;
        for (std::size_t a = 0; a < na + nb; ++a) {
            double skip;
            node >> skip;
        }
    }
    std::size_t nt = 0, per = 0, nattr = 0;
    ele >> nt >> per >> nattr;
    for (std::size_t i = 0; i < nt; ++i) {
        std::size_t id;
        std::array<std::int32_t, 4> t{};
        double attr = 0;
        ele >> id >> t[0] >> t[1] >> t[2] >> t[3];
        if (nattr > 0)
            ele >> attr;
        // tetgen's tets are negatively oriented in lobe's convention: swap two vertices.
        if (core::signed_volume(out.mesh.vertices[t[0]], out.mesh.vertices[t[1]], out.mesh.vertices[t[2]],
                                out.mesh.vertices[t[3]]) < 0)
            std::swap(t[0], t[1]);
        out.mesh.tets.push_back(t);
        out.mesh.tet_labels.push_back(static_cast<std::int32_t>(attr));
    }
    out.ok = !out.mesh.tets.empty() && core::mesh_problem(out.mesh).empty();
    if (!out.ok)
        out.message = "tetgen's output is not a valid mesh: " + core::mesh_problem(out.mesh);
    return out;
}

} // namespace lobe::bench
