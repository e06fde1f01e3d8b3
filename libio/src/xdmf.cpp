// The XDMF sidecar. XDMF 3 (Version="3.0"), restricted to elements that ParaView's Xdmf3 readers
// and its legacy XDMF 2 reader both understand: uniform grids inside spatial collections,
// 3DCoRectMesh + ORIGIN_DXDYDZ, XYZ geometry, Triangle and Tetrahedron topologies, scalar
// attributes, and HDF data items addressed as "file.h5:/path".

#include "detail/xdmf.h"

#include <cstdio>
#include <cstdlib>
#include <sstream>

namespace lobe::io::detail {
namespace {

std::string xml_escape(const std::string& s)
{
    std::string out;
    out.reserve(s.size());
    for (const char c : s) {
        switch (c) {
        case '&': out += "&amp;"; break;
        case '<': out += "&lt;"; break;
        case '>': out += "&gt;"; break;
        case '"': out += "&quot;"; break;
        case '\'': out += "&apos;"; break;
        default: out += c;
        }
    }
    return out;
}

// Shortest text that reads back as the same double, so origin and spacing are exact.
std::string exact(double v)
{
    char buf[32];
    for (int precision = 15; precision <= 17; ++precision) {
        std::snprintf(buf, sizeof buf, "%.*g", precision, v);
        if (std::strtod(buf, nullptr) == v)
            break;
    }
    return buf;
}

struct NumberType {
    const char* name;
    int precision;
};

NumberType number_type(core::PixelType t)
{
    switch (t) {
    case core::PixelType::UInt8: return {"UChar", 1};
    case core::PixelType::Int8: return {"Char", 1};
    case core::PixelType::Int16: return {"Int", 2};
    case core::PixelType::UInt16: return {"UInt", 2};
    case core::PixelType::Int32: return {"Int", 4};
    case core::PixelType::UInt32: return {"UInt", 4};
    case core::PixelType::Float32: return {"Float", 4};
    case core::PixelType::Float64: return {"Float", 8};
    }
    return {"Float", 8};
}

class Document {
public:
    explicit Document(std::string h5) : h5_(xml_escape(h5)) {}

    void line(int indent, const std::string& text) { out_ << std::string(std::size_t(2 * indent), ' ') << text << '\n'; }

    // <DataItem> referencing a dataset of the container.
    void hdf_item(int indent, const std::string& dims, NumberType t, const std::string& dataset)
    {
        line(indent, "<DataItem Dimensions=\"" + dims + "\" NumberType=\"" + t.name + "\" Precision=\"" +
                         std::to_string(t.precision) + "\" Format=\"HDF\">" + h5_ + ":" + xml_escape(dataset) +
                         "</DataItem>");
    }

    void volume(int indent, const std::string& group, const XdmfVolume& v)
    {
        const auto& g = v.geometry;
        // XDMF lists structured dimensions, origin and spacing slowest axis first: z, y, x.
        const std::string dims =
            std::to_string(g.size[2]) + " " + std::to_string(g.size[1]) + " " + std::to_string(g.size[0]);
        line(indent, "<Grid Name=\"" + xml_escape(v.name) + "\" GridType=\"Uniform\">");
        line(indent + 1, "<Topology TopologyType=\"3DCoRectMesh\" Dimensions=\"" + dims + "\"/>");
        line(indent + 1, "<Geometry GeometryType=\"ORIGIN_DXDYDZ\">");
        line(indent + 2, "<DataItem Name=\"Origin\" Dimensions=\"3\" NumberType=\"Float\" Precision=\"8\" "
                         "Format=\"XML\">" +
                             exact(g.origin[2]) + " " + exact(g.origin[1]) + " " + exact(g.origin[0]) + "</DataItem>");
        line(indent + 2, "<DataItem Name=\"Spacing\" Dimensions=\"3\" NumberType=\"Float\" Precision=\"8\" "
                         "Format=\"XML\">" +
                             exact(g.spacing[2]) + " " + exact(g.spacing[1]) + " " + exact(g.spacing[0]) +
                             "</DataItem>");
        line(indent + 1, "</Geometry>");
        // Voxel values sit on the grid points: ITK's origin is the centre of voxel (0,0,0).
        line(indent + 1, "<Attribute Name=\"" + xml_escape(v.name) + "\" AttributeType=\"Scalar\" Center=\"Node\">");
        hdf_item(indent + 2, dims, number_type(v.pixel_type), "/" + group + "/" + v.name);
        line(indent + 1, "</Attribute>");
        line(indent, "</Grid>");
    }

