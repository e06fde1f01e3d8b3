// lio run as a program: exit codes, messages, outputs.
#include "lobe/io/hdf5.h"
#include "lobe/io/metaimage.h"

#include <nifti1_io.h>

#include "common/orientation.h"
#include "common/run_tool.h"
#include "common/test_data.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

using namespace lobe;
namespace fs = std::filesystem;

namespace {

test::ToolRun lio(const std::string& args, const fs::path& scratch)
{
    return test::run_tool(LIO_EXE, args, scratch);
}

fs::path small_image(const fs::path& dir)
{
    core::ImageGeometry g;
    g.size = {4, 3, 2};
    g.spacing = {0.5, 0.75, 2.0};
    g.origin = {-10, 20, -30};
    core::Image3D<std::int16_t> img(g);
    for (std::size_t i = 0; i < img.data.size(); ++i)
        img.data[i] = static_cast<std::int16_t>(static_cast<int>(i) - 5);
    io::write_metaimage(dir / "small.mha", img);
    return dir / "small.mha";
}

} // namespace

TEST(Lio, HelpVersionAndUsageErrors)
{
    const auto dir = test::scratch_dir();
    auto r = lio("--help", dir);
    EXPECT_EQ(r.exit_code, 0);
    EXPECT_NE(r.out.find("info"), std::string::npos);
    EXPECT_NE(r.out.find("convert"), std::string::npos);
    r = lio("--version", dir);
    EXPECT_EQ(r.exit_code, 0);
    EXPECT_NE(r.out.find(LOBE_VERSION_STRING), std::string::npos);
    r = lio("", dir); // a subcommand is required
    EXPECT_EQ(r.exit_code, 1);
    r = lio("convert only-one-arg.mha", dir);
    EXPECT_EQ(r.exit_code, 1);
}

TEST(Lio, InfoPrintsGeometryTypeAndRange)
{
    const auto dir = test::scratch_dir();
    const auto img = small_image(dir);
    auto r = lio("info " + test::shell_quote(img.string()), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("MetaImage"), std::string::npos);
    EXPECT_NE(r.out.find("int16"), std::string::npos);
    EXPECT_NE(r.out.find("4 x 3 x 2"), std::string::npos);
    EXPECT_NE(r.out.find("0.5 x 0.75 x 2.0 mm"), std::string::npos);
    EXPECT_NE(r.out.find("-5 .. 18"), std::string::npos); // values i - 5 for i in 0..23

    r = lio("info --json " + test::shell_quote(img.string()), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["size"], nlohmann::json({4, 3, 2}));
    EXPECT_EQ(j["spacing"][1].get<double>(), 0.75);
    EXPECT_EQ(j["origin"][2].get<double>(), -30.0);
    EXPECT_EQ(j["pixel_type"], "int16");
    EXPECT_EQ(j["max"].get<double>(), 18.0);
}

// Where each axis runs, by its nearest patient direction: the same small volume stored as DICOM
// stacks it (LPS), as NIfTI does (x and y reversed: RAS), and as a coronal series (LIP).
TEST(Lio, InfoNamesWhereTheAxesRun)
{
    const auto dir = test::scratch_dir();
    const auto img = io::read_metaimage(small_image(dir));
    const auto axial = std::get<core::Image3D<std::int16_t>>(img);
    core::AxisOrder ras;
    ras.flip = {true, true, false};
    const struct {
        const char* name;
        core::AxisOrder order;
        const char* code;
        const char* slices;
    } cases[] = {{"lps", core::AxisOrder{}, "LPS", "axial"}, {"ras", ras, "RAS", "axial"},
                 {"coronal", test::coronal_storage(), "LIP", "coronal"}};
    for (const auto& c : cases) {
        const fs::path path = dir / (std::string(c.name) + ".mha");
        io::write_metaimage(path, core::reorder_axes(axial, c.order));
        auto r = lio("info " + test::shell_quote(path.string()), dir);
        ASSERT_EQ(r.exit_code, 0) << r.err;
        EXPECT_NE(r.out.find(std::string("axes to:   ") + c.code + ", " + c.slices + " slices"), std::string::npos) << r.out;
        r = lio("info --json " + test::shell_quote(path.string()), dir);
        ASSERT_EQ(r.exit_code, 0) << r.err;
        const auto j = nlohmann::json::parse(r.out);
        EXPECT_EQ(j["orientation"], c.code);
        EXPECT_EQ(j["slices"], c.slices);
    }
}

