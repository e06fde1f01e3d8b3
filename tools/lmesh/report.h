#pragma once
// lmesh's quality report: JSON (machine) and text (people), from the meshing result, the
// quality evaluation and the surface checks.

#include "lobe/mesh/quality.h"
#include "lobe/mesh/surface.h"
#include "lobe/mesh/tetrahedralize.h"

#include <nlohmann/json.hpp>

#include <string>
#include <utility>
#include <vector>

namespace lobe::lmesh {

struct SurfaceReport {
    int label = 0;
    std::string name;
    mesh::SurfaceCheck check;
};

struct Report {
    std::string input;
    const mesh::MeshResult* result = nullptr;
    const mesh::MeshQuality* quality = nullptr;
    std::vector<SurfaceReport> surfaces;
    std::vector<std::pair<int, std::string>> names; //!< tissue label -> name
    double seconds = 0;
};

nlohmann::json report_json(const Report& r);
std::string report_text(const Report& r);

} // namespace lobe::lmesh