    void vertices(int indent, const std::string& dataset, std::size_t n)
    {
        line(indent, "<Geometry GeometryType=\"XYZ\">");
        hdf_item(indent + 1, std::to_string(n) + " 3", {"Float", 8}, dataset);
        line(indent, "</Geometry>");
    }

    void surface(int indent, const XdmfSurface& s)
    {
        const std::string base = "/surfaces/" + s.name;
        line(indent, "<Grid Name=\"" + xml_escape(s.name) + "\" GridType=\"Uniform\">");
        line(indent + 1, "<Topology TopologyType=\"Triangle\" NumberOfElements=\"" + std::to_string(s.triangles) + "\">");
        hdf_item(indent + 2, std::to_string(s.triangles) + " 3", {"Int", 4}, base + "/triangles");
        line(indent + 1, "</Topology>");
        vertices(indent + 1, base + "/vertices", s.vertices);
        line(indent, "</Grid>");
    }

    void tet_mesh(int indent, const XdmfTetMesh& m)
    {
        const std::string base = "/meshes/" + m.name;
        const std::string cells = std::to_string(m.tets);
        line(indent, "<Grid Name=\"" + xml_escape(m.name) + "\" GridType=\"Uniform\">");
        line(indent + 1, "<Topology TopologyType=\"Tetrahedron\" NumberOfElements=\"" + cells + "\">");
        hdf_item(indent + 2, cells + " 4", {"Int", 4}, base + "/tets");
        line(indent + 1, "</Topology>");
        vertices(indent + 1, base + "/vertices", m.vertices);
        line(indent + 1, "<Attribute Name=\"tet_labels\" AttributeType=\"Scalar\" Center=\"Cell\">");
        hdf_item(indent + 2, cells, {"Int", 4}, base + "/tet_labels");
        line(indent + 1, "</Attribute>");
        for (const auto& q : m.quality) {
            line(indent + 1, "<Attribute Name=\"quality_" + xml_escape(q) + "\" AttributeType=\"Scalar\" Center=\"Cell\">");
            hdf_item(indent + 2, cells, {"Float", 8}, base + "/quality/" + q);
            line(indent + 1, "</Attribute>");
        }
        line(indent, "</Grid>");
    }

    // A temporal collection: one grid per frame, its epoch's topology with the frame's hyperslab
    // of that epoch's positions as geometry, so ParaView plays the run, cuts and refinement
    // included.
    void simulation(int indent, const XdmfSimulation& sim)
    {
        line(indent, "<Grid Name=\"" + xml_escape(sim.name) + "\" GridType=\"Collection\" CollectionType=\"Temporal\">");
        for (const auto& e : sim.epochs)
            for (std::size_t k = 0; k < e.frames; ++k) {
                const std::size_t f = e.first_frame + k;
                const std::string cells = std::to_string(e.cells), n = std::to_string(e.vertices);
                line(indent + 1, "<Grid Name=\"" + xml_escape(sim.name) + "_" + std::to_string(f) + "\" GridType=\"Uniform\">");
                line(indent + 2, "<Time Value=\"" + exact(sim.times[f]) + "\"/>");
                line(indent + 2, "<Topology TopologyType=\"Tetrahedron\" NumberOfElements=\"" + cells + "\">");
                hdf_item(indent + 3, cells + " 4", {"Int", 4}, e.tets);
                line(indent + 2, "</Topology>");
                line(indent + 2, "<Geometry GeometryType=\"XYZ\">");
                line(indent + 3, "<DataItem ItemType=\"HyperSlab\" Dimensions=\"1 " + n + " 3\" Type=\"HyperSlab\">");
                line(indent + 4, "<DataItem Dimensions=\"3 3\" Format=\"XML\">" + std::to_string(k) + " 0 0 1 1 1 1 " + n +
                                     " 3</DataItem>");
                hdf_item(indent + 4, std::to_string(e.frames) + " " + n + " 3", {"Float", 8}, e.positions);
                line(indent + 3, "</DataItem>");
                line(indent + 2, "</Geometry>");
                line(indent + 2, "<Attribute Name=\"tet_labels\" AttributeType=\"Scalar\" Center=\"Cell\">");
                hdf_item(indent + 3, cells, {"Int", 4}, e.tet_labels);
                line(indent + 2, "</Attribute>");
                line(indent + 1, "</Grid>");
            }
        line(indent, "</Grid>");
    }

