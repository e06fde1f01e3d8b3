#pragma once
//! \file
//! \brief The HDF5 pipeline container: one file per pipeline stage (lseg, lmesh, lsim) holding
//! images, label volumes, surfaces, tetrahedral meshes and the provenance of every tool that
//! contributed, with an XDMF sidecar so that ParaView opens it as it is.
//!
//! The schema is specified in docs/file-format.md. In short:
//!     /                     attrs lobe_schema = "lobe", lobe_schema_version = 1, lobe_version, created
//!     /provenance/NNN_tool  one group per tool run (attrs + parameters/ and timings/ sub-groups)
//!     /images/NAME          [nz][ny][nx] dataset of the image's pixel type + spacing/origin/direction
//!     /labels/NAME          [nz][ny][nx] uint8 label volume + label_values/label_names table
//!     /surfaces/NAME/       vertices (n,3) float64, triangles (m,3) int32
//!     /meshes/NAME/         vertices (n,3) float64, tets (m,4) int32, tet_labels (m) int32,
//!                           quality/MEASURE (m) float64
//!     /simulation/NAME/     attr mesh; times (F), positions (F,n,3) [mm]; epochs/K/ after topology changes;
//!                           steps/{time,dt,force,energy};
//!                           statistics/ (float64 attributes), attr status
//!     /graphs/NAME/         centre-line graph: nodes (n,3), node_radius (n), edges (m,2) int32,
//!                           edge_level/edge_label (m) int32, edge_radius/edge_length (m), polylines:
//!                           points (p,3), point_radius (p), edge_offsets (m+1) int64
//! Geometry attributes are in ITK's (x, y, z) order although the dataset dimensions are (z, y, x).
//!
//! Errors: core::IoError when a file cannot be opened, read or written or is not HDF5 at all;
//! core::InvalidInputError when an HDF5 file breaks the lobe schema (every message names the
//! file and the object, e.g. "ct.h5: /images/ct has no spacing attribute") or when an argument
//! is invalid.
//!
//! An Hdf5Writer or Hdf5Reader is used by one thread at a time; distinct objects may be used from
//! different threads (Debian's HDF5 is the thread-safe build, which serialises its calls).

#include "lobe/core/any_image.h"
#include "lobe/core/centreline_graph.h"
#include "lobe/core/tet_mesh.h"
#include "lobe/core/tri_mesh.h"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace lobe::io {

//! The schema version this lobe writes, and the newest it reads.
inline constexpr int kHdf5SchemaVersion = 1;

//! One entry of a label table: a label value and its name ("liver", "portal_vein", ...).
struct LabelEntry {
    std::int32_t value = 0;
    std::string name;
};

//! Label value -> name, in the order written. Values are unique; names are non-empty.
using LabelTable = std::vector<LabelEntry>;

//! A label volume with its table.
struct LabelVolume {
    core::LabelImage3D image;
    LabelTable table; //!< empty if the file has none
};

//! One value per element (tet) of a mesh, e.g. a quality measure.
struct ElementArray {
    std::string name;           //!< e.g. "min_dihedral_angle"; [A-Za-z0-9_.-], unique per mesh
    std::vector<double> values; //!< one per tet
    std::string units;          //!< e.g. "degree"; empty = dimensionless (not stored)
};

//! A tetrahedral mesh as the container holds it.
struct TetMeshData {
    core::TetMesh mesh;
    std::vector<ElementArray> quality; //!< per-tet arrays, in the order written
    LabelTable tissues;                //!< names of the tet labels; empty if the file has none
};

//! What one tool run did: stored as /provenance/NNN_<tool>.
struct Provenance {
    std::string tool;         //!< e.g. "lmesh"; must not be empty
    std::string version;      //!< the tool's version
    std::string command_line; //!< as typed (see join_command_line)
    std::string started;      //!< ISO 8601 UTC (see utc_timestamp); empty = the time of writing
    std::vector<std::pair<std::string, std::string>> parameters; //!< (name, value), CLI order; unique names
    std::vector<std::pair<std::string, double>> timings;         //!< (step, seconds), run order; unique steps
};

//! One integration step of a simulation, as /simulation/<name>/steps stores it.
struct SimulationStep {
    double time = 0;           //!< time at the end of the step [s]
    double dt = 0;             //!< [s]
    core::Vec3 force{0, 0, 0}; //!< force of the tissue on the instruments [N]
    double energy = 0;         //!< total energy [J]
};

