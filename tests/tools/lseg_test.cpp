// lseg run as a program: exit codes, messages, outputs.
#include "lobe/io/image_io.h"
#include "lobe/io/hdf5.h"

#include "common/run_tool.h"
#include "common/test_data.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <array>
#include <string>
#include <vector>

using namespace lobe;
namespace fs = std::filesystem;

namespace {

using test::q;

test::ToolRun lseg(const std::string& args, const fs::path& scratch)
{
    return test::run_tool(LSEG_EXE, args, scratch);
}

core::ImageGeometry small_grid()
{
    core::ImageGeometry g;
    g.size = {24, 20, 12};
    g.spacing = {0.8, 0.8, 2.0};
    g.origin = {-10, 5, 30};
    return g;
}

// A file holding a box of `value` voxels [lo, lo + n) on `g`, as pixel type T.
template <class T = std::uint8_t>
fs::path box_file(const fs::path& path, const core::ImageGeometry& g, std::array<int, 3> lo, std::array<int, 3> n,
                  T value = 1)
{
    core::Image3D<T> img(g, T{0});
    for (int k = lo[2]; k < lo[2] + n[2]; ++k)
        for (int j = lo[1]; j < lo[1] + n[1]; ++j)
            for (int i = lo[0]; i < lo[0] + n[0]; ++i)
                img.at(i, j, k) = value;
    io::write_image(path, img);
    return path;
}

nlohmann::json parse_json(const test::ToolRun& r)
{
    return nlohmann::json::parse(r.out);
}

} // namespace

TEST(Lseg, HelpAndUsageErrors)
{
    const auto dir = test::scratch_dir();
    auto r = lseg("--help", dir);
    EXPECT_EQ(r.exit_code, 0);
    EXPECT_NE(r.out.find("eval"), std::string::npos);
    r = lseg("eval --help", dir);
    EXPECT_EQ(r.exit_code, 0);
    EXPECT_NE(r.out.find("SLIVER07"), std::string::npos);
    EXPECT_NE(r.out.find("--ref-label"), std::string::npos);
    r = lseg("--version", dir);
    EXPECT_EQ(r.exit_code, 0);
    EXPECT_NE(r.out.find(LOBE_VERSION_STRING), std::string::npos);
    r = lseg("eval only-one.mhd", dir); // REF missing
    EXPECT_EQ(r.exit_code, 1);
    r = lseg("eval a.mhd b.mhd --label notanumber", dir);
    EXPECT_EQ(r.exit_code, 1);
}

