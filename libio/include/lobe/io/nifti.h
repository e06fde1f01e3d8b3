#pragma once
//! \file
//! \brief NIfTI-1 (.nii, .nii.gz) reading and writing through nifti_clib, with the geometry
//! converted between NIfTI's RAS and lobe's LPS world coordinates.
//!
//! Reading places the voxels as the NIfTI-1 standard says: the sform when sform_code > 0, else
//! the qform when qform_code > 0, else pixdim alone ("method 1"). The 3x4 affine (RAS, in the
//! file's xyz unit) is scaled to millimetres, its first two rows are negated (RAS -> LPS), and
//! its 3x3 part is split into spacing (column norms) and direction (unit columns); the
//! translation is the origin. Scalar types uint8 ... float64 map to the matching AnyImage type;
//! scl_slope/scl_inter, when not the identity, give a float32 image (float64 if the file
//! stores float64). Writing does the inverse and sets sform and qform (both code 1,
//! NIFTI_XFORM_SCANNER_ANAT). NIfTI-1 stores the affine as float32, so geometry survives a
//! round trip to about 1e-7 relative (e.g. 2e-5 mm for an origin 200 mm from 0).
//! See docs/formats/nifti.md for every choice and every error.

#include "lobe/core/any_image.h"

#include <cstdint>
#include <filesystem>
#include <string>

namespace lobe::io {

//! Which of NIfTI-1's three ways of placing voxels a file uses.
enum class NiftiTransform {
    Sform,  //!< srow_x/y/z (sform_code > 0)
    Qform,  //!< quaternion + qoffset + pixdim, qfac = sign of pixdim[0] (qform_code > 0)
    Pixdim, //!< neither: x = pixdim[1] * i etc. in RAS, origin 0 ("method 1", ANALYZE legacy)
};

//! What a NIfTI-1 header says, validated as read_nifti() validates it.
struct NiftiHeader {
    core::ImageGeometry geometry;      //!< LPS millimetres, ITK's meaning (see the file comment)
    int ndims = 3;                     //!< dim[0]
    int volumes = 1;                   //!< dim[4] when dim[0] >= 4 (time points), else 1
    core::PixelType stored_type = core::PixelType::UInt8; //!< the voxel type on disk
    core::PixelType pixel_type = core::PixelType::UInt8;  //!< the type read_nifti() returns
    bool scaled = false;               //!< scl_slope/scl_inter are applied (not the identity)
    double scl_slope = 1.0;            //!< value = scl_slope * stored + scl_inter when `scaled`
    double scl_inter = 0.0;
    NiftiTransform transform = NiftiTransform::Sform; //!< the transform `geometry` comes from
    int qform_code = 0;                //!< NIFTI_XFORM_* code of the qform (0 = absent)
    int sform_code = 0;                //!< NIFTI_XFORM_* code of the sform (0 = absent)
    double unit_to_mm = 1.0;           //!< xyzt_units factor applied (unknown units count as mm)
    bool byte_swapped = false;         //!< the file's byte order differs from this machine's
    bool compressed = false;           //!< gzip (.nii.gz)
    std::int64_t data_offset = 352;    //!< vox_offset: byte where the voxels start
    std::string description;           //!< descrip (up to 80 characters)
};

//! Options of read_nifti().
struct NiftiReadParams {
    //! Volume (0-based index along dim[4]) to read from a 4-D series; -1 reads a file that holds
    //! exactly one volume and refuses a series.
    int volume = -1;
};

//! Reads and validates the header of a .nii/.nii.gz without reading its voxels.
//! \throw core::IoError if the file is missing, unreadable, shorter than its header promises
//! (uncompressed) or than any gzip stream could expand to, or its gzip stream is corrupt.
//! \throw core::InvalidInputError if it is not a single-file NIfTI-1 image lobe can read: bad
//! magic or sizeof_hdr (NIfTI-2 and .hdr/.img pairs included), dimensions that are not
//! positive or exceed io::kMaxVoxels, a non-scalar or unsupported datatype (complex, RGB,
//! int64, ...), pixdim that is zero, negative or NaN, a non-finite or singular transform,
//! or a file name that does not end in .nii or .nii.gz. Every message names the file.
NiftiHeader read_nifti_header(const std::filesystem::path& path);

//! Reads a single-volume NIfTI-1 image (2-D or 3-D; a 4-D file with one time point counts).
//! \throw core::InvalidInputError for a series of several volumes (use the overload with
//! NiftiReadParams::volume), and as read_nifti_header(); core::IoError for truncated or
//! corrupt data.
core::AnyImage read_nifti(const std::filesystem::path& path);

//! Reads one volume of a NIfTI-1 image. \throw core::InvalidInputError if params.volume is
//! out of range, and as read_nifti(path).
core::AnyImage read_nifti(const std::filesystem::path& path, const NiftiReadParams& params);

//! Writes `image` as NIfTI-1, gzip-compressed when the name ends in .nii.gz, atomically (a
//! temporary sibling renamed into place; nothing is left behind on failure). An image with
//! size[2] == 1 is written with dim[0] = 2; its third axis is kept in pixdim[3] and the sform.
//! \throw core::InvalidInputError for an invalid geometry, data whose length does not match
//! the size, a size above 32767 along an axis (NIfTI-1 stores dimensions as int16), or a
//! name not ending in .nii/.nii.gz; core::IoError if the file cannot be written.
void write_nifti(const std::filesystem::path& path, const core::AnyImage& image);

} // namespace lobe::io
