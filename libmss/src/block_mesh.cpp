// Box meshes for tests and demonstrations.
#include "lobe/mss/block_mesh.h"

#include "lobe/core/errors.h"

#include <cmath>
#include <string>
#include <utility>

namespace lobe::mss {

core::TetMesh make_block_mesh(const BlockMeshParams& p)
{
    for (int c = 0; c < 3; ++c)
        if (p.cells[c] < 1 || p.cells[c] > 1000 || !(p.size[c] > 0) || !std::isfinite(p.size[c]) ||
            !std::isfinite(p.origin[c]))
            throw core::InvalidInputError("block mesh: cells must be 1..1000 and the size positive along every axis");
    if (p.tets_per_cell != 5 && p.tets_per_cell != 6)
        throw core::InvalidInputError("block mesh: tets_per_cell must be 5 or 6, not " + std::to_string(p.tets_per_cell));
    const int nx = p.cells[0], ny = p.cells[1], nz = p.cells[2];
    core::TetMesh m;
    for (int k = 0; k <= nz; ++k)
        for (int j = 0; j <= ny; ++j)
            for (int i = 0; i <= nx; ++i)
                m.vertices.push_back({p.origin.x + p.size.x * i / nx, p.origin.y + p.size.y * j / ny,
                                      p.origin.z + p.size.z * k / nz});
    auto vid = [&](int i, int j, int k) { return static_cast<std::int32_t>(i + (nx + 1) * (j + (ny + 1) * k)); };
    // Corner c of a cell has offset (c & 1, c >> 1 & 1, c >> 2 & 1).
    static constexpr int kKuhn[6][4] = {{0, 1, 3, 7}, {0, 1, 5, 7}, {0, 2, 3, 7}, {0, 2, 6, 7}, {0, 4, 5, 7}, {0, 4, 6, 7}};
    // Five tets: a central one on the corners of one parity and four corner tets; alternating the
    // parity from cell to cell makes the face diagonals of neighbours agree.
    static constexpr int kFiveEven[5][4] = {{0, 3, 5, 6}, {1, 0, 3, 5}, {2, 0, 3, 6}, {4, 0, 5, 6}, {7, 3, 5, 6}};
    static constexpr int kFiveOdd[5][4] = {{1, 2, 4, 7}, {0, 1, 2, 4}, {3, 1, 2, 7}, {5, 1, 4, 7}, {6, 2, 4, 7}};
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                std::int32_t corner[8];
                for (int c = 0; c < 8; ++c)
                    corner[c] = vid(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1));
                const int count = p.tets_per_cell;
                for (int t = 0; t < count; ++t) {
                    const int* q = count == 6 ? kKuhn[t] : ((i + j + k) % 2 == 0 ? kFiveEven[t] : kFiveOdd[t]);
                    std::array<std::int32_t, 4> tet{corner[q[0]], corner[q[1]], corner[q[2]], corner[q[3]]};
                    const auto& v = m.vertices;
                    if (core::signed_volume(v[tet[0]], v[tet[1]], v[tet[2]], v[tet[3]]) < 0)
                        std::swap(tet[2], tet[3]);
                    m.tets.push_back(tet);
                    m.tet_labels.push_back(p.label);
                }
            }
    return m;
}

std::size_t label_sphere(core::TetMesh& mesh, const core::Vec3& centre, double radius, std::int32_t label)
{
    std::size_t count = 0;
    for (std::size_t t = 0; t < mesh.tets.size(); ++t) {
        core::Vec3 c{0, 0, 0};
        for (auto v : mesh.tets[t])
            c += mesh.vertices[v] * 0.25;
        if (distance(c, centre) <= radius) {
            mesh.tet_labels[t] = label;
            ++count;
        }
    }
    return count;
}

} // namespace lobe::mss
