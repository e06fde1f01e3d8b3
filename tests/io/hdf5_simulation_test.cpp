// /simulation/<name>: frames, steps, statistics and the XDMF temporal collection.
#include "lobe/io/hdf5.h"

#include "lobe/core/errors.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

using namespace lobe;
namespace fs = std::filesystem;

namespace {

core::TetMesh two_tets()
{
    core::TetMesh m;
    m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
    m.tets = {{0, 1, 2, 3}, {1, 2, 3, 4}};
    if (core::signed_volume(m, 1) < 0)
        std::swap(m.tets[1][2], m.tets[1][3]);
    m.tet_labels = {1, 4};
    return m;
}

std::string read_text(const fs::path& path)
{
    std::ifstream x(path);
    std::stringstream text;
    text << x.rdbuf();
    return text.str();
}

} // namespace

TEST(Hdf5Simulation, FramesStepsAndStatisticsRoundTrip)
{
    // Everything is stored as float64 and read back bit for bit: exact equality.
    const fs::path dir = fs::temp_directory_path() / "lobe_hdf5_simulation";
    fs::create_directories(dir);
    const fs::path file = dir / "sim.h5";
    const core::TetMesh mesh = two_tets();
    {
        io::Hdf5Writer w(file);
        w.write_tet_mesh("block", mesh);
        EXPECT_THROW(w.begin_simulation("run", "nope"), core::InvalidInputError);
        w.begin_simulation("run", "block");
        for (int f = 0; f < 3; ++f) {
            auto p = mesh.vertices;
            for (auto& v : p)
                v.z += 0.5 * f;
            w.append_frame("run", 0.1 * f, p);
            w.append_steps("run", {{0.1 * f + 0.05, 0.05, {0, 0, 0.25 * f}, 1e-3 * f}, {0.1 * f + 0.1, 0.05, {1, 2, 3}, 2e-3}});
        }
        EXPECT_THROW(w.append_frame("run", 0.1, mesh.vertices), core::InvalidInputError); // time not after
        EXPECT_THROW(w.append_frame("run", 1.0, {{0, 0, 0}}), core::InvalidInputError);   // wrong node count
        w.finish_simulation("run", {{"steps", 6}, {"floor_hits", 0}}, "completed");
        w.commit();
    }
    io::Hdf5Reader r(file);
    ASSERT_EQ(r.simulations(), std::vector<std::string>{"run"});
    const io::SimulationInfo s = r.read_simulation("run");
    EXPECT_EQ(s.mesh, "block");
    EXPECT_EQ(s.status, "completed");
    EXPECT_EQ(s.nodes, mesh.vertices.size());
    ASSERT_EQ(s.times.size(), 3u);
    EXPECT_EQ(s.times[2], 0.1 * 2);
    ASSERT_EQ(s.steps.size(), 6u);
    EXPECT_EQ(s.steps[2].time, 0.1 + 0.05);
    EXPECT_EQ(s.steps[4].force.z, 0.5);
    EXPECT_EQ(s.steps[5].force.y, 2);
    EXPECT_EQ(s.steps[5].energy, 2e-3);
    ASSERT_EQ(s.statistics.size(), 2u);
    EXPECT_EQ(s.statistics[0].first, "steps");
    EXPECT_EQ(s.statistics[0].second, 6);
    const auto frame = r.read_frame("run", 2);
    ASSERT_EQ(frame.size(), mesh.vertices.size());
    EXPECT_EQ(frame[4].z, 1 + 1.0);
    EXPECT_THROW(r.read_frame("run", 3), core::InvalidInputError);

    // The sidecar plays the frames: one temporal collection with a grid per frame, each a
    // hyperslab of the positions.
    const std::string xml = read_text(dir / "sim.xdmf");
    EXPECT_NE(xml.find("CollectionType=\"Temporal\""), std::string::npos);
    EXPECT_NE(xml.find("<Time Value=\"0.2\"/>"), std::string::npos);
    EXPECT_NE(xml.find("2 0 0 1 1 1 1 5 3"), std::string::npos);
    EXPECT_NE(xml.find("sim.h5:/simulation/run/positions"), std::string::npos);
    fs::remove_all(dir);
}