// Identical masks: every measure is exact (Dice 1, distances 0), hence the score 100.
TEST(Lseg, EvalOfIdenticalMasksIsPerfect)
{
    const auto dir = test::scratch_dir();
    const auto a = box_file(dir / "a.mhd", small_grid(), {4, 5, 3}, {10, 8, 5});
    auto r = lseg("eval " + q(a) + " " + q(a), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("Dice"), std::string::npos);
    EXPECT_NE(r.out.find("1.0000"), std::string::npos);
    EXPECT_NE(r.out.find("100.0"), std::string::npos);
    r = lseg("eval --json " + q(a) + " " + q(a), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto j = parse_json(r);
    EXPECT_EQ(j["dice"].get<double>(), 1.0);
    EXPECT_EQ(j["maxd_mm"].get<double>(), 0.0);
    EXPECT_EQ(j["score"]["total"].get<double>(), 100.0);
    EXPECT_EQ(j["segmentation"]["voxels"].get<int>(), 10 * 8 * 5);
}

// Boxes of 10 voxels along x shifted by 2: 8 of 10 columns shared, Dice 0.8 exactly (a ratio
// of counts, 1e-12), and the Hausdorff distance is the two-voxel shift, 1.6 mm (float, 1e-5).
TEST(Lseg, EvalOfAShiftedMaskGivesTheCountedDice)
{
    const auto dir = test::scratch_dir();
    const auto g = small_grid();
    const auto ref = box_file(dir / "ref.mha", g, {4, 5, 3}, {10, 8, 5});
    const auto seg = box_file(dir / "seg.nii", g, {6, 5, 3}, {10, 8, 5});
    auto r = lseg("eval " + q(seg) + " " + q(ref) + " --json --quiet", dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.err, ""); // --quiet
    const auto j = parse_json(r);
    EXPECT_NEAR(j["dice"].get<double>(), 0.8, 1e-12);
    EXPECT_NEAR(j["jaccard"].get<double>(), 8.0 / 12.0, 1e-12);
    EXPECT_NEAR(j["rvd_percent"].get<double>(), 0.0, 1e-12);
    EXPECT_NEAR(j["maxd_mm"].get<double>(), 1.6, 1e-5);
    for (const char* key : {"voe_percent", "abs_rvd_percent", "asd_mm", "rmsd_mm"})
        EXPECT_TRUE(j.contains(key)) << key;
    for (const char* key : {"voe", "abs_rvd", "asd", "rmsd", "maxd", "total"})
        EXPECT_TRUE(j["score"].contains(key)) << key;
    EXPECT_EQ(j["segmentation"]["file"].get<std::string>(), seg.string());
    EXPECT_TRUE(j["segmentation"]["labels"].is_null());
    r = lseg("eval " + q(seg) + " " + q(ref), dir); // the table says the same
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("0.8000"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("1.60"), std::string::npos) << r.out;
}

// --label and --ref-label pick one value in each file, compared in the file's own pixel type
// (label 300 in a uint16 file is not saturated into 255).
TEST(Lseg, LabelsSelectOneValueInEachFile)
{
    const auto dir = test::scratch_dir();
    const auto g = small_grid();
    core::Image3D<std::uint16_t> multi(g, 0);
    for (int k = 2; k < 8; ++k)
        for (int j = 2; j < 10; ++j)
            for (int i = 2; i < 20; ++i)
                multi.at(i, j, k) = i < 10 ? 300 : 255;
    io::write_image(dir / "multi.mhd", multi);
    const auto ref = box_file<std::int16_t>(dir / "ref.mhd", g, {2, 2, 2}, {8, 8, 6}, 5);
    auto r = lseg("eval --json " + q(dir / "multi.mhd") + " " + q(ref) + " --label 300 --ref-label 5", dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    auto j = parse_json(r);
    EXPECT_EQ(j["dice"].get<double>(), 1.0);
    EXPECT_EQ(j["segmentation"]["labels"], nlohmann::json::array({300}));
    EXPECT_EQ(j["reference"]["labels"], nlohmann::json::array({5}));
    r = lseg("eval --json " + q(dir / "multi.mhd") + " " + q(ref), dir); // every non-zero voxel: 18 columns vs 8
    ASSERT_EQ(r.exit_code, 0) << r.err;
    j = parse_json(r);
    EXPECT_NEAR(j["dice"].get<double>(), 2.0 * 8 / (18 + 8), 1e-12);
    // A set of values: 300 and 255 together are every non-zero voxel again.
    r = lseg("eval --json " + q(dir / "multi.mhd") + " " + q(ref) + " --label 300,255", dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NEAR(parse_json(r)["dice"].get<double>(), 2.0 * 8 / (18 + 8), 1e-12);
}

// --slice compares one axial slice: a 2-D result against a reference volume.
TEST(Lseg, EvalOneSliceOfAVolume)
{
    const auto dir = test::scratch_dir();
    const auto g = small_grid();
    const auto vol = box_file(dir / "vol.mhd", g, {4, 4, 2}, {10, 8, 6});
    core::LabelImage3D slice(g, 0);
    slice = core::axial_slice(slice, 5);
    for (int j = 4; j < 12; ++j)
        for (int i = 4; i < 9; ++i) // half the box's width
            slice.at(i, j, 0) = 1;
    io::write_image(dir / "slice.mhd", slice);
    auto r = lseg("eval --json " + q(dir / "slice.mhd") + " " + q(vol) + " --slice 5", dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NEAR(parse_json(r)["dice"].get<double>(), 2.0 * 40 / (40 + 80), 1e-12);
    r = lseg("eval " + q(dir / "slice.mhd") + " " + q(vol) + " --slice 1", dir); // the box starts at slice 2
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("slice 1"), std::string::npos) << r.err;
    r = lseg("eval " + q(dir / "slice.mhd") + " " + q(vol) + " --slice 12", dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("outside"), std::string::npos) << r.err;
}

TEST(Lseg, BadInputNamesTheFileAndExitsTwo)
{
    const auto dir = test::scratch_dir();
    const auto g = small_grid();
    const auto a = box_file(dir / "a.mhd", g, {4, 5, 3}, {10, 8, 5});
    auto g2 = g;
    g2.spacing[2] = 2.5;
    const auto other = box_file(dir / "other-grid.mhd", g2, {4, 5, 3}, {10, 8, 5});
    const auto empty = box_file(dir / "empty.mhd", g, {0, 0, 0}, {0, 0, 0});

    auto r = lseg("eval " + q(dir / "missing.mhd") + " " + q(a), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("missing.mhd"), std::string::npos) << r.err;

    r = lseg("eval " + q(a) + " " + q(other), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("other-grid.mhd"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("same grid"), std::string::npos) << r.err;

    r = lseg("eval " + q(empty) + " " + q(a), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("empty.mhd"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("empty"), std::string::npos) << r.err;

    r = lseg("eval " + q(a) + " " + q(a) + " --ref-label 7", dir); // no voxel of label 7
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("label 7"), std::string::npos) << r.err;

    r = lseg("eval " + q(dir / "a.txt") + " " + q(a), dir); // unknown format
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("a.txt"), std::string::npos) << r.err;
    EXPECT_TRUE(r.out.empty()); // no half report on stdout
}

// The shared CT's liver-only mask is its multi-organ label 5: identical, so Dice 1 exactly.
TEST(Lseg, EvalOnTheSharedCtLiver)
{
    const auto ct = test::data_dir() / "ct-small";
    LOBE_REQUIRE_PATH(ct / "liver.mhd");
    const auto dir = test::scratch_dir();
    const auto r = lseg("eval --json " + q(ct / "liver.mhd") + " " + q(ct / "labels.mhd") + " --ref-label 5", dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto j = parse_json(r);
    EXPECT_EQ(j["dice"].get<double>(), 1.0);
    EXPECT_EQ(j["score"]["total"].get<double>(), 100.0);
}

// ---------------------------------------------------------------------------------------------
// lseg snake tests are added below by the snake work
// ---------------------------------------------------------------------------------------------

namespace {

// A 2-D slice stack: a bright disc (150 HU on 0) of radius 20 voxels in every slice.
core::ImageGeometry disc_grid()
{
    core::ImageGeometry g;
    g.size = {64, 64, 3};
    g.spacing = {1.0, 1.0, 2.0};
    return g;
}

fs::path disc_file(const fs::path& path, double radius, std::int16_t value)
{
    const auto g = disc_grid();
    core::Image3D<std::int16_t> img(g, 0);
    for (int k = 0; k < g.size[2]; ++k)
        for (int j = 0; j < g.size[1]; ++j)
            for (int i = 0; i < g.size[0]; ++i)
                if ((i - 32) * (i - 32) + (j - 32) * (j - 32) <= radius * radius)
                    img.at(i, j, k) = value;
    io::write_image(path, img);
    return path;
}

} // namespace

// lseg snake on one slice from a seed, then lseg eval of the result against the disc.
TEST(LsegSnake, SegmentsASliceFromASeedAndRecordsProvenance)
{
    const auto dir = test::scratch_dir();
    const auto ct = disc_file(dir / "ct.mhd", 20, 150);
    const auto ref = disc_file(dir / "ref.mhd", 20, 1);
    for (const std::string method : {"cdsg", "gac"}) {
        const auto out = dir / ("snake-" + method + ".h5");
        auto r = lseg("snake " + q(ct) + " --slice 1 --seed 32,32,1 --method " + method + " -o " + q(out) +
                          " --mask " + q(dir / ("mask-" + method + ".mhd")) + " --png " + q(dir / (method + ".png")),
                      dir);
        ASSERT_EQ(r.exit_code, 0) << r.err;
        EXPECT_NE(r.err.find("converged"), std::string::npos) << r.err;
        ASSERT_TRUE(fs::exists(out));
        EXPECT_TRUE(fs::exists(dir / (method + ".png")));
        const io::Hdf5Reader h5(out);
        EXPECT_EQ(h5.labels(), std::vector<std::string>{"snake"});
        const auto prov = h5.provenance();
        ASSERT_EQ(prov.size(), 1u);
        bool converged = false, has_method = false;
        int iterations = -1, reinitialisations = -1;
        for (const auto& [k, v] : prov[0].parameters) {
            converged = converged || (k == "result.converged" && v == "true");
            has_method = has_method || (k.find("method") != std::string::npos && v == method);
            if (k == "result.iterations")
                iterations = std::stoi(v);
            if (k == "result.reinitialisations")
                reinitialisations = std::stoi(v);
        }
        EXPECT_TRUE(converged);
        EXPECT_TRUE(has_method);
        // The front moves 15 mm from the 5 mm seed ball, farther than the band's 4 mm half-width,
        // so φ was re-initialised at least once, and never more than once per step.
        EXPECT_GE(reinitialisations, 1) << method;
        EXPECT_LE(reinitialisations, iterations) << method;
        // A disc of radius 20 found to within about a voxel: Dice > 0.95.
        r = lseg("eval --json " + q(out) + " " + q(ref) + " --slice 1", dir);
        ASSERT_EQ(r.exit_code, 0) << r.err;
        EXPECT_GT(parse_json(r)["dice"].get<double>(), 0.95) << method;
    }
}

// --3d segments the volume; --init takes a mask file.
TEST(LsegSnake, VolumeFromAnInitialMask)
{
    const auto dir = test::scratch_dir();
    const auto ct = disc_file(dir / "ct.mhd", 20, 150);
    const auto init = disc_file(dir / "init.mhd", 6, 1);
    const auto ref = disc_file(dir / "ref.mhd", 20, 1);
    auto r = lseg("snake " + q(ct) + " --3d --init " + q(init) + " -o " + q(dir / "vol.h5") + " --quiet", dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(r.err.empty()) << "--quiet: " << r.err;
    r = lseg("eval --json " + q(dir / "vol.h5") + " " + q(ref), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_GT(parse_json(r)["dice"].get<double>(), 0.95);
}

TEST(LsegSnake, BadInputAndUsage)
{
    const auto dir = test::scratch_dir();
    const auto ct = disc_file(dir / "ct.mhd", 20, 150);
    auto r = lseg("snake " + q(ct) + " --seed 32,32,1 -o " + q(dir / "a.h5"), dir);
    EXPECT_EQ(r.exit_code, 2) << "a volume needs --slice or --3d";
    EXPECT_NE(r.err.find("--slice"), std::string::npos) << r.err;
    r = lseg("snake " + q(ct) + " --slice 1 -o " + q(dir / "a.h5"), dir);
    EXPECT_EQ(r.exit_code, 1) << "no --init or --seed";
    r = lseg("snake " + q(ct) + " --slice 7 --seed 32,32,7 -o " + q(dir / "a.h5"), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("outside"), std::string::npos) << r.err;
    r = lseg("snake " + q(ct) + " --slice 1 --seed 32,32,1 --method nope -o " + q(dir / "a.h5"), dir);
    EXPECT_EQ(r.exit_code, 1);
    r = lseg("snake " + q(ct) + " --slice 1 --seed 32,32,1 --leak-checks -1 -o " + q(dir / "a.h5"), dir);
    EXPECT_EQ(r.exit_code, 1) << "a negative leak-stop count";
    EXPECT_NE(r.err.find("--leak-checks"), std::string::npos) << r.err;
    r = lseg("snake " + q(dir / "missing.mhd") + " --slice 1 --seed 32,32,1 -o " + q(dir / "a.h5"), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("missing.mhd"), std::string::npos) << r.err;
    const auto empty = disc_file(dir / "empty.mhd", 0, 0);
    r = lseg("snake " + q(ct) + " --slice 1 --init " + q(empty) + " -o " + q(dir / "a.h5"), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("empty.mhd"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "a.h5")) << "nothing half-written";
    // Out of iterations: written, flagged, and exit 3 only when convergence is required.
    r = lseg("snake " + q(ct) + " --slice 1 --seed 32,32,1 --max-iterations 3 -o " + q(dir / "b.h5"), dir);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("NOT converge"), std::string::npos) << r.err;
    r = lseg("snake " + q(ct) + " --slice 1 --seed 32,32,1 --max-iterations 3 --require-convergence -o " +
                 q(dir / "c.h5"),
             dir);
    EXPECT_EQ(r.exit_code, 3) << r.err;
    r = lseg("snake --help", dir);
    EXPECT_EQ(r.exit_code, 0);
    EXPECT_NE(r.out.find("--method"), std::string::npos);
}
