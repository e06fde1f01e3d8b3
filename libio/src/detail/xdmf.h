#pragma once
// The XDMF sidecar of an HDF5 container: what the writer put into the file, described so that
// ParaView can read the heavy data straight from the .h5 (docs/file-format.md, "XDMF sidecar").

#include "lobe/core/any_image.h"

#include <cstddef>
#include <string>
#include <vector>

namespace lobe::io::detail {

struct XdmfVolume {
    std::string name;          // item name; the dataset is /<group>/<name>
    core::PixelType pixel_type;
    core::ImageGeometry geometry;
};

struct XdmfSurface {
    std::string name;          // /surfaces/<name>/{vertices,triangles}
    std::size_t vertices = 0;
    std::size_t triangles = 0;
};

struct XdmfTetMesh {
    std::string name;          // /meshes/<name>/{vertices,tets,tet_labels,quality/<q>}
    std::size_t vertices = 0;
    std::size_t tets = 0;
    std::vector<std::string> quality;
};

// A run of frames on one topology: /simulation/<name>/positions on /meshes/<mesh> (epoch 0), or
// /simulation/<name>/epochs/<k>/{positions,tets,tet_labels} after the k-th topology change.
struct XdmfEpoch {
    std::string positions;     // dataset path (frames, vertices, 3)
    std::string tets;          // dataset path (cells, 4)
    std::string tet_labels;    // dataset path (cells)
    std::size_t vertices = 0;
    std::size_t cells = 0;
    std::size_t first_frame = 0;
    std::size_t frames = 0;
};

struct XdmfSimulation {
    std::string name;
    XdmfTetMesh mesh;          // the topology of epoch 0: /meshes/<mesh.name>/tets and tet_labels
    std::vector<double> times; // one per frame
    std::vector<XdmfEpoch> epochs; // epochs[0] is the mesh's
};

struct XdmfGraph {
    std::string name;          // /graphs/<name>/{points,segments,point_radius,segment_level,segment_label}
    std::size_t points = 0;
    std::size_t segments = 0;
};

struct XdmfContents {
    std::vector<XdmfVolume> images;
    std::vector<XdmfVolume> labels;
    std::vector<XdmfSurface> surfaces;
    std::vector<XdmfTetMesh> meshes;
    std::vector<XdmfSimulation> simulations;
    std::vector<XdmfGraph> graphs;
};

// The XDMF 3 document describing `contents`, whose heavy data lives in `h5_file_name`
// (a file name relative to the XDMF file, normally the container's own file name).
std::string xdmf_document(const XdmfContents& contents, const std::string& h5_file_name);

} // namespace lobe::io::detail
