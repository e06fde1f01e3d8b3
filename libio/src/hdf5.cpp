// The HDF5 pipeline container (schema: docs/file-format.md). HDF5's C API, wrapped in RAII
// handles; every failure becomes a core::IoError or core::InvalidInputError naming the file and
// the object, and HDF5's own error printing is switched off.

#include "lobe/io/hdf5.h"

#include "detail/atomic_file.h"
#include "detail/chunk_filters.h"
#include "detail/checks.h"
#include "detail/xdmf.h"
#include "lobe/io/limits.h"

#include <hdf5.h>
#include <omp.h>

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <type_traits>
#include <variant>

#ifndef LOBE_VERSION_STRING
#define LOBE_VERSION_STRING "unknown"
#endif

namespace lobe::io {
namespace {

using core::InvalidInputError;
using core::IoError;

constexpr const char* kSchemaName = "lobe";
// Entries of a label table; links per group and attributes per object a reader looks at.
constexpr std::size_t kMaxTableEntries = 1 << 16;
constexpr std::size_t kMaxChildren = 1 << 16;
constexpr std::size_t kMaxNameLength = 255;
constexpr std::size_t kMaxStringBytes = std::size_t(1) << 24;
// Chunks of at most 1 MiB: HDF5's default chunk cache holds one, and deflate works well on it.
constexpr std::size_t kChunkBytes = std::size_t(1) << 20;

// ---- handles ---------------------------------------------------------------------------------

template <herr_t (*Close)(hid_t)>
class Handle {
public:
    Handle() = default;
    explicit Handle(hid_t id) : id_(id) {}
    Handle(Handle&& o) noexcept : id_(o.id_) { o.id_ = H5I_INVALID_HID; }
    Handle& operator=(Handle&& o) noexcept
    {
        if (this != &o) {
            reset();
            id_ = o.id_;
            o.id_ = H5I_INVALID_HID;
        }
        return *this;
    }
    Handle(const Handle&) = delete;
    Handle& operator=(const Handle&) = delete;
    ~Handle() { reset(); }