    // One spatial collection per kind, so that equal names of different kinds (labels/liver,
    // surfaces/liver, meshes/liver) stay distinct blocks in ParaView.
    template <class Items, class Emit>
    void collection(const char* name, const Items& items, Emit emit)
    {
        if (items.empty())
            return;
        line(2, std::string("<Grid Name=\"") + name + "\" GridType=\"Collection\" CollectionType=\"Spatial\">");
        for (const auto& item : items)
            emit(item);
        line(2, "</Grid>");
    }

    // A centre-line graph as line segments between consecutive polyline points, coloured by
    // radius (per point), branch level and tissue label (per segment).
    void graph(int indent, const XdmfGraph& g)
    {
        const std::string base = "/graphs/" + g.name;
        const std::string cells = std::to_string(g.segments), n = std::to_string(g.points);
        line(indent, "<Grid Name=\"" + xml_escape(g.name) + "\" GridType=\"Uniform\">");
        line(indent + 1, "<Topology TopologyType=\"Polyline\" NodesPerElement=\"2\" NumberOfElements=\"" + cells + "\">");
        hdf_item(indent + 2, cells + " 2", {"Int", 4}, base + "/segments");
        line(indent + 1, "</Topology>");
        vertices(indent + 1, base + "/points", g.points);
        line(indent + 1, "<Attribute Name=\"radius\" AttributeType=\"Scalar\" Center=\"Node\">");
        hdf_item(indent + 2, n, {"Float", 8}, base + "/point_radius");
        line(indent + 1, "</Attribute>");
        for (const char* a : {"level", "label"}) {
            line(indent + 1, std::string("<Attribute Name=\"") + a + "\" AttributeType=\"Scalar\" Center=\"Cell\">");
            hdf_item(indent + 2, cells, {"Int", 4}, base + "/segment_" + a);
            line(indent + 1, "</Attribute>");
        }
        line(indent, "</Grid>");
    }

    std::string str() const { return out_.str(); }

private:
    std::string h5_;
    std::ostringstream out_;
};

} // namespace

std::string xdmf_document(const XdmfContents& contents, const std::string& h5_file_name)
{
    Document doc(h5_file_name);
    doc.line(0, "<?xml version=\"1.0\" encoding=\"utf-8\"?>");
    doc.line(0, "<Xdmf xmlns:xi=\"http://www.w3.org/2001/XInclude\" Version=\"3.0\">");
    doc.line(1, "<Domain>");
    doc.collection("images", contents.images, [&](const XdmfVolume& v) { doc.volume(3, "images", v); });
    doc.collection("labels", contents.labels, [&](const XdmfVolume& v) { doc.volume(3, "labels", v); });
    // Readers choke on zero-sized heavy data; an empty mesh stays in the .h5 but not in the view.
    std::vector<XdmfSurface> surfaces;
    for (const auto& s : contents.surfaces)
        if (s.vertices > 0 && s.triangles > 0)
            surfaces.push_back(s);
    std::vector<XdmfTetMesh> meshes;
    for (const auto& m : contents.meshes)
        if (m.vertices > 0 && m.tets > 0)
            meshes.push_back(m);
    doc.collection("surfaces", surfaces, [&](const XdmfSurface& s) { doc.surface(3, s); });
    doc.collection("meshes", meshes, [&](const XdmfTetMesh& m) { doc.tet_mesh(3, m); });
    std::vector<XdmfGraph> graphs;
    for (const auto& g : contents.graphs)
        if (g.points > 0 && g.segments > 0)
            graphs.push_back(g);
    doc.collection("graphs", graphs, [&](const XdmfGraph& g) { doc.graph(3, g); });
    std::vector<XdmfSimulation> simulations;
    for (const auto& s : contents.simulations)
        if (!s.times.empty() && s.mesh.vertices > 0 && s.mesh.tets > 0)
            simulations.push_back(s);
    // Temporal collections sit directly in the Domain, where every ParaView reader looks for time.
    for (const auto& s : simulations)
        doc.simulation(2, s);
    doc.line(1, "</Domain>");
    doc.line(0, "</Xdmf>");
    return doc.str();
}

} // namespace lobe::io::detail
