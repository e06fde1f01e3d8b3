#pragma once
// lmesh's pictures: the mesh cut by a plane, coloured by tissue and by quality, and quality
// histograms per tissue (OpenCV drawing, PNG through tools/common/picture.h).

#include "lobe/core/tet_mesh.h"
#include "lobe/mesh/quality.h"

#include <filesystem>
#include <string>
#include <vector>

namespace lobe::lmesh {

//! Writes into `dir`: cut-{axial,coronal,sagittal}-{tissue,quality}.png (planes through
//! `centre` [mm]) and quality-histogram.png (the combined measure per tissue with the
//! 0.3/0.5/0.7 bands). `names` are the tissue names for the legends. Returns the files written.
std::vector<std::filesystem::path> write_mesh_pictures(const std::filesystem::path& dir, const core::TetMesh& mesh,
                                                       const mesh::MeshQuality& quality, const core::Vec3& centre,
                                                       const std::vector<std::pair<int, std::string>>& names);

} // namespace lobe::lmesh
