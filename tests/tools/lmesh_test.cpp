// lmesh run as a program: exit codes, messages, outputs.
#include "lobe/io/hdf5.h"
#include "lobe/io/image_io.h"

#include "common/run_tool.h"
#include "common/test_data.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <map>
#include <string>

using namespace lobe;
namespace fs = std::filesystem;

namespace {

using test::q;

test::ToolRun lmesh(const std::string& args, const fs::path& scratch)
{
    return test::run_tool(LMESH_EXE, args, scratch);
}

// The parameters lmesh recorded in the last provenance entry of `file`.
std::map<std::string, std::string> recorded_parameters(const fs::path& file)
{
    // Held in a variable: in a range-for over provenance().back().parameters the vector would
    // die before the loop runs.
    const auto provenance = io::Hdf5Reader(file).provenance();
    std::map<std::string, std::string> params;
    for (const auto& [k, v] : provenance.back().parameters)
        params[k] = v;
    return params;
}

// Liver (1): a 20 mm ball; tumour (4): a 6 mm ball inside it; on 0.8 mm voxels.
core::LabelImage3D two_tissues()
{
    core::ImageGeometry g;
    g.size = {36, 36, 30};
    g.spacing = {0.8, 0.8, 1.0};
    g.origin = {-14, -14, -15};
    core::LabelImage3D img(g, 0);
    for (int k = 0; k < g.size[2]; ++k)
        for (int j = 0; j < g.size[1]; ++j)
            for (int i = 0; i < g.size[0]; ++i) {
                const auto p = img.index_to_physical(i, j, k);
                const double r = core::norm(p), rt = core::distance(p, {3, 0, 0});
                img.at(i, j, k) = rt <= 5 ? 4 : (r <= 12 ? 1 : 0);
            }
    return img;
}

} // namespace

TEST(Lmesh, HelpAndUsageErrors)
{
    const auto dir = test::scratch_dir();
    auto r = lmesh("--help", dir);
    EXPECT_EQ(r.exit_code, 0);
    EXPECT_NE(r.out.find("--roi"), std::string::npos);
    r = lmesh("in.mhd", dir); // no -o
    EXPECT_EQ(r.exit_code, 1);
    io::write_image(dir / "l.mhd", two_tissues());
    r = lmesh(q(dir / "l.mhd") + " -o " + q(dir / "m.h5") + " --roi 1,2,3", dir); // a ball needs 4 numbers
    EXPECT_EQ(r.exit_code, 1);
    r = lmesh(q(dir / "l.mhd") + " -o " + q(dir / "m.h5") + " --roi 1,2,3,4 --roi-box 0,0,0,1,1,1", dir);
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_FALSE(fs::exists(dir / "m.h5"));
}

