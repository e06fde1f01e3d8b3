#pragma once
//! \file
//! \brief TetMesh: a tetrahedral mesh whose tets carry tissue labels.
//!
//! Tets are positively oriented: for tet (a, b, c, d), dot(b - a, cross(c - a, d - a)) > 0,
//! i.e. six times its signed volume is positive. Tissue labels follow the label volume's
//! convention (docs/file-format.md): 1 liver parenchyma, 2 portal vein, 3 hepatic veins,
//! 4 tumour; 0 is never a tet label.

#include "lobe/core/types.h"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace lobe::core {

struct TetMesh {
    std::vector<Vec3> vertices;                      //!< positions [mm]
    std::vector<std::array<std::int32_t, 4>> tets;   //!< vertex indices, positively oriented
    std::vector<std::int32_t> tet_labels;            //!< one tissue label per tet
};

//! Signed volume [mm^3] of tet (a, b, c, d); positive for a positively oriented tet.
inline double signed_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d)
{
    return dot(b - a, cross(c - a, d - a)) / 6.0;
}

inline double signed_volume(const TetMesh& m, std::size_t t)
{
    const auto& q = m.tets[t];
    return signed_volume(m.vertices[q[0]], m.vertices[q[1]], m.vertices[q[2]], m.vertices[q[3]]);
}

//! Why a tet mesh is malformed, or an empty string if it is valid: one label per tet, every
//! index in range, no repeated vertex in a tet, and every tet positively oriented.
inline std::string mesh_problem(const TetMesh& m)
{
    if (m.tet_labels.size() != m.tets.size())
        return "has " + std::to_string(m.tets.size()) + " tets but " + std::to_string(m.tet_labels.size()) +
               " tet labels";
    const auto n = static_cast<std::int64_t>(m.vertices.size());
    for (std::size_t t = 0; t < m.tets.size(); ++t) {
        const auto& q = m.tets[t];
        for (auto v : q)
            if (v < 0 || v >= n)
                return "tet " + std::to_string(t) + " has vertex index " + std::to_string(v) +
                       " outside [0, " + std::to_string(n) + ")";
        for (int i = 0; i < 4; ++i)
            for (int j = i + 1; j < 4; ++j)
                if (q[i] == q[j])
                    return "tet " + std::to_string(t) + " repeats a vertex";
        if (!(signed_volume(m, t) > 0))
            return "tet " + std::to_string(t) + " is not positively oriented (signed volume " +
                   std::to_string(signed_volume(m, t)) + " mm^3)";
    }
    return {};
}

} // namespace lobe::core
