// NIfTI-1 through nifti_clib. The library reads and writes the 348-byte header, swaps bytes,
// converts quaternions and does the gzip I/O (znzlib). lobe adds what the library does not do:
// it validates the raw header before anything is allocated (nifti_clib silently turns zero
// dims and NaN pixdim into 1), converts RAS to LPS, reads the voxels straight into the image
// (one allocation, no NaN -> 0 "fix"), and writes atomically. See docs/formats/nifti.md.
#include "lobe/io/nifti.h"

#include "detail/atomic_file.h"
#include "detail/checks.h"
#include "lobe/io/limits.h"

// znzlib declares the gzFile member of its file struct only under HAVE_ZLIB. Debian builds
// nifti_clib with zlib (upstream exports HAVE_ZLIB with its znz target); we need the member to
// ask zlib why a gzip stream failed, and use it only if nifti_compiled_with_zlib() says so.
#ifndef HAVE_ZLIB
#define HAVE_ZLIB 1
#endif
#include <nifti1_io.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <utility>
#include <variant>

#ifndef LOBE_VERSION_STRING
#define LOBE_VERSION_STRING "unknown"
#endif

namespace lobe::io {
namespace {

namespace fs = std::filesystem;
using core::InvalidInputError;
using core::IoError;
using core::PixelType;

constexpr int kNifti1HeaderSize = 348;
constexpr int kNifti2HeaderSize = 540;
constexpr int kMinVoxOffset = 352; // header + 4-byte extension flag
constexpr int kMaxDim = 32767;     // dim[] is int16 in NIfTI-1

// nifti_clib reports errors on stderr unless its debug level is 0; we throw our own messages.
void quiet_nifti_clib() { nifti_set_debug_level(0); }

struct FreeDeleter {
    void operator()(void* p) const { std::free(p); }
};
struct NimDeleter {
    void operator()(nifti_image* p) const { nifti_image_free(p); }
};

// Owns a znzFile. close() returns fclose/gzclose's result: buffered and gzip writes can fail
// only there.
class ZnzHandle {
public:
    explicit ZnzHandle(znzFile f = nullptr) : f_(f) {}
    ZnzHandle(const ZnzHandle&) = delete;
    ZnzHandle& operator=(const ZnzHandle&) = delete;
    ~ZnzHandle()
    {
        if (f_)
            znzclose(f_);
    }
    znzFile get() const { return f_; }
    explicit operator bool() const { return f_ != nullptr; }
    znzFile release() { return std::exchange(f_, nullptr); }
    void reset(znzFile f)
    {
        if (f_)
            znzclose(f_);
        f_ = f;
    }
    int close() { return f_ ? znzclose(f_) : 0; } // znzclose also sets f_ to NULL

private:
    znzFile f_;
};

std::string errno_message() { return std::error_code(errno, std::generic_category()).message(); }

std::string num(double v)
{
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.9g", v);
    return buf;
}

std::string printable(const char* s, std::size_t n)
{
    std::string out;
    for (std::size_t i = 0; i < n; ++i) {
        const auto c = static_cast<unsigned char>(s[i]);
        if (c >= 0x20 && c < 0x7f) {
            out += static_cast<char>(c);
        } else {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\x%02x", static_cast<unsigned>(c));
            out += buf;
        }
    }
    return out;
}

bool has_suffix(const std::string& s, std::string_view suffix)
{
    // Strictly longer: nifti_clib refuses a name that is only an extension.
    return s.size() > suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

bool is_gz_name(const fs::path& p) { return has_suffix(p.filename().string(), ".nii.gz"); }

void check_name(const fs::path& p)
{
    const std::string name = p.filename().string();
    if (!has_suffix(name, ".nii") && !has_suffix(name, ".nii.gz"))
        throw InvalidInputError(p.string() + ": not a NIfTI file name (expected the extension .nii or .nii.gz)");
}

bool pixel_type_of_datatype(int datatype, PixelType& out)
{
    switch (datatype) {
    case DT_UINT8: out = PixelType::UInt8; return true;
    case DT_INT8: out = PixelType::Int8; return true;
    case DT_INT16: out = PixelType::Int16; return true;
    case DT_UINT16: out = PixelType::UInt16; return true;
    case DT_INT32: out = PixelType::Int32; return true;
    case DT_UINT32: out = PixelType::UInt32; return true;
    case DT_FLOAT32: out = PixelType::Float32; return true;
    case DT_FLOAT64: out = PixelType::Float64; return true;
    default: return false;
    }
}

int datatype_of(PixelType t)
{
    switch (t) {
    case PixelType::UInt8: return DT_UINT8;
    case PixelType::Int8: return DT_INT8;
    case PixelType::Int16: return DT_INT16;
    case PixelType::UInt16: return DT_UINT16;
    case PixelType::Int32: return DT_INT32;
    case PixelType::UInt32: return DT_UINT32;
    case PixelType::Float32: return DT_FLOAT32;
    case PixelType::Float64: return DT_FLOAT64;
    }
    return DT_UNKNOWN;
}

const char* transform_name(NiftiTransform t)
{
    switch (t) {
    case NiftiTransform::Sform: return "sform";
    case NiftiTransform::Qform: return "qform";
    case NiftiTransform::Pixdim: return "pixdim-only transform";
    }
    return "transform";
}

// A hint for the common mistake of a gzip-compressed file named .nii.
std::string gzip_hint(const fs::path& path)
{
    std::ifstream f(path, std::ios::binary);
    unsigned char magic[2] = {0, 0};
    f.read(reinterpret_cast<char*>(magic), 2);
    if (f && magic[0] == 0x1f && magic[1] == 0x8b && !is_gz_name(path))
        return "; the file is gzip-compressed: name it .nii.gz";
    return {};
}

// Why zlib stopped, or "" (also when the file is not compressed). zlib prefixes its message
// with the file name, which our messages already start with.
std::string gz_problem(znzFile f, const std::string& file)
{
    if (!f || !nifti_compiled_with_zlib() || !f->zfptr)
        return {};
    int err = Z_OK;
    const char* msg = gzerror(f->zfptr, &err);
    if (err == Z_OK)
        return {};
    if (err == Z_ERRNO)
        return errno_message();
    std::string text = msg ? msg : "zlib error " + std::to_string(err);
    if (text.compare(0, file.size() + 2, file + ": ") == 0)
        text.erase(0, file.size() + 2);
    return text;
}

// The raw header, checked field by field. Everything read_nifti needs to know comes from here,
// so that a bad header is refused before the voxels are allocated.
NiftiHeader parse_header(const nifti_1_header& h, bool swapped, const fs::path& path)
{
    const std::string name = path.string();
    const auto bad = [&name](const std::string& what) { return InvalidInputError(name + ": " + what); };

    std::int32_t other_order = h.sizeof_hdr;
    nifti_swap_4bytes(1, &other_order);
    if (std::memcmp(h.data_type, "n+2", 4) == 0 || h.sizeof_hdr == kNifti2HeaderSize ||
        other_order == kNifti2HeaderSize)
        throw bad("is a NIfTI-2 file; lobe reads NIfTI-1 only (nifti_clib's niftiio): convert it to "
                  "NIfTI-1, e.g. with ITK or nibabel");
    if (h.sizeof_hdr != kNifti1HeaderSize)
        throw bad("not a NIfTI-1 file (sizeof_hdr is " + std::to_string(h.sizeof_hdr) + ", expected 348)" +
                  gzip_hint(path));
    if (std::memcmp(h.magic, "ni1", 4) == 0)
        throw bad("is the header of a NIfTI-1 .hdr/.img pair (magic 'ni1'); lobe reads single-file "
                  ".nii/.nii.gz only");
    if (std::memcmp(h.magic, "n+1", 4) != 0)
        throw bad("not a NIfTI-1 file: its magic is '" + printable(h.magic, 4) +
                  "', expected 'n+1' (ANALYZE 7.5 files have none and no defined orientation)");

    NiftiHeader out;
    const int ndims = h.dim[0];
    if (ndims < 1 || ndims > 7)
        throw bad("dim[0] is " + std::to_string(ndims) + " (the number of dimensions must be 1 to 7)");
    for (int a = 1; a <= ndims; ++a)
        if (h.dim[a] < 1)
            throw bad("dim[" + std::to_string(a) + "] is " + std::to_string(h.dim[a]) + " (must be positive)");
    for (int a = 5; a <= ndims; ++a)
        if (h.dim[a] != 1)
            throw bad("dim[" + std::to_string(a) + "] is " + std::to_string(h.dim[a]) +
                      ": the file holds several values per voxel (vector, RGB or tensor data, intent code " +
                      std::to_string(h.intent_code) + "); lobe reads scalar images only");
    out.ndims = ndims;
    out.volumes = ndims >= 4 ? h.dim[4] : 1;
    const std::array<std::int64_t, 3> dims{h.dim[1], ndims >= 2 ? h.dim[2] : 1, ndims >= 3 ? h.dim[3] : 1};
    detail::checked_voxel_count(dims, name);

    if (!pixel_type_of_datatype(h.datatype, out.stored_type))
        throw bad("datatype " + std::to_string(h.datatype) + " (" + nifti_datatype_string(h.datatype) +
                  ") is not supported; lobe reads the scalar types UINT8, INT8, INT16, UINT16, INT32, "
                  "UINT32, FLOAT32 and FLOAT64");

    // Voxel sizes of the axes the file has must be valid; a collapsed axis (e.g. z of a 2-D
    // image) keeps its pixdim when that is valid (lobe writes it), else gets 1.
    std::array<double, 3> pixdim{1.0, 1.0, 1.0};
    for (int a = 1; a <= 3; ++a) {
        const double d = static_cast<double>(h.pixdim[a]);
        if (a <= ndims) {
            if (!std::isfinite(d) || !(d > 0))
                throw bad("pixdim[" + std::to_string(a) + "] is " + num(d) +
                          " (the voxel size must be finite and positive)");
            pixdim[a - 1] = d;
        } else if (std::isfinite(d) && d > 0) {
            pixdim[a - 1] = d;
        }
    }

    const double offset = static_cast<double>(h.vox_offset);
    if (!std::isfinite(offset) || offset < kMinVoxOffset || offset > 2147483647.0 || offset != std::floor(offset))
        throw bad("vox_offset is " + num(offset) +
                  " (the voxels must start at a whole byte offset of at least 352 in a .nii file)");
    out.data_offset = static_cast<std::int64_t>(offset);

    // Standard: slope 0 means "no scaling". nibabel writes NaN for the same, so any non-finite
    // slope counts as none; a valid slope with a non-finite intercept is corrupt (as in nibabel).
    const double slope = static_cast<double>(h.scl_slope);
    const double inter = static_cast<double>(h.scl_inter);
    if (std::isfinite(slope) && slope != 0.0) {
        if (!std::isfinite(inter))
            throw bad("scl_inter is " + num(inter) + " while scl_slope is " + num(slope) +
                      " (the intercept must be finite)");
        if (slope != 1.0 || inter != 0.0) {
            out.scaled = true;
            out.scl_slope = slope;
            out.scl_inter = inter;
        }
    }
    out.pixel_type = !out.scaled ? out.stored_type
                     : out.stored_type == PixelType::Float64 ? PixelType::Float64
                                                               : PixelType::Float32;

    // The unit applies to pixdim and to both transforms; unknown (0) is taken as mm, as ITK does.
    switch (XYZT_TO_SPACE(h.xyzt_units)) {
    case NIFTI_UNITS_METER: out.unit_to_mm = 1000.0; break;
    case NIFTI_UNITS_MICRON: out.unit_to_mm = 1e-3; break;
    default: out.unit_to_mm = 1.0; break;
    }

    // The 3x4 affine (i, j, k) -> RAS, chosen as the standard says.
    double m[3][4] = {};
    out.qform_code = h.qform_code;
    out.sform_code = h.sform_code;
    if (h.sform_code > 0) {
        out.transform = NiftiTransform::Sform;
        const float* rows[3] = {h.srow_x, h.srow_y, h.srow_z};
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 4; ++c)
                m[r][c] = static_cast<double>(rows[r][c]);
    } else if (h.qform_code > 0) {
        out.transform = NiftiTransform::Qform;
        const float q[6] = {h.quatern_b, h.quatern_c, h.quatern_d, h.qoffset_x, h.qoffset_y, h.qoffset_z};
        for (float v : q)
            if (!std::isfinite(v))
                throw bad("the qform (quatern_b/c/d, qoffset_x/y/z) contains a non-finite value");
        // qfac is the sign of pixdim[0]; 0 counts as +1 (nifti1.h).
        const float qfac = h.pixdim[0] < 0.0f ? -1.0f : 1.0f;
        const mat44 q44 = nifti_quatern_to_mat44(q[0], q[1], q[2], q[3], q[4], q[5], static_cast<float>(pixdim[0]),
                                                 static_cast<float>(pixdim[1]), static_cast<float>(pixdim[2]), qfac);
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 4; ++c)
                m[r][c] = static_cast<double>(q44.m[r][c]);
    } else {
        out.transform = NiftiTransform::Pixdim;
        for (int a = 0; a < 3; ++a)
            m[a][a] = pixdim[a];
    }
    const std::string tname = transform_name(out.transform);
    for (const auto& row : m)
        for (double v : row)
            if (!std::isfinite(v))
                throw bad("the " + tname + " contains a non-finite value");