TEST(Lmesh, MeshesALabelImageAndWritesEverything)
{
    const auto dir = test::scratch_dir();
    const auto labels = two_tissues();
    io::write_image(dir / "labels.mhd", labels);
    const auto r = lmesh(q(dir / "labels.mhd") + " -o " + q(dir / "mesh.h5") + " --size 2 --threads 1 --report " +
                             q(dir / "report.json") + " --png " + q(dir / "png") + " --export " + q(dir / "stl"),
                         dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    io::Hdf5Reader h5(dir / "mesh.h5");
    const auto data = h5.read_tet_mesh("liver");
    EXPECT_EQ(core::mesh_problem(data.mesh), "");
    bool has_combined = false;
    for (const auto& a : data.quality)
        if (a.name == "combined") {
            has_combined = true;
            EXPECT_EQ(a.values.size(), data.mesh.tets.size());
        }
    EXPECT_TRUE(has_combined);
    ASSERT_EQ(data.tissues.size(), 2u);
    EXPECT_EQ(data.tissues[1].name, "tumour");
    const auto surfaces = h5.surfaces();
    EXPECT_NE(std::find(surfaces.begin(), surfaces.end(), "tumour"), surfaces.end());
    EXPECT_NE(std::find(surfaces.begin(), surfaces.end(), "outer"), surfaces.end());
    const auto prov = h5.provenance();
    ASSERT_EQ(prov.size(), 1u);
    EXPECT_EQ(prov[0].tool, "lmesh");
    bool tets_recorded = false;
    for (const auto& [k, v] : prov[0].parameters)
        if (k == "result.tets")
            tets_recorded = std::stoul(v) == data.mesh.tets.size();
    EXPECT_TRUE(tets_recorded);
    // The report: each tissue's mesh volume within 5% of its label volume (the surface follows
    // the voxel boundary to a fraction of a voxel on balls of 15 and 6 voxels' radius).
    std::ifstream f(dir / "report.json");
    const auto j = nlohmann::json::parse(f);
    ASSERT_EQ(j["tissues"].size(), 2u);
    for (const auto& t : j["tissues"]) {
        EXPECT_NEAR(t["volume_ratio"].get<double>(), 1.0, 0.05) << t["name"];
        EXPECT_EQ(t["components_meshed"], t["components"]);
    }
    EXPECT_EQ(j["mesh"]["tets"].get<std::size_t>(), data.mesh.tets.size());
    // Every surface closed, manifold, oriented and free of self-intersections (the manifold
    // repair leaves no bad vertex).
    ASSERT_EQ(j["surfaces"].size(), 3u);
    for (const auto& s : j["surfaces"])
        EXPECT_TRUE(s["ok"].get<bool>()) << s["name"];
    EXPECT_EQ(j["manifold_repair"]["bad_vertices_after"].get<int>(), 0);
    EXPECT_TRUE(fs::exists(dir / "report.txt"));
    for (const char* png : {"cut-axial-tissue.png", "cut-coronal-quality.png", "quality-histogram.png"})
        EXPECT_GT(fs::file_size(dir / "png" / png), 1000u) << png;
    EXPECT_TRUE(fs::exists(dir / "stl" / "tumour.stl"));
}

TEST(Lmesh, ReadsAnInrimage)
{
    // CGAL's example images are INRIMAGE-4: the two balls written as one (a 256-byte header,
    // then the voxels) mesh like the MetaImage.
    const auto dir = test::scratch_dir();
    const auto img = two_tissues();
    std::string header = "#INRIMAGE-4#{\nXDIM=36\nYDIM=36\nZDIM=30\nVDIM=1\nVX=0.8\nVY=0.8\nVZ=1\n"
                         "TYPE=unsigned fixed\nPIXSIZE=8 bits\nCPU=decm\n##}\n";
    header.insert(header.size() - 4, std::string(256 - header.size(), '\n'));
    std::ofstream(dir / "l.inr", std::ios::binary) << header << std::string(img.data.begin(), img.data.end());
    const auto r = lmesh(q(dir / "l.inr") + " --size 4 --threads 1 --quiet -o " + q(dir / "m.h5") + " --report " +
                             q(dir / "m.json"),
                         dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    std::ifstream f(dir / "m.json");
    const auto j = nlohmann::json::parse(f);
    ASSERT_EQ(j["tissues"].size(), 2u);
    // The same tolerance as the MetaImage run: the voxels, not the format, set the volume.
    for (const auto& t : j["tissues"])
        EXPECT_NEAR(t["volume_ratio"].get<double>(), 1.0, 0.1) << t["label"];
}

TEST(Lmesh, ReadsAContainerAndKeepsItsHistory)
{
    const auto dir = test::scratch_dir();
    {
        io::Hdf5Writer w(dir / "seg.h5");
        w.write_labels("truth", two_tissues(), {{1, "liver"}, {4, "tumour"}});
        w.write_labels("other", two_tissues());
        io::Provenance p;
        p.tool = "lseg";
        p.version = "0";
        w.write_provenance(p);
        w.commit();
    }
    // Two label volumes and no --labels: refused, naming them.
    auto r = lmesh(q(dir / "seg.h5") + " -o " + q(dir / "mesh.h5"), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("truth, other"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "mesh.h5"));
    r = lmesh(q(dir / "seg.h5") + " --labels truth --tissues 4 --size 2 -o " + q(dir / "mesh.h5") + " --quiet", dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(r.err.empty()); // --quiet
    io::Hdf5Reader h5(dir / "mesh.h5");
    const auto prov = h5.provenance();
    ASSERT_EQ(prov.size(), 2u);
    EXPECT_EQ(prov[0].tool, "lseg");
    EXPECT_EQ(prov[1].tool, "lmesh");
    const auto data = h5.read_tet_mesh("liver");
    for (auto l : data.mesh.tet_labels)
        EXPECT_EQ(l, 4); // only the tumour was asked for
}

TEST(Lmesh, RefusesBadInputWithoutWriting)
{
    const auto dir = test::scratch_dir();
    core::ImageGeometry g;
    g.size = {10, 10, 10};
    io::write_image(dir / "empty.mhd", core::LabelImage3D(g, 0));
    auto r = lmesh(q(dir / "empty.mhd") + " -o " + q(dir / "mesh.h5"), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("empty.mhd"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("no voxel"), std::string::npos) << r.err;
    core::ImageF f(g, 0.5f);
    io::write_image(dir / "float.mhd", f);
    r = lmesh(q(dir / "float.mhd") + " -o " + q(dir / "mesh.h5"), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("not a label image"), std::string::npos) << r.err;
    io::write_image(dir / "l.mhd", two_tissues());
    r = lmesh(q(dir / "l.mhd") + " -o " + q(dir / "mesh.h5") + " --size 0.01", dir); // far too many tets
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("larger element size"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "mesh.h5"));
}

TEST(Lmesh, SliverPassRunsByDefaultAndRecordsIt)
{
    // Without CGAL's perturber and exuder the mesh keeps slivers, so the sliver pass has work:
    // it runs by default, records its outcome, raises the worst dihedral angle above the 10
    // degree goal on this small two-tissue mesh (measured: 0.63 -> 12.00 degrees, 420 changes), and
    // --no-slivers skips it. The report's worst angle is the mesh's.
    const auto dir = test::scratch_dir();
    io::write_image(dir / "labels.mhd", two_tissues());
    const std::string common = q(dir / "labels.mhd") + " --size 4 --threads 1 --no-exude";
    auto r = lmesh(common + " -o " + q(dir / "on.h5") + " --report " + q(dir / "on.json"), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("removing slivers"), std::string::npos) << r.err;
    auto params = recorded_parameters(dir / "on.h5");
    ASSERT_EQ(params.count("result.slivers.seconds"), 1u);
    const double before = std::stod(params["result.slivers.min_dihedral_before_deg"]);
    const double after = std::stod(params["result.slivers.min_dihedral_after_deg"]);
    std::printf("sliver pass without perturb/exude: %.2f -> %.2f deg, %s changes\n", before, after,
                params["result.slivers.changes"].c_str());
    EXPECT_GE(after, before);
    EXPECT_GT(after, 10.0);
    EXPECT_EQ(params["result.slivers.below_goal_after"], "0");
    // The recorded angle is rounded to 2 decimals; the report's is the mesh's own.
    EXPECT_NEAR(std::stod(params["result.min_dihedral_deg"]), after, 0.01);
    std::ifstream f(dir / "on.json");
    const auto j = nlohmann::json::parse(f);
    ASSERT_TRUE(j.contains("slivers"));
    EXPECT_EQ(j["slivers"]["below_goal_after"].get<int>(), 0);
    r = lmesh(common + " --no-slivers -o " + q(dir / "off.h5"), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    for (const auto& [k, v] : recorded_parameters(dir / "off.h5"))
        EXPECT_EQ(k.rfind("result.slivers.", 0), std::string::npos) << k;
    r = lmesh(common + " --sliver-target 5 -o " + q(dir / "bad.h5"), dir);
    EXPECT_NE(r.exit_code, 0);
    EXPECT_FALSE(fs::exists(dir / "bad.h5"));
}

TEST(Lmesh, RegionOfInterestRunsTheQualityPassAndRecordsIt)
{
    // A ball ROI around the tumour: the pass runs by default and records what it did in the
    // provenance and the report; --no-improve skips it.
    const auto dir = test::scratch_dir();
    io::write_image(dir / "labels.mhd", two_tissues());
    const std::string common = q(dir / "labels.mhd") + " --size 4 --threads 1 --roi 3,0,0,5 --roi-size 2";
    auto r = lmesh(common + " -o " + q(dir / "on.h5") + " --report " + q(dir / "on.json"), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("ROI quality pass"), std::string::npos) << r.err;
    auto params = recorded_parameters(dir / "on.h5");
    EXPECT_EQ(params["improve-target"].empty(), false);
    ASSERT_EQ(params.count("result.improve.seconds"), 1u);
    // The pass never lowers the ROI's worst tet nor, in its first stage, adds tets below 0.3;
    // the recorded values are rounded to 4 decimals.
    EXPECT_GE(std::stod(params["result.improve.roi_min_combined_after"]),
              std::stod(params["result.improve.roi_min_combined_before"]));
    std::ifstream f(dir / "on.json");
    const auto j = nlohmann::json::parse(f);
    ASSERT_TRUE(j.contains("roi_improvement"));
    EXPECT_GE(j["roi_improvement"]["roi_min_combined_after"].get<double>(),
              j["roi_improvement"]["roi_min_combined_before"].get<double>());
    r = lmesh(common + " --no-improve -o " + q(dir / "off.h5"), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    for (const auto& [k, v] : recorded_parameters(dir / "off.h5"))
        EXPECT_EQ(k.rfind("result.improve.", 0), std::string::npos) << k;
}

TEST(Lmesh, MeshesTheRealScansLiverAndVeinsWithEveryPieceAndVolume)
{
    // The shared CT's reference labels (TotalSegmentator's): liver (5), inferior vena cava (63),
    // portal and splenic vein (64) on 3 mm voxels, the veins 2-4 voxels across: the issue's
    // failure case (CGAL alone kept 15% of a portal vein). Default settings (2 threads, so the
    // mesh varies run to run). Measured: 62-63 k tets in about 2 s end to end, volumes 0.998,
    // 0.986-0.988, 0.944-0.945, worst dihedral 12.0 degrees, the two 6- and 7-voxel specks of
    // label 64 dropped and reported. The bounds are the issue's: every piece of 100 voxels or
    // more meshed, every tissue within 10% of its label volume, worst dihedral above 10 degrees.
    const auto labels = test::data_dir() / "ct-small" / "labels.mhd";
    LOBE_REQUIRE_PATH(labels);
    const auto dir = test::scratch_dir();
    auto r =
        lmesh(q(labels) + " --tissues 5,63,64 --quiet -o " + q(dir / "m.h5") + " --report " + q(dir / "m.json"), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    std::ifstream f(dir / "m.json");
    const auto j = nlohmann::json::parse(f);
    ASSERT_EQ(j["tissues"].size(), 3u);
    for (const auto& t : j["tissues"]) {
        const double ratio = t["volume_ratio"].get<double>();
        std::printf("label %d: %lld voxels, mesh / label volume %.3f, pieces %d/%d, worst dihedral %.2f deg\n",
                    t["label"].get<int>(), t["voxels"].get<long long>(), ratio, t["components_meshed"].get<int>(),
                    t["components"].get<int>(), t["quality"]["min_dihedral_deg"].get<double>());
        EXPECT_NEAR(ratio, 1.0, 0.1) << t["label"];
        EXPECT_EQ(t["components_meshed"], t["components"]) << t["label"];
        EXPECT_GT(t["quality"]["min_dihedral_deg"].get<double>(), 10.0) << t["label"];
    }
    for (const auto& w : j["warnings"])
        EXPECT_EQ(w.get<std::string>().find("got no tet"), std::string::npos) << w;
    for (const auto& s : j["surfaces"])
        EXPECT_TRUE(s["ok"].get<bool>()) << s["name"];
}
