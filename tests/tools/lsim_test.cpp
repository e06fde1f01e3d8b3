// lsim run as a program: exit codes, messages, the container it writes, pictures.
#include "lobe/io/hdf5.h"
#include "lobe/mss/model.h"

#include "common/run_tool.h"
#include "common/test_data.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <string>

using namespace lobe;
namespace fs = std::filesystem;

namespace {

using test::q;

test::ToolRun lsim(const std::string& args, const fs::path& scratch) { return test::run_tool(LSIM_EXE, args, scratch); }


fs::path write_text(const fs::path& path, const std::string& text)
{
    std::ofstream(path) << text;
    return path;
}

// A 40 mm cube of 4^3 cells with a tumour, pressed by a probe for 0.2 s.
const char* kScene = R"(# test scene
[model]
stiffness = havp
mass_damping = 10
[fixed]
box = -1 -1 -1 41 41 0.001
[time]
duration = 0.2
frame_interval = 0.05
[probe]
radius = 12
point = 0 20 20 52
point = 0.2 20 20 48
[output]
png_times = 0 0.2
)";

} // namespace

TEST(Lsim, HelpAndUsageErrors)
{
    const fs::path dir = test::scratch_dir();
    EXPECT_EQ(lsim("--help", dir).exit_code, 0);
    EXPECT_NE(lsim("--help", dir).out.find("--make-block"), std::string::npos);
    const auto r = lsim("", dir);
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.err.find("MESH SCENE"), std::string::npos) << r.err;
}

TEST(Lsim, RunsAProbeSceneAndWritesFramesStepsStatisticsAndPictures)
{
    const fs::path dir = test::scratch_dir();
    ASSERT_EQ(lsim("--quiet --make-block " + q(dir / "block.h5") + " --cells 4,4,4 --size 40 --tumour 20,20,20,8", dir).exit_code, 0);
    const fs::path scene = write_text(dir / "probe.scene", kScene);
    const auto r = lsim(q(dir / "block.h5") + " " + q(scene) + " -o " + q(dir / "sim.h5") + " --png " + q(dir / "pics"), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("us per step"), std::string::npos) << r.err;

    io::Hdf5Reader in(dir / "sim.h5");
    ASSERT_EQ(in.simulations(), std::vector<std::string>{"run"});
    const io::SimulationInfo s = in.read_simulation("run");
    EXPECT_EQ(s.status, "completed");
    EXPECT_EQ(s.mesh, "block");
    // Frames at 0, 0.05, ..., 0.2 s: exactly 5, the last at the duration (times are landed on).
    ASSERT_EQ(s.times.size(), 5u);
    EXPECT_DOUBLE_EQ(s.times.back(), 0.2);
    ASSERT_GT(s.steps.size(), 10u);
    EXPECT_DOUBLE_EQ(s.steps.back().time, 0.2);
    // The probe pushes the tissue down: the tissue pushes the probe up by the end.
    EXPECT_GT(s.steps.back().force.z, 0);
    double steps_stat = -1;
    for (const auto& [k, v] : s.statistics)
        if (k == "steps")
            steps_stat = v;
    EXPECT_EQ(steps_stat, double(s.steps.size()));
    // Every frame finite, and the top centre moved down under the probe (it is 4 mm in).
    const auto last = in.read_frame("run", 4);
    const auto first = in.read_frame("run", 0);
    double lowest = 1e300;
    for (std::size_t i = 0; i < last.size(); ++i) {
        ASSERT_TRUE(std::isfinite(last[i].x + last[i].y + last[i].z));
        if (first[i].z > 40 - 1e-9)
            lowest = std::min(lowest, last[i].z);
    }
    EXPECT_LT(lowest, 40 - 2); // a node under the 12 mm sphere 4 mm in sits at least 2 mm down
    const auto prov = in.provenance();
    ASSERT_EQ(prov.size(), 2u); // --make-block, then this run
    EXPECT_EQ(prov[1].tool, "lsim");
    bool has_scene = false;
    std::string kernel;
    for (const auto& [k, v] : prov[1].parameters) {
        has_scene = has_scene || (k == "scene" && v.find("[probe]") != std::string::npos);
        if (k == "spring_kernel")
            kernel = v;
    }
    EXPECT_TRUE(has_scene);
    EXPECT_EQ(kernel, mss::simd_spring_kernel_available() ? "avx2" : "scalar"); // the scene leaves simd on
    EXPECT_NE(test::read_file(dir / "sim.xdmf").find("CollectionType=\"Temporal\""), std::string::npos);
    EXPECT_TRUE(fs::exists(dir / "pics" / "force.png"));
    EXPECT_TRUE(fs::exists(dir / "pics" / "frame_000.000s.png"));
    EXPECT_TRUE(fs::exists(dir / "pics" / "frame_000.200s.png"));
}

