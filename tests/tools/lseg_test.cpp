// lseg run as a program: exit codes, messages, outputs.
#include "lobe/io/image_io.h"

#include "common/run_tool.h"
#include "common/test_data.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <array>
#include <string>

using namespace lobe;
namespace fs = std::filesystem;

namespace {

test::ToolRun lseg(const std::string& args, const fs::path& scratch)
{
    return test::run_tool(LSEG_EXE, args, scratch);
}

std::string q(const fs::path& p)
{
    return test::shell_quote(p.string());
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
