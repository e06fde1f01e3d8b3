// /graphs/<name> in the HDF5 container: centre-line graphs (vessel trees) round trip exactly, show in
// the XDMF sidecar as polylines, and malformed graphs are refused when written and when read.
#include "lobe/io/hdf5.h"

#include "common/expect_error.h"
#include "common/test_data.h"

#include <gtest/gtest.h>
#include <hdf5.h>

#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using lobe::core::CentrelineGraph;
using lobe::core::InvalidInputError;
using namespace lobe::io;

// A trunk splitting in two, with names, levels, labels and per-point radii.
CentrelineGraph small_tree()
{
    CentrelineGraph g;
    g.nodes = {{{0.125, -3.5, 10}, 6.0}, {{0, 20, 12}, 4.5}, {{-15, 35, 12.25}, 2.0}, {{16, 33, 9}, 1.75}};
    auto edge = [&](int a, int b, int level, const char* name, std::vector<lobe::core::Vec3> mid) {
        lobe::core::CentrelineEdge e;
        e.from = a;
        e.to = b;
        e.level = level;
        e.label = 2;
        e.name = name;
        e.points.push_back(g.nodes[std::size_t(a)].position);
        for (const auto& p : mid)
            e.points.push_back(p);
        e.points.push_back(g.nodes[std::size_t(b)].position);
        for (std::size_t i = 0; i < e.points.size(); ++i)
            e.point_radius.push_back(6.0 - 0.5 * double(i) - 0.1 * level);
        e.radius_mm = e.point_radius[e.points.size() / 2];
        for (std::size_t i = 1; i < e.points.size(); ++i)
            e.length_mm += lobe::core::distance(e.points[i - 1], e.points[i]);
        g.edges.push_back(e);
    };
    edge(0, 1, 1, "PV", {{0.1, 5, 10.5}, {0.05, 12, 11.25}});
    edge(1, 2, 2, "RPV", {{-7, 28, 12}});
    edge(1, 3, 2, "", {});
    return g;
}

struct H5Id {
    hid_t id;
    herr_t (*close)(hid_t);
    H5Id(hid_t i, herr_t (*c)(hid_t)) : id(i), close(c) {}
    ~H5Id()
    {
        if (id >= 0)
            close(id);
    }
    H5Id(const H5Id&) = delete;
    H5Id& operator=(const H5Id&) = delete;
    operator hid_t() const { return id; }
};

template <class T>
void overwrite(const fs::path& p, const std::string& path, hid_t mem_type, const std::vector<T>& data)
{
    H5Id f(H5Fopen(p.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose);
    H5Id ds(H5Dopen2(f, path.c_str(), H5P_DEFAULT), H5Dclose);
    EXPECT_GE(H5Dwrite(ds, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()), 0);
}

void write_tree(const fs::path& p)
{
    Hdf5Writer w(p);
    w.write_graph("vessels", small_tree());
    w.commit();
}

} // namespace

TEST(Hdf5Graph, RoundTripsExactly)
{
    const fs::path dir = lobe::test::scratch_dir();
    const fs::path p = dir / "g.h5";
    const CentrelineGraph g = small_tree();
    {
        Hdf5Writer w(p);
        w.write_graph("vessels", g);
        w.write_graph("empty", CentrelineGraph{});
        w.commit();
    }
    const Hdf5Reader r(p);
    EXPECT_EQ(r.graphs(), (std::vector<std::string>{"vessels", "empty"}));
    const CentrelineGraph back = r.read_graph("vessels");
    ASSERT_EQ(back.nodes.size(), g.nodes.size());
    ASSERT_EQ(back.edges.size(), g.edges.size());
    for (std::size_t i = 0; i < g.nodes.size(); ++i) {
        EXPECT_EQ(back.nodes[i].position, g.nodes[i].position);
        EXPECT_EQ(back.nodes[i].radius_mm, g.nodes[i].radius_mm);
    }
    for (std::size_t e = 0; e < g.edges.size(); ++e) {
        const auto& a = g.edges[e];
        const auto& b = back.edges[e];
        EXPECT_EQ(b.from, a.from);
        EXPECT_EQ(b.to, a.to);
        EXPECT_EQ(b.level, a.level);
        EXPECT_EQ(b.label, a.label);
        EXPECT_EQ(b.name, a.name);
        EXPECT_EQ(b.radius_mm, a.radius_mm);
        EXPECT_EQ(b.length_mm, a.length_mm);
        EXPECT_EQ(b.points, a.points);
        EXPECT_EQ(b.point_radius, a.point_radius);
    }
    EXPECT_TRUE(r.read_graph("empty").edges.empty());
    EXPECT_LOBE_ERROR(InvalidInputError, (void)r.read_graph("arteries"), "g.h5", "no graph 'arteries'", "vessels");

    // The sidecar shows the tree as line segments between consecutive points (3 + 2 + 1 = 6 for
    // polylines of 4, 3 and 2 points) with radius, level and label; the empty graph is left out.
    const std::string xml = lobe::test::read_file(dir / "g.xdmf");
    EXPECT_NE(xml.find(R"(<Grid Name="graphs" GridType="Collection")"), std::string::npos) << xml;
    EXPECT_NE(xml.find(R"(TopologyType="Polyline" NodesPerElement="2" NumberOfElements="6")"), std::string::npos) << xml;
    EXPECT_NE(xml.find(R"(Dimensions="9 3" NumberType="Float" Precision="8" Format="HDF">g.h5:/graphs/vessels/points)"),
              std::string::npos)
        << xml;
    for (const char* a : {"radius", "level", "label"})
        EXPECT_NE(xml.find(std::string("Attribute Name=\"") + a + "\""), std::string::npos) << a;
    EXPECT_EQ(xml.find("/graphs/empty"), std::string::npos);
}