    hid_t get() const { return id_; }
    bool valid() const { return id_ >= 0; }
    void reset()
    {
        if (id_ >= 0)
            Close(id_);
        id_ = H5I_INVALID_HID;
    }
    //! Closes now and reports whether closing worked (closing a file flushes it).
    herr_t close()
    {
        const herr_t r = id_ >= 0 ? Close(id_) : 0;
        id_ = H5I_INVALID_HID;
        return r;
    }

private:
    hid_t id_ = H5I_INVALID_HID;
};

using File = Handle<H5Fclose>;
using Group = Handle<H5Gclose>;
using Dataset = Handle<H5Dclose>;
using Space = Handle<H5Sclose>;
using Type = Handle<H5Tclose>;
using Attr = Handle<H5Aclose>;
using Plist = Handle<H5Pclose>;
using Object = Handle<H5Oclose>;

// ---- errors ----------------------------------------------------------------------------------

void silence_hdf5()
{
    // Errors are reported through exceptions; HDF5's stack dump on stderr would only confuse.
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
}

// The innermost message of HDF5's error stack (the most specific one), then clears the stack.
std::string hdf5_detail()
{
    std::string msg;
    H5Ewalk2(
        H5E_DEFAULT, H5E_WALK_DOWNWARD,
        [](unsigned, const H5E_error2_t* e, void* data) -> herr_t {
            if (e && e->desc && *e->desc)
                *static_cast<std::string*>(data) = e->desc;
            return 0;
        },
        &msg);
    H5Eclear2(H5E_DEFAULT);
    return msg.empty() ? std::string("HDF5 error") : msg;
}

hid_t ok_id(hid_t id, const std::string& what)
{
    if (id < 0)
        throw IoError(what + ": " + hdf5_detail());
    return id;
}

void ok(herr_t r, const std::string& what)
{
    if (r < 0)
        throw IoError(what + ": " + hdf5_detail());
}

// ---- types -----------------------------------------------------------------------------------

template <class T> hid_t native_type();
template <> hid_t native_type<std::uint8_t>() { return H5T_NATIVE_UINT8; }
template <> hid_t native_type<std::int8_t>() { return H5T_NATIVE_INT8; }
template <> hid_t native_type<std::int16_t>() { return H5T_NATIVE_INT16; }
template <> hid_t native_type<std::uint16_t>() { return H5T_NATIVE_UINT16; }
template <> hid_t native_type<std::int32_t>() { return H5T_NATIVE_INT32; }
template <> hid_t native_type<std::uint32_t>() { return H5T_NATIVE_UINT32; }
template <> hid_t native_type<std::int64_t>() { return H5T_NATIVE_INT64; }
template <> hid_t native_type<float>() { return H5T_NATIVE_FLOAT; }
template <> hid_t native_type<double>() { return H5T_NATIVE_DOUBLE; }

// Files are little-endian whatever the host, so that they are byte-identical everywhere.
template <class T> hid_t file_type();
template <> hid_t file_type<std::uint8_t>() { return H5T_STD_U8LE; }
template <> hid_t file_type<std::int8_t>() { return H5T_STD_I8LE; }
template <> hid_t file_type<std::int16_t>() { return H5T_STD_I16LE; }
template <> hid_t file_type<std::uint16_t>() { return H5T_STD_U16LE; }
template <> hid_t file_type<std::int32_t>() { return H5T_STD_I32LE; }
template <> hid_t file_type<std::uint32_t>() { return H5T_STD_U32LE; }
template <> hid_t file_type<std::int64_t>() { return H5T_STD_I64LE; }
template <> hid_t file_type<float>() { return H5T_IEEE_F32LE; }
template <> hid_t file_type<double>() { return H5T_IEEE_F64LE; }

std::string describe_type(hid_t t)
{
    const std::string bits = std::to_string(8 * H5Tget_size(t));
    switch (H5Tget_class(t)) {
    case H5T_INTEGER: return (H5Tget_sign(t) == H5T_SGN_NONE ? "uint" : "int") + bits;
    case H5T_FLOAT: return "float" + bits;
    case H5T_STRING: return "string";
    case H5T_COMPOUND: return "compound";
    case H5T_ENUM: return "enum";
    case H5T_ARRAY: return "array";
    case H5T_VLEN: return "variable-length sequence";
    case H5T_OPAQUE: return "opaque";
    case H5T_BITFIELD: return "bitfield";
    case H5T_REFERENCE: return "reference";
    case H5T_TIME: return "time";
    default: return "unknown";
    }
}

std::optional<core::PixelType> pixel_type_of_h5(hid_t t)
{
    const std::size_t size = H5Tget_size(t);
    switch (H5Tget_class(t)) {
    case H5T_INTEGER: {
        const bool is_unsigned = H5Tget_sign(t) == H5T_SGN_NONE;
        if (size == 1) return is_unsigned ? core::PixelType::UInt8 : core::PixelType::Int8;
        if (size == 2) return is_unsigned ? core::PixelType::UInt16 : core::PixelType::Int16;
        if (size == 4) return is_unsigned ? core::PixelType::UInt32 : core::PixelType::Int32;
        return std::nullopt;
    }
    case H5T_FLOAT:
        if (size == 4) return core::PixelType::Float32;
        if (size == 8) return core::PixelType::Float64;
        return std::nullopt;
    default: return std::nullopt;
    }
}

Type utf8_string_type()
{
    Type t(ok_id(H5Tcopy(H5T_C_S1), "string type"));
    ok(H5Tset_size(t.get(), H5T_VARIABLE), "string type");
    ok(H5Tset_cset(t.get(), H5T_CSET_UTF8), "string type");
    return t;
}

// ---- small helpers ---------------------------------------------------------------------------

// ASCII only, whatever the locale: names must mean the same on every machine.
bool is_alnum(char c)
{
    return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z');
}

bool valid_item_name(const std::string& name)
{
    if (name.empty() || name.size() > kMaxNameLength)
        return false;
    for (std::size_t i = 0; i < name.size(); ++i) {
        const char c = name[i];
        const bool word = is_alnum(c) || c == '_';
        if (!(word || (i > 0 && (c == '.' || c == '-'))))
            return false;
    }
    return true;
}

std::string join(const std::vector<std::string>& v, const char* sep = ", ")
{
    std::string s;
    for (std::size_t i = 0; i < v.size(); ++i)
        s += (i ? sep : "") + v[i];
    return s;
}

// ---- writing primitives ----------------------------------------------------------------------

Plist group_plist()
{
    Plist p(ok_id(H5Pcreate(H5P_GROUP_CREATE), "group properties"));
    // Listing in creation order keeps items, parameters and timings in the order they were written.
    ok(H5Pset_link_creation_order(p.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED), "group properties");
    ok(H5Pset_attr_creation_order(p.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED), "group properties");
    // No object timestamps: the same input gives the same bytes (apart from the 'created' attribute).
    ok(H5Pset_obj_track_times(p.get(), false), "group properties");
    return p;
}

Group create_group(hid_t loc, const std::string& name, const std::string& what)
{
    Plist gcpl = group_plist();
    return Group(ok_id(H5Gcreate2(loc, name.c_str(), H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), what + ": cannot create group"));
}

void write_string_attr(hid_t obj, const std::string& name, const std::string& value, const std::string& what)
{
    if (value.find('\0') != std::string::npos)
        throw InvalidInputError(what + ": attribute " + name + " contains a NUL character");
    Type t = utf8_string_type();
    Space s(ok_id(H5Screate(H5S_SCALAR), what));
    Attr a(ok_id(H5Acreate2(obj, name.c_str(), t.get(), s.get(), H5P_DEFAULT, H5P_DEFAULT),
                 what + ": cannot create attribute " + name));
    const char* p = value.c_str();
    ok(H5Awrite(a.get(), t.get(), &p), what + ": cannot write attribute " + name);
}

void write_strings_attr(hid_t obj, const std::string& name, const std::vector<std::string>& values,
                        const std::string& what)
{
    Type t = utf8_string_type();
    const hsize_t n = values.size();
    Space s(ok_id(H5Screate_simple(1, &n, nullptr), what));
    Attr a(ok_id(H5Acreate2(obj, name.c_str(), t.get(), s.get(), H5P_DEFAULT, H5P_DEFAULT),
                 what + ": cannot create attribute " + name));
    std::vector<const char*> ptrs;
    for (const auto& v : values)
        ptrs.push_back(v.c_str());
    ok(H5Awrite(a.get(), t.get(), ptrs.data()), what + ": cannot write attribute " + name);
}

template <class T>
void write_array_attr(hid_t obj, const std::string& name, const T* values, std::size_t n, const std::string& what,
                      bool scalar = false)
{
    const hsize_t dims = n;
    Space s(ok_id(scalar ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, &dims, nullptr), what));
    Attr a(ok_id(H5Acreate2(obj, name.c_str(), file_type<T>(), s.get(), H5P_DEFAULT, H5P_DEFAULT),
                 what + ": cannot create attribute " + name));
    ok(H5Awrite(a.get(), native_type<T>(), values), what + ": cannot write attribute " + name);
}

template <class T>
void write_scalar_attr(hid_t obj, const std::string& name, T value, const std::string& what)
{
    write_array_attr(obj, name, &value, 1, what, true);
}

static_assert(std::is_same_v<hsize_t, unsigned long long>, "detail::ChunkGrid takes HDF5's hsize_t");

// Filters the chunks of a row-major array of rank <= 3 on every core and stores them with
// H5Dwrite_chunk: HDF5 1.10 runs a dataset's filters on one thread, which made writing a
// 512 x 512 x 200 CT take seconds. Only the master thread calls HDF5. The chunks are the bytes
// HDF5's own pipeline would store, edge chunks padded with the fill value 0 as HDF5 pads them.
template <class T>
void write_filtered_chunks(hid_t ds, const detail::ChunkGrid& cg, const T* data, const Hdf5WriteParams& params,
                           const std::string& what)
{
    const std::size_t chunks = cg.count(), batch = detail::chunk_batch();
    std::vector<std::vector<unsigned char>> filtered(batch);
    for (std::size_t first = 0; first < chunks; first += batch) {
        const std::size_t last = std::min(chunks, first + batch);
        bool failed = false;
#pragma omp parallel
        {
            std::vector<T> raw(cg.chunk_values());
            std::vector<unsigned char> scratch;
#pragma omp for schedule(dynamic, 1) reduction(|| : failed)
            for (std::ptrdiff_t i = static_cast<std::ptrdiff_t>(first); i < static_cast<std::ptrdiff_t>(last); ++i) {
                const std::size_t c = static_cast<std::size_t>(i);
                const auto origin = cg.origin(c);
                if (cg.partial(origin))
                    std::fill(raw.begin(), raw.end(), T{});
                cg.rows(origin, [&](std::size_t at, std::size_t in_chunk, std::size_t n) {
                    std::copy_n(data + at, n, raw.data() + in_chunk);
                });
                if (!detail::filter_chunk(reinterpret_cast<const unsigned char*>(raw.data()), raw.size() * sizeof(T),
                                          sizeof(T), params.gzip_level, params.checksum, scratch, filtered[c - first]))
                    failed = true;
            }
        }
        if (failed)
            throw IoError(what + ": zlib could not compress a chunk");
        for (std::size_t c = first; c < last; ++c) {
            const auto origin = cg.origin(c);
            const std::array<hsize_t, 3> offset{origin[0], origin[1], origin[2]};
            const std::vector<unsigned char>& bytes = filtered[c - first];
            ok(H5Dwrite_chunk(ds, H5P_DEFAULT, 0, offset.data() + (3 - cg.rank), bytes.size(), bytes.data()),
               what + ": cannot write chunk " + std::to_string(c));
        }
    }
}

// Creates and fills a dataset; chunked and filtered unless it is empty (an empty chunked dataset
// with fixed dimensions is not allowed in HDF5).
template <class T>
Dataset write_dataset(hid_t loc, const std::string& name, const std::vector<hsize_t>& dims,
                      const std::vector<hsize_t>& chunk, const T* data, const Hdf5WriteParams& params,
                      const std::string& what)
{
    const int rank = static_cast<int>(dims.size());
    Space space(ok_id(H5Screate_simple(rank, dims.data(), nullptr), what));
    Plist dcpl(ok_id(H5Pcreate(H5P_DATASET_CREATE), what));
    ok(H5Pset_obj_track_times(dcpl.get(), false), what);
    const bool empty = std::any_of(dims.begin(), dims.end(), [](hsize_t d) { return d == 0; });
    if (!empty) {
        ok(H5Pset_chunk(dcpl.get(), rank, chunk.data()), what + ": chunking");
        if (params.gzip_level > 0) {
            // Shuffle groups the bytes of equal significance, which is what makes CT values compress.
            ok(H5Pset_shuffle(dcpl.get()), what + ": shuffle filter");
            ok(H5Pset_deflate(dcpl.get(), static_cast<unsigned>(params.gzip_level)), what + ": deflate filter");
        }
        if (params.checksum)
            ok(H5Pset_fletcher32(dcpl.get()), what + ": checksum filter");
    }
    Dataset ds(ok_id(H5Dcreate2(loc, name.c_str(), file_type<T>(), space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
                     what + ": cannot create dataset"));
    if (empty)
        return ds;
    // file_type<T> is little-endian, as the native types here are, so the chunks' bytes are the
    // values' bytes; on a big-endian machine HDF5 converts and we let it.
    const bool filtered = params.gzip_level > 0 || params.checksum;
    if (filtered && rank <= 3 && H5Tequal(file_type<T>(), native_type<T>()) > 0) {
        const detail::ChunkGrid cg(dims.data(), chunk.data(), rank);
        if (cg.count() >= 2) {
            write_filtered_chunks(ds.get(), cg, data, params, what);
            return ds;
        }
    }
    ok(H5Dwrite(ds.get(), native_type<T>(), H5S_ALL, H5S_ALL, H5P_DEFAULT, data), what + ": cannot write data");
    return ds;
}

// Rows per chunk for an (n, cols) array, so that a chunk holds about kChunkBytes.
hsize_t row_chunk(std::size_t rows, std::size_t row_bytes)
{
    return std::max<hsize_t>(1, std::min<hsize_t>(rows, kChunkBytes / row_bytes));
}

template <class T>
Dataset write_volume_dataset(hid_t group, const std::string& name, const core::Image3D<T>& im,
                             const Hdf5WriteParams& params, const std::string& what)
{
    const std::vector<hsize_t> dims{hsize_t(im.size[2]), hsize_t(im.size[1]), hsize_t(im.size[0])};
    const hsize_t cx = std::min<hsize_t>(dims[2], 128), cy = std::min<hsize_t>(dims[1], 128);
    const hsize_t cz = std::clamp<hsize_t>(kChunkBytes / (sizeof(T) * cx * cy), 1, dims[0]);
    Dataset ds = write_dataset(group, name, dims, {cz, cy, cx}, im.data.data(), params, what);
    write_array_attr(ds.get(), "spacing", im.spacing.data(), 3, what);
    write_array_attr(ds.get(), "origin", im.origin.data(), 3, what);
    write_array_attr(ds.get(), "direction", im.direction.data(), 9, what);
    write_string_attr(ds.get(), "units", "mm", what);
    return ds;
}

void write_label_table(hid_t obj, const LabelTable& table, const std::string& what)
{
    if (table.empty())
        return;
    std::vector<std::int32_t> values;
    std::vector<std::string> names;
    for (const auto& e : table) {
        values.push_back(e.value);
        names.push_back(e.name);
    }
    write_array_attr(obj, "label_values", values.data(), values.size(), what);
    write_strings_attr(obj, "label_names", names, what);
}

void check_label_table(const LabelTable& table, bool uint8_values, const std::string& what)
{
    if (table.size() > kMaxTableEntries)
        throw InvalidInputError(what + ": label table has " + std::to_string(table.size()) + " entries (at most " +
                                std::to_string(kMaxTableEntries) + ")");
    std::set<std::int32_t> seen;
    for (const auto& e : table) {
        if (uint8_values && (e.value < 0 || e.value > 255))
            throw InvalidInputError(what + ": label value " + std::to_string(e.value) +
                                    " does not fit a uint8 label volume (0..255)");
        if (!seen.insert(e.value).second)
            throw InvalidInputError(what + ": label value " + std::to_string(e.value) + " appears twice in the table");
        if (e.name.empty() || e.name.find('\0') != std::string::npos)
            throw InvalidInputError(what + ": label " + std::to_string(e.value) + " has an empty or invalid name");
    }
}

void check_finite(const std::vector<core::Vec3>& vertices, const std::string& what)
{
    for (std::size_t i = 0; i < vertices.size(); ++i)
        if (!std::isfinite(vertices[i].x) || !std::isfinite(vertices[i].y) || !std::isfinite(vertices[i].z))
            throw InvalidInputError(what + ": vertex " + std::to_string(i) + " has a non-finite coordinate");
}

std::string provenance_group_name(int index, const std::string& tool)
{
    std::string t;
    for (const char c : tool.substr(0, 64))
        t += (is_alnum(c) || c == '_' || c == '-' || c == '.') ? c : '_';
    char num[16];
    std::snprintf(num, sizeof num, "%03d_", index);
    return num + t;
}

// ---- reading primitives ----------------------------------------------------------------------

// Only the writer sets file access properties: a reader uses HDF5's defaults, because HDF5 refuses
// to open a file twice in one process with different access properties (locking, close degree),
// and a caller may hold the same file open through another HDF5 user.
Plist writer_access_plist()
{
    Plist fapl(ok_id(H5Pcreate(H5P_FILE_ACCESS), "file access properties"));
    // The HDF5 1.8 file format: readable by every HDF5 from 1.8 on (ParaView, h5py, MATLAB).
    ok(H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V18, H5F_LIBVER_V18), "file access properties");
    return fapl;
}

// Error messages say "<file>: <object path> ...".
struct Where {
    std::string file;
    std::string at(const std::string& object) const { return file + ": " + object; }
};

bool has_link(hid_t loc, const std::string& name)
{
    const htri_t r = H5Lexists(loc, name.c_str(), H5P_DEFAULT);
    if (r < 0)
        H5Eclear2(H5E_DEFAULT);
    return r > 0;
}

bool has_attr(hid_t obj, const std::string& name)
{
    const htri_t r = H5Aexists(obj, name.c_str());
    if (r < 0)
        H5Eclear2(H5E_DEFAULT);
    return r > 0;
}

// Opens child `name` of `loc`, which must be a hard link to an object of type `want`
// (soft and external links could lead anywhere, including other files).
Object open_child(hid_t loc, const std::string& name, H5I_type_t want, const std::string& where)
{
    H5L_info_t info{};
    if (H5Lget_info(loc, name.c_str(), &info, H5P_DEFAULT) < 0)
        throw IoError(where + ": cannot inspect the link: " + hdf5_detail());
    if (info.type != H5L_TYPE_HARD)
        throw InvalidInputError(where + " is a soft or external link; the schema allows only plain objects");
    Object o(ok_id(H5Oopen(loc, name.c_str(), H5P_DEFAULT), where + ": cannot open"));
    const H5I_type_t got = H5Iget_type(o.get());
    if (got != want)
        throw InvalidInputError(where + (want == H5I_GROUP ? " is not a group" : " is not a dataset"));
    return o;
}

Group open_group(hid_t loc, const std::string& name, const std::string& where)
{
    open_child(loc, name, H5I_GROUP, where);
    return Group(ok_id(H5Gopen2(loc, name.c_str(), H5P_DEFAULT), where + ": cannot open group"));
}

std::vector<std::string> link_names(hid_t group, const std::string& where)
{
    H5G_info_t info{};
    ok(H5Gget_info(group, &info), where + ": cannot list");
    if (info.nlinks > kMaxChildren)
        throw InvalidInputError(where + " has " + std::to_string(info.nlinks) + " members (at most " +
                                std::to_string(kMaxChildren) + ")");
    Plist gcpl(ok_id(H5Gget_create_plist(group), where));
    unsigned flags = 0;
    ok(H5Pget_link_creation_order(gcpl.get(), &flags), where);
    const H5_index_t index = (flags & H5P_CRT_ORDER_TRACKED) ? H5_INDEX_CRT_ORDER : H5_INDEX_NAME;
    std::vector<std::string> names;
    for (hsize_t i = 0; i < info.nlinks; ++i) {
        const ssize_t len = H5Lget_name_by_idx(group, ".", index, H5_ITER_INC, i, nullptr, 0, H5P_DEFAULT);
        if (len < 0)
            throw IoError(where + ": cannot list: " + hdf5_detail());
        std::string name(static_cast<std::size_t>(len) + 1, '\0');
        if (H5Lget_name_by_idx(group, ".", index, H5_ITER_INC, i, name.data(), name.size(), H5P_DEFAULT) < 0)
            throw IoError(where + ": cannot list: " + hdf5_detail());
        name.resize(static_cast<std::size_t>(len));
        names.push_back(std::move(name));
    }
    return names;
}

std::vector<std::string> attribute_names(hid_t group, const std::string& where)
{
    Plist gcpl(ok_id(H5Gget_create_plist(group), where));
    unsigned flags = 0;
    ok(H5Pget_attr_creation_order(gcpl.get(), &flags), where);
    const H5_index_t index = (flags & H5P_CRT_ORDER_TRACKED) ? H5_INDEX_CRT_ORDER : H5_INDEX_NAME;
    std::vector<std::string> names;
    hsize_t idx = 0;
    const herr_t r = H5Aiterate2(
        group, index, H5_ITER_INC, &idx,
        [](hid_t, const char* name, const H5A_info_t*, void* data) -> herr_t {
            auto* v = static_cast<std::vector<std::string>*>(data);
            v->emplace_back(name);
            return v->size() > kMaxChildren ? 1 : 0;
        },
        &names);
    if (r < 0)
        throw IoError(where + ": cannot list attributes: " + hdf5_detail());
    if (names.size() > kMaxChildren)
        throw InvalidInputError(where + " has more than " + std::to_string(kMaxChildren) + " attributes");
    return names;
}

Attr open_attr(hid_t obj, const std::string& name, const std::string& where)
{
    if (!has_attr(obj, name))
        throw InvalidInputError(where + " has no " + name + " attribute");
    return Attr(ok_id(H5Aopen(obj, name.c_str(), H5P_DEFAULT), where + ": cannot open attribute " + name));
}

hssize_t attr_points(hid_t attr, const std::string& where, const std::string& name)
{
    Space s(ok_id(H5Aget_space(attr), where));
    const H5S_class_t c = H5Sget_simple_extent_type(s.get());
    if (c == H5S_NULL)
        return 0;
    if (c == H5S_SIMPLE && H5Sget_simple_extent_ndims(s.get()) != 1)
        throw InvalidInputError(where + ": attribute " + name + " is not one-dimensional");
    return H5Sget_simple_extent_npoints(s.get());
}

// Reads `n` strings (variable or fixed length) from a string attribute.
std::vector<std::string> read_strings(hid_t attr, hid_t ftype, std::size_t n, const std::string& what)
{
    std::vector<std::string> out;
    if (H5Tis_variable_str(ftype) > 0) {
        Type mem = utf8_string_type();
        ok(H5Tset_cset(mem.get(), H5Tget_cset(ftype)), what);
        std::vector<char*> ptrs(n, nullptr);
        ok(H5Aread(attr, mem.get(), ptrs.data()), what + ": cannot read");
        for (char* p : ptrs) {
            std::string s = p ? std::string(p, ::strnlen(p, kMaxStringBytes)) : std::string();
            H5free_memory(p);
            out.push_back(std::move(s));
        }
        return out;
    }
    const std::size_t size = H5Tget_size(ftype);
    if (size == 0 || size > kMaxStringBytes || n > kMaxStringBytes / size)
        throw InvalidInputError(what + ": string of absurd size");
    Type mem(ok_id(H5Tcopy(ftype), what));
    std::vector<char> buf(size * n);
    ok(H5Aread(attr, mem.get(), buf.data()), what + ": cannot read");
    const bool space_padded = H5Tget_strpad(ftype) == H5T_STR_SPACEPAD;
    for (std::size_t i = 0; i < n; ++i) {
        const char* p = buf.data() + i * size;
        std::string s(p, ::strnlen(p, size));
        if (space_padded)
            s.erase(s.find_last_not_of(' ') + 1);
        out.push_back(std::move(s));
    }
    return out;
}

std::string read_string_attr(hid_t obj, const std::string& name, const std::string& where)
{
    Attr a = open_attr(obj, name, where);
    Type t(ok_id(H5Aget_type(a.get()), where));
    if (H5Tget_class(t.get()) != H5T_STRING)
        throw InvalidInputError(where + ": attribute " + name + " is " + describe_type(t.get()) + ", expected a string");
    if (attr_points(a.get(), where, name) != 1)
        throw InvalidInputError(where + ": attribute " + name + " is not a single string");
    return read_strings(a.get(), t.get(), 1, where + ": attribute " + name).front();
}

// A numeric attribute with exactly `n` values (n == 1: scalar or one-element array).
std::vector<double> read_numbers_attr(hid_t obj, const std::string& name, std::size_t n, const std::string& where)
{
    Attr a = open_attr(obj, name, where);
    Type t(ok_id(H5Aget_type(a.get()), where));
    const H5T_class_t c = H5Tget_class(t.get());
    if (c != H5T_FLOAT && c != H5T_INTEGER)
        throw InvalidInputError(where + ": attribute " + name + " is " + describe_type(t.get()) + ", expected numbers");
    const hssize_t got = attr_points(a.get(), where, name);
    if (got != static_cast<hssize_t>(n))
        throw InvalidInputError(where + ": attribute " + name + " has " + std::to_string(got) + " values, expected " +
                                std::to_string(n));
    std::vector<double> v(n);
    ok(H5Aread(a.get(), H5T_NATIVE_DOUBLE, v.data()), where + ": cannot read attribute " + name);
    return v;
}

long long read_integer_attr(hid_t obj, const std::string& name, const std::string& where)
{
    Attr a = open_attr(obj, name, where);
    Type t(ok_id(H5Aget_type(a.get()), where));
    if (H5Tget_class(t.get()) != H5T_INTEGER)
        throw InvalidInputError(where + ": attribute " + name + " is " + describe_type(t.get()) + ", expected an integer");
    if (attr_points(a.get(), where, name) != 1)
        throw InvalidInputError(where + ": attribute " + name + " is not a single integer");
    long long v = 0;
    ok(H5Aread(a.get(), H5T_NATIVE_LLONG, &v), where + ": cannot read attribute " + name);
    return v;
}

LabelTable read_label_table(hid_t obj, const std::string& where)
{
    const bool has_values = has_attr(obj, "label_values"), has_names = has_attr(obj, "label_names");
    if (!has_values && !has_names)
        return {};
    if (has_values != has_names)
        throw InvalidInputError(where + " has " + (has_values ? "label_values but no label_names" : "label_names but no label_values") +
                                " attribute");
    Attr va = open_attr(obj, "label_values", where);
    Type vt(ok_id(H5Aget_type(va.get()), where));
    if (H5Tget_class(vt.get()) != H5T_INTEGER)
        throw InvalidInputError(where + ": attribute label_values is " + describe_type(vt.get()) + ", expected integers");
    const hssize_t n = attr_points(va.get(), where, "label_values");
    if (n < 0 || static_cast<std::size_t>(n) > kMaxTableEntries)
        throw InvalidInputError(where + ": attribute label_values has " + std::to_string(n) + " entries (at most " +
                                std::to_string(kMaxTableEntries) + ")");
    std::vector<long long> values(static_cast<std::size_t>(n));
    if (n > 0)
        ok(H5Aread(va.get(), H5T_NATIVE_LLONG, values.data()), where + ": cannot read attribute label_values");

    Attr na = open_attr(obj, "label_names", where);
    Type nt(ok_id(H5Aget_type(na.get()), where));
    if (H5Tget_class(nt.get()) != H5T_STRING)
        throw InvalidInputError(where + ": attribute label_names is " + describe_type(nt.get()) + ", expected strings");
    if (attr_points(na.get(), where, "label_names") != n)
        throw InvalidInputError(where + ": attributes label_values and label_names differ in length");
    const auto names = n > 0 ? read_strings(na.get(), nt.get(), static_cast<std::size_t>(n), where + ": attribute label_names")
                             : std::vector<std::string>{};
    LabelTable table;
    for (std::size_t i = 0; i < values.size(); ++i) {
        if (values[i] < INT32_MIN || values[i] > INT32_MAX)
            throw InvalidInputError(where + ": label value " + std::to_string(values[i]) + " does not fit int32");
        table.push_back({static_cast<std::int32_t>(values[i]), names[i]});
    }
    return table;
}

// An open dataset with its shape and type, checked for a sane layout.
struct DatasetView {
    Dataset ds;
    Type type;
    std::vector<hsize_t> dims;
    std::string where;
};

DatasetView open_dataset(hid_t loc, const std::string& name, const std::string& where)
{
    if (!has_link(loc, name))
        throw InvalidInputError(where + " is missing");
    open_child(loc, name, H5I_DATASET, where);
    DatasetView v;
    v.where = where;
    v.ds = Dataset(ok_id(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), where + ": cannot open"));
    v.type = Type(ok_id(H5Dget_type(v.ds.get()), where));
    Space s(ok_id(H5Dget_space(v.ds.get()), where));
    const H5S_class_t c = H5Sget_simple_extent_type(s.get());
    if (c == H5S_SIMPLE) {
        const int rank = H5Sget_simple_extent_ndims(s.get());
        if (rank < 0 || rank > H5S_MAX_RANK)
            throw InvalidInputError(where + " has an invalid rank");
        v.dims.resize(static_cast<std::size_t>(rank));
        H5Sget_simple_extent_dims(s.get(), v.dims.data(), nullptr);
    }
    // Virtual and external datasets read other files; the schema keeps all data in the container.
    Plist dcpl(ok_id(H5Dget_create_plist(v.ds.get()), where));
    const H5D_layout_t layout = H5Pget_layout(dcpl.get());
    if (layout != H5D_CONTIGUOUS && layout != H5D_CHUNKED && layout != H5D_COMPACT)
        throw InvalidInputError(where + " has an unsupported storage layout (virtual or unknown)");
    if (H5Pget_external_count(dcpl.get()) != 0)
        throw InvalidInputError(where + " keeps its data in external files; the schema stores data in the container");
    return v;
}