    // RAS -> LPS: negate x and y. Then spacing = column norms, direction = unit columns.
    core::ImageGeometry& g = out.geometry;
    for (int a = 0; a < 3; ++a)
        g.size[a] = static_cast<int>(dims[a]);
    std::array<core::Vec3, 3> axis;
    std::array<bool, 3> have{false, false, false};
    for (int r = 0; r < 3; ++r) {
        const double sign = r < 2 ? -1.0 : 1.0;
        for (int c = 0; c < 4; ++c)
            m[r][c] *= sign * out.unit_to_mm;
        g.origin[r] = m[r][3];
    }
    for (int c = 0; c < 3; ++c) {
        const core::Vec3 col{m[0][c], m[1][c], m[2][c]};
        const double n = core::norm(col);
        if (n > 0) {
            axis[c] = col / n;
            g.spacing[c] = n;
            have[c] = true;
        } else if (c < ndims) {
            throw bad("the " + tname + " maps image axis " + std::to_string(c) + " to a zero vector");
        }
    }
    // Some writers leave the column of a collapsed axis zero: complete a right-handed frame.
    if (!have[1]) {
        if (have[2]) {
            axis[1] = core::normalized(core::cross(axis[2], axis[0]));
        } else {
            int least = 0;
            for (int i = 1; i < 3; ++i)
                if (std::abs(axis[0][i]) < std::abs(axis[0][least]))
                    least = i;
            core::Vec3 e;
            e[least] = 1.0;
            axis[1] = core::normalized(e - axis[0] * core::dot(e, axis[0]));
        }
        g.spacing[1] = pixdim[1] * out.unit_to_mm;
    }
    if (!have[2]) {
        axis[2] = core::normalized(core::cross(axis[0], axis[1]));
        g.spacing[2] = pixdim[2] * out.unit_to_mm;
    }
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
            g.direction[3 * r + c] = axis[c][r];
    const std::string problem = core::geometry_problem(g);
    if (!problem.empty())
        throw bad("the " + tname + " gives an invalid geometry: " + problem);

