// lseg train run as a program: trains from lphantom volumes, reads the file back, bad inputs.
#include "lobe/io/hdf5.h"
#include "lobe/io/image_io.h"
#include "lobe/seg/shape_memory.h"

#include "common/expect_error.h"
#include "common/run_tool.h"
#include "tools/lseg_run.h"
#include "common/test_data.h"

// The reader lives in the tool (tools/lseg); tests/CMakeLists.txt compiles it into this test.
#include "lseg/shape_file.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

using namespace lobe;
namespace fs = std::filesystem;

namespace {

using test::q;
using test::run_lseg;

//! A coarse phantom (fast) written by lphantom into `dir`.
fs::path phantom_dir(const fs::path& dir, const std::string& spacing, int seed)
{
    const auto r = test::run_tool(LPHANTOM_EXE, q(dir) + " --spacing " + spacing + " --seed " + std::to_string(seed) +
                                                    " --quiet",
                                  dir.parent_path());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return dir;
}

core::LabelImage3D liver_of(const fs::path& labels)
{
    const auto l = core::convert_image<std::int32_t>(io::read_image(labels));
    core::LabelImage3D m(l.geometry(), 0);
    for (std::size_t i = 0; i < m.data.size(); ++i)
        m.data[i] = l.data[i] >= 1 && l.data[i] <= 4 ? 1 : 0;
    return m;
}

} // namespace

TEST(LsegTrain, TrainsFromPhantomsAndReadsBack)
{
    const auto dir = test::scratch_dir();
    const auto a = phantom_dir(dir / "a", "2.8,2.8,5", 1);
    const auto b = phantom_dir(dir / "b", "2.4,2.4,4", 2);
    const auto out = dir / "shape.h5";
    const auto r = run_lseg("train --image " + q(a / "ct.mhd") + " --labels " + q(a / "labels.mhd") + " --image " +
                            q(b / "ct.mhd") + " --labels " + q(b / "labels.mhd") + " --label 1,2,3,4 -o " + q(out),
                        dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("2 volumes"), std::string::npos) << r.err;
    ASSERT_TRUE(fs::exists(out));

    // Round trip: the file holds exactly what training the same pairs in-process gives.
    const seg::ShapeMemory m = lseg::read_shape_memory(out);
    const auto ia = core::convert_image<float>(io::read_image(a / "ct.mhd"));
    const auto ib = core::convert_image<float>(io::read_image(b / "ct.mhd"));
    const auto la = liver_of(a / "labels.mhd"), lb = liver_of(b / "labels.mhd");
    const seg::ShapeMemory ref = seg::train_shape_memory({&ia, &ib}, {&la, &lb});
    EXPECT_EQ(m.volumes, 2);
    EXPECT_EQ(m.slices, ref.slices);
    EXPECT_EQ(m.transitions, ref.transitions);
    EXPECT_EQ(m.margin, ref.margin);
    EXPECT_EQ(m.intensity.modality, "CT");
    EXPECT_EQ(m.intensity.mean, ref.intensity.mean); // float64 stored: bit-exact
    EXPECT_EQ(m.intensity.quantiles, ref.intensity.quantiles);
    EXPECT_EQ(m.volume_ml_min, ref.volume_ml_min);
    ASSERT_EQ(m.steps.size(), ref.steps.size());
    for (std::size_t s = 0; s < m.steps.size(); ++s) {
        EXPECT_EQ(m.steps[s].radius_min_mm, ref.steps[s].radius_min_mm);
        EXPECT_EQ(m.steps[s].radius_max_mm, ref.steps[s].radius_max_mm);
        EXPECT_EQ(m.steps[s].rho_min, ref.steps[s].rho_min);
        EXPECT_EQ(m.steps[s].rho_max, ref.steps[s].rho_max);
        EXPECT_EQ(m.steps[s].transitions, ref.steps[s].transitions);
        EXPECT_EQ(m.steps[s].outward_per_mm, ref.steps[s].outward_per_mm);
        EXPECT_EQ(m.steps[s].envelope_per_mm, ref.steps[s].envelope_per_mm);
        EXPECT_EQ(m.steps[s].inward_per_mm, ref.steps[s].inward_per_mm);
        EXPECT_EQ(m.steps[s].growth_per_mm, ref.steps[s].growth_per_mm);
        EXPECT_EQ(m.steps[s].shrink_per_mm, ref.steps[s].shrink_per_mm);
        EXPECT_EQ(m.steps[s].centroid_per_mm, ref.steps[s].centroid_per_mm);
    }
    // Provenance: the training files and the timings.
    const io::Hdf5Reader h5(out);
    const auto prov = h5.provenance();
    ASSERT_EQ(prov.size(), 1u);
    EXPECT_EQ(prov[0].tool, "lseg");
    bool has_file = false, has_train_time = false;
    for (const auto& [k, v] : prov[0].parameters)
        has_file = has_file || (k == "training.2.labels" && v == (b / "labels.mhd").string());
    for (const auto& [k, v] : prov[0].timings)
        has_train_time = has_train_time || k == "train";
    EXPECT_TRUE(has_file);
    EXPECT_TRUE(has_train_time);
}

TEST(LsegTrain, BadInputsFailNamingTheFile)
{
    const auto dir = test::scratch_dir();
    const auto a = phantom_dir(dir / "a", "2.8,2.8,5", 1);
    const auto b = phantom_dir(dir / "b", "2.4,2.4,4", 2);
    const auto out = dir / "shape.h5";
    // Missing file: CLI11's existence check (usage error).
    auto r = run_lseg("train --image " + q(dir / "nope.mhd") + " --labels " + q(a / "labels.mhd") + " -o " + q(out), dir);
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.err.find("nope.mhd"), std::string::npos) << r.err;
    // Labels on another grid.
    r = run_lseg("train --image " + q(a / "ct.mhd") + " --labels " + q(b / "labels.mhd") + " -o " + q(out), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find((b / "labels.mhd").string()), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("grid"), std::string::npos) << r.err;
    // No liver voxels with the chosen label.
    r = run_lseg("train --image " + q(a / "ct.mhd") + " --labels " + q(a / "labels.mhd") + " --label 99 -o " + q(out),
             dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("no liver voxels"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("labels.mhd"), std::string::npos) << r.err;
    // Unpaired --image / --labels.
    r = run_lseg("train --image " + q(a / "ct.mhd") + " --image " + q(b / "ct.mhd") + " --labels " + q(a / "labels.mhd") +
                 " -o " + q(out),
             dir);
    EXPECT_NE(r.exit_code, 0);
    EXPECT_FALSE(fs::exists(out)); // nothing left behind by any failure
    for (const auto& name : test::list_dir(dir))
        EXPECT_EQ(name.find("shape"), std::string::npos) << name;

    // Reading: not a shape memory, and not HDF5 at all.
    io::write_hdf5_image(dir / "other.h5", core::LabelImage3D(core::ImageGeometry{{2, 2, 1}}, 0));
    EXPECT_LOBE_ERROR(core::InvalidInputError, lseg::read_shape_memory(dir / "other.h5"), "other.h5",
                      "not a shape memory");
    std::ofstream(dir / "junk.h5") << "junk";
    EXPECT_THROW(lseg::read_shape_memory(dir / "junk.h5"), core::Error);
}