TEST(Hdf5Graph, WriterRefusesMalformedGraphs)
{
    const fs::path dir = lobe::test::scratch_dir();
    Hdf5Writer w(dir / "bad.h5");
    CentrelineGraph g = small_tree();
    g.edges[1].to = 7;
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_graph("vessels", g), "bad.h5", "/graphs/vessels", "edge 1");
    g = small_tree();
    g.edges[2].point_radius.pop_back();
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_graph("vessels", g), "edge 2", "radii");
    g = small_tree();
    g.nodes[0].position.x = std::nan("");
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_graph("vessels", g), "node 0");
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_graph("no/slash", small_tree()), "invalid graph name");
    w.write_graph("vessels", small_tree()); // a refused write leaves the writer usable
    EXPECT_LOBE_ERROR(InvalidInputError, w.write_graph("vessels", small_tree()), "already written");
    w.commit();
    EXPECT_EQ(Hdf5Reader(dir / "bad.h5").read_graph("vessels").edges.size(), 3u);
}

// Files whose graph breaks the schema: offsets out of order, an edge index out of range, a name
// for an edge that does not exist, a missing dataset. Each message names the file and the object.
TEST(Hdf5Graph, ReaderRefusesInconsistentGraphs)
{
    const fs::path dir = lobe::test::scratch_dir();
    const fs::path p = dir / "v.h5";

    write_tree(p);
    overwrite<std::int64_t>(p, "/graphs/vessels/edge_offsets", H5T_NATIVE_INT64, {0, 4, 3, 9});
    EXPECT_LOBE_ERROR(InvalidInputError, (void)Hdf5Reader(p).read_graph("vessels"), "v.h5", "edge_offsets", "edge 1");

    write_tree(p);
    overwrite<std::int64_t>(p, "/graphs/vessels/edge_offsets", H5T_NATIVE_INT64, {0, 4, 7, 8});
    EXPECT_LOBE_ERROR(InvalidInputError, (void)Hdf5Reader(p).read_graph("vessels"), "edge_offsets", "number of points");

    write_tree(p);
    overwrite<std::int32_t>(p, "/graphs/vessels/edges", H5T_NATIVE_INT32, {0, 1, 1, 2, 1, 40});
    EXPECT_LOBE_ERROR(InvalidInputError, (void)Hdf5Reader(p).read_graph("vessels"), "/graphs/vessels", "node index");

    write_tree(p);
    {
        H5Id f(H5Fopen(p.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose);
        H5Id g(H5Gopen2(f, "/graphs/vessels", H5P_DEFAULT), H5Gclose);
        H5Id a(H5Aopen(g, "named_edges", H5P_DEFAULT), H5Aclose);
        const std::int32_t idx[2] = {0, 5};
        EXPECT_GE(H5Awrite(a, H5T_NATIVE_INT32, idx), 0);
    }
    EXPECT_LOBE_ERROR(InvalidInputError, (void)Hdf5Reader(p).read_graph("vessels"), "named_edges", "edge 5");

    write_tree(p);
    {
        H5Id f(H5Fopen(p.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose);
        EXPECT_GE(H5Ldelete(f, "/graphs/vessels/point_radius", H5P_DEFAULT), 0);
    }
    EXPECT_LOBE_ERROR(InvalidInputError, (void)Hdf5Reader(p).read_graph("vessels"), "/graphs/vessels/point_radius",
                      "missing");
}