    out.byte_swapped = swapped;
    out.compressed = is_gz_name(path);
    out.description.assign(h.descrip, strnlen(h.descrip, sizeof h.descrip));
    return out;
}

// A header that promises more bytes than the file can hold means truncation: say so now,
// before allocating memory for data that is not there.
void check_data_size(const NiftiHeader& hdr, const fs::path& path)
{
    const std::string name = path.string();
    const auto bytes = static_cast<std::uint64_t>(hdr.geometry.voxel_count()) *
                       static_cast<std::uint64_t>(core::pixel_size(hdr.stored_type)) *
                       static_cast<std::uint64_t>(hdr.volumes);
    const std::uint64_t need = static_cast<std::uint64_t>(hdr.data_offset) + bytes;
    std::error_code ec;
    const std::uint64_t have = fs::file_size(path, ec);
    if (ec)
        throw IoError(name + ": cannot get the file size: " + ec.message());
    const auto& s = hdr.geometry.size;
    const std::string what = std::to_string(s[0]) + " x " + std::to_string(s[1]) + " x " + std::to_string(s[2]) +
                             (hdr.volumes > 1 ? " x " + std::to_string(hdr.volumes) : std::string()) + " " +
                             core::pixel_type_name(hdr.stored_type);
    if (!hdr.compressed && have < need)
        throw IoError(name + ": truncated: the header promises " + std::to_string(need) + " bytes (" + what +
                      " voxels from byte " + std::to_string(hdr.data_offset) + ") but the file has " +
                      std::to_string(have));
    // A .nii.gz promising more than deflate can expand to is refused before allocating.
    const auto max_expanded = static_cast<std::uint64_t>(static_cast<double>(have) * detail::kMaxDeflateRatio);
    if (hdr.compressed && need > max_expanded)
        throw IoError(name + ": truncated or corrupt: the header promises " + std::to_string(need) +
                      " bytes (" + what + ") but a gzip stream of " + std::to_string(have) +
                      " bytes cannot expand to more than " + std::to_string(max_expanded));
}

NiftiHeader load_header(const fs::path& path)
{
    quiet_nifti_clib();
    check_name(path);
    const std::string name = path.string();
    std::error_code ec;
    const fs::file_status st = fs::status(path, ec);
    if (!fs::exists(st)) {
        if (ec && ec != std::errc::no_such_file_or_directory)
            throw IoError(name + ": cannot access: " + ec.message());
        throw IoError(name + ": file does not exist");
    }
    if (fs::is_directory(st))
        throw IoError(name + ": is a directory, not a NIfTI file");
    // nifti_read_header cannot tell "unreadable" from "too short"; open it once to know which.
    if (std::FILE* f = std::fopen(name.c_str(), "rb"))
        std::fclose(f);
    else
        throw IoError(name + ": cannot open: " + errno_message());

    int swapped = 0;
    // check = 0: the raw header, byte-swapped to this machine, without nifti_clib's own
    // judgement, so that we can say precisely what is wrong with it.
    const std::unique_ptr<nifti_1_header, FreeDeleter> h(nifti_read_header(name.c_str(), &swapped, 0));
    if (!h)
        throw IoError(name + ": cannot read the 348-byte NIfTI-1 header: the file is shorter than that" +
                      (is_gz_name(path) ? " or its gzip stream is corrupt" : ""));
    NiftiHeader hdr = parse_header(*h, swapped != 0, path);
    check_data_size(hdr, path);
    return hdr;
}

template <class T>
core::Image3D<T> read_voxels(const fs::path& path, const NiftiHeader& hdr, int volume)
{
    const std::string name = path.string();
    core::Image3D<T> img(hdr.geometry);
    const std::size_t bytes = img.data.size() * sizeof(T);
    const std::int64_t offset = hdr.data_offset + static_cast<std::int64_t>(volume) * static_cast<std::int64_t>(bytes);

    ZnzHandle fp(znzopen(name.c_str(), "rb", hdr.compressed ? 1 : 0));
    if (!fp)
        throw IoError(name + ": cannot open: " + errno_message());
    // Skips any header extensions (they are not read at all).
    if (znzseek(fp.get(), static_cast<znz_off_t>(offset), SEEK_SET) < 0) {
        const std::string why = gz_problem(fp.get(), name);
        throw IoError(name + ": cannot reach the voxel data at byte " + std::to_string(offset) +
                      (why.empty() ? std::string(": the file is truncated")
                                   : ": the gzip stream is truncated or corrupt (zlib: " + why + ")"));
    }
    const std::size_t got = znzread(img.data.data(), 1, bytes, fp.get());
    if (got != bytes) {
        // znzread returns (size_t)-1 when zlib fails.
        const std::string count = got > bytes ? std::string()
                                              : ": read " + std::to_string(got) + " of " + std::to_string(bytes) +
                                                    " bytes of voxel data";
        if (hdr.compressed) {
            const std::string why = gz_problem(fp.get(), name);
            throw IoError(name + ": the gzip stream is truncated or corrupt" + count +
                          (why.empty() ? std::string() : " (zlib: " + why + ")"));
        }
        throw IoError(name + ": the voxel data is truncated or unreadable" + count);
    }
    if (hdr.compressed && volume == hdr.volumes - 1) {
        // zlib checks the gzip CRC and length only at the end of the stream: read past the data.
        char extra = 0;
        if (znzread(&extra, 1, 1, fp.get()) > 1)
            throw IoError(name + ": the gzip stream is corrupt (zlib: " + gz_problem(fp.get(), name) + ")");
    }
    if (hdr.byte_swapped && sizeof(T) > 1)
        nifti_swap_Nbytes(img.data.size(), static_cast<int>(sizeof(T)), img.data.data());
    return img;
}

template <class Out, class T>
core::Image3D<Out> apply_scaling(const core::Image3D<T>& in, double slope, double inter)
{
    core::Image3D<Out> out;
    static_cast<core::ImageGeometry&>(out) = in.geometry();
    out.data.resize(in.data.size());
    std::transform(in.data.begin(), in.data.end(), out.data.begin(),
                   [=](T v) { return static_cast<Out>(slope * static_cast<double>(v) + inter); });
    return out;
}

template <class T>
core::AnyImage read_as(const fs::path& path, const NiftiHeader& hdr, int volume)
{
    core::Image3D<T> raw = read_voxels<T>(path, hdr, volume);
    if (!hdr.scaled)
        return raw;
    // float32 holds every int16/uint16/int8/uint8 value exactly; float64 data stays float64.
    if constexpr (std::is_same_v<T, double>)
        return apply_scaling<double>(raw, hdr.scl_slope, hdr.scl_inter);
    else
        return apply_scaling<float>(raw, hdr.scl_slope, hdr.scl_inter);
}

} // namespace

