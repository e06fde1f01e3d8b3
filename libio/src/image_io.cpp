#include "lobe/io/image_io.h"

#include "lobe/io/dicom.h"
#include "lobe/io/hdf5.h"
#include "lobe/io/inrimage.h"
#include "lobe/io/metaimage.h"
#include "lobe/io/nifti.h"

#include <algorithm>
#include <cctype>

namespace lobe::io {
namespace {

bool ends_with(std::string s, const std::string& suffix)
{
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

} // namespace

const char* format_name(ImageFormat format)
{
    switch (format) {
    case ImageFormat::MetaImage: return "MetaImage";
    case ImageFormat::Nifti: return "NIfTI";
    case ImageFormat::Hdf5: return "HDF5";
    case ImageFormat::Dicom: return "DICOM";
    case ImageFormat::Inrimage: return "INRIMAGE";
    }
    return "unknown";
}

ImageFormat image_format(const std::filesystem::path& path)
{
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec))
        return ImageFormat::Dicom;
    const std::string name = path.filename().string();
    if (ends_with(name, ".mhd") || ends_with(name, ".mha"))
        return ImageFormat::MetaImage;
    if (ends_with(name, ".nii") || ends_with(name, ".nii.gz"))
        return ImageFormat::Nifti;
    if (ends_with(name, ".h5") || ends_with(name, ".hdf5"))
        return ImageFormat::Hdf5;
    if (ends_with(name, ".dcm") || ends_with(name, ".dicom"))
        return ImageFormat::Dicom;
    if (ends_with(name, ".inr") || ends_with(name, ".inr.gz"))
        return ImageFormat::Inrimage;
    throw core::InvalidInputError(path.string() +
                                  ": unknown image format (expected .mhd, .mha, .nii, .nii.gz, .h5, .hdf5, "
                                  ".inr, .inr.gz, .dcm or a DICOM folder)");
}

core::AnyImage read_image(const std::filesystem::path& path)
{
    switch (image_format(path)) {
    case ImageFormat::MetaImage: return read_metaimage(path);
    case ImageFormat::Nifti: return read_nifti(path);
    case ImageFormat::Hdf5: return read_hdf5_image(path);
    case ImageFormat::Dicom: return read_dicom_series(path).image;
    case ImageFormat::Inrimage: return read_inrimage(path);
    }
    throw core::InvalidInputError(path.string() + ": unknown image format");
}

void write_image(const std::filesystem::path& path, const core::AnyImage& image)
{
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec))
        throw core::InvalidInputError(path.string() + ": is a folder; lobe writes no DICOM (read only), "
                                                      "choose .mhd, .mha, .nii, .nii.gz or .h5");
    switch (image_format(path)) {
    case ImageFormat::MetaImage: write_metaimage(path, image); return;
    case ImageFormat::Nifti: write_nifti(path, image); return;
    case ImageFormat::Hdf5: write_hdf5_image(path, image); return;
    case ImageFormat::Dicom:
        throw core::InvalidInputError(path.string() + ": lobe reads DICOM but does not write it; "
                                                      "choose .mhd, .mha, .nii, .nii.gz or .h5");
    case ImageFormat::Inrimage:
        throw core::InvalidInputError(path.string() + ": lobe reads INRIMAGE but does not write it; "
                                                      "choose .mhd, .mha, .nii, .nii.gz or .h5");
    }
}

} // namespace lobe::io
