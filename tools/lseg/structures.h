#pragma once
// What `lseg vessels`, `lseg tumours` and `lseg all` share: where the liver mask comes from, the
// provenance entries of each structure, and their pictures.

#include "common/cli.h"

#include "lobe/core/centreline_graph.h"
#include "lobe/core/image3d.h"
#include "lobe/io/hdf5.h"
#include "lobe/seg/tumours.h"
#include "lobe/seg/vessels.h"

#include <filesystem>
#include <string>
#include <vector>

namespace lobe::lseg {

//! Options naming the liver mask the structures are searched in.
struct LiverSource {
    std::filesystem::path liver;        //!< --liver: a mask file (any image format, or a .h5)
    std::string liver_name = "liver";   //!< its label volume when it is a .h5
    std::vector<long long> liver_labels; //!< --liver-label: values counted as liver (empty: non-zero)
    std::filesystem::path shape;        //!< --shape: shape memory for the automatic liver pipeline
    bool force_ct = false;              //!< --modality ct: run on a volume that reads as MR
};

//! Adds --liver, --liver-name, --liver-label, --shape and --modality to a subcommand.
void add_liver_options(CLI::App* cmd, LiverSource& source);

//! The liver mask (0/1) on the grid of `image`: from --liver; else the label volume `liver` of an
//! .h5 input (what `lseg liver` writes); else the automatic liver pipeline (lobe/seg/liver.h).
//! `how` says which. \throw core::InvalidInputError naming the file if a mask is on another grid,
//! is empty, or no liver is found.
core::LabelImage3D obtain_liver(const std::filesystem::path& image_path, const core::ImageF& image,
                                const LiverSource& source, const tools::Progress& progress, tools::Timings& timings,
                                std::string& how);

//! What lseg vessels, tumours and all start from: the volume (an .h5 input's `image_name`) and
//! the liver mask found for it (obtain_liver), with where it came from.
struct StructureInput {
    bool h5_input = false;    //!< the image came from a lobe .h5 (its provenance is carried over)
    core::AnyImage source;    //!< the image as read, in its own type (what the container stores)
    core::ImageF volume;      //!< the same as float, what the methods work on
    core::LabelImage3D liver;
    std::string liver_from;   //!< obtain_liver's `how`
};

//! Reads the image and obtains its liver, timing both and reporting the mask's source.
//! \throw core::InvalidInputError naming the file if the volume reads as MR (seg::detect_modality)
//! and `source.force_ct` is off: the vessel and tumour finders' defaults are contrast CT in HU.
StructureInput read_structure_input(const std::filesystem::path& image, const std::string& image_name,
                                    const LiverSource& source, const tools::Progress& progress, tools::Timings& timings);

//! The label table of the tissue volume: 1 liver, 2 portal_vein, 3 hepatic_veins, 4 tumour.
const io::LabelTable& tissue_table();

//! Adds the vessel results (prefix "vessels.") to a provenance record.
void add_vessel_provenance(io::Provenance& prov, const seg::VesselResult& r);

//! Pictures of the vessels: the axial slice with the most vessel voxels and a coronal slice
//! through their centroid with the labels drawn, and the centre-line tree coloured by branch level
//! over a coronal maximum-intensity projection of the liver ("<prefix>-tree.png").
void write_vessel_pictures(const std::filesystem::path& dir, const std::string& prefix, const core::ImageF& image,
                           const core::LabelImage3D& liver, const seg::VesselResult& r);

//! Adds the tumour results (prefix "tumours.") to a provenance record.
void add_tumour_provenance(io::Provenance& prov, const seg::TumourResult& r);

//! An optional mask read from `path` (any image format; a .h5's label volume `h5_name`), non-zero
//! = object, on the grid of `image`. \throw core::InvalidInputError naming the file otherwise.
core::LabelImage3D read_mask(const std::filesystem::path& path, const std::string& h5_name, const core::ImageGeometry& image,
                             const std::string& what);

//! True if the container at `path` (a .h5) has the label volume `name`.
bool has_labels(const std::filesystem::path& path, const std::string& name);

//! Parses "x,y,z" [mm]. \throw CLI::ValidationError (bad command line) otherwise.
core::Vec3 parse_point(const std::string& text);
//! parse_point of each text.
std::vector<core::Vec3> parse_points(const std::vector<std::string>& texts);

//! Axial pictures through each tumour's centre (at most three, largest first) with the tumour and
//! liver contours: "<prefix>-1.png", ...
void write_tumour_pictures(const std::filesystem::path& dir, const std::string& prefix, const core::ImageF& image,
                           const core::LabelImage3D& liver, const seg::TumourResult& r);

//! "12.3" style formatting.
std::string fixed(double v, int digits);

//! "wrote OUT[, LABELS][, pictures in DIR]": the last progress line of vessels, tumours and all.
std::string wrote_message(const std::filesystem::path& out, const std::filesystem::path& labels_out,
                          const std::filesystem::path& png_dir);

} // namespace lobe::lseg