NiftiHeader read_nifti_header(const std::filesystem::path& path) { return load_header(path); }

core::AnyImage read_nifti(const std::filesystem::path& path) { return read_nifti(path, NiftiReadParams{}); }

core::AnyImage read_nifti(const std::filesystem::path& path, const NiftiReadParams& params)
{
    const NiftiHeader hdr = load_header(path);
    const std::string name = path.string();
    int volume = params.volume;
    if (volume < 0) {
        if (hdr.volumes > 1)
            throw InvalidInputError(name + ": is a series of " + std::to_string(hdr.volumes) +
                                    " volumes (dim[4]); lobe reads one volume at a time: choose one "
                                    "(NiftiReadParams::volume; `lio convert IN OUT --volume K` extracts it)");
        volume = 0;
    } else if (volume >= hdr.volumes) {
        throw InvalidInputError(name + ": volume " + std::to_string(volume) + " requested but the file holds " +
                                std::to_string(hdr.volumes));
    }
    switch (hdr.stored_type) {
    case PixelType::UInt8: return read_as<std::uint8_t>(path, hdr, volume);
    case PixelType::Int8: return read_as<std::int8_t>(path, hdr, volume);
    case PixelType::Int16: return read_as<std::int16_t>(path, hdr, volume);
    case PixelType::UInt16: return read_as<std::uint16_t>(path, hdr, volume);
    case PixelType::Int32: return read_as<std::int32_t>(path, hdr, volume);
    case PixelType::UInt32: return read_as<std::uint32_t>(path, hdr, volume);
    case PixelType::Float32: return read_as<float>(path, hdr, volume);
    case PixelType::Float64: return read_as<double>(path, hdr, volume);
    }
    throw InvalidInputError(name + ": unsupported pixel type");
}

