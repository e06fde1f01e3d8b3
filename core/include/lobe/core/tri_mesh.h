#pragma once
//! \file
//! \brief TriMesh: an indexed triangle surface (vertices in mm, counter-clockwise = outward).

#include "lobe/core/types.h"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace lobe::core {

struct TriMesh {
    std::vector<Vec3> vertices;                          //!< positions [mm]
    std::vector<std::array<std::int32_t, 3>> triangles;  //!< vertex indices, CCW seen from outside
};

//! Why a surface is malformed (an index out of range or a repeated vertex in a triangle), or an
//! empty string if it is well formed. Closedness and manifoldness are libmesh's checks.
inline std::string mesh_problem(const TriMesh& m)
{
    const auto n = static_cast<std::int64_t>(m.vertices.size());
    for (std::size_t t = 0; t < m.triangles.size(); ++t) {
        const auto& f = m.triangles[t];
        for (auto v : f)
            if (v < 0 || v >= n)
                return "triangle " + std::to_string(t) + " has vertex index " + std::to_string(v) +
                       " outside [0, " + std::to_string(n) + ")";
        if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2])
            return "triangle " + std::to_string(t) + " repeats a vertex";
    }
    return {};
}

} // namespace lobe::core