//! A simulation read back (frames are read one at a time with Hdf5Reader::read_frame).
struct SimulationInfo {
    std::string mesh;                 //!< name of the tet mesh (in /meshes) whose topology the first frames use
    std::size_t nodes = 0;            //!< vertices per frame, until the first topology change
    //! Frames at which the topology changed (a cut, a refinement): frame topology_changes[k] and
    //! the ones after it use epochs/<k+1> (read_frame_mesh gives each frame's mesh).
    std::vector<std::size_t> topology_changes;
    std::vector<double> times;        //!< time of each frame [s]
    std::vector<SimulationStep> steps;
    std::vector<std::pair<std::string, double>> statistics; //!< in the order written
    std::string status;               //!< "completed" or why the run stopped
};

//! Header of an image without its pixels.
struct ImageInfo {
    core::PixelType pixel_type = core::PixelType::UInt8;
    core::ImageGeometry geometry;
};

//! Options of Hdf5Writer.
struct Hdf5WriteParams {
    int gzip_level = 1;     //!< deflate level 0 (no compression) .. 9; shuffle is on whenever deflate is.
                            //!< 1: 17 % less write time than 4 for 2 % more bytes on a CT (docs/benchmarks.md,
                            //!< "Image I/O"), the level lobe's MetaImage and NIfTI writers use too
    bool checksum = true;   //!< Fletcher-32 checksum per chunk, so corruption is an error, not wrong data
    bool write_xdmf = true; //!< write the XDMF sidecar (the path with extension .xdmf) on commit
};

//! Current time as ISO 8601 UTC, e.g. "2024-05-01T12:34:56Z".
std::string utc_timestamp();

//! The command line as one string; arguments holding spaces or shell metacharacters are
//! single-quoted so that the string can be pasted back into a shell.
std::string join_command_line(int argc, const char* const argv[]);

class Hdf5Reader;

//! Writes one container. Everything goes to a temporary sibling of `path`; commit() moves the
//! finished file (and its XDMF sidecar) into place. A writer destroyed without commit() removes
//! its temporary, so a failed run never leaves a half file and an existing file at `path` stays
//! untouched until commit(). Names of items match [A-Za-z0-9_][A-Za-z0-9_.-]* (at most 255 chars)
//! and are unique per kind. Each write checks its arguments before touching the file, so a
//! refused write leaves the writer usable.
class Hdf5Writer {
public:
    //! \param path final file name (conventionally .h5); its directory must exist
    //! \throw core::InvalidInputError for bad params or a .xdmf path, core::IoError if the
    //!        temporary cannot be created
    explicit Hdf5Writer(std::filesystem::path path, const Hdf5WriteParams& params = {});
    ~Hdf5Writer();
    Hdf5Writer(Hdf5Writer&&) noexcept;
    Hdf5Writer& operator=(Hdf5Writer&&) noexcept;
    Hdf5Writer(const Hdf5Writer&) = delete;
    Hdf5Writer& operator=(const Hdf5Writer&) = delete;

    //! The final path given to the constructor.
    const std::filesystem::path& path() const;

    //! Writes /images/<name> in the image's own pixel type.
    //! \throw core::InvalidInputError for a bad name, duplicate, invalid geometry or data size
    void write_image(const std::string& name, const core::AnyImage& image);

    //! Writes /labels/<name> with its label table (values must be 0..255).
    void write_labels(const std::string& name, const core::LabelImage3D& labels, const LabelTable& table = {});

    //! Writes /surfaces/<name>. \throw core::InvalidInputError if core::mesh_problem() finds an
    //! index out of range or a repeated vertex, or a coordinate is not finite
    void write_surface(const std::string& name, const core::TriMesh& mesh);

    //! Writes /meshes/<name> with per-tet arrays (each must have one value per tet) and an optional
    //! table naming the tet labels. \throw core::InvalidInputError if core::mesh_problem() rejects
    //! the mesh (index range, one label per tet, positive orientation) or an array has the wrong size
    void write_tet_mesh(const std::string& name, const core::TetMesh& mesh,
                        const std::vector<ElementArray>& quality = {}, const LabelTable& tissues = {});

    //! Starts /simulation/<name> on the tet mesh /meshes/<mesh>, which this writer must have
    //! written. Frames and steps are appended as the run goes; the file stays a valid container.
    //! \throw core::InvalidInputError for a bad or duplicate name or an unknown mesh
    void begin_simulation(const std::string& name, const std::string& mesh);

    //! Appends one output frame: node positions [mm] (one per mesh vertex, finite) at `time` [s]
    //! (after the previous frame's). \throw core::InvalidInputError otherwise
    void append_frame(const std::string& name, double time, const std::vector<core::Vec3>& positions_mm);

    //! Starts a new topology for the frames that follow (a cut or a refinement changed the mesh):
    //! /simulation/<name>/epochs/<k>/ with the mesh's tets, tet labels and rest vertices; the
    //! next frames must have mesh.vertices.size() positions.
    //! \throw core::InvalidInputError for an unknown simulation or a mesh core::mesh_problem() rejects
    void begin_topology(const std::string& name, const core::TetMesh& mesh);

