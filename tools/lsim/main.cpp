// lsim: mass-spring simulation of a tetrahedral mesh with instruments (docs/algorithms/mass_spring.md).
#include "common/cli.h"
#include "lsim/run.h"

using namespace lobe;

int main(int argc, char** argv)
{
    CLI::App app{"lsim: simulate a multi-tissue tetrahedral mesh (mass-spring, HAVP stiffness, adaptive time step) "
                 "probed by a scripted instrument; writes frames, forces, energies and statistics to HDF5 + XDMF",
                 "lsim"};
    bool quiet = false;
    tools::add_common_options(app, quiet);
    lsim::RunOptions run;
    lsim::BlockOptions block;
    app.add_option("MESH", run.mesh_file, "Container (.h5) holding the tet mesh, e.g. from lmesh or --make-block")
        ->check(CLI::ExistingFile);
    app.add_option("SCENE", run.scene_file, "Scene file (docs/algorithms/mass_spring.md, examples/*.scene)")
        ->check(CLI::ExistingFile);
    app.add_option("-o,--output", run.out, "Output container (.h5) with the mesh, /simulation/run and the provenance");
    app.add_option("--mesh", run.mesh_name, "Tet mesh to simulate when the container holds several");
    app.add_option("--png", run.png_dir, "Also write pictures of chosen frames and a force plot into this folder");
    auto* mk = app.add_option("--make-block", block.out, "Instead of simulating, write a block tet mesh to this .h5");
    std::vector<int> cells{4, 4, 4};
    app.add_option("--cells", cells, "--make-block: cells along x, y, z")->delimiter(',')->expected(3)->capture_default_str();
    app.add_option("--size", block.block.size.x, "--make-block: edge length of the cube [mm] (or see --size-xyz)")
        ->capture_default_str();
    std::vector<double> size_xyz;
    app.add_option("--size-xyz", size_xyz, "--make-block: box size x,y,z [mm]")->delimiter(',')->expected(3);
    app.add_option("--split", block.block.tets_per_cell, "--make-block: tets per cell, 5 or 6")
        ->check(CLI::IsMember({5, 6}))
        ->capture_default_str();
    app.add_option("--tumour", block.tumour, "--make-block: a spherical tumour x,y,z,radius [mm]")->delimiter(',')->expected(4);
    app.get_option("-o")->excludes(mk);
    app.get_option("MESH")->excludes(mk);

    tools::RunRecord record(app, argc, argv);
    return tools::run_tool(app, argc, argv, [&] {
        const tools::Progress progress("lsim", quiet);
        if (!block.out.empty()) {
            block.block.cells = {cells[0], cells[1], cells[2]};
            block.block.size = size_xyz.empty() ? core::Vec3{block.block.size.x, block.block.size.x, block.block.size.x}
                                                : core::Vec3{size_xyz[0], size_xyz[1], size_xyz[2]};
            return lsim::make_block(block, progress, record);
        }
        if (run.mesh_file.empty() || run.scene_file.empty() || run.out.empty())
            throw CLI::ValidationError("lsim needs MESH SCENE -o OUT.h5 (or --make-block OUT.h5)");
        return lsim::run_scene(run, progress, record);
    });
}