std::string dims_text(const std::vector<hsize_t>& dims)
{
    std::string s = "(";
    for (std::size_t i = 0; i < dims.size(); ++i)
        s += (i ? ", " : "") + std::to_string(dims[i]);
    return s + ")";
}

// Requires rank `rank`, and columns `cols` in the last dimension if cols > 0. Returns the rows.
std::size_t check_shape(const DatasetView& v, std::size_t rank, hsize_t cols, std::size_t max_rows)
{
    if (v.dims.size() != rank)
        throw InvalidInputError(v.where + " has rank " + std::to_string(v.dims.size()) + " " + dims_text(v.dims) +
                                ", expected " + std::to_string(rank));
    if (cols > 0 && v.dims.back() != cols)
        throw InvalidInputError(v.where + " has shape " + dims_text(v.dims) + ", expected (n, " + std::to_string(cols) + ")");
    if (v.dims[0] > max_rows)
        throw InvalidInputError(v.where + " has " + std::to_string(v.dims[0]) + " rows, more than the limit of " +
                                std::to_string(max_rows));
    return static_cast<std::size_t>(v.dims[0]);
}

void check_class(const DatasetView& v, H5T_class_t want, const char* expected)
{
    if (H5Tget_class(v.type.get()) != want)
        throw InvalidInputError(v.where + " has type " + describe_type(v.type.get()) + ", expected " + expected);
}

// Refuses datasets that claim far more data than they store: nothing written at all, or more than
// deflate could expand to. This keeps a tiny corrupt file from making us allocate gigabytes.
void check_stored(const DatasetView& v, std::size_t raw_bytes)
{
    if (raw_bytes == 0)
        return;
    const hsize_t stored = H5Dget_storage_size(v.ds.get());
    if (stored == 0 || static_cast<double>(stored) * detail::kMaxDeflateRatio < static_cast<double>(raw_bytes))
        throw InvalidInputError(v.where + " claims " + std::to_string(raw_bytes) + " bytes of data but stores only " +
                                std::to_string(stored));
}

// The filters of a chunked dataset, in pipeline order, if read_chunks_parallel can undo them:
// any of shuffle, deflate, Fletcher-32 in HDF5's usual order (shuffle only together with deflate).
std::optional<std::vector<H5Z_filter_t>> undoable_filters(hid_t dcpl)
{
    std::vector<H5Z_filter_t> f;
    for (int i = 0; i < H5Pget_nfilters(dcpl); ++i) {
        unsigned flags = 0, cd[8] = {};
        size_t ncd = 8;
        f.push_back(H5Pget_filter2(dcpl, unsigned(i), &flags, &ncd, cd, 0, nullptr, nullptr));
    }
    using F = std::vector<H5Z_filter_t>;
    for (const F& known : {F{}, F{H5Z_FILTER_FLETCHER32}, F{H5Z_FILTER_DEFLATE}, F{H5Z_FILTER_DEFLATE, H5Z_FILTER_FLETCHER32},
                           F{H5Z_FILTER_SHUFFLE, H5Z_FILTER_DEFLATE},
                           F{H5Z_FILTER_SHUFFLE, H5Z_FILTER_DEFLATE, H5Z_FILTER_FLETCHER32}})
        if (f == known)
            return f;
    return std::nullopt;
}

// The reading twin of write_filtered_chunks: the stored chunks are fetched with H5Dread_chunk on
// the master thread and unfiltered (checksum, inflate, unshuffle) on every core. Anything unusual
// (another filter, a chunk not written or stored unfiltered, a checksum or size that does not
// match) returns false before `out` is trusted, and the caller reads through HDF5 instead, whose
// verdict (data or error) then stands.
template <class T>
bool read_chunks_parallel(const DatasetView& v, T* out)
{
    const int rank = static_cast<int>(v.dims.size());
    if (rank < 1 || rank > 3 || H5Tequal(v.type.get(), native_type<T>()) <= 0)
        return false;
    Plist dcpl(H5Dget_create_plist(v.ds.get()));
    if (dcpl.get() < 0 || H5Pget_layout(dcpl.get()) != H5D_CHUNKED)
        return false;
    const auto filters = undoable_filters(dcpl.get());
    if (!filters)
        return false;
    std::array<hsize_t, 3> chunk_in{};
    if (H5Pget_chunk(dcpl.get(), rank, chunk_in.data()) != rank ||
        std::any_of(chunk_in.begin(), chunk_in.begin() + rank, [](hsize_t c) { return c == 0; }))
        return false;
    const detail::ChunkGrid cg(v.dims.data(), chunk_in.data(), rank);
    const std::size_t chunks = cg.count();
    const std::size_t chunk_bytes = cg.chunk_values() * sizeof(T);
    Space space(H5Dget_space(v.ds.get()));
    hsize_t stored_chunks = 0;
    if (chunks < 2 || chunk_bytes > 64 * kChunkBytes || space.get() < 0 ||
        H5Dget_num_chunks(v.ds.get(), space.get(), &stored_chunks) < 0 || stored_chunks != chunks)
        return false;
    const bool checksum = filters->back() == H5Z_FILTER_FLETCHER32;
    const bool deflate = std::find(filters->begin(), filters->end(), H5Z_FILTER_DEFLATE) != filters->end();
    const bool shuffle = filters->front() == H5Z_FILTER_SHUFFLE;
    // The most a chunk can take on disk: deflate's worst case plus the checksum.
    const std::size_t max_stored = chunk_bytes + chunk_bytes / 1000 + 64;

    const std::size_t batch = detail::chunk_batch();
    std::vector<std::vector<unsigned char>> stored(batch);
    std::vector<std::array<std::size_t, 3>> origins(batch);
    std::vector<char> seen(chunks, 0);
    for (std::size_t first = 0; first < chunks; first += batch) {
        const std::size_t last = std::min(chunks, first + batch);
        for (std::size_t c = first; c < last; ++c) {
            std::array<hsize_t, 3> off{};
            unsigned mask = 0;
            haddr_t addr = 0;
            hsize_t size = 0;
            if (H5Dget_chunk_info(v.ds.get(), space.get(), c, off.data(), &mask, &addr, &size) < 0 || mask != 0 ||
                size == 0 || size > max_stored)
                return false;
            stored[c - first].resize(static_cast<std::size_t>(size));
            if (H5Dread_chunk(v.ds.get(), H5P_DEFAULT, off.data(), &mask, stored[c - first].data()) < 0 || mask != 0)
                return false;
            std::array<std::size_t, 3>& origin = origins[c - first];
            origin = {0, 0, 0};
            for (int a = 0; a < rank; ++a) {
                const auto u = static_cast<std::size_t>(a);
                if (off[u] % chunk_in[u] != 0 || off[u] >= v.dims[u])
                    return false;
                origin[static_cast<std::size_t>(3 - rank + a)] = static_cast<std::size_t>(off[u]);
            }
            // Each chunk of the grid must come exactly once.
            if (seen[cg.index(origin)])
                return false;
            seen[cg.index(origin)] = 1;
        }
        bool failed = false;
#pragma omp parallel
        {
            std::vector<unsigned char> scratch, plain;
#pragma omp for schedule(dynamic, 1) reduction(|| : failed)
            for (std::ptrdiff_t i = static_cast<std::ptrdiff_t>(first); i < static_cast<std::ptrdiff_t>(last); ++i) {
                const std::size_t b = static_cast<std::size_t>(i) - first;
                if (!detail::unfilter_chunk(stored[b].data(), stored[b].size(), chunk_bytes, sizeof(T), shuffle, deflate,
                                            checksum, scratch, plain)) {
                    failed = true;
                    continue;
                }
                cg.rows(origins[b], [&](std::size_t at, std::size_t in_chunk, std::size_t n) {
                    std::memcpy(out + at, plain.data() + in_chunk * sizeof(T), n * sizeof(T));
                });
            }
        }
        if (failed)
            return false;
    }
    return true;
}