    //! Appends integration steps (any number, e.g. those since the last frame).
    void append_steps(const std::string& name, const std::vector<SimulationStep>& steps);

    //! Writes the run statistics (float64 attributes of statistics/) and the status attribute
    //! ("completed", or why the run stopped: the frames kept are the last good ones).
    void finish_simulation(const std::string& name, const std::vector<std::pair<std::string, double>>& statistics,
                           const std::string& status = "completed");

    //! Writes /graphs/<name>: a centre-line graph (vessel trees) with its polylines, radii, branch
    //! levels, tissue labels and edge names (docs/file-format.md, /graphs).
    //! \throw core::InvalidInputError if core::graph_problem() rejects it or it exceeds the limits
    void write_graph(const std::string& name, const core::CentrelineGraph& graph);

    //! Appends a provenance record as /provenance/NNN_<tool>, NNN counting from 000 in call order.
    void write_provenance(const Provenance& record);

    //! Appends every provenance record of `input`, oldest first, so that each stage keeps the
    //! history of the stages before it. Call it before write_provenance() for the current run.
    void copy_provenance(const Hdf5Reader& input);

    //! Closes the file, writes the XDMF sidecar and moves both into place. The writer accepts
    //! nothing afterwards. \throw core::IoError if closing, writing or renaming fails
    void commit();

private:
    struct Impl;
    Impl& impl(); // throws if moved from
    std::unique_ptr<Impl> impl_;
};

//! Reads a container. The constructor checks the root attributes; each read checks the item it
//! reads (ranks, dimensions against lobe/io/limits.h, types, index ranges, geometry).
class Hdf5Reader {
public:
    //! \throw core::IoError (missing, unreadable, not HDF5), core::InvalidInputError (not a lobe
    //!        container, missing root attributes, schema version newer than kHdf5SchemaVersion)
    explicit Hdf5Reader(const std::filesystem::path& path);
    ~Hdf5Reader();
    Hdf5Reader(Hdf5Reader&&) noexcept;
    Hdf5Reader& operator=(Hdf5Reader&&) noexcept;
    Hdf5Reader(const Hdf5Reader&) = delete;
    Hdf5Reader& operator=(const Hdf5Reader&) = delete;

    const std::filesystem::path& path() const;
    int schema_version() const;
    const std::string& lobe_version() const; //!< version of the lobe that wrote the file
    const std::string& created() const;      //!< ISO 8601 UTC

    //! Names of the items of each kind, in the order written (empty if the group is absent).
    std::vector<std::string> images() const;
    std::vector<std::string> labels() const;
    std::vector<std::string> surfaces() const;
    std::vector<std::string> tet_meshes() const;
    std::vector<std::string> simulations() const;
    std::vector<std::string> graphs() const;

    //! Pixel type and geometry of /images/<name>, without reading the pixels.
    ImageInfo image_info(const std::string& name) const;
    //! Geometry of /labels/<name> (pixel type uint8), without reading the labels.
    ImageInfo label_info(const std::string& name) const;

    core::AnyImage read_image(const std::string& name) const;
    LabelVolume read_labels(const std::string& name) const;
    core::TriMesh read_surface(const std::string& name) const;
    TetMeshData read_tet_mesh(const std::string& name) const;
    //! Everything of /simulation/<name> but the frames.
    SimulationInfo read_simulation(const std::string& name) const;
    //! /graphs/<name>, checked with core::graph_problem and for consistent sizes and offsets.
    core::CentrelineGraph read_graph(const std::string& name) const;
    //! Node positions [mm] of frame `index` (0-based) of /simulation/<name>.
    std::vector<core::Vec3> read_frame(const std::string& name, std::size_t index) const;
    //! Frame `index` as a mesh: its positions as vertices, the tets and labels of its topology.
    core::TetMesh read_frame_mesh(const std::string& name, std::size_t index) const;

    //! Every provenance record, oldest first.
    std::vector<Provenance> provenance() const;

private:
    struct Impl;
    const Impl& impl() const; // throws if moved from
    std::unique_ptr<Impl> impl_;
};

//! Reads image `name` from a container: "ct" looks in /images then /labels; "images/ct" or
//! "labels/liver" is explicit; empty = the file's only image or label volume (an error listing
//! them if there are none or several). Label volumes come back as uint8 images.
core::AnyImage read_hdf5_image(const std::filesystem::path& path, const std::string& name = {});

//! Writes a container holding one image /images/<name>, atomically, with its XDMF sidecar.
void write_hdf5_image(const std::filesystem::path& path, const core::AnyImage& image,
                      const std::string& name = "image");

} // namespace lobe::io