TEST(Lsim, SceneErrorsNameTheLine)
{
    const fs::path dir = test::scratch_dir();
    ASSERT_EQ(lsim("--quiet --make-block " + q(dir / "block.h5") + " --cells 2,2,2", dir).exit_code, 0);
    const fs::path scene = write_text(dir / "bad.scene", "[model]\nstiffness = havp\nstifness = 3\n");
    const auto r = lsim(q(dir / "block.h5") + " " + q(scene) + " -o " + q(dir / "sim.h5"), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("bad.scene:3: unknown key 'stifness'"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "sim.h5"));
    write_text(scene, "[time]\nduration = -1\n");
    EXPECT_NE(lsim(q(dir / "block.h5") + " " + q(scene) + " -o " + q(dir / "sim.h5"), dir).err.find("bad.scene:2:"),
              std::string::npos);
    // More frames than an output file should hold (and than lsim counts in an int): 10^32.
    write_text(scene, "[time]\nduration = 1e30\nframe_interval = 1e-2\n");
    const auto frames = lsim(q(dir / "block.h5") + " " + q(scene) + " -o " + q(dir / "sim.h5"), dir);
    EXPECT_EQ(frames.exit_code, 2);
    EXPECT_NE(frames.err.find("bad.scene: [time] duration / frame_interval asks for 1e+32 frames, more than 100000"),
              std::string::npos)
        << frames.err;
    EXPECT_FALSE(fs::exists(dir / "sim.h5"));
    // A probe that starts inside the 40 mm block (centre 5 mm below its top face, radius 10)
    write_text(scene, "[time]\nduration = 0.1\n[probe]\nradius = 10\npoint = 0 20 20 35\n");
    const auto inside = lsim(q(dir / "block.h5") + " " + q(scene) + " -o " + q(dir / "sim.h5"), dir);
    EXPECT_EQ(inside.exit_code, 2);
    EXPECT_NE(inside.err.find("bad.scene: probe 'probe0' starts"), std::string::npos) << inside.err;
    EXPECT_FALSE(fs::exists(dir / "sim.h5"));
}

TEST(Lsim, ABlowUpExitsWith3AndKeepsTheLastGoodFrames)
{
    // A fixed step 3x Paloc's critical step (about 10x the explicit limit) under gravity: the run
    // must stop with exit code 3 and a message, and the container must hold only finite frames,
    // marked with why it stopped.
    const fs::path dir = test::scratch_dir();
    ASSERT_EQ(lsim("--quiet --make-block " + q(dir / "block.h5") + " --cells 3,3,3", dir).exit_code, 0);
    const fs::path scene = write_text(dir / "blow.scene", "[model]\ngravity = 0 0 -9.81\n[fixed]\nbox = -1 -1 -1 41 41 0.001\n"
                                                          "[time]\npolicy = fixed\ndt = 0.02\nduration = 2\n");
    const auto r = lsim(q(dir / "block.h5") + " " + q(scene) + " -o " + q(dir / "sim.h5"), dir);
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_NE(r.err.find("blew up"), std::string::npos) << r.err;
    io::Hdf5Reader in(dir / "sim.h5");
    const auto s = in.read_simulation("run");
    EXPECT_NE(s.status.find("blew up"), std::string::npos);
    EXPECT_LT(s.times.size(), 101u);
    for (std::size_t f = 0; f < s.times.size(); ++f)
        for (const auto& p : in.read_frame("run", f)) // read_frame itself refuses non-finite values
            ASSERT_TRUE(std::isfinite(p.z));
    for (const auto& st : s.steps)
        ASSERT_TRUE(std::isfinite(st.energy));
}