template <class T>
void read_all(const DatasetView& v, T* out, std::size_t count)
{
    check_stored(v, count * sizeof(T));
    if (count > 0 && !read_chunks_parallel(v, out))
        ok(H5Dread(v.ds.get(), native_type<T>(), H5S_ALL, H5S_ALL, H5P_DEFAULT, out), v.where + ": cannot read data");
}

core::ImageGeometry read_volume_geometry(const DatasetView& v, std::optional<core::PixelType>& type)
{
    if (v.dims.size() != 3)
        throw InvalidInputError(v.where + " has rank " + std::to_string(v.dims.size()) + " " + dims_text(v.dims) +
                                ", expected 3 (nz, ny, nx)");
    for (const hsize_t d : v.dims)
        if (d > static_cast<hsize_t>(INT_MAX))
            throw InvalidInputError(v.where + ": dimensions " + dims_text(v.dims) + " exceed the voxel limit");
    detail::checked_voxel_count(
        {static_cast<std::int64_t>(v.dims[2]), static_cast<std::int64_t>(v.dims[1]), static_cast<std::int64_t>(v.dims[0])},
        v.where);
    type = pixel_type_of_h5(v.type.get());
    core::ImageGeometry g;
    g.size = {static_cast<int>(v.dims[2]), static_cast<int>(v.dims[1]), static_cast<int>(v.dims[0])};
    const hid_t ds = v.ds.get();
    const auto spacing = read_numbers_attr(ds, "spacing", 3, v.where);
    const auto origin = read_numbers_attr(ds, "origin", 3, v.where);
    const auto direction = read_numbers_attr(ds, "direction", 9, v.where);
    std::copy(spacing.begin(), spacing.end(), g.spacing.begin());
    std::copy(origin.begin(), origin.end(), g.origin.begin());
    std::copy(direction.begin(), direction.end(), g.direction.begin());
    if (has_attr(ds, "units")) {
        const std::string units = read_string_attr(ds, "units", v.where);
        if (units != "mm")
            throw InvalidInputError(v.where + ": units are '" + units + "', expected 'mm'");
    }
    core::validate_geometry(g, v.where);
    return g;
}

std::vector<core::Vec3> read_vertices(hid_t group, const std::string& where)
{
    static_assert(sizeof(core::Vec3) == 3 * sizeof(double) && std::is_standard_layout_v<core::Vec3>,
                  "Vec3 must be three packed doubles to be read in place");
    DatasetView v = open_dataset(group, "vertices", where + "/vertices");
    const std::size_t n = check_shape(v, 2, 3, kMaxMeshElements);
    check_class(v, H5T_FLOAT, "float64");
    check_stored(v, n * sizeof(core::Vec3)); // before allocating
    std::vector<core::Vec3> vertices(n);
    read_all(v, reinterpret_cast<double*>(vertices.data()), 3 * n);
    check_finite(vertices, v.where);
    return vertices;
}

template <std::size_t K>
std::vector<std::array<std::int32_t, K>> read_cells(hid_t group, const std::string& name, const std::string& where)
{
    static_assert(sizeof(std::array<std::int32_t, K>) == K * sizeof(std::int32_t), "cells must be packed");
    DatasetView v = open_dataset(group, name, where + "/" + name);
    const std::size_t n = check_shape(v, 2, K, kMaxMeshElements);
    check_class(v, H5T_INTEGER, "int32");
    check_stored(v, n * sizeof(std::array<std::int32_t, K>)); // before allocating
    std::vector<std::array<std::int32_t, K>> cells(n);
    read_all(v, reinterpret_cast<std::int32_t*>(cells.data()), K * n);
    return cells;
}

// ---- extendible datasets (/simulation) ---------------------------------------------------------

// An empty dataset whose first dimension grows with each append.
template <class T>
Dataset create_extendible(hid_t loc, const std::string& name, std::vector<hsize_t> dims, const std::vector<hsize_t>& chunk,
                          const Hdf5WriteParams& params, const std::string& what)
{
    std::vector<hsize_t> maxdims = dims;
    dims[0] = 0;
    maxdims[0] = H5S_UNLIMITED;
    const int rank = static_cast<int>(dims.size());
    Space space(ok_id(H5Screate_simple(rank, dims.data(), maxdims.data()), what));
    Plist dcpl(ok_id(H5Pcreate(H5P_DATASET_CREATE), what));
    ok(H5Pset_obj_track_times(dcpl.get(), false), what);
    ok(H5Pset_chunk(dcpl.get(), rank, chunk.data()), what + ": chunking");
    if (params.gzip_level > 0) {
        ok(H5Pset_shuffle(dcpl.get()), what + ": shuffle filter");
        ok(H5Pset_deflate(dcpl.get(), static_cast<unsigned>(params.gzip_level)), what + ": deflate filter");
    }
    if (params.checksum)
        ok(H5Pset_fletcher32(dcpl.get()), what + ": checksum filter");
    return Dataset(ok_id(H5Dcreate2(loc, name.c_str(), file_type<T>(), space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
                         what + ": cannot create dataset"));
}

// Appends `rows` rows (each of the dataset's trailing shape) to an extendible dataset.
template <class T>
void append_rows(hid_t loc, const std::string& name, const T* data, hsize_t rows, const std::string& what)
{
    if (rows == 0)
        return;
    Dataset ds(ok_id(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), what + ": cannot open"));
    Space old(ok_id(H5Dget_space(ds.get()), what));
    const int rank = H5Sget_simple_extent_ndims(old.get());
    std::vector<hsize_t> dims(static_cast<std::size_t>(rank));
    H5Sget_simple_extent_dims(old.get(), dims.data(), nullptr);
    std::vector<hsize_t> start(dims.size(), 0), count = dims;
    start[0] = dims[0];
    count[0] = rows;
    dims[0] += rows;
    ok(H5Dset_extent(ds.get(), dims.data()), what + ": cannot extend");
    Space file(ok_id(H5Dget_space(ds.get()), what));
    ok(H5Sselect_hyperslab(file.get(), H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr), what);
    Space mem(ok_id(H5Screate_simple(rank, count.data(), nullptr), what));
    ok(H5Dwrite(ds.get(), native_type<T>(), mem.get(), file.get(), H5P_DEFAULT, data), what + ": cannot write data");
}

} // namespace

// ---- free helpers ------------------------------------------------------------------------------

std::string utc_timestamp()
{
    const std::time_t now = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&now, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return buf;
}

std::string join_command_line(int argc, const char* const argv[])
{
    std::string out;
    for (int i = 0; i < argc; ++i) {
        const std::string a = argv[i] ? argv[i] : "";
        const bool plain = !a.empty() && std::all_of(a.begin(), a.end(), [](char c) {
            return is_alnum(c) || (c != '\0' && std::strchr("_-./=:,+@%", c) != nullptr);
        });
        if (i)
            out += ' ';
        if (plain) {
            out += a;
        } else {
            out += '\'';
            for (const char c : a)
                out += c == '\'' ? std::string("'\\''") : std::string(1, c);
            out += '\'';
        }
    }
    return out;
}

// ---- Hdf5Writer --------------------------------------------------------------------------------

struct Hdf5Writer::Impl {
    std::filesystem::path path;
    std::string file; // for messages
    Hdf5WriteParams params;
    detail::AtomicOutput out;
    File h; // declared after `out`: the file is closed before its temporary is removed
    detail::XdmfContents xdmf;
    std::set<std::string> names[5]; // images, labels, surfaces, meshes, graphs
    int next_record = 0;
    struct Simulation {
        std::size_t nodes = 0;  // vertices per frame in the current epoch
        std::size_t xdmf = 0;   // index into xdmf.simulations
        double last_time = -std::numeric_limits<double>::infinity();
        std::size_t frames = 0; // written so far, all epochs
        std::string positions = "positions"; // of the current epoch, relative to the group
    };
    std::map<std::string, Simulation> simulations;
    bool closed = false;
    bool failed = false;

    Impl(std::filesystem::path p, const Hdf5WriteParams& prm)
        : path(std::move(p)), file(path.string()), params(prm), out(path)
    {
    }

    std::string what(const std::string& object) const { return file + ": " + object; }

    void require_open() const
    {
        if (closed)
            throw InvalidInputError(file + ": the container was already committed or closed");
    }

    // Runs one write; an HDF5 failure in the middle leaves the file in an unknown state, so the
    // writer then refuses to commit it.
    template <class F>
    void guarded(F&& f)
    {
        require_open();
        try {
            f();
        } catch (const IoError&) {
            failed = true;
            throw;
        }
    }

    void check_new_name(int kind, const char* kind_name, const std::string& name) const
    {
        if (!valid_item_name(name))
            throw InvalidInputError(file + ": invalid " + kind_name + " name '" + name +
                                    "' (use letters, digits, '_', '.', '-', at most 255 characters)");
        if (names[kind].count(name))
            throw InvalidInputError(file + ": " + kind_name + " '" + name + "' was already written");
    }

    Group group(const std::string& name)
    {
        if (has_link(h.get(), name))
            return Group(ok_id(H5Gopen2(h.get(), name.c_str(), H5P_DEFAULT), what("/" + name)));
        return create_group(h.get(), name, what("/" + name));
    }
};

Hdf5Writer::Hdf5Writer(std::filesystem::path path, const Hdf5WriteParams& params)
{
    silence_hdf5();
    const std::string file = path.string();
    if (params.gzip_level < 0 || params.gzip_level > 9)
        throw InvalidInputError(file + ": gzip_level " + std::to_string(params.gzip_level) + " is outside 0..9");
    if (path.filename().empty())
        throw InvalidInputError(file + ": not a file name");
    if (path.extension() == ".xdmf")
        throw InvalidInputError(file + ": the container must not end in .xdmf (that name is its XDMF sidecar)");
    if (params.gzip_level > 0 && H5Zfilter_avail(H5Z_FILTER_DEFLATE) <= 0)
        throw IoError(file + ": this HDF5 library has no deflate filter");
    impl_ = std::make_unique<Impl>(std::move(path), params);
    Impl& m = *impl_;

    Plist fcpl(ok_id(H5Pcreate(H5P_FILE_CREATE), file));
    ok(H5Pset_link_creation_order(fcpl.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED), file);
    ok(H5Pset_attr_creation_order(fcpl.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED), file);
    ok(H5Pset_obj_track_times(fcpl.get(), false), file);
    Plist fapl = writer_access_plist();
    m.h = File(ok_id(H5Fcreate(m.out.temp_path().c_str(), H5F_ACC_EXCL, fcpl.get(), fapl.get()),
                     file + ": cannot create " + m.out.temp_path().string()));
    Group root(ok_id(H5Gopen2(m.h.get(), "/", H5P_DEFAULT), file));
    const std::string where = m.what("/");
    write_string_attr(root.get(), "lobe_schema", kSchemaName, where);
    write_scalar_attr<std::int32_t>(root.get(), "lobe_schema_version", kHdf5SchemaVersion, where);
    write_string_attr(root.get(), "lobe_version", LOBE_VERSION_STRING, where);
    write_string_attr(root.get(), "created", utc_timestamp(), where);
}

Hdf5Writer::~Hdf5Writer() = default;

Hdf5Writer::Impl& Hdf5Writer::impl()
{
    silence_hdf5(); // per thread in Debian's thread-safe HDF5, and the writer may change threads
    if (!impl_)
        throw InvalidInputError("Hdf5Writer: used after being moved from");
    return *impl_;
}
Hdf5Writer::Hdf5Writer(Hdf5Writer&&) noexcept = default;
Hdf5Writer& Hdf5Writer::operator=(Hdf5Writer&&) noexcept = default;

