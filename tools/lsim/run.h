#pragma once
// lsim's two jobs: run a scene on a mesh, and write a block mesh to try it on.

#include "common/cli.h"
#include "lobe/mss/block_mesh.h"

#include <filesystem>
#include <string>

namespace lobe::lsim {

struct RunOptions {
    std::filesystem::path mesh_file, scene_file, out, png_dir;
    std::string mesh_name; // empty = the file's only tet mesh
};

// Reads the mesh and scene, simulates, writes the container (and pictures). Returns the exit code;
// a blow-up commits the frames so far (status attribute says why) and returns kExitAlgorithm.
int run_scene(const RunOptions& o, const tools::Progress& progress, tools::RunRecord& record);

struct BlockOptions {
    std::filesystem::path out;
    mss::BlockMeshParams block;
    std::vector<double> tumour; // x y z r [mm], empty = none
};

// Writes a block mesh (and optionally a spherical tumour) as /meshes/block.
int make_block(const BlockOptions& o, const tools::Progress& progress, tools::RunRecord& record);

} // namespace lobe::lsim