// A 4-D NIfTI series: info says what it holds and how to choose, --volume reads one volume,
// and asking for one that is not there, or a volume of a file that is no series, is an error.
TEST(Lio, ChoosesAVolumeOfANiftiSeries)
{
    const auto dir = test::scratch_dir();
    const fs::path p = dir / "series.nii.gz";
    const int dims[8] = {4, 4, 3, 2, 3, 1, 1, 1}; // 4 x 3 x 2 voxels, 3 volumes
    nifti_set_debug_level(0);
    nifti_image* nim = nifti_make_new_nim(dims, DT_INT16, 1);
    ASSERT_NE(nim, nullptr);
    auto* v = static_cast<std::int16_t*>(nim->data);
    for (std::size_t i = 0; i < nim->nvox; ++i)
        v[i] = static_cast<std::int16_t>(i); // volume t holds 24 t .. 24 t + 23
    ASSERT_EQ(nifti_set_filenames(nim, p.string().c_str(), 0, 1), 0);
    nifti_image_write(nim);
    nifti_image_free(nim);

    auto r = lio("info " + test::shell_quote(p.string()), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("is a series of 3 volumes of 4 x 3 x 2 int16 voxels"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("--volume K (0..2)"), std::string::npos) << r.out;
    r = lio("info --json " + test::shell_quote(p.string()), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(nlohmann::json::parse(r.out)["volumes"], 3);

    r = lio("info --volume 2 " + test::shell_quote(p.string()), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("48 .. 71"), std::string::npos) << r.out; // the third volume's range
    r = lio("convert --volume 1 --quiet " + test::shell_quote(p.string()) + " " + test::shell_quote((dir / "v1.mha").string()), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto v1 = std::get<core::Image3D<std::int16_t>>(io::read_metaimage(dir / "v1.mha"));
    ASSERT_EQ(v1.data.size(), 24u);
    for (std::size_t i = 0; i < 24; ++i)
        EXPECT_EQ(v1.data[i], static_cast<std::int16_t>(24 + i));

    r = lio("convert --volume 3 " + test::shell_quote(p.string()) + " " + test::shell_quote((dir / "v3.mha").string()), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("volume 3 requested but the file holds 3"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "v3.mha"));
    r = lio("info --volume 0 " + test::shell_quote(small_image(dir).string()), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("--volume chooses a volume of a NIfTI series"), std::string::npos) << r.err;
}

TEST(Lio, InfoOnTheDicomSeries)
{
    const auto series = test::data_dir() / "ct-dicom-jpeg2000" / "dicom";
    LOBE_REQUIRE_PATH(series);
    const auto dir = test::scratch_dir();
    const auto r = lio("info " + test::shell_quote(series.string()), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    // The acceptance line: 512 x 512 x 20, spacing 0.977 x 0.977 x 2.0.
    EXPECT_NE(r.out.find("512 x 512 x 20"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("0.977 x 0.977 x 2.0 mm"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("DICOM"), std::string::npos);
}

TEST(Lio, BadInputNamesTheFileAndExitsTwo)
{
    const auto dir = test::scratch_dir();
    auto r = lio("info " + test::shell_quote((dir / "missing.mhd").string()), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("missing.mhd"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("does not exist"), std::string::npos) << r.err;

    std::ofstream(dir / "broken.mha") << "NDims = 3\nDimSize = 2 2\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n";
    r = lio("info " + test::shell_quote((dir / "broken.mha").string()), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("broken.mha"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("DimSize"), std::string::npos) << r.err;
}

TEST(Lio, ConvertsBetweenFormats)
{
    const auto dir = test::scratch_dir();
    const auto img = small_image(dir);
    const auto original = std::get<core::ImageI16>(io::read_metaimage(img));
    for (const char* out : {"a.nii.gz", "a.h5", "a.mhd"}) {
        SCOPED_TRACE(out);
        const auto r = lio("--quiet convert " + test::shell_quote(img.string()) + " " +
                               test::shell_quote((dir / out).string()),
                           dir);
        ASSERT_EQ(r.exit_code, 0) << r.err;
        EXPECT_TRUE(r.err.empty()) << "--quiet printed: " << r.err;
        ASSERT_TRUE(fs::exists(dir / out));
    }
    // Through NIfTI and back to MetaImage: values exact, geometry within float32 precision.
    const auto r = lio("convert " + test::shell_quote((dir / "a.nii.gz").string()) + " " +
                           test::shell_quote((dir / "b.mha").string()) + " --type float32",
                       dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("wrote"), std::string::npos); // progress on stderr
    const auto back = std::get<core::Image3D<float>>(io::read_metaimage(dir / "b.mha"));
    for (std::size_t i = 0; i < back.data.size(); ++i)
        ASSERT_EQ(back.data[i], static_cast<float>(original.data[i]));
    EXPECT_TRUE(core::same_grid(back, original, 1e-4));
}

TEST(Lio, FailedConvertWritesNothing)
{
    const auto dir = test::scratch_dir();
    const auto img = small_image(dir);
    auto r = lio("convert " + test::shell_quote(img.string()) + " " + test::shell_quote((dir / "out.png").string()), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("out.png"), std::string::npos);
    EXPECT_FALSE(fs::exists(dir / "out.png"));
    r = lio("convert " + test::shell_quote((dir / "nope.nii").string()) + " " +
                test::shell_quote((dir / "out.mha").string()),
            dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_FALSE(fs::exists(dir / "out.mha"));
    r = lio("convert " + test::shell_quote(img.string()) + " out.mha --type complex", dir);
    EXPECT_EQ(r.exit_code, 1);
    // Only our inputs and the captured stdout/stderr remain: no temporaries.
    for (const auto& e : fs::directory_iterator(dir))
        EXPECT_EQ(e.path().filename().string().rfind(".tmp-", 0), std::string::npos) << e.path();
}

TEST(Lio, Hdf5OutputRecordsProvenanceAndKeepsHistory)
{
    const auto dir = test::scratch_dir();
    const auto img = small_image(dir);
    auto r = lio("convert " + test::shell_quote(img.string()) + " " + test::shell_quote((dir / "a.h5").string()) +
                     " --name ct",
                 dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    r = lio("convert " + test::shell_quote((dir / "a.h5").string()) + " " + test::shell_quote((dir / "b.h5").string()) +
                " --type float32 --quiet",
            dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const io::Hdf5Reader reader(dir / "b.h5");
    EXPECT_EQ(reader.images(), std::vector<std::string>{"image"});
    const auto history = reader.provenance();
    ASSERT_EQ(history.size(), 2u); // the first conversion, copied, then this one
    EXPECT_EQ(history[0].tool, "lio");
    EXPECT_NE(history[0].command_line.find("--name ct"), std::string::npos);
    const auto find = [](const io::Provenance& p, const std::string& key) {
        for (const auto& [k, v] : p.parameters)
            if (k == key)
                return v;
        return std::string("<absent>");
    };
    EXPECT_EQ(find(history[0], "convert.name"), "ct");
    EXPECT_EQ(find(history[1], "convert.type"), "float32");
    EXPECT_EQ(find(history[1], "quiet"), "true");
    ASSERT_EQ(history[1].timings.size(), 2u);
    EXPECT_EQ(history[1].timings[0].first, "read");
    EXPECT_GE(history[1].timings[0].second, 0.0);
}

TEST(Lio, ListsSeveralDicomSeriesAndReadsTheChosenOne)
{
    const auto src = test::pydicom_data_dir();
    LOBE_REQUIRE_PATH(src / "CT_small.dcm");
    const auto dir = test::scratch_dir();
    const auto folder = dir / "two";
    fs::create_directories(folder);
    fs::copy_file(src / "CT_small.dcm", folder / "ct.dcm");
    fs::copy_file(src / "MR_small.dcm", folder / "mr.dcm");
    const std::string mr_uid = "1.3.6.1.4.1.5962.1.3.4.1.20040826185059.5457"; // MR_small's SeriesInstanceUID

    auto r = lio("info " + test::shell_quote(folder.string()), dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("holds 2 DICOM series"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(mr_uid), std::string::npos) << r.out;

    // Converting needs a choice: without one it fails (exit 2) naming the series.
    r = lio("convert " + test::shell_quote(folder.string()) + " " + test::shell_quote((dir / "mr.mha").string()), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("--series"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "mr.mha"));
    r = lio("convert " + test::shell_quote(folder.string()) + " " + test::shell_quote((dir / "mr.mha").string()) +
                " --series " + mr_uid,
            dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto mr = io::read_metaimage(dir / "mr.mha");
    EXPECT_EQ(core::geometry(mr).size, (std::array<int, 3>{64, 64, 1})); // MR_small is 64 x 64
}

TEST(Lio, InfoListsAContainerAndReadsTheChosenItem)
{
    const auto dir = test::scratch_dir();
    const auto img = std::get<core::ImageI16>(io::read_metaimage(small_image(dir)));
    core::LabelImage3D labels(img.geometry(), 1);
    {
        io::Hdf5Writer w(dir / "two.h5");
        w.write_image("ct", img);
        w.write_labels("liver", labels, {{0, "background"}, {1, "liver"}});
        w.commit();
    }
    const std::string h5 = test::shell_quote((dir / "two.h5").string());
    auto r = lio("info " + h5, dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("images:    ct  int16  4 x 3 x 2"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("labels:    liver  uint8  4 x 3 x 2"), std::string::npos) << r.out;
    r = lio("info --json " + h5, dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["labels"][0]["name"], "liver");
    EXPECT_EQ(j["images"][0]["spacing"][1].get<double>(), 0.75);

    r = lio("info " + h5 + " --item liver", dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("range:     1 .. 1"), std::string::npos) << r.out;
    // Without a choice, converting fails and names the items.
    r = lio("convert " + h5 + " " + test::shell_quote((dir / "x.mha").string()), dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("labels/liver"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "x.mha"));
}