const std::filesystem::path& Hdf5Writer::path() const
{
    static const std::filesystem::path none;
    return impl_ ? impl_->path : none;
}

void Hdf5Writer::write_image(const std::string& name, const core::AnyImage& image)
{
    Impl& m = impl();
    m.require_open();
    m.check_new_name(0, "image", name);
    const std::string where = m.what("/images/" + name);
    const core::ImageGeometry& g = core::geometry(image);
    core::validate_geometry(g, where);
    const std::size_t values = std::visit([](const auto& im) { return im.data.size(); }, image);
    if (values != g.voxel_count())
        throw InvalidInputError(where + ": image has " + std::to_string(values) + " values for " +
                                std::to_string(g.voxel_count()) + " voxels");
    m.guarded([&] {
        Group grp = m.group("images");
        std::visit([&](const auto& im) { write_volume_dataset(grp.get(), name, im, m.params, where); }, image);
    });
    m.names[0].insert(name);
    m.xdmf.images.push_back({name, core::pixel_type(image), g});
}

void Hdf5Writer::write_labels(const std::string& name, const core::LabelImage3D& labels, const LabelTable& table)
{
    Impl& m = impl();
    m.require_open();
    m.check_new_name(1, "label volume", name);
    const std::string where = m.what("/labels/" + name);
    core::validate_geometry(labels, where);
    if (labels.data.size() != labels.voxel_count())
        throw InvalidInputError(where + ": label volume has " + std::to_string(labels.data.size()) + " values for " +
                                std::to_string(labels.voxel_count()) + " voxels");
    check_label_table(table, true, where);
    m.guarded([&] {
        Group grp = m.group("labels");
        Dataset ds = write_volume_dataset(grp.get(), name, labels, m.params, where);
        write_label_table(ds.get(), table, where);
    });
    m.names[1].insert(name);
    m.xdmf.labels.push_back({name, core::PixelType::UInt8, labels.geometry()});
}

void Hdf5Writer::write_surface(const std::string& name, const core::TriMesh& mesh)
{
    Impl& m = impl();
    m.require_open();
    m.check_new_name(2, "surface", name);
    const std::string where = m.what("/surfaces/" + name);
    if (const std::string problem = core::mesh_problem(mesh); !problem.empty())
        throw InvalidInputError(where + ": " + problem);
    if (mesh.vertices.size() > kMaxMeshElements || mesh.triangles.size() > kMaxMeshElements)
        throw InvalidInputError(where + ": mesh exceeds the limit of " + std::to_string(kMaxMeshElements) + " elements");
    check_finite(mesh.vertices, where);
    m.guarded([&] {
        Group surfaces = m.group("surfaces");
        Group grp = create_group(surfaces.get(), name, where);
        const std::size_t n = mesh.vertices.size(), t = mesh.triangles.size();
        Dataset v = write_dataset(grp.get(), "vertices", {n, 3}, {row_chunk(n, 24), 3},
                                  reinterpret_cast<const double*>(mesh.vertices.data()), m.params, where + "/vertices");
        write_string_attr(v.get(), "units", "mm", where + "/vertices");
        write_dataset(grp.get(), "triangles", {t, 3}, {row_chunk(t, 12), 3},
                      reinterpret_cast<const std::int32_t*>(mesh.triangles.data()), m.params, where + "/triangles");
    });
    m.names[2].insert(name);
    m.xdmf.surfaces.push_back({name, mesh.vertices.size(), mesh.triangles.size()});
}

void Hdf5Writer::write_tet_mesh(const std::string& name, const core::TetMesh& mesh,
                                const std::vector<ElementArray>& quality, const LabelTable& tissues)
{
    Impl& m = impl();
    m.require_open();
    m.check_new_name(3, "tet mesh", name);
    const std::string where = m.what("/meshes/" + name);
    if (const std::string problem = core::mesh_problem(mesh); !problem.empty())
        throw InvalidInputError(where + ": " + problem);
    if (mesh.vertices.size() > kMaxMeshElements || mesh.tets.size() > kMaxMeshElements)
        throw InvalidInputError(where + ": mesh exceeds the limit of " + std::to_string(kMaxMeshElements) + " elements");
    check_finite(mesh.vertices, where);
    check_label_table(tissues, false, where + "/tet_labels");
    std::set<std::string> measures;
    for (const auto& q : quality) {
        if (!valid_item_name(q.name))
            throw InvalidInputError(where + ": invalid quality measure name '" + q.name + "'");
        if (!measures.insert(q.name).second)
            throw InvalidInputError(where + ": quality measure '" + q.name + "' appears twice");
        if (q.values.size() != mesh.tets.size())
            throw InvalidInputError(where + ": quality measure '" + q.name + "' has " + std::to_string(q.values.size()) +
                                    " values for " + std::to_string(mesh.tets.size()) + " tets");
    }
    m.guarded([&] {
        Group meshes = m.group("meshes");
        Group grp = create_group(meshes.get(), name, where);
        const std::size_t n = mesh.vertices.size(), t = mesh.tets.size();
        Dataset v = write_dataset(grp.get(), "vertices", {n, 3}, {row_chunk(n, 24), 3},
                                  reinterpret_cast<const double*>(mesh.vertices.data()), m.params, where + "/vertices");
        write_string_attr(v.get(), "units", "mm", where + "/vertices");
        write_dataset(grp.get(), "tets", {t, 4}, {row_chunk(t, 16), 4},
                      reinterpret_cast<const std::int32_t*>(mesh.tets.data()), m.params, where + "/tets");
        Dataset labels = write_dataset(grp.get(), "tet_labels", {t}, {row_chunk(t, 4)}, mesh.tet_labels.data(),
                                       m.params, where + "/tet_labels");
        write_label_table(labels.get(), tissues, where + "/tet_labels");
        Group qg = create_group(grp.get(), "quality", where + "/quality");
        for (const auto& q : quality) {
            Dataset d = write_dataset(qg.get(), q.name, {t}, {row_chunk(t, 8)}, q.values.data(), m.params,
                                      where + "/quality/" + q.name);
            if (!q.units.empty())
                write_string_attr(d.get(), "units", q.units, where + "/quality/" + q.name);
        }
    });
    m.names[3].insert(name);
    detail::XdmfTetMesh x{name, mesh.vertices.size(), mesh.tets.size(), {}};
    for (const auto& q : quality)
        x.quality.push_back(q.name);
    m.xdmf.meshes.push_back(std::move(x));
}

void Hdf5Writer::write_graph(const std::string& name, const core::CentrelineGraph& graph)
{
    Impl& m = impl();
    m.require_open();
    m.check_new_name(4, "graph", name);
    const std::string where = m.what("/graphs/" + name);
    if (const std::string problem = core::graph_problem(graph); !problem.empty())
        throw InvalidInputError(where + ": " + problem);
    std::size_t points = 0;
    for (const auto& e : graph.edges)
        points += e.points.size();
    if (graph.nodes.size() > kMaxMeshElements || graph.edges.size() > kMaxMeshElements || points > kMaxMeshElements)
        throw InvalidInputError(where + ": graph exceeds the limit of " + std::to_string(kMaxMeshElements) + " elements");
    for (const auto& e : graph.edges)
        if (e.name.find('\0') != std::string::npos)
            throw InvalidInputError(where + ": an edge name contains a NUL character");

    const std::size_t n = graph.nodes.size(), ne = graph.edges.size();
    std::vector<core::Vec3> nodes(n), pts;
    std::vector<double> node_radius(n), edge_radius(ne), edge_length(ne), point_radius;
    std::vector<std::int32_t> edges(2 * ne), level(ne), label(ne), segments, seg_level, seg_label, named;
    std::vector<std::int64_t> offsets{0};
    std::vector<std::string> names;
    for (std::size_t i = 0; i < n; ++i) {
        nodes[i] = graph.nodes[i].position;
        node_radius[i] = graph.nodes[i].radius_mm;
    }
    pts.reserve(points);
    for (std::size_t e = 0; e < ne; ++e) {
        const auto& ed = graph.edges[e];
        edges[2 * e] = ed.from;
        edges[2 * e + 1] = ed.to;
        level[e] = ed.level;
        label[e] = ed.label;
        edge_radius[e] = ed.radius_mm;
        edge_length[e] = ed.length_mm;
        for (std::size_t p = 0; p < ed.points.size(); ++p) {
            if (p > 0) {
                segments.push_back(static_cast<std::int32_t>(pts.size() - 1));
                segments.push_back(static_cast<std::int32_t>(pts.size()));
                seg_level.push_back(ed.level);
                seg_label.push_back(ed.label);
            }
            pts.push_back(ed.points[p]);
            point_radius.push_back(ed.point_radius[p]);
        }
        offsets.push_back(static_cast<std::int64_t>(pts.size()));
        if (!ed.name.empty()) {
            named.push_back(static_cast<std::int32_t>(e));
            names.push_back(ed.name);
        }
    }
    const std::size_t np = pts.size(), ns = seg_level.size();
    m.guarded([&] {
        Group graphs = m.group("graphs");
        Group grp = create_group(graphs.get(), name, where);
        auto mm = [&](Dataset d, const std::string& w) { write_string_attr(d.get(), "units", "mm", w); };
        mm(write_dataset(grp.get(), "nodes", {n, 3}, {row_chunk(n, 24), 3}, reinterpret_cast<const double*>(nodes.data()),
                         m.params, where + "/nodes"),
           where + "/nodes");
        mm(write_dataset(grp.get(), "node_radius", {n}, {row_chunk(n, 8)}, node_radius.data(), m.params, where + "/node_radius"),
           where + "/node_radius");
        write_dataset(grp.get(), "edges", {ne, 2}, {row_chunk(ne, 8), 2}, edges.data(), m.params, where + "/edges");
        write_dataset(grp.get(), "edge_level", {ne}, {row_chunk(ne, 4)}, level.data(), m.params, where + "/edge_level");
        write_dataset(grp.get(), "edge_label", {ne}, {row_chunk(ne, 4)}, label.data(), m.params, where + "/edge_label");
        mm(write_dataset(grp.get(), "edge_radius", {ne}, {row_chunk(ne, 8)}, edge_radius.data(), m.params, where + "/edge_radius"),
           where + "/edge_radius");
        mm(write_dataset(grp.get(), "edge_length", {ne}, {row_chunk(ne, 8)}, edge_length.data(), m.params, where + "/edge_length"),
           where + "/edge_length");
        write_dataset(grp.get(), "edge_offsets", {ne + 1}, {row_chunk(ne + 1, 8)}, offsets.data(), m.params,
                      where + "/edge_offsets");
        mm(write_dataset(grp.get(), "points", {np, 3}, {row_chunk(np, 24), 3}, reinterpret_cast<const double*>(pts.data()),
                         m.params, where + "/points"),
           where + "/points");
        mm(write_dataset(grp.get(), "point_radius", {np}, {row_chunk(np, 8)}, point_radius.data(), m.params,
                         where + "/point_radius"),
           where + "/point_radius");
        // Derived, for the XDMF sidecar: consecutive polyline points as line segments.
        write_dataset(grp.get(), "segments", {ns, 2}, {row_chunk(ns, 8), 2}, segments.data(), m.params, where + "/segments");
        write_dataset(grp.get(), "segment_level", {ns}, {row_chunk(ns, 4)}, seg_level.data(), m.params, where + "/segment_level");
        write_dataset(grp.get(), "segment_label", {ns}, {row_chunk(ns, 4)}, seg_label.data(), m.params, where + "/segment_label");
        if (!named.empty()) {
            write_array_attr(grp.get(), "named_edges", named.data(), named.size(), where);
            write_strings_attr(grp.get(), "edge_names", names, where);
        }
    });
    m.names[4].insert(name);
    m.xdmf.graphs.push_back({name, np, ns});
}

