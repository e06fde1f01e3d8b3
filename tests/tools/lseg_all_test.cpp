// lseg all and lseg tumours run as programs: the tissue label volume (0-4) with its table, volumes
// in mL, the vessel graph, pictures and provenance; the automatic liver; seed points; refusals.
#include "lobe/io/hdf5.h"
#include "lobe/io/image_io.h"

#include "common/run_tool.h"
#include "tools/lseg_run.h"
#include "common/test_data.h"
#include "common/orientation.h"
#include "common/pictures.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>

using namespace lobe;
namespace fs = std::filesystem;

namespace {

using test::q;
using test::run_lseg;
using test::parameter;


double dice_of(const fs::path& seg, const fs::path& ref, int label, const fs::path& dir)
{
    const auto r = test::run_tool(LSEG_EXE,
                                  "eval " + q(seg) + " " + q(ref) + " --seg-name tissues --label " + std::to_string(label) +
                                      " --ref-label " + std::to_string(label) + " --json",
                                  dir);
    return r.exit_code != 0 ? -1.0 : test::dice_from_eval(r.out);
}

} // namespace

// The phantom at 1.5 x 1.5 x 3 mm with its truth liver: one label volume whose every tissue
// matches the truth (measured Dice: parenchyma 0.996, portal 0.936, hepatic 0.942, tumour 0.938),
// volumes that add up, the graph, the pictures and the provenance.
TEST(LsegAll, OneLabelVolumeWithVolumesGraphAndPictures)
{
    const auto dir = test::scratch_dir();
    auto r = test::run_tool(LPHANTOM_EXE, q(dir / "ph") + " --spacing 1.5,1.5,3 --seed 8 --quiet", dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto out = dir / "all.h5";
    r = run_lseg("all " + q(dir / "ph" / "ct.mhd") + " --liver " + q(dir / "ph" / "labels.mhd") +
                     " --liver-label 1,2,3,4 -o " + q(out) + " --png " + q(dir / "pics") + " --labels-out " +
                     q(dir / "tissues.nii.gz"),
                 dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    for (const char* row : {"liver_parenchyma", "portal_vein", "hepatic_veins", "tumour", "3 tumours"})
        EXPECT_NE(r.out.find(row), std::string::npos) << row << "\n" << r.out;
    for (const char* pic : {"all-axial.png", "all-coronal.png", "vessels-tree.png", "tumour-1.png", "tumour-3.png"})
        EXPECT_TRUE(fs::exists(dir / "pics" / pic)) << pic;
    EXPECT_TRUE(fs::exists(dir / "tissues.nii.gz"));

    const io::Hdf5Reader h5(out);
    const auto tissues = h5.read_labels("tissues");
    ASSERT_EQ(tissues.table.size(), 4u);
    EXPECT_EQ(tissues.table[0].name, "liver");
    EXPECT_EQ(tissues.table[3].name, "tumour");
    EXPECT_TRUE(std::all_of(tissues.image.data.begin(), tissues.image.data.end(), [](std::uint8_t v) { return v <= 4; }));
    EXPECT_FALSE(h5.read_graph("vessels").edges.empty());
    const io::Provenance prov = h5.provenance().back();
    double parts = 0;
    for (const char* k : {"volume_ml.liver_parenchyma", "volume_ml.portal_vein", "volume_ml.hepatic_veins", "volume_ml.tumour"})
        parts += std::stod(parameter(prov, k));
    EXPECT_NEAR(parts, std::stod(parameter(prov, "volume_ml.liver")), 0.01);
    EXPECT_EQ(parameter(prov, "tumours.count"), "3");
    EXPECT_EQ(parameter(prov, "vessels.found"), "true");

    const double minimum[5] = {0, 0.98, 0.85, 0.85, 0.85};
    for (int l = 1; l <= 4; ++l)
        EXPECT_GE(dice_of(out, dir / "ph" / "labels.mhd", l, dir), minimum[l]) << "label " << l;
}

// The same phantom and liver stored as a coronal stack (rows along x, columns to the feet, slices
// to the back): the tissue labels are the axial run's reordered, voxel for voxel (the vessels run
// on the patient frame's grid), the same volumes are printed, and every picture is the axial
// run's pixel for pixel but for the caption (the views follow the patient's axes; the captions
// name the stored voxel index).
TEST(LsegAll, ACoronalStackGivesTheSameLabelsAndPictures)
{
    const auto dir = test::scratch_dir();
    auto r = test::run_tool(LPHANTOM_EXE, q(dir / "ph") + " --spacing 1.5,1.5,3 --seed 8 --quiet", dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const core::AxisOrder order = test::coronal_storage();
    io::write_image(dir / "ct-coronal.mhd",
                    core::reorder_axes(std::get<core::ImageI16>(io::read_image(dir / "ph" / "ct.mhd")), order));
    io::write_image(dir / "labels-coronal.mhd",
                    core::reorder_axes(std::get<core::LabelImage3D>(io::read_image(dir / "ph" / "labels.mhd")), order));
    std::string printed[2];
    for (int run = 0; run < 2; ++run) {
        const std::string name = run == 0 ? "axial" : "coronal";
        const fs::path ct = run == 0 ? dir / "ph" / "ct.mhd" : dir / "ct-coronal.mhd";
        const fs::path labels = run == 0 ? dir / "ph" / "labels.mhd" : dir / "labels-coronal.mhd";
        r = run_lseg("all " + q(ct) + " --liver " + q(labels) + " --liver-label 1,2,3,4 -o " + q(dir / (name + ".h5")) +
                         " --png " + q(dir / name) + " --labels-out " + q(dir / (name + "-tissues.mhd")) + " --quiet",
                     dir);
        ASSERT_EQ(r.exit_code, 0) << r.err;
        printed[run] = r.out;
    }
    EXPECT_EQ(printed[1], printed[0]);
    const auto axial = std::get<core::LabelImage3D>(io::read_image(dir / "axial-tissues.mhd"));
    const auto coronal = std::get<core::LabelImage3D>(io::read_image(dir / "coronal-tissues.mhd"));
    EXPECT_TRUE(core::reorder_axes(axial, order).data == coronal.data);
    int pictures = 0;
    for (const auto& e : fs::directory_iterator(dir / "axial")) {
        ++pictures;
        EXPECT_EQ(test::picture_difference_above_caption(e.path(), dir / "coronal" / e.path().filename()), "")
            << e.path().filename();
    }
    EXPECT_GE(pictures, 5);
}

// Without --liver the automatic liver pipeline runs first (a coarse phantom, as in
// lseg_liver_test), and the structures are searched in its mask.
TEST(LsegAll, AutomaticLiverFirst)
{
    const auto dir = test::scratch_dir();
    auto r = test::run_tool(LPHANTOM_EXE, q(dir / "ph") + " --spacing 2.1,2.1,5 --seed 4 --quiet", dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    r = run_lseg("all " + q(dir / "ph" / "ct.mhd") + " -o " + q(dir / "all.h5"), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("automatic liver pipeline"), std::string::npos) << r.err;
    const io::Hdf5Reader h5(dir / "all.h5");
    EXPECT_EQ(parameter(h5.provenance().back(), "liver_mask"), "automatic (lseg liver)");
    // The liver (all tissue labels) against the truth's liver with its vessels and tumours: the
    // liver pipeline's own accuracy on this grid (measured 0.83 in lseg_liver_test).
    r = run_lseg("eval " + q(dir / "all.h5") + " " + q(dir / "ph" / "labels.mhd") +
                     " --seg-name tissues --label 1,2,3,4 --ref-label 1,2,3,4 --json",
                 dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const double dice = test::dice_from_eval(r.out);
    ASSERT_GE(dice, 0) << r.out;
    EXPECT_GE(dice, 0.7) << r.out;
}

// lseg tumours with a seed at the satellite (lphantom's truth: (-60, -35, 7) mm) returns that
// tumour only; malformed seeds are a bad command line (1); a seed outside the liver is bad input
// (2) naming the image; nothing is written when it fails.
TEST(LsegTumours, SeedPointsAndRefusals)
{
    const auto dir = test::scratch_dir();
    auto r = test::run_tool(LPHANTOM_EXE, q(dir / "ph") + " --spacing 1.5,1.5,3 --seed 8 --quiet", dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const std::string base = "tumours " + q(dir / "ph" / "ct.mhd") + " --liver " + q(dir / "ph" / "labels.mhd") +
                             " --liver-label 1,2,3,4 ";
    r = run_lseg(base + "-o " + q(dir / "t.h5") + " --seed=-60,-35,7 --png " + q(dir / "pics"), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("1 tumour:"), std::string::npos) << r.err;
    EXPECT_TRUE(fs::exists(dir / "pics" / "tumour-1.png"));
    const io::Hdf5Reader h5(dir / "t.h5");
    EXPECT_EQ(parameter(h5.provenance().back(), "tumours.count"), "1");
    EXPECT_NE(parameter(h5.provenance().back(), "tumours.tumour0").find("from a seed"), std::string::npos);
    const auto m = h5.read_labels("tumours").image;
    const std::size_t voxels = static_cast<std::size_t>(std::count(m.data.begin(), m.data.end(), std::uint8_t{4}));
    const double ml = static_cast<double>(voxels) * 1.5 * 1.5 * 3 / 1000;
    EXPECT_GT(ml, 0.4); // the satellite is 0.9 mL
    EXPECT_LT(ml, 1.4);

    r = run_lseg(base + "-o " + q(dir / "a.h5") + " --seed=1,2", dir);
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.err.find("x,y,z"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "a.h5"));
    r = run_lseg(base + "-o " + q(dir / "b.h5") + " --seed=0,0,500", dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("ct.mhd"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("not inside the liver"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "b.h5"));
}
