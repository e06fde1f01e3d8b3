#pragma once
// Reading lmesh's input: a label volume from a lobe container or a label image file.

#include "lobe/core/image3d.h"
#include "lobe/io/hdf5.h"

#include <filesystem>
#include <string>

namespace lobe::lmesh {

struct LabelInput {
    core::LabelImage3D labels;
    io::LabelTable table;  //!< from the container, empty for image files
    std::string name;      //!< the /labels item read, or the file's stem
    bool from_container = false;
};

//! /labels/<name> of a .h5 (empty name = the file's only label volume), or a label image
//! (MetaImage, NIfTI) with integer values in 0..255. \throw core::InvalidInputError naming the
//! file otherwise.
LabelInput read_label_input(const std::filesystem::path& path, const std::string& name);

//! The tissue's name: from the table, else liver / portal_vein / hepatic_veins / tumour for
//! 1-4, else "tissue_<label>".
std::string tissue_name(const io::LabelTable& table, int label);

} // namespace lobe::lmesh