void Hdf5Writer::write_provenance(const Provenance& record)
{
    Impl& m = impl();
    m.require_open();
    const std::string base = m.file + ": provenance record";
    if (record.tool.empty())
        throw InvalidInputError(base + " has no tool name");
    std::set<std::string> keys;
    for (const auto& [key, value] : record.parameters) {
        if (key.empty() || key.size() > kMaxNameLength || key.find('\0') != std::string::npos)
            throw InvalidInputError(base + " of " + record.tool + ": invalid parameter name '" + key + "'");
        if (!keys.insert(key).second)
            throw InvalidInputError(base + " of " + record.tool + ": parameter '" + key + "' appears twice");
        if (value.find('\0') != std::string::npos)
            throw InvalidInputError(base + " of " + record.tool + ": parameter '" + key + "' contains a NUL character");
    }
    keys.clear();
    for (const auto& [step, seconds] : record.timings) {
        if (step.empty() || step.size() > kMaxNameLength || step.find('\0') != std::string::npos)
            throw InvalidInputError(base + " of " + record.tool + ": invalid timing name '" + step + "'");
        if (!keys.insert(step).second)
            throw InvalidInputError(base + " of " + record.tool + ": timing '" + step + "' appears twice");
        if (!std::isfinite(seconds))
            throw InvalidInputError(base + " of " + record.tool + ": timing '" + step + "' is not finite");
    }
    for (const std::string* s : {&record.tool, &record.version, &record.command_line, &record.started})
        if (s->find('\0') != std::string::npos)
            throw InvalidInputError(base + " of " + record.tool + " contains a NUL character");

    m.guarded([&] {
        Group prov = m.group("provenance");
        const std::string name = provenance_group_name(m.next_record, record.tool);
        const std::string where = m.what("/provenance/" + name);
        Group g = create_group(prov.get(), name, where);
        write_string_attr(g.get(), "tool", record.tool, where);
        write_string_attr(g.get(), "version", record.version, where);
        write_string_attr(g.get(), "command_line", record.command_line, where);
        write_string_attr(g.get(), "started", record.started.empty() ? utc_timestamp() : record.started, where);
        Group params = create_group(g.get(), "parameters", where + "/parameters");
        for (const auto& [key, value] : record.parameters)
            write_string_attr(params.get(), key, value, where + "/parameters");
        Group timings = create_group(g.get(), "timings", where + "/timings");
        for (const auto& [step, seconds] : record.timings)
            write_scalar_attr(timings.get(), step, seconds, where + "/timings");
    });
    ++m.next_record;
}

void Hdf5Writer::copy_provenance(const Hdf5Reader& input)
{
    for (const auto& record : input.provenance())
        write_provenance(record);
}

void Hdf5Writer::commit()
{
    Impl& m = impl();
    m.require_open();
    if (m.failed)
        throw IoError(m.file + ": not committed because an earlier write failed");
    m.closed = true;
    if (m.h.close() < 0)
        throw IoError(m.file + ": cannot finish the HDF5 file: " + hdf5_detail());
    // The sidecar is complete before either file moves, so the two renames are all that can fail
    // between an old pair and a new pair.
    std::optional<detail::AtomicOutput> sidecar;
    if (m.params.write_xdmf) {
        std::filesystem::path xdmf_path = m.path;
        xdmf_path.replace_extension(".xdmf");
        sidecar.emplace(xdmf_path);
        std::ofstream f(sidecar->temp_path(), std::ios::binary);
        f << detail::xdmf_document(m.xdmf, m.path.filename().string());
        f.close();
        if (!f)
            throw IoError(xdmf_path.string() + ": cannot write the XDMF sidecar");
    }
    m.out.commit();
    if (sidecar)
        sidecar->commit();
}

void Hdf5Writer::begin_simulation(const std::string& name, const std::string& mesh)
{
    Impl& m = impl();
    m.require_open();
    if (!valid_item_name(name))
        throw InvalidInputError(m.file + ": invalid simulation name '" + name + "'");
    if (m.simulations.count(name))
        throw InvalidInputError(m.file + ": simulation '" + name + "' was already written");
    const auto it = std::find_if(m.xdmf.meshes.begin(), m.xdmf.meshes.end(), [&](const detail::XdmfTetMesh& x) { return x.name == mesh; });
    if (it == m.xdmf.meshes.end())
        throw InvalidInputError(m.file + ": simulation '" + name + "' refers to tet mesh '" + mesh +
                                "', which this writer has not written");
    const std::string where = m.what("/simulation/" + name);
    const std::size_t n = it->vertices;
    m.guarded([&] {
        Group sims = m.group("simulation");
        Group g = create_group(sims.get(), name, where);
        write_string_attr(g.get(), "mesh", "/meshes/" + mesh, where);
        write_string_attr(g.get(), "status", "running", where);
        create_extendible<double>(g.get(), "times", {0}, {1024}, m.params, where + "/times");
        // One frame per chunk (fewer rows for very large meshes), so appending touches one chunk.
        const hsize_t rows = std::max<hsize_t>(1, std::min<hsize_t>(n, kChunkBytes / 24));
        Dataset pos = create_extendible<double>(g.get(), "positions", {0, std::max<hsize_t>(n, 1), 3}, {1, rows, 3}, m.params,
                                                where + "/positions");
        write_string_attr(pos.get(), "units", "mm", where + "/positions");
        Group steps = create_group(g.get(), "steps", where + "/steps");
        for (const char* d : {"time", "dt", "energy"})
            create_extendible<double>(steps.get(), d, {0}, {4096}, m.params, where + "/steps/" + d);
        create_extendible<double>(steps.get(), "force", {0, 3}, {4096, 3}, m.params, where + "/steps/force");
    });
    m.simulations[name] = {n, m.xdmf.simulations.size(), -std::numeric_limits<double>::infinity(), 0, "positions"};
    detail::XdmfEpoch first{"/simulation/" + name + "/positions", "/meshes/" + mesh + "/tets", "/meshes/" + mesh + "/tet_labels",
                            it->vertices, it->tets, 0, 0};
    m.xdmf.simulations.push_back({name, *it, {}, {first}});
}

void Hdf5Writer::append_frame(const std::string& name, double time, const std::vector<core::Vec3>& positions)
{
    Impl& m = impl();
    m.require_open();
    const auto it = m.simulations.find(name);
    if (it == m.simulations.end())
        throw InvalidInputError(m.file + ": append_frame to simulation '" + name + "', which was not begun");
    const std::string where = m.what("/simulation/" + name);
    if (positions.size() != it->second.nodes)
        throw InvalidInputError(where + ": frame has " + std::to_string(positions.size()) + " positions for " +
                                std::to_string(it->second.nodes) + " mesh vertices");
    if (!std::isfinite(time) || !(time > it->second.last_time))
        throw InvalidInputError(where + ": frame time " + std::to_string(time) + " is not finite or not after the previous frame");
    check_finite(positions, where + "/positions");
    m.guarded([&] {
        Group g(ok_id(H5Gopen2(m.h.get(), ("simulation/" + name).c_str(), H5P_DEFAULT), where));
        append_rows(g.get(), it->second.positions, reinterpret_cast<const double*>(positions.data()), 1,
                    where + "/" + it->second.positions);
        append_rows(g.get(), "times", &time, 1, where + "/times");
    });
    it->second.last_time = time;
    ++it->second.frames;
    auto& x = m.xdmf.simulations[it->second.xdmf];
    x.times.push_back(time);
    ++x.epochs.back().frames;
}

void Hdf5Writer::begin_topology(const std::string& name, const core::TetMesh& mesh)
{
    Impl& m = impl();
    m.require_open();
    const auto it = m.simulations.find(name);
    if (it == m.simulations.end())
        throw InvalidInputError(m.file + ": begin_topology of simulation '" + name + "', which was not begun");
    auto& x = m.xdmf.simulations[it->second.xdmf];
    const std::size_t k = x.epochs.size();
    char id[32];
    std::snprintf(id, sizeof id, "%03zu", k);
    const std::string rel = std::string("epochs/") + id;
    const std::string where = m.what("/simulation/" + name + "/" + rel);
    if (const std::string problem = core::mesh_problem(mesh); !problem.empty())
        throw InvalidInputError(where + ": " + problem);
    if (mesh.vertices.size() > kMaxMeshElements || mesh.tets.size() > kMaxMeshElements)
        throw InvalidInputError(where + ": mesh exceeds the limit of " + std::to_string(kMaxMeshElements) + " elements");
    check_finite(mesh.vertices, where);
    const std::size_t n = mesh.vertices.size(), t = mesh.tets.size();
    m.guarded([&] {
        Group g(ok_id(H5Gopen2(m.h.get(), ("simulation/" + name).c_str(), H5P_DEFAULT), m.what("/simulation/" + name)));
        Group epochs = has_link(g.get(), "epochs") ? open_group(g.get(), "epochs", where) : create_group(g.get(), "epochs", where);
        Group e = create_group(epochs.get(), id, where);
        write_scalar_attr(e.get(), "first_frame", double(it->second.frames), where);
        Dataset v = write_dataset(e.get(), "rest_vertices", {n, 3}, {row_chunk(n, 24), 3},
                                  reinterpret_cast<const double*>(mesh.vertices.data()), m.params, where + "/rest_vertices");
        write_string_attr(v.get(), "units", "mm", where + "/rest_vertices");
        write_dataset(e.get(), "tets", {t, 4}, {row_chunk(t, 16), 4}, reinterpret_cast<const std::int32_t*>(mesh.tets.data()),
                      m.params, where + "/tets");
        write_dataset(e.get(), "tet_labels", {t}, {row_chunk(t, 4)}, mesh.tet_labels.data(), m.params, where + "/tet_labels");
        const hsize_t rows = std::max<hsize_t>(1, std::min<hsize_t>(n, kChunkBytes / 24));
        Dataset pos = create_extendible<double>(e.get(), "positions", {0, std::max<hsize_t>(n, 1), 3}, {1, rows, 3}, m.params,
                                                where + "/positions");
        write_string_attr(pos.get(), "units", "mm", where + "/positions");
    });
    it->second.nodes = n;
    it->second.positions = rel + "/positions";
    const std::string base = "/simulation/" + name + "/" + rel;
    x.epochs.push_back({base + "/positions", base + "/tets", base + "/tet_labels", n, t, it->second.frames, 0});
}

void Hdf5Writer::append_steps(const std::string& name, const std::vector<SimulationStep>& steps)
{
    Impl& m = impl();
    m.require_open();
    if (!m.simulations.count(name))
        throw InvalidInputError(m.file + ": append_steps to simulation '" + name + "', which was not begun");
    const std::string where = m.what("/simulation/" + name + "/steps");
    std::vector<double> t, dt, e, f;
    for (const auto& st : steps) {
        t.push_back(st.time);
        dt.push_back(st.dt);
        e.push_back(st.energy);
        f.insert(f.end(), {st.force.x, st.force.y, st.force.z});
    }
    m.guarded([&] {
        Group g(ok_id(H5Gopen2(m.h.get(), ("simulation/" + name + "/steps").c_str(), H5P_DEFAULT), where));
        append_rows(g.get(), "time", t.data(), t.size(), where + "/time");
        append_rows(g.get(), "dt", dt.data(), dt.size(), where + "/dt");
        append_rows(g.get(), "energy", e.data(), e.size(), where + "/energy");
        append_rows(g.get(), "force", f.data(), t.size(), where + "/force");
    });
}

void Hdf5Writer::finish_simulation(const std::string& name, const std::vector<std::pair<std::string, double>>& statistics,
                                   const std::string& status)
{
    Impl& m = impl();
    m.require_open();
    if (!m.simulations.count(name))
        throw InvalidInputError(m.file + ": finish_simulation of '" + name + "', which was not begun");
    const std::string where = m.what("/simulation/" + name);
    std::set<std::string> keys;
    for (const auto& [key, value] : statistics)
        if (key.empty() || key.size() > kMaxNameLength || !keys.insert(key).second)
            throw InvalidInputError(where + ": invalid or repeated statistic '" + key + "'");
    m.guarded([&] {
        Group g(ok_id(H5Gopen2(m.h.get(), ("simulation/" + name).c_str(), H5P_DEFAULT), where));
        ok(H5Adelete(g.get(), "status"), where + ": status");
        write_string_attr(g.get(), "status", status, where);
        Group st = create_group(g.get(), "statistics", where + "/statistics");
        for (const auto& [key, value] : statistics)
            write_scalar_attr(st.get(), key, value, where + "/statistics");
    });
}

// ---- Hdf5Reader --------------------------------------------------------------------------------

struct Hdf5Reader::Impl {
    std::filesystem::path path;
    Where where;
    File h;
    Group root;
    int version = 0;
    std::string lobe_version;
    std::string created;

    std::string at(const std::string& object) const { return where.at(object); }

    // Names in /<group>, or none if the group is absent.
    std::vector<std::string> list(const std::string& group) const
    {
        if (!has_link(root.get(), group))
            return {};
        Group g = open_group(root.get(), group, at("/" + group));
        return link_names(g.get(), at("/" + group));
    }

    // Opens /<group> for item `name`, with a message listing what there is if it is absent.
    Group item_group(const std::string& group, const std::string& name, const char* kind) const
    {
        const auto names = list(group);
        if (std::find(names.begin(), names.end(), name) == names.end())
            throw InvalidInputError(where.file + ": has no " + kind + " '" + name + "' (" + group + ": " +
                                    (names.empty() ? std::string("none") : join(names)) + ")");
        return open_group(root.get(), group, at("/" + group));
    }
};

