// lseg vessels run as a program: outputs (labels, graph, pictures, provenance), the liver mask's
// sources, a scan without vessels, and refusals.
#include "lobe/io/hdf5.h"
#include "lobe/io/image_io.h"

#include "common/run_tool.h"
#include "tools/lseg_run.h"
#include "common/test_data.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <iostream>
#include <string>

using namespace lobe;
namespace fs = std::filesystem;

namespace {

using test::q;
using test::run_lseg;
using test::dice_from_eval;
using test::parameter;


} // namespace

// A coarse phantom (1.5 x 1.5 x 3 mm, about a second) with its truth liver: the container holds
// the image, the liver mask, the vessel labels with their table and the centre-line graph with 4
// branch levels; the pictures exist; `lseg eval` reads the labels back (measured Dice 0.94 against
// the truth's labels 2 and 3; tests/seg/vessels_test.cpp holds the accuracy checks, this one the
// plumbing).
TEST(LsegVessels, SegmentsThePhantomsTreesAndRecordsWhatItDid)
{
    const auto dir = test::scratch_dir();
    auto r = test::run_tool(LPHANTOM_EXE, q(dir / "ph") + " --spacing 1.5,1.5,3 --seed 8 --quiet", dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto out = dir / "v.h5";
    r = run_lseg("vessels " + q(dir / "ph" / "ct.mhd") + " --liver " + q(dir / "ph" / "labels.mhd") +
                     " --liver-label 1,2,3,4 -o " + q(out) + " --png " + q(dir / "pics") + " --labels-out " +
                     q(dir / "vessels.nii.gz"),
                 dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("seeds:"), std::string::npos) << r.err; // progress on stderr
    EXPECT_NE(r.err.find("3 trees (1 portal)"), std::string::npos) << r.err;
    for (const char* pic : {"vessels-axial.png", "vessels-coronal.png", "vessels-tree.png"})
        EXPECT_TRUE(fs::exists(dir / "pics" / pic)) << pic;
    EXPECT_TRUE(fs::exists(dir / "vessels.nii.gz"));

    const io::Hdf5Reader h5(out);
    const auto labels = h5.labels();
    EXPECT_NE(std::find(labels.begin(), labels.end(), "vessels"), labels.end());
    EXPECT_NE(std::find(labels.begin(), labels.end(), "liver"), labels.end());
    const auto table = h5.read_labels("vessels").table;
    ASSERT_EQ(table.size(), 2u);
    EXPECT_EQ(table[0].name, "portal_vein");
    ASSERT_EQ(h5.graphs(), std::vector<std::string>{"vessels"});
    const auto graph = h5.read_graph("vessels");
    int levels = 0, named = 0;
    for (const auto& e : graph.edges) {
        levels = std::max(levels, static_cast<int>(e.level));
        named += !e.name.empty();
    }
    EXPECT_GE(levels, 4);
    EXPECT_GE(named, 4); // PV, RPV, LPV and the hepatic trunks
    const auto prov = h5.provenance();
    ASSERT_FALSE(prov.empty());
    EXPECT_EQ(parameter(prov.back(), "vessels.found"), "true");
    EXPECT_EQ(parameter(prov.back(), "vessels.separated_by"), "contrast");
    EXPECT_FALSE(parameter(prov.back(), "vessels.portal_ml").empty());
    EXPECT_NE(parameter(prov.back(), "liver_mask").find("labels.mhd"), std::string::npos);
    bool timed = false;
    for (const auto& [name, seconds] : prov.back().timings)
        timed = timed || (name == "vessels.fuzzy connectedness" && seconds > 0);
    EXPECT_TRUE(timed);

    r = run_lseg("eval " + q(out) + " " + q(dir / "ph" / "labels.mhd") + " --seg-name vessels --label 2,3 --ref-label 2,3 --json",
                 dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_GE(dice_from_eval(r.out), 0.85) << r.out;
}

// The liver from an .h5 input (what lseg liver writes), and a scan without vessels: exit 0, the
// message says so, and the labels and graph are empty (nothing rather than noise).
TEST(LsegVessels, LiverFromTheInputContainerAndNoVessels)
{
    const auto dir = test::scratch_dir();
    auto r = test::run_tool(LPHANTOM_EXE, q(dir / "ph") + " --spacing 1.5,1.5,3 --seed 9 --no-vessels --quiet", dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    // A container like lseg liver's: the image and labels/liver.
    {
        const auto ct = io::read_image(dir / "ph" / "ct.mhd");
        auto lab = std::get<core::LabelImage3D>(io::read_image(dir / "ph" / "labels.mhd"));
        for (auto& v : lab.data)
            v = v >= 1 && v <= 4 ? 1 : 0;
        io::Hdf5Writer w(dir / "liver.h5");
        w.write_image("image", ct);
        w.write_labels("liver", lab);
        w.commit();
    }
    const auto out = dir / "v.h5";
    r = run_lseg("vessels " + q(dir / "liver.h5") + " -o " + q(out), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("labels/liver of the input"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("no vessels"), std::string::npos) << r.err;
    const io::Hdf5Reader h5(out);
    const auto v = h5.read_labels("vessels").image;
    EXPECT_TRUE(std::all_of(v.data.begin(), v.data.end(), [](std::uint8_t x) { return x == 0; }));
    EXPECT_TRUE(h5.read_graph("vessels").edges.empty());
    EXPECT_EQ(parameter(h5.provenance().back(), "vessels.found"), "false");
}

// Inputs it cannot use: a message naming the file, exit code 2, and no output left behind.
TEST(LsegVessels, RefusesWithAClearMessageAndNoOutput)
{
    const auto dir = test::scratch_dir();
    core::ImageGeometry g;
    g.size = {40, 40, 12};
    g.spacing = {2, 2, 3};
    core::Image3D<std::int16_t> ct(g, std::int16_t{100});
    for (int k = 0; k < g.size[2]; ++k) // a row of air on each slice: it reads as a CT
        for (int i = 0; i < g.size[0]; ++i)
            ct.at(i, 0, k) = -1000;
    io::write_image(dir / "ct.mhd", ct);
    g.size[2] = 11;
    io::write_image(dir / "other.mhd", core::LabelImage3D(g, 1));
    g.size[2] = 12;
    io::write_image(dir / "empty.mhd", core::LabelImage3D(g, 0));

    auto r = run_lseg("vessels " + q(dir / "ct.mhd") + " --liver " + q(dir / "other.mhd") + " -o " + q(dir / "a.h5"), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("other.mhd"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("grid"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "a.h5"));

    r = run_lseg("vessels " + q(dir / "ct.mhd") + " --liver " + q(dir / "empty.mhd") + " -o " + q(dir / "b.h5"), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("empty.mhd"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("empty"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "b.h5"));

    r = run_lseg("vessels " + q(dir / "ct.mhd") + " --liver " + q(dir / "missing.mhd") + " -o " + q(dir / "c.h5"), dir);
    EXPECT_NE(r.exit_code, 0);
    EXPECT_FALSE(fs::exists(dir / "c.h5"));

    r = run_lseg("vessels " + q(dir / "ct.mhd") + " -o " + q(dir / "d.h5") + " --link-threshold 2", dir);
    EXPECT_EQ(r.exit_code, 1); // a bad command line
    EXPECT_FALSE(fs::exists(dir / "d.h5"));
}

// A volume with no air reads as MR (seg::detect_modality): vessels, tumours and all refuse it with
// exit 2, a message naming the file and the way round, and no output, since their contrast and
// fluid thresholds are HU; `--modality ct` runs them anyway.
TEST(LsegVessels, StructuresRefuseAVolumeThatReadsAsMr)
{
    const auto dir = test::scratch_dir();
    core::ImageGeometry g;
    g.size = {40, 40, 12};
    g.spacing = {2, 2, 3};
    io::write_image(dir / "mr.mhd", core::Image3D<std::int16_t>(g, std::int16_t{100}));
    io::write_image(dir / "liver.mhd", core::LabelImage3D(g, 1));
    for (const std::string command : {"vessels", "tumours", "all"}) {
        const fs::path out = dir / (command + ".h5");
        auto r = run_lseg(command + " " + q(dir / "mr.mhd") + " --liver " + q(dir / "liver.mhd") + " -o " + q(out), dir);
        EXPECT_EQ(r.exit_code, 2) << command << ": " << r.err;
        EXPECT_NE(r.err.find("mr.mhd"), std::string::npos) << r.err;
        EXPECT_NE(r.err.find("reads as MR"), std::string::npos) << r.err;
        EXPECT_NE(r.err.find("--modality ct"), std::string::npos) << r.err;
        EXPECT_FALSE(fs::exists(out)) << command;
        r = run_lseg(command + " " + q(dir / "mr.mhd") + " --liver " + q(dir / "liver.mhd") + " -o " + q(out) +
                         " --modality ct --quiet",
                     dir);
        EXPECT_EQ(r.exit_code, 0) << command << ": " << r.err;
        EXPECT_TRUE(fs::exists(out)) << command;
    }
    const auto r = run_lseg("vessels " + q(dir / "mr.mhd") + " -o " + q(dir / "x.h5") + " --modality mr", dir);
    EXPECT_EQ(r.exit_code, 1) << r.err; // a bad command line: only auto and ct
    EXPECT_FALSE(fs::exists(dir / "x.h5"));
}

// The shared real scans (skipped without ../shared/data). Neither has vessel labels inside the
// liver, so accuracy cannot be measured on them; what can be checked is the failure case "no
// contrast" on a real scan, and that on an enhanced one what is found is bright vessel inside the
// liver. ct-small is unenhanced (medians: liver 46 HU, portal vein 38, vena cava 39): no vessels.
// ct-dicom-jpeg2000 is portal-venous (liver 93 HU, portal vein 133): trees are found, every vessel
// voxel lies in the liver, and their median is at least 25 HU above the liver's (measured: 7 trees,
// 9.5 mL, vessel median 126 HU against the liver's 93).
TEST(LsegVessels, RealScansUnenhancedAndPortalVenous)
{
    const fs::path data = test::data_dir();
    if (!fs::exists(data / "ct-small" / "ct.mhd") || !fs::exists(data / "ct-dicom-jpeg2000" / "dicom"))
        GTEST_SKIP() << "shared scans not found in " << data;
    const auto dir = test::scratch_dir();
    auto r = run_lseg("vessels " + q(data / "ct-small" / "ct.mhd") + " --liver " + q(data / "ct-small" / "liver.mhd") +
                          " -o " + q(dir / "small.h5"),
                      dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("no vessels"), std::string::npos) << r.err;

    r = run_lseg("vessels " + q(data / "ct-dicom-jpeg2000" / "dicom") + " --liver " +
                     q(data / "ct-dicom-jpeg2000" / "liver.mhd") + " -o " + q(dir / "dicom.h5"),
                 dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const io::Hdf5Reader h5(dir / "dicom.h5");
    const auto vessels = h5.read_labels("vessels").image;
    const auto liver = h5.read_labels("liver").image;
    const auto image = core::convert_image<float>(h5.read_image("image"));
    std::vector<float> in_vessels, in_liver;
    std::size_t outside = 0;
    for (std::size_t u = 0; u < vessels.data.size(); ++u) {
        if (vessels.data[u]) {
            in_vessels.push_back(image.data[u]);
            outside += liver.data[u] == 0;
        } else if (liver.data[u]) {
            in_liver.push_back(image.data[u]);
        }
    }
    ASSERT_GT(in_vessels.size(), 500u) << r.err;
    EXPECT_EQ(outside, 0u);
    auto median = [](std::vector<float> v) {
        std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
        return static_cast<double>(v[v.size() / 2]);
    };
    std::cout << "vessel median " << median(in_vessels) << " HU, liver median " << median(in_liver) << " HU, "
              << in_vessels.size() << " vessel voxels\n";
    EXPECT_GE(median(in_vessels), median(in_liver) + 25.0);
    EXPECT_FALSE(h5.read_graph("vessels").edges.empty());
}