TEST(Hdf5Simulation, AWriterNotCommittedLeavesNothing)
{
    // A run that fails before commit must not leave a file (exactly zero files in the folder).
    const fs::path dir = fs::temp_directory_path() / "lobe_hdf5_simulation_abort";
    fs::remove_all(dir);
    fs::create_directories(dir);
    {
        io::Hdf5Writer w(dir / "sim.h5");
        w.write_tet_mesh("block", two_tets());
        w.begin_simulation("run", "block");
        w.append_frame("run", 0, two_tets().vertices);
    }
    EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 0);
    fs::remove_all(dir);
}

TEST(Hdf5Simulation, FramesAfterATopologyChangeUseTheirOwnMesh)
{
    // Two frames on the mesh, then a cut adds a vertex and splits a tet: the next two frames
    // carry 6 positions and epochs/001's tets. Reading any frame gives its own mesh back, bit for
    // bit; the sidecar's grids after the change point at the epoch's datasets.
    const fs::path dir = fs::temp_directory_path() / "lobe_hdf5_simulation_epochs";
    fs::create_directories(dir);
    const fs::path file = dir / "sim.h5";
    const core::TetMesh mesh = two_tets();
    core::TetMesh cut = mesh; // tet 0 split at the midpoint of edge 0-1
    cut.vertices.push_back({0.5, 0, 0});
    cut.tets = {{0, 5, 2, 3}, {5, 1, 2, 3}, mesh.tets[1]};
    cut.tet_labels = {1, 1, 4};
    ASSERT_EQ(core::mesh_problem(cut), "");
    {
        io::Hdf5Writer w(file);
        w.write_tet_mesh("block", mesh);
        w.begin_simulation("run", "block");
        w.append_frame("run", 0.0, mesh.vertices);
        w.append_frame("run", 0.1, mesh.vertices);
        core::TetMesh bad = cut;
        bad.tets[0] = {0, 0, 2, 3};
        EXPECT_THROW(w.begin_topology("run", bad), core::InvalidInputError);
        EXPECT_THROW(w.begin_topology("nope", cut), core::InvalidInputError);
        w.begin_topology("run", cut);
        EXPECT_THROW(w.append_frame("run", 0.2, mesh.vertices), core::InvalidInputError); // 5 positions for 6
        auto moved = cut.vertices;
        moved[5].y = 0.25;
        w.append_frame("run", 0.2, cut.vertices);
        w.append_frame("run", 0.3, moved);
        w.finish_simulation("run", {}, "completed");
        w.commit();
    }
    io::Hdf5Reader r(file);
    const io::SimulationInfo s = r.read_simulation("run");
    EXPECT_EQ(s.nodes, 5u);
    ASSERT_EQ(s.times.size(), 4u);
    ASSERT_EQ(s.topology_changes, std::vector<std::size_t>{2});
    EXPECT_EQ(r.read_frame("run", 1).size(), 5u);
    const core::TetMesh f3 = r.read_frame_mesh("run", 3);
    ASSERT_EQ(f3.vertices.size(), 6u);
    EXPECT_EQ(f3.vertices[5].y, 0.25);
    EXPECT_EQ(f3.tets, cut.tets);
    EXPECT_EQ(f3.tet_labels, cut.tet_labels);
    const core::TetMesh f0 = r.read_frame_mesh("run", 0);
    EXPECT_EQ(f0.tets, mesh.tets);
    EXPECT_THROW(r.read_frame("run", 4), core::InvalidInputError);
    const std::string xml = read_text(dir / "sim.xdmf");
    EXPECT_NE(xml.find("sim.h5:/simulation/run/epochs/001/tets"), std::string::npos);
    EXPECT_NE(xml.find("1 0 0 1 1 1 1 6 3"), std::string::npos); // frame 3 is the epoch's second
    EXPECT_NE(xml.find("<Time Value=\"0.3\"/>"), std::string::npos);
    fs::remove_all(dir);
}