Hdf5Reader::Hdf5Reader(const std::filesystem::path& path) : impl_(std::make_unique<Impl>())
{
    silence_hdf5();
    Impl& m = *impl_;
    m.path = path;
    m.where.file = path.string();
    const std::string& file = m.where.file;
    std::error_code ec;
    if (!std::filesystem::exists(path, ec))
        throw IoError(file + ": no such file");
    if (std::filesystem::is_directory(path, ec))
        throw IoError(file + ": is a directory, not an HDF5 file");
    const htri_t is_hdf5 = H5Fis_hdf5(file.c_str());
    if (is_hdf5 < 0)
        throw IoError(file + ": cannot read: " + hdf5_detail());
    if (is_hdf5 == 0)
        throw IoError(file + ": not an HDF5 file (no HDF5 signature)");
    m.h = File(H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT));
    if (!m.h.valid())
        throw IoError(file + ": cannot open as HDF5 (damaged or truncated?): " + hdf5_detail());
    m.root = Group(ok_id(H5Gopen2(m.h.get(), "/", H5P_DEFAULT), file + ": cannot open the root group"));
    const hid_t root = m.root.get();
    if (!has_attr(root, "lobe_schema"))
        throw InvalidInputError(file + ": not a lobe container (no lobe_schema attribute)");
    const std::string schema = read_string_attr(root, "lobe_schema", m.at("/"));
    if (schema != kSchemaName)
        throw InvalidInputError(file + ": not a lobe container (lobe_schema is '" + schema + "', expected '" +
                                kSchemaName + "')");
    const long long version = read_integer_attr(root, "lobe_schema_version", m.at("/"));
    if (version > kHdf5SchemaVersion)
        throw InvalidInputError(file + ": schema version " + std::to_string(version) + " is newer than this lobe (" +
                                std::to_string(kHdf5SchemaVersion) + "); update lobe to read it");
    if (version < 1)
        throw InvalidInputError(file + ": schema version " + std::to_string(version) + " is invalid (must be >= 1)");
    m.version = static_cast<int>(version);
    m.lobe_version = read_string_attr(root, "lobe_version", m.at("/"));
    m.created = read_string_attr(root, "created", m.at("/"));
}

Hdf5Reader::~Hdf5Reader() = default;

const Hdf5Reader::Impl& Hdf5Reader::impl() const
{
    silence_hdf5(); // per thread in Debian's thread-safe HDF5, and the reader may change threads
    if (!impl_)
        throw InvalidInputError("Hdf5Reader: used after being moved from");
    return *impl_;
}
Hdf5Reader::Hdf5Reader(Hdf5Reader&&) noexcept = default;
Hdf5Reader& Hdf5Reader::operator=(Hdf5Reader&&) noexcept = default;

const std::filesystem::path& Hdf5Reader::path() const { return impl().path; }
int Hdf5Reader::schema_version() const { return impl().version; }
const std::string& Hdf5Reader::lobe_version() const { return impl().lobe_version; }
const std::string& Hdf5Reader::created() const { return impl().created; }

std::vector<std::string> Hdf5Reader::images() const { return impl().list("images"); }
std::vector<std::string> Hdf5Reader::labels() const { return impl().list("labels"); }
std::vector<std::string> Hdf5Reader::surfaces() const { return impl().list("surfaces"); }
std::vector<std::string> Hdf5Reader::tet_meshes() const { return impl().list("meshes"); }
std::vector<std::string> Hdf5Reader::simulations() const { return impl().list("simulation"); }
std::vector<std::string> Hdf5Reader::graphs() const { return impl().list("graphs"); }

ImageInfo Hdf5Reader::image_info(const std::string& name) const
{
    Group g = impl().item_group("images", name, "image");
    DatasetView v = open_dataset(g.get(), name, impl().at("/images/" + name));
    std::optional<core::PixelType> type;
    ImageInfo info;
    info.geometry = read_volume_geometry(v, type);
    if (!type)
        throw InvalidInputError(v.where + " has type " + describe_type(v.type.get()) +
                                ", expected one of uint8, int8, int16, uint16, int32, uint32, float32, float64");
    info.pixel_type = *type;
    return info;
}

ImageInfo Hdf5Reader::label_info(const std::string& name) const
{
    Group g = impl().item_group("labels", name, "label volume");
    DatasetView v = open_dataset(g.get(), name, impl().at("/labels/" + name));
    std::optional<core::PixelType> type;
    ImageInfo info;
    info.geometry = read_volume_geometry(v, type);
    if (type != core::PixelType::UInt8)
        throw InvalidInputError(v.where + " has type " + describe_type(v.type.get()) + ", expected uint8");
    info.pixel_type = core::PixelType::UInt8;
    return info;
}

core::AnyImage Hdf5Reader::read_image(const std::string& name) const
{
    Group g = impl().item_group("images", name, "image");
    DatasetView v = open_dataset(g.get(), name, impl().at("/images/" + name));
    std::optional<core::PixelType> type;
    const core::ImageGeometry geom = read_volume_geometry(v, type);
    if (!type)
        throw InvalidInputError(v.where + " has type " + describe_type(v.type.get()) +
                                ", expected one of uint8, int8, int16, uint16, int32, uint32, float32, float64");
    check_stored(v, geom.voxel_count() * static_cast<std::size_t>(core::pixel_size(*type))); // before allocating
    core::AnyImage image = core::make_image(*type, geom);
    std::visit([&](auto& im) { read_all(v, im.data.data(), im.data.size()); }, image);
    return image;
}

LabelVolume Hdf5Reader::read_labels(const std::string& name) const
{
    Group g = impl().item_group("labels", name, "label volume");
    DatasetView v = open_dataset(g.get(), name, impl().at("/labels/" + name));
    std::optional<core::PixelType> type;
    const core::ImageGeometry geom = read_volume_geometry(v, type);
    if (type != core::PixelType::UInt8)
        throw InvalidInputError(v.where + " has type " + describe_type(v.type.get()) + ", expected uint8");
    LabelVolume out;
    out.table = read_label_table(v.ds.get(), v.where);
    check_stored(v, geom.voxel_count()); // before allocating
    out.image = core::LabelImage3D(geom);
    read_all(v, out.image.data.data(), out.image.data.size());
    return out;
}

core::CentrelineGraph Hdf5Reader::read_graph(const std::string& name) const
{
    Group parent = impl().item_group("graphs", name, "graph");
    const std::string where = impl().at("/graphs/" + name);
    Group g = open_group(parent.get(), name, where);
    // A one-column dataset of `rows` values (rows == npos: any number up to the limit).
    auto column = [&](const char* ds, H5T_class_t cls, const char* type_name, std::size_t rows, auto tag) {
        using T = decltype(tag);
        DatasetView v = open_dataset(g.get(), ds, where + "/" + ds);
        const std::size_t n = check_shape(v, 1, 0, kMaxMeshElements + 1);
        check_class(v, cls, type_name);
        if (rows != std::size_t(-1) && n != rows)
            throw InvalidInputError(v.where + " has " + std::to_string(n) + " values, expected " + std::to_string(rows));
        check_stored(v, n * sizeof(T));
        std::vector<T> out(n);
        read_all(v, out.data(), n);
        return out;
    };
    auto xyz = [&](const char* ds) {
        DatasetView v = open_dataset(g.get(), ds, where + "/" + ds);
        const std::size_t n = check_shape(v, 2, 3, kMaxMeshElements);
        check_class(v, H5T_FLOAT, "float64");
        check_stored(v, n * sizeof(core::Vec3));
        std::vector<core::Vec3> out(n);
        read_all(v, reinterpret_cast<double*>(out.data()), 3 * n);
        check_finite(out, v.where);
        return out;
    };
    const auto nodes = xyz("nodes");
    const auto node_radius = column("node_radius", H5T_FLOAT, "float64", nodes.size(), double{});
    const auto edges = read_cells<2>(g.get(), "edges", where);
    const std::size_t ne = edges.size();
    const auto level = column("edge_level", H5T_INTEGER, "int32", ne, std::int32_t{});
    const auto label = column("edge_label", H5T_INTEGER, "int32", ne, std::int32_t{});
    const auto radius = column("edge_radius", H5T_FLOAT, "float64", ne, double{});
    const auto length = column("edge_length", H5T_FLOAT, "float64", ne, double{});
    const auto offsets = column("edge_offsets", H5T_INTEGER, "int64", ne + 1, std::int64_t{});
    const auto points = xyz("points");
    const auto point_radius = column("point_radius", H5T_FLOAT, "float64", points.size(), double{});
    if (offsets.front() != 0 || offsets.back() != static_cast<std::int64_t>(points.size()))
        throw InvalidInputError(where + "/edge_offsets must run from 0 to the number of points (" +
                                std::to_string(points.size()) + ")");
    core::CentrelineGraph out;
    for (std::size_t i = 0; i < nodes.size(); ++i)
        out.nodes.push_back({nodes[i], node_radius[i]});
    for (std::size_t e = 0; e < ne; ++e) {
        if (offsets[e + 1] < offsets[e] + 2)
            throw InvalidInputError(where + "/edge_offsets: edge " + std::to_string(e) + " has fewer than two points");
        core::CentrelineEdge ed;
        ed.from = edges[e][0];
        ed.to = edges[e][1];
        ed.level = level[e];
        ed.label = label[e];
        ed.radius_mm = radius[e];
        ed.length_mm = length[e];
        ed.points.assign(points.begin() + offsets[e], points.begin() + offsets[e + 1]);
        ed.point_radius.assign(point_radius.begin() + offsets[e], point_radius.begin() + offsets[e + 1]);
        out.edges.push_back(std::move(ed));
    }
    const bool has_index = has_attr(g.get(), "named_edges"), has_names = has_attr(g.get(), "edge_names");
    if (has_index != has_names)
        throw InvalidInputError(where + " has one of the attributes named_edges and edge_names but not the other");
    if (has_index) {
        Attr ia = open_attr(g.get(), "named_edges", where);
        const hssize_t k = attr_points(ia.get(), where, "named_edges");
        if (k < 0 || static_cast<std::size_t>(k) > ne)
            throw InvalidInputError(where + ": attribute named_edges has " + std::to_string(k) + " entries for " +
                                    std::to_string(ne) + " edges");
        std::vector<long long> idx(static_cast<std::size_t>(k));
        if (k > 0)
            ok(H5Aread(ia.get(), H5T_NATIVE_LLONG, idx.data()), where + ": cannot read attribute named_edges");
        Attr na = open_attr(g.get(), "edge_names", where);
        Type nt(ok_id(H5Aget_type(na.get()), where));
        if (H5Tget_class(nt.get()) != H5T_STRING || attr_points(na.get(), where, "edge_names") != k)
            throw InvalidInputError(where + ": attribute edge_names must hold one string per entry of named_edges");
        const auto names = k > 0 ? read_strings(na.get(), nt.get(), static_cast<std::size_t>(k), where + ": attribute edge_names")
                                 : std::vector<std::string>{};
        for (std::size_t i = 0; i < idx.size(); ++i) {
            if (idx[i] < 0 || idx[i] >= static_cast<long long>(ne))
                throw InvalidInputError(where + ": named_edges holds edge " + std::to_string(idx[i]) + " outside [0, " +
                                        std::to_string(ne) + ")");
            out.edges[static_cast<std::size_t>(idx[i])].name = names[i];
        }
    }
    if (const std::string problem = core::graph_problem(out); !problem.empty())
        throw InvalidInputError(where + ": " + problem);
    return out;
}

core::TriMesh Hdf5Reader::read_surface(const std::string& name) const
{
    Group parent = impl().item_group("surfaces", name, "surface");
    const std::string where = impl().at("/surfaces/" + name);
    Group g = open_group(parent.get(), name, where);
    core::TriMesh mesh;
    mesh.vertices = read_vertices(g.get(), where);
    mesh.triangles = read_cells<3>(g.get(), "triangles", where);
    if (const std::string problem = core::mesh_problem(mesh); !problem.empty())
        throw InvalidInputError(where + "/triangles: " + problem);
    return mesh;
}

namespace {

// Reads a rank-1 float64 dataset of at most max_rows values.
std::vector<double> read_doubles(hid_t g, const std::string& name, const std::string& where, std::size_t max_rows)
{
    DatasetView v = open_dataset(g, name, where + "/" + name);
    const std::size_t n = check_shape(v, 1, 0, max_rows);
    check_class(v, H5T_FLOAT, "float64");
    std::vector<double> out(n);
    read_all(v, out.data(), n);
    return out;
}

// The longest simulation the reader accepts, in frames and steps.
constexpr std::size_t kMaxSimulationRows = std::size_t(1) << 28;

} // namespace