void write_nifti(const std::filesystem::path& path, const core::AnyImage& image)
{
    quiet_nifti_clib();
    check_name(path);
    const std::string name = path.string();
    const core::ImageGeometry& g = core::geometry(image);
    core::validate_geometry(g, name);
    const std::size_t count = std::visit([](const auto& im) { return im.data.size(); }, image);
    if (count != g.voxel_count())
        throw InvalidInputError(name + ": the image holds " + std::to_string(count) + " values for " +
                                std::to_string(g.voxel_count()) + " voxels");
    for (int a = 0; a < 3; ++a)
        if (g.size[a] > kMaxDim)
            throw InvalidInputError(name + ": size along axis " + std::to_string(a) + " is " +
                                    std::to_string(g.size[a]) +
                                    "; NIfTI-1 stores dimensions as 16-bit integers (at most 32767)");
    const bool gz = is_gz_name(path);
    if (gz && !nifti_compiled_with_zlib())
        throw IoError(name + ": cannot write .nii.gz: nifti_clib was built without zlib");

    const PixelType type = core::pixel_type(image);
    const int ndims = g.size[2] == 1 ? 2 : 3;
    const int dims[8] = {ndims, g.size[0], g.size[1], g.size[2], 1, 1, 1, 1};
    const std::unique_ptr<nifti_image, NimDeleter> nim(nifti_make_new_nim(dims, datatype_of(type), 0));
    if (!nim)
        throw IoError(name + ": nifti_clib could not create a header");
    // nifti_make_new_nim zeroes the dims past dim[0]; 1 is what readers expect there.
    nim->nz = nim->dim[3] = g.size[2];
    nim->nt = nim->dim[4] = nim->nu = nim->dim[5] = nim->nv = nim->dim[6] = nim->nw = nim->dim[7] = 1;
    nim->dx = nim->pixdim[1] = static_cast<float>(g.spacing[0]);
    nim->dy = nim->pixdim[2] = static_cast<float>(g.spacing[1]);
    nim->dz = nim->pixdim[3] = static_cast<float>(g.spacing[2]);
    nim->dt = nim->pixdim[4] = nim->du = nim->pixdim[5] = nim->dv = nim->pixdim[6] = nim->dw = nim->pixdim[7] = 1.0f;

    // LPS -> RAS: negate the x and y rows of [D * diag(spacing) | origin].
    mat44 sto{};
    for (int r = 0; r < 3; ++r) {
        const double sign = r < 2 ? -1.0 : 1.0;
        for (int c = 0; c < 3; ++c)
            sto.m[r][c] = static_cast<float>(sign * g.direction[3 * r + c] * g.spacing[c]);
        sto.m[r][3] = static_cast<float>(sign * g.origin[r]);
    }
    sto.m[3][3] = 1.0f;
    // Both codes 1 (scanner-based anatomical): lobe's coordinates are the scanner's LPS ones
    // (DICOM patient coordinates), only flipped to RAS. The sform is exact; the qform is its
    // closest rotation (nifti_mat44_to_quatern), for readers that look only at the qform.
    nim->sform_code = NIFTI_XFORM_SCANNER_ANAT;
    nim->sto_xyz = sto;
    nim->sto_ijk = nifti_mat44_inverse(sto);
    nim->qform_code = NIFTI_XFORM_SCANNER_ANAT;
    float qdx = 0, qdy = 0, qdz = 0;
    nifti_mat44_to_quatern(sto, &nim->quatern_b, &nim->quatern_c, &nim->quatern_d, &nim->qoffset_x, &nim->qoffset_y,
                           &nim->qoffset_z, &qdx, &qdy, &qdz, &nim->qfac);
    nim->qto_xyz = nifti_quatern_to_mat44(nim->quatern_b, nim->quatern_c, nim->quatern_d, nim->qoffset_x,
                                          nim->qoffset_y, nim->qoffset_z, nim->dx, nim->dy, nim->dz, nim->qfac);
    nim->qto_ijk = nifti_mat44_inverse(nim->qto_xyz);
    nim->xyz_units = NIFTI_UNITS_MM;
    nim->time_units = NIFTI_UNITS_UNKNOWN;
    // An explicit identity scaling: unambiguous for every reader (0 would also mean "none").
    nim->scl_slope = 1.0f;
    nim->scl_inter = 0.0f;
    std::snprintf(nim->descrip, sizeof nim->descrip, "lobe %s", LOBE_VERSION_STRING);

    detail::AtomicOutput out(path);
    const std::string temp = out.temp_path().string();
    if (nifti_set_filenames(nim.get(), temp.c_str(), 0, 1) != 0)
        throw IoError(name + ": nifti_clib rejected the file name '" + temp + "'");
    // We open the file ourselves (nifti_clib would print its own error) and let nifti_clib
    // write the header and the empty extension flag into it, leaving it open (option 2).
    // gzip level 1: 6x faster than zlib's default 6 on CT and only ~2% larger
    // (docs/benchmarks.md, io_bench).
    ZnzHandle fp(znzopen(temp.c_str(), gz ? "wb1" : "wb", gz ? 1 : 0));
    if (!fp)
        throw IoError(name + ": cannot create '" + temp + "': " + errno_message());
    znzFile after_header = nifti_image_write_hdr_img2(nim.get(), 2, "wb", fp.release(), nullptr);
    if (!after_header) // nifti_clib has closed the file
        throw IoError(name + ": cannot write the NIfTI header: " + errno_message());
    fp.reset(after_header);
    const void* data = std::visit([](const auto& im) { return static_cast<const void*>(im.data.data()); }, image);
    const std::size_t bytes = count * static_cast<std::size_t>(core::pixel_size(type));
    if (nifti_write_buffer(fp.get(), data, bytes) != bytes) {
        const std::string why = gz_problem(fp.get(), temp);
        throw IoError(name + ": cannot write the voxel data: " + (why.empty() ? errno_message() : why));
    }
    if (fp.close() != 0)
        throw IoError(name + ": cannot finish writing (disk full?): " + errno_message());
    out.commit();
}

} // namespace lobe::io