TEST(Lsim, CutGraspAndRefineScenesWriteEachTopology)
{
    // A 40 mm cube: forceps hold the top corner region while a blade cuts the cube in two down
    // the middle, then carry the freed half away; refinement runs around the instruments. The
    // container must hold every frame on its own mesh (the topology changes at the cut), with
    // the mass, read back from the frames' rest shape, unchanged; the grasp force is in the
    // steps; the cut line shows in the pictures.
    const fs::path dir = test::scratch_dir();
    ASSERT_EQ(lsim("--quiet --make-block " + q(dir / "block.h5") + " --cells 4,4,4 --size 40", dir).exit_code, 0);
    const fs::path scene = write_text(dir / "cut.scene", R"([model]
mass_damping = 10
[fixed]
box = -1 -1 -1 1e-3 41 41
[time]
duration = 0.3
frame_interval = 0.05
[grasp]
radius = 6
close = 0.01
point = 0 40 20 40
point = 0.2 40 20 40
point = 0.3 45 20 40
[blade]
pose = 0 21.3 -5 45 21.3 45 45
pose = 0.15 21.3 -5 -5 21.3 45 -5
[refine]
min_quality = 0.05
[output]
png_times = 0 0.3
)");
    const auto r = lsim(q(dir / "block.h5") + " " + q(scene) + " -o " + q(dir / "sim.h5") + " --png " + q(dir / "pics"), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    io::Hdf5Reader in(dir / "sim.h5");
    const io::SimulationInfo s = in.read_simulation("run");
    EXPECT_EQ(s.status, "completed");
    ASSERT_EQ(s.times.size(), 7u);
    ASSERT_FALSE(s.topology_changes.empty());
    std::map<std::string, double> st(s.statistics.begin(), s.statistics.end());
    EXPECT_GT(st.at("cut_splits") + st.at("cut_snaps"), 0);
    EXPECT_GT(st.at("cut_separations"), 0);
    EXPECT_GT(st.at("final_nodes"), st.at("nodes"));
    // The last frame's mesh: valid indices, and its tets at rest (the epoch's rest vertices are
    // not exposed; the frame's own positions suffice for the volume check) split the cube's
    // 64000 mm^3 between the two pieces: the deformed volume stays within 5 %.
    const core::TetMesh last = in.read_frame_mesh("run", s.times.size() - 1);
    double volume = 0;
    for (std::size_t t = 0; t < last.tets.size(); ++t)
        volume += core::signed_volume(last, t);
    EXPECT_NEAR(volume, 64000, 0.05 * 64000);
    bool held = false;
    for (const auto& step : s.steps)
        held = held || norm(step.force) > 0;
    EXPECT_TRUE(held);
    EXPECT_TRUE(fs::exists(dir / "pics" / "frame_000.300s.png"));
    // Every frame reads back on its own topology.
    for (std::size_t f = 0; f < s.times.size(); ++f)
        EXPECT_NO_THROW(in.read_frame_mesh("run", f)) << f;
}

TEST(Lsim, InstrumentSectionsRefuseBadValuesNamingTheLine)
{
    const fs::path dir = test::scratch_dir();
    ASSERT_EQ(lsim("--quiet --make-block " + q(dir / "block.h5") + " --cells 2,2,2", dir).exit_code, 0);
    const std::pair<std::string, std::string> cases[] = {
        {"[blade]\npose = 0 0 0 0 0 0 0\n", "bad.scene:2: the blade's two ends coincide"},
        {"[blade]\nsnap = 0.7\n", "bad.scene:2: 'snap' must be below 0.5"},
        {"[blade]\nname = b\n", "blade 'b' has no 'pose'"},
        {"[grasp]\nclose = 0.5\nopen = 0.2\n", "bad.scene:3: 'open' must come after 'close'"},
        {"[grasp]\nradius = 3\n", "forceps 'forceps0' have no 'point'"},
        {"[refine]\ncoarsen_factor = 0.5\n", "bad.scene:2: 'coarsen_factor' must be at least 1"},
        {"[refine]\nenabled = maybe\n", "bad.scene:2: 'enabled' is true or false"},
        {"[grasp]\njaws = 2\n", "bad.scene:2: unknown key 'jaws' in [grasp]"},
        {"[model]\nthreads = 1.5\n", "bad.scene:2: threads must be a whole number from 1 to 64"},
        {"[model]\nsimd = yes\n", "bad.scene:2: 'simd' is true or false, got 'yes'"},
    };
    for (const auto& [text, message] : cases) {
        const fs::path scene = write_text(dir / "bad.scene", text);
        const auto r = lsim(q(dir / "block.h5") + " " + q(scene) + " -o " + q(dir / "sim.h5"), dir);
        EXPECT_EQ(r.exit_code, 2) << text;
        EXPECT_NE(r.err.find(message), std::string::npos) << text << " -> " << r.err;
        EXPECT_FALSE(fs::exists(dir / "sim.h5"));
    }
}