namespace {

// The frames of one topology of a simulation (docs/file-format.md, section 1.9): epoch 0 is
// /simulation/<name>/positions on /meshes/<mesh>; epoch k >= 1 is epochs/<k> with its own tets.
struct Epoch {
    std::string group;      // relative to the simulation group: "" for epoch 0, "epochs/001", ...
    std::size_t first = 0;  // global index of its first frame
    std::size_t frames = 0;
    std::size_t nodes = 0;
};

std::vector<Epoch> read_epochs(hid_t g, std::size_t total_frames, const std::string& where)
{
    std::vector<Epoch> out(1);
    std::vector<std::string> names;
    if (has_link(g, "epochs")) {
        Group eg = open_group(g, "epochs", where + "/epochs");
        names = link_names(eg.get(), where + "/epochs");
        std::sort(names.begin(), names.end());
        for (const auto& id : names) {
            Group e = open_group(eg.get(), id, where + "/epochs/" + id);
            const double first = read_numbers_attr(e.get(), "first_frame", 1, where + "/epochs/" + id)[0];
            if (!(first >= double(out.back().first)) || first > double(total_frames) || first != std::floor(first))
                throw InvalidInputError(where + "/epochs/" + id + ": first_frame " + std::to_string(first) +
                                        " is not after the previous epoch's or beyond the frames");
            out.push_back({"epochs/" + id, static_cast<std::size_t>(first), 0, 0});
        }
    }
    for (std::size_t k = 0; k < out.size(); ++k) {
        out[k].frames = (k + 1 < out.size() ? out[k + 1].first : total_frames) - out[k].first;
        const std::string rel = out[k].group.empty() ? "positions" : out[k].group + "/positions";
        DatasetView v = open_dataset(g, rel, where + "/" + rel);
        check_shape(v, 3, 3, kMaxSimulationRows);
        check_class(v, H5T_FLOAT, "float64");
        if (v.dims[0] != out[k].frames)
            throw InvalidInputError(v.where + " has " + std::to_string(v.dims[0]) + " frames, its epoch " +
                                    std::to_string(out[k].frames));
        if (v.dims[1] > kMaxMeshElements)
            throw InvalidInputError(v.where + " has too many nodes");
        out[k].nodes = static_cast<std::size_t>(v.dims[1]);
    }
    return out;
}

} // namespace

SimulationInfo Hdf5Reader::read_simulation(const std::string& name) const
{
    Group parent = impl().item_group("simulation", name, "simulation");
    const std::string where = impl().at("/simulation/" + name);
    Group g = open_group(parent.get(), name, where);
    SimulationInfo out;
    out.mesh = read_string_attr(g.get(), "mesh", where);
    if (out.mesh.rfind("/meshes/", 0) == 0)
        out.mesh = out.mesh.substr(8);
    out.status = has_attr(g.get(), "status") ? read_string_attr(g.get(), "status", where) : std::string();
    out.times = read_doubles(g.get(), "times", where, kMaxSimulationRows);
    const auto epochs = read_epochs(g.get(), out.times.size(), where);
    out.nodes = epochs[0].nodes;
    for (std::size_t k = 1; k < epochs.size(); ++k)
        out.topology_changes.push_back(epochs[k].first);
    const std::string sw = where + "/steps";
    Group steps = open_group(g.get(), "steps", sw);
    const auto t = read_doubles(steps.get(), "time", sw, kMaxSimulationRows);
    const auto dt = read_doubles(steps.get(), "dt", sw, kMaxSimulationRows);
    const auto e = read_doubles(steps.get(), "energy", sw, kMaxSimulationRows);
    DatasetView fv = open_dataset(steps.get(), "force", sw + "/force");
    const std::size_t nf = check_shape(fv, 2, 3, kMaxSimulationRows);
    check_class(fv, H5T_FLOAT, "float64");
    if (dt.size() != t.size() || e.size() != t.size() || nf != t.size())
        throw InvalidInputError(sw + ": time, dt, energy and force differ in length");
    std::vector<double> f(3 * nf);
    read_all(fv, f.data(), f.size());
    for (std::size_t i = 0; i < t.size(); ++i)
        out.steps.push_back({t[i], dt[i], {f[3 * i], f[3 * i + 1], f[3 * i + 2]}, e[i]});
    if (has_link(g.get(), "statistics")) {
        Group st = open_group(g.get(), "statistics", where + "/statistics");
        for (const auto& key : attribute_names(st.get(), where + "/statistics")) {
            const auto v = read_numbers_attr(st.get(), key, 1, where + "/statistics");
            out.statistics.emplace_back(key, v[0]);
        }
    }
    return out;
}

std::vector<core::Vec3> Hdf5Reader::read_frame(const std::string& name, std::size_t index) const
{
    Group parent = impl().item_group("simulation", name, "simulation");
    const std::string where = impl().at("/simulation/" + name);
    Group g = open_group(parent.get(), name, where);
    const auto times = read_doubles(g.get(), "times", where, kMaxSimulationRows);
    if (index >= times.size())
        throw InvalidInputError(where + ": no frame " + std::to_string(index) + " (it has " + std::to_string(times.size()) + ")");
    const auto epochs = read_epochs(g.get(), times.size(), where);
    std::size_t k = epochs.size() - 1;
    while (epochs[k].first > index)
        --k;
    const std::string rel = epochs[k].group.empty() ? "positions" : epochs[k].group + "/positions";
    DatasetView v = open_dataset(g.get(), rel, where + "/" + rel);
    std::vector<core::Vec3> out(epochs[k].nodes);
    const hsize_t start[3] = {index - epochs[k].first, 0, 0}, count[3] = {1, v.dims[1], 3};
    Space file(ok_id(H5Dget_space(v.ds.get()), v.where));
    ok(H5Sselect_hyperslab(file.get(), H5S_SELECT_SET, start, nullptr, count, nullptr), v.where);
    Space mem(ok_id(H5Screate_simple(3, count, nullptr), v.where));
    if (!out.empty())
        ok(H5Dread(v.ds.get(), H5T_NATIVE_DOUBLE, mem.get(), file.get(), H5P_DEFAULT, out.data()), v.where + ": cannot read frame");
    check_finite(out, v.where);
    return out;
}

core::TetMesh Hdf5Reader::read_frame_mesh(const std::string& name, std::size_t index) const
{
    const std::string where = impl().at("/simulation/" + name);
    core::TetMesh mesh;
    mesh.vertices = read_frame(name, index);
    const SimulationInfo info = read_simulation(name);
    std::size_t epoch = 0;
    while (epoch < info.topology_changes.size() && info.topology_changes[epoch] <= index)
        ++epoch;
    if (epoch == 0) {
        const TetMeshData m = read_tet_mesh(info.mesh);
        mesh.tets = m.mesh.tets;
        mesh.tet_labels = m.mesh.tet_labels;
    } else {
        Group parent = impl().item_group("simulation", name, "simulation");
        Group g = open_group(parent.get(), name, where);
        char id[32];
        std::snprintf(id, sizeof id, "epochs/%03zu", epoch);
        Group e = open_group(g.get(), id, where + "/" + id);
        mesh.tets = read_cells<4>(e.get(), "tets", where + "/" + id);
        DatasetView lv = open_dataset(e.get(), "tet_labels", where + "/" + id + "/tet_labels");
        check_shape(lv, 1, 0, kMaxMeshElements);
        mesh.tet_labels.resize(static_cast<std::size_t>(lv.dims[0]));
        read_all(lv, mesh.tet_labels.data(), mesh.tet_labels.size());
    }
    // Frames are deformed states: a tet may be inverted in one (a blow-up is caught later), so
    // only the indices and label count are checked here, not the orientation.
    if (mesh.tet_labels.size() != mesh.tets.size())
        throw InvalidInputError(where + ": frame " + std::to_string(index) + " has " + std::to_string(mesh.tets.size()) +
                                " tets but " + std::to_string(mesh.tet_labels.size()) + " labels");
    for (const auto& q : mesh.tets)
        for (auto v : q)
            if (v < 0 || std::size_t(v) >= mesh.vertices.size())
                throw InvalidInputError(where + ": frame " + std::to_string(index) + " has a tet vertex out of range");
    return mesh;
}

TetMeshData Hdf5Reader::read_tet_mesh(const std::string& name) const
{
    Group parent = impl().item_group("meshes", name, "tet mesh");
    const std::string where = impl().at("/meshes/" + name);
    Group g = open_group(parent.get(), name, where);
    TetMeshData out;
    out.mesh.vertices = read_vertices(g.get(), where);
    out.mesh.tets = read_cells<4>(g.get(), "tets", where);
    const std::size_t m = out.mesh.tets.size();
    {
        DatasetView v = open_dataset(g.get(), "tet_labels", where + "/tet_labels");
        const std::size_t n = check_shape(v, 1, 0, kMaxMeshElements);
        check_class(v, H5T_INTEGER, "int32");
        if (n != m)
            throw InvalidInputError(v.where + " has " + std::to_string(n) + " values but the mesh has " +
                                    std::to_string(m) + " tets");
        check_stored(v, n * sizeof(std::int32_t));
        out.mesh.tet_labels.resize(n);
        read_all(v, out.mesh.tet_labels.data(), n);
        out.tissues = read_label_table(v.ds.get(), v.where);
    }
    if (const std::string problem = core::mesh_problem(out.mesh); !problem.empty())
        throw InvalidInputError(where + ": " + problem);
    if (has_link(g.get(), "quality")) {
        Group qg = open_group(g.get(), "quality", where + "/quality");
        for (const auto& q : link_names(qg.get(), where + "/quality")) {
            DatasetView v = open_dataset(qg.get(), q, where + "/quality/" + q);
            const std::size_t n = check_shape(v, 1, 0, kMaxMeshElements);
            const H5T_class_t c = H5Tget_class(v.type.get());
            if (c != H5T_FLOAT && c != H5T_INTEGER)
                throw InvalidInputError(v.where + " has type " + describe_type(v.type.get()) + ", expected float64");
            if (n != m)
                throw InvalidInputError(v.where + " has " + std::to_string(n) + " values but the mesh has " +
                                        std::to_string(m) + " tets");
            check_stored(v, n * sizeof(double));
            ElementArray a;
            a.name = q;
            a.values.resize(n);
            read_all(v, a.values.data(), n);
            if (has_attr(v.ds.get(), "units"))
                a.units = read_string_attr(v.ds.get(), "units", v.where);
            out.quality.push_back(std::move(a));
        }
    }
    return out;
}

std::vector<Provenance> Hdf5Reader::provenance() const
{
    const Impl& m = impl();
    std::vector<std::pair<long, std::string>> order;
    for (const auto& name : m.list("provenance")) {
        // NNN_tool: the number, not the spelling, orders the records (so 1000_x follows 999_y).
        char* end = nullptr;
        const long n = std::strtol(name.c_str(), &end, 10);
        if (end == name.c_str() || *end != '_' || n < 0)
            throw InvalidInputError(m.at("/provenance/" + name) + ": record name is not NNN_<tool>");
        order.emplace_back(n, name);
    }
    std::stable_sort(order.begin(), order.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    std::vector<Provenance> records;
    if (order.empty())
        return records;
    Group prov = open_group(m.root.get(), "provenance", m.at("/provenance"));
    for (const auto& entry : order) {
        const std::string& name = entry.second;
        const std::string where = m.at("/provenance/" + name);
        Group g = open_group(prov.get(), name, where);
        Provenance p;
        p.tool = read_string_attr(g.get(), "tool", where);
        p.version = read_string_attr(g.get(), "version", where);
        p.command_line = read_string_attr(g.get(), "command_line", where);
        p.started = read_string_attr(g.get(), "started", where);
        if (has_link(g.get(), "parameters")) {
            Group pg = open_group(g.get(), "parameters", where + "/parameters");
            for (const auto& key : attribute_names(pg.get(), where + "/parameters"))
                p.parameters.emplace_back(key, read_string_attr(pg.get(), key, where + "/parameters"));
        }
        if (has_link(g.get(), "timings")) {
            Group tg = open_group(g.get(), "timings", where + "/timings");
            for (const auto& step : attribute_names(tg.get(), where + "/timings"))
                p.timings.emplace_back(step, read_numbers_attr(tg.get(), step, 1, where + "/timings").front());
        }
        records.push_back(std::move(p));
    }
    return records;
}

// ---- convenience ---------------------------------------------------------------------------------

core::AnyImage read_hdf5_image(const std::filesystem::path& path, const std::string& name)
{
    Hdf5Reader r(path);
    const auto images = r.images();
    const auto labels = r.labels();
    const auto has = [](const std::vector<std::string>& v, const std::string& s) {
        return std::find(v.begin(), v.end(), s) != v.end();
    };
    std::vector<std::string> all;
    for (const auto& n : images)
        all.push_back("images/" + n);
    for (const auto& n : labels)
        all.push_back("labels/" + n);

    std::string qualified = name;
    if (name.empty()) {
        if (all.empty())
            throw InvalidInputError(path.string() + ": contains no image (nothing in /images or /labels)");
        if (all.size() > 1)
            throw InvalidInputError(path.string() + ": contains several images (" + join(all) + "); name one");
        qualified = all.front();
    } else if (name.rfind("images/", 0) != 0 && name.rfind("labels/", 0) != 0) {
        if (has(images, name))
            qualified = "images/" + name;
        else if (has(labels, name))
            qualified = "labels/" + name;
        else
            throw InvalidInputError(path.string() + ": has no image '" + name + "' (it has: " +
                                    (all.empty() ? std::string("none") : join(all)) + ")");
    }
    if (qualified.rfind("labels/", 0) == 0)
        return r.read_labels(qualified.substr(7)).image;
    return r.read_image(qualified.substr(7));
}

void write_hdf5_image(const std::filesystem::path& path, const core::AnyImage& image, const std::string& name)
{
    Hdf5Writer w(path);
    w.write_image(name, image);
    w.commit();
}

} // namespace lobe::io
