#include "lobe/io/metaimage.h"

#include "detail/atomic_file.h"
#include "detail/checks.h"
#include "detail/text.h"
#include "lobe/io/limits.h"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cstring>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>

namespace lobe::io {
namespace {

using core::InvalidInputError;
using core::IoError;
using core::PixelType;

// A header longer than this is not a header: a binary file handed to the reader by mistake.
constexpr std::size_t kMaxHeaderBytes = 1 << 20;

struct ElementTypeName {
    const char* name;
    PixelType type;
};
constexpr std::array<ElementTypeName, 8> kElementTypes{{
    {"MET_UCHAR", PixelType::UInt8},
    {"MET_CHAR", PixelType::Int8},
    {"MET_SHORT", PixelType::Int16},
    {"MET_USHORT", PixelType::UInt16},
    {"MET_INT", PixelType::Int32},
    {"MET_UINT", PixelType::UInt32},
    {"MET_FLOAT", PixelType::Float32},
    {"MET_DOUBLE", PixelType::Float64},
}};

const char* element_type_name(PixelType t)
{
    for (const auto& e : kElementTypes)
        if (e.type == t)
            return e.name;
    return "MET_OTHER";
}

std::string lower(std::string s)
{
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return s;
}

bool host_is_big_endian()
{
    const std::uint16_t one = 1;
    unsigned char b[2];
    std::memcpy(b, &one, 2);
    return b[0] == 0;
}

// One "Key = Value" field, with its line number for error messages.
struct Field {
    std::string key;
    std::string value;
    int line = 0;
};

class HeaderParser {
public:
    HeaderParser(std::string_view text, std::filesystem::path name) : text_(text), name_(std::move(name)) {}

    MetaImageHeader parse()
    {
        read_fields();
        MetaImageHeader h;
        interpret(h);
        return h;
    }

private:
    [[noreturn]] void fail(const std::string& what) const
    {
        throw InvalidInputError(name_.string() + ": " + what);
    }

    const Field* find(std::initializer_list<const char*> keys) const
    {
        for (const char* k : keys)
            for (const auto& f : fields_)
                if (lower(f.key) == lower(k))
                    return &f;
        return nullptr;
    }

    void read_fields()
    {
        std::size_t pos = 0;
        int line_no = 0;
        bool found_data_file = false;
        while (pos < text_.size()) {
            const std::size_t eol = text_.find('\n', pos);
            const std::size_t end = eol == std::string_view::npos ? text_.size() : eol;
            ++line_no;
            std::string_view line = text_.substr(pos, end - pos);
            pos = eol == std::string_view::npos ? text_.size() : eol + 1;
            if (pos > kMaxHeaderBytes)
                fail("no ElementDataFile field within the first " + std::to_string(kMaxHeaderBytes) +
                     " bytes: not a MetaImage header");
            const std::string trimmed = detail::trim(line);
            if (trimmed.empty())
                continue;
            const auto eq = trimmed.find('=');
            if (eq == std::string::npos)
                fail("line " + std::to_string(line_no) + " is not of the form 'Key = Value': '" +
                     detail::printable(trimmed, 60) + "'");
            Field f{detail::trim(trimmed.substr(0, eq)), detail::trim(trimmed.substr(eq + 1)), line_no};
            if (f.key.empty())
                fail("line " + std::to_string(line_no) + " has an empty key");
            fields_.push_back(f);
            // ElementDataFile ends the header; for LOCAL data the bytes start on the next line.
            if (lower(f.key) == "elementdatafile") {
                data_offset_ = pos;
                found_data_file = true;
                break;
            }
        }
        if (!found_data_file)
            fail("the header has no ElementDataFile field");
    }

    std::vector<double> numbers(const Field& f, std::size_t expected) const
    {
        std::vector<double> out;
        const char* p = f.value.data();
        const char* e = p + f.value.size();
        while (p < e) {
            while (p < e && std::isspace(static_cast<unsigned char>(*p)))
                ++p;
            if (p == e)
                break;
            double v = 0;
            const auto r = std::from_chars(p, e, v);
            if (r.ec != std::errc() || (r.ptr < e && !std::isspace(static_cast<unsigned char>(*r.ptr))))
                fail(f.key + " (line " + std::to_string(f.line) + ") is not a list of numbers: '" +
                     detail::printable(f.value, 60) + "'");
            out.push_back(v);
            p = r.ptr;
        }
        if (out.size() != expected)
            fail(f.key + " (line " + std::to_string(f.line) + ") has " + std::to_string(out.size()) +
                 " values, expected " + std::to_string(expected));
        return out;
    }

    std::int64_t integer(const Field& f) const
    {
        const double v = numbers(f, 1)[0];
        if (!(std::abs(v) < 9.0e15) || v != std::floor(v))
            fail(f.key + " (line " + std::to_string(f.line) + ") is not an integer: '" + f.value + "'");
        return static_cast<std::int64_t>(v);
    }

    bool boolean(const Field& f) const
    {
        const std::string v = lower(f.value);
        if (v == "true" || v == "1")
            return true;
        if (v == "false" || v == "0")
            return false;
        fail(f.key + " (line " + std::to_string(f.line) + ") must be True or False, not '" +
             detail::printable(f.value, 40) + "'");
    }

    void interpret(MetaImageHeader& h) const
    {
        if (const Field* f = find({"ObjectType"}); f && lower(f->value) != "image")
            fail("ObjectType is '" + detail::printable(f->value, 40) + "', not Image");

        const Field* nd = find({"NDims"});
        if (!nd)
            fail("the header has no NDims field");
        const std::int64_t ndims = integer(*nd);
        if (ndims != 2 && ndims != 3)
            fail("NDims = " + std::to_string(ndims) + " is not supported (lobe reads 2-D and 3-D images)");
        h.ndims = static_cast<int>(ndims);
        const auto n = static_cast<std::size_t>(ndims);

        const Field* ds = find({"DimSize"});
        if (!ds)
            fail("the header has no DimSize field");
        const auto dims_d = numbers(*ds, n);
        std::array<std::int64_t, 3> dims{1, 1, 1};
        for (std::size_t a = 0; a < n; ++a) {
            if (dims_d[a] != std::floor(dims_d[a]) || !(std::abs(dims_d[a]) < 9.0e15))
                fail("DimSize (line " + std::to_string(ds->line) + ") has a non-integer value");
            dims[a] = static_cast<std::int64_t>(dims_d[a]);
        }
        detail::checked_voxel_count(dims, name_.string() + ": DimSize");

        const Field* et = find({"ElementType"});
        if (!et)
            fail("the header has no ElementType field");
        bool known = false;
        for (const auto& e : kElementTypes)
            if (et->value == e.name) {
                h.pixel_type = e.type;
                known = true;
            }
        if (!known)
            fail("ElementType '" + detail::printable(et->value, 40) +
                 "' is not supported (MET_UCHAR, MET_CHAR, MET_SHORT, MET_USHORT, MET_INT, MET_UINT, "
                 "MET_FLOAT, MET_DOUBLE)");

        if (const Field* f = find({"ElementNumberOfChannels"})) {
            const std::int64_t c = integer(*f);
            if (c < 1 || c > 64)
                fail("ElementNumberOfChannels = " + std::to_string(c) + " is outside 1..64");
            h.channels = static_cast<int>(c);
        }
        std::array<std::int64_t, 3> with_channels = dims;
        with_channels[0] *= h.channels;
        detail::checked_voxel_count(with_channels, name_.string() + ": DimSize x ElementNumberOfChannels");

        // Geometry. ElementSize stands in for a missing ElementSpacing, as MetaIO does.
        std::array<double, 3> spacing{1, 1, 1}, origin{0, 0, 0};
        std::array<double, 9> dir{1, 0, 0, 0, 1, 0, 0, 0, 1};
        if (const Field* f = find({"ElementSpacing", "ElementSize"})) {
            const auto v = numbers(*f, n);
            for (std::size_t a = 0; a < n; ++a) {
                if (!std::isfinite(v[a]) || !(v[a] > 0))
                    fail(f->key + " (line " + std::to_string(f->line) + ") has spacing " +
                         detail::format_number(v[a]) + " along axis " + std::to_string(a) +
                         ": spacing must be finite and positive");
                spacing[a] = v[a];
            }
        }
        if (const Field* f = find({"Offset", "Position", "Origin"})) {
            const auto v = numbers(*f, n);
            for (std::size_t a = 0; a < n; ++a) {
                if (!std::isfinite(v[a]))
                    fail(f->key + " (line " + std::to_string(f->line) + ") is not finite");
                origin[a] = v[a];
            }
        }
        if (const Field* f = find({"TransformMatrix", "Rotation", "Orientation"})) {
            const auto v = numbers(*f, n * n);
            // The file lists the axes one after another: value r*n + c is component c of axis r,
            // which is column r of ITK's direction matrix.
            for (std::size_t r = 0; r < n; ++r)
                for (std::size_t c = 0; c < n; ++c)
                    dir[c * 3 + r] = v[r * n + c];
        }
        core::ImageGeometry& g = h.geometry;
        for (int a = 0; a < 3; ++a)
            g.size[a] = static_cast<int>(dims[a]);
        g.spacing = spacing;
        g.origin = origin;
        g.direction = dir;
        const std::string problem = core::geometry_problem(g);
        if (!problem.empty())
            fail("invalid geometry: " + problem);

        if (const Field* f = find({"BinaryData"}))
            h.binary = boolean(*f);
        if (const Field* f = find({"BinaryDataByteOrderMSB", "ElementByteOrderMSB"}))
            h.big_endian = boolean(*f);
        if (const Field* f = find({"CompressedData"}))
            h.compressed = boolean(*f);
        if (const Field* f = find({"CompressedDataSize"})) {
            h.compressed_size = integer(*f);
            if (h.compressed_size < 0)
                fail("CompressedDataSize is negative");
        }
        if (const Field* f = find({"HeaderSize"})) {
            h.header_size = integer(*f);
            if (h.header_size < -1)
                fail("HeaderSize = " + std::to_string(h.header_size) + " (must be -1 or >= 0)");
        }
        if (h.compressed && !h.binary)
            fail("CompressedData = True needs BinaryData = True");

        const Field* df = find({"ElementDataFile"});
        const std::string& file = df->value;
        if (file.empty())
            fail("ElementDataFile is empty");
        if (lower(file) == "local") {
            h.local = true;
            h.data_offset = data_offset_;
        } else if (lower(file).rfind("list", 0) == 0 || file.find('%') != std::string::npos) {
            fail("ElementDataFile = " + detail::printable(file, 60) +
                 " (a list of files or a file-name pattern) is not supported; convert to a single data file");
        } else {
            h.local = false;
            std::filesystem::path p(file);
            h.data_file = p.is_absolute() ? p : name_.parent_path() / p;
        }
    }

    std::string_view text_;
    std::filesystem::path name_;
    std::vector<Field> fields_;
    std::size_t data_offset_ = 0;
};

std::size_t file_size_or_throw(const std::filesystem::path& p, const std::string& role)
{
    std::error_code ec;
    if (!std::filesystem::exists(p, ec))
        throw IoError(p.string() + ": " + role + " does not exist");
    if (std::filesystem::is_directory(p, ec))
        throw IoError(p.string() + ": " + role + " is a directory, not a file");
    const auto size = std::filesystem::file_size(p, ec);
    if (ec)
        throw IoError(p.string() + ": cannot read " + role + ": " + ec.message());
    return static_cast<std::size_t>(size);
}

// Reads `count` bytes from `p` starting at `offset`.
std::string read_bytes(const std::filesystem::path& p, std::size_t offset, std::size_t count)
{
    std::ifstream in(p, std::ios::binary);
    if (!in)
        throw IoError(p.string() + ": cannot open for reading");
    in.seekg(static_cast<std::streamoff>(offset));
    std::string buf(count, '\0');
    in.read(buf.data(), static_cast<std::streamsize>(count));
    if (static_cast<std::size_t>(in.gcount()) != count)
        throw IoError(p.string() + ": read " + std::to_string(in.gcount()) + " of " + std::to_string(count) +
                      " bytes");
    return buf;
}

std::string describe(const MetaImageHeader& h)
{
    const auto& s = h.geometry.size;
    std::string d = "DimSize " + std::to_string(s[0]) + " x " + std::to_string(s[1]);
    if (h.ndims == 3)
        d += " x " + std::to_string(s[2]);
    d += std::string(", ") + element_type_name(h.pixel_type);
    if (h.channels > 1)
        d += ", " + std::to_string(h.channels) + " channels";
    return d;
}

std::size_t payload_bytes(const MetaImageHeader& h)
{
    return h.geometry.voxel_count() * static_cast<std::size_t>(h.channels) *
           static_cast<std::size_t>(core::pixel_size(h.pixel_type));
}

std::string inflate_payload(std::string_view compressed, std::size_t expected, const std::string& where)
{
    if (static_cast<double>(expected) > detail::kMaxDeflateRatio * static_cast<double>(compressed.size()) + 1024.0)
        throw InvalidInputError(where + ": " + std::to_string(compressed.size()) +
                                " bytes of compressed data cannot hold the " + std::to_string(expected) +
                                " bytes the header describes");
    std::string out(expected, '\0');
    z_stream zs{};
    // 15 + 32: accept both zlib and gzip wrappers (MetaIO writes zlib; some tools gzip).
    if (inflateInit2(&zs, 15 + 32) != Z_OK)
        throw IoError(where + ": cannot initialise zlib");
    // zlib counts in uInt: feed input and output in pieces so that > 4 GiB payloads work.
    constexpr std::size_t kStep = std::size_t(1) << 30;
    std::size_t in_pos = 0, out_pos = 0;
    unsigned char probe = 0; // one byte past the end: catches streams longer than the header says
    int rc = Z_OK;
    for (;;) {
        if (zs.avail_in == 0 && in_pos < compressed.size()) {
            const std::size_t n = std::min(compressed.size() - in_pos, kStep);
            zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(compressed.data() + in_pos));
            zs.avail_in = static_cast<uInt>(n);
            in_pos += n;
        }
        if (zs.avail_out == 0) {
            if (out_pos < expected) {
                const std::size_t n = std::min(expected - out_pos, kStep);
                zs.next_out = reinterpret_cast<Bytef*>(out.data() + out_pos);
                zs.avail_out = static_cast<uInt>(n);
                out_pos += n;
            } else {
                zs.next_out = &probe;
                zs.avail_out = 1;
            }
        }
        rc = inflate(&zs, Z_NO_FLUSH);
        if (rc == Z_STREAM_END || zs.total_out > expected)
            break;
        if (rc == Z_BUF_ERROR && zs.avail_in == 0 && in_pos == compressed.size())
            break; // input exhausted before the stream ended
        if (rc != Z_OK && rc != Z_BUF_ERROR)
            break;
    }
    const std::size_t produced = static_cast<std::size_t>(zs.total_out);
    const std::string msg = zs.msg ? zs.msg : "zlib error " + std::to_string(rc);
    inflateEnd(&zs);
    if (produced > expected)
        throw InvalidInputError(where + ": the compressed data holds more than the " + std::to_string(expected) +
                                " bytes the header describes");
    if (rc != Z_STREAM_END && rc != Z_OK && rc != Z_BUF_ERROR)
        throw InvalidInputError(where + ": corrupt compressed data (" + msg + ")");
    if (produced != expected)
        throw IoError(where + ": compressed data is truncated: it decompresses to " + std::to_string(produced) +
                      " bytes, the header describes " + std::to_string(expected));
    return out;
}

// A vector holding `image`, moved in: `return {image}` would copy it (initializer lists are const).
std::vector<core::AnyImage> one(core::AnyImage&& image)
{
    std::vector<core::AnyImage> v;
    v.push_back(std::move(image));
    return v;
}

template <class V>
void swap_bytes(V& v)
{
    using T = typename V::value_type;
    for (auto& x : v) {
        unsigned char b[sizeof(T)];
        std::memcpy(b, &x, sizeof(T));
        std::reverse(b, b + sizeof(T));
        std::memcpy(&x, b, sizeof(T));
    }
}

// Splits interleaved channel data into one image per channel.
template <class T>
std::vector<core::AnyImage> split_channels(const MetaImageHeader& h, const T* values)
{
    const std::size_t n = h.geometry.voxel_count();
    const auto c = static_cast<std::size_t>(h.channels);
    std::vector<core::AnyImage> out;
    for (std::size_t ch = 0; ch < c; ++ch) {
        core::Image3D<T> img(h.geometry);
        for (std::size_t i = 0; i < n; ++i)
            img.data[i] = values[i * c + ch];
        out.emplace_back(std::move(img));
    }
    return out;
}

// The decoded values as one image, or one image per channel.
template <class T>
std::vector<core::AnyImage> to_images(const MetaImageHeader& h, core::BigVector<T>&& values)
{
    if (h.channels > 1)
        return split_channels(h, values.data());
    core::Image3D<T> img;
    static_cast<core::ImageGeometry&>(img) = h.geometry;
    img.data = std::move(values);
    return one(core::AnyImage(std::move(img)));
}

template <class T>
std::vector<core::AnyImage> decode_typed(const MetaImageHeader& h, std::string_view bytes)
{
    core::BigVector<T> values(h.geometry.voxel_count() * static_cast<std::size_t>(h.channels));
    std::memcpy(values.data(), bytes.data(), values.size() * sizeof(T));
    if (sizeof(T) > 1 && h.big_endian != host_is_big_endian())
        swap_bytes(values);
    return to_images(h, std::move(values));
}

template <class T>
std::vector<core::AnyImage> decode_ascii(const MetaImageHeader& h, std::string_view text, const std::string& where)
{
    const std::size_t count = h.geometry.voxel_count() * static_cast<std::size_t>(h.channels);
    core::BigVector<T> values;
    values.reserve(std::min<std::size_t>(count, text.size() / 2 + 1));
    const char* p = text.data();
    const char* e = p + text.size();
    while (values.size() < count) {
        while (p < e && std::isspace(static_cast<unsigned char>(*p)))
            ++p;
        if (p == e)
            throw IoError(where + ": ASCII data is truncated: " + std::to_string(values.size()) + " of " +
                          std::to_string(count) + " values");
        double v = 0;
        const auto r = std::from_chars(p, e, v);
        if (r.ec != std::errc())
            throw InvalidInputError(where + ": ASCII data value " + std::to_string(values.size()) + " is not a number");
        values.push_back(core::saturate_cast<T>(v));
        p = r.ptr;
    }
    return to_images(h, std::move(values));
}

template <template <class> class F, class... Args>
auto dispatch(PixelType t, Args&&... args)
{
    switch (t) {
    case PixelType::UInt8: return F<std::uint8_t>{}(std::forward<Args>(args)...);
    case PixelType::Int8: return F<std::int8_t>{}(std::forward<Args>(args)...);
    case PixelType::Int16: return F<std::int16_t>{}(std::forward<Args>(args)...);
    case PixelType::UInt16: return F<std::uint16_t>{}(std::forward<Args>(args)...);
    case PixelType::Int32: return F<std::int32_t>{}(std::forward<Args>(args)...);
    case PixelType::UInt32: return F<std::uint32_t>{}(std::forward<Args>(args)...);
    case PixelType::Float32: return F<float>{}(std::forward<Args>(args)...);
    case PixelType::Float64: return F<double>{}(std::forward<Args>(args)...);
    }
    throw InvalidInputError("unknown pixel type");
}

template <class T>
struct DecodeBinary {
    std::vector<core::AnyImage> operator()(const MetaImageHeader& h, std::string_view bytes) const
    {
        return decode_typed<T>(h, bytes);
    }
};
template <class T>
struct DecodeAscii {
    std::vector<core::AnyImage> operator()(const MetaImageHeader& h, std::string_view text, const std::string& where) const
    {
        return decode_ascii<T>(h, text, where);
    }
};

// Decodes the data bytes that follow the header (or the whole data file), whatever their
// encoding. `where` names the file holding them.
std::vector<core::AnyImage> decode_payload(const MetaImageHeader& h, std::string_view data, const std::string& where)
{
    if (!h.binary)
        return dispatch<DecodeAscii>(h.pixel_type, h, data, where);

    const std::size_t expected = payload_bytes(h);
    if (h.compressed) {
        std::string_view z = data;
        if (h.compressed_size >= 0) {
            if (static_cast<std::size_t>(h.compressed_size) > data.size())
                throw IoError(where + ": truncated: CompressedDataSize is " + std::to_string(h.compressed_size) +
                              " bytes but only " + std::to_string(data.size()) + " follow");
            z = data.substr(0, static_cast<std::size_t>(h.compressed_size));
        }
        const std::string raw = inflate_payload(z, expected, where);
        return dispatch<DecodeBinary>(h.pixel_type, h, std::string_view(raw));
    }
    if (data.size() < expected)
        throw IoError(where + ": truncated: " + std::to_string(data.size()) + " bytes of data, the header (" +
                      describe(h) + ") needs " + std::to_string(expected));
    if (data.size() > expected && h.header_size != -1)
        throw InvalidInputError(where + ": " + std::to_string(data.size()) + " bytes of data, but the header (" +
                                describe(h) + ") describes " + std::to_string(expected) +
                                ": the header and the data disagree");
    // HeaderSize = -1: the data is the last `expected` bytes.
    return dispatch<DecodeBinary>(h.pixel_type, h, data.substr(data.size() - expected));
}

// Reads the header text of a file: everything up to and including the ElementDataFile line,
// reading more only while needed so that a large .mha is not read twice.
std::string read_header_text(const std::filesystem::path& path)
{
    file_size_or_throw(path, "MetaImage header");
    std::ifstream in(path, std::ios::binary);
    if (!in)
        throw IoError(path.string() + ": cannot open for reading");
    std::string text;
    std::array<char, 4096> buf{};
    while (text.size() < kMaxHeaderBytes) {
        in.read(buf.data(), buf.size());
        const auto got = static_cast<std::size_t>(in.gcount());
        if (got == 0)
            break;
        text.append(buf.data(), got);
        // Stop once the ElementDataFile line is complete.
        const auto k = lower(text).find("elementdatafile");
        if (k != std::string::npos && text.find('\n', k) != std::string::npos)
            break;
    }
    return text;
}

// Reads uncompressed single-channel binary data straight into the image: no intermediate
// buffer, so reading costs little more than the file read itself (docs/benchmarks.md).
core::AnyImage read_raw_direct(const MetaImageHeader& h, const std::filesystem::path& file, std::size_t begin)
{
    core::AnyImage image = core::make_image(h.pixel_type, h.geometry);
    std::visit(
        [&](auto& im) {
            using T = typename std::decay_t<decltype(im)>::value_type;
            std::ifstream in(file, std::ios::binary);
            if (!in)
                throw IoError(file.string() + ": cannot open for reading");
            in.seekg(static_cast<std::streamoff>(begin));
            const auto n = static_cast<std::streamsize>(im.data.size() * sizeof(T));
            in.read(reinterpret_cast<char*>(im.data.data()), n);
            if (in.gcount() != n)
                throw IoError(file.string() + ": read " + std::to_string(in.gcount()) + " of " + std::to_string(n) +
                              " bytes");
            if (sizeof(T) > 1 && h.big_endian != host_is_big_endian())
                swap_bytes(im.data);
        },
        image);
    return image;
}

std::vector<core::AnyImage> read_all(const std::filesystem::path& path)
{
    const std::string text = read_header_text(path);
    const MetaImageHeader h = parse_metaimage_header(text, path);
    // Where the data lies: after the header (LOCAL) or in its own file, after HeaderSize bytes.
    const std::filesystem::path& file = h.local ? path : h.data_file;
    const std::size_t total = h.local ? file_size_or_throw(path, "MetaImage file")
                                      : file_size_or_throw(h.data_file, "data file (ElementDataFile of " +
                                                                            path.string() + ")");
    const std::size_t begin = (h.local ? h.data_offset : 0) + static_cast<std::size_t>(std::max<std::int64_t>(h.header_size, 0));
    if (begin > total)
        throw IoError(file.string() + ": truncated: no data after the header (HeaderSize " +
                      std::to_string(h.header_size) + ")");
    const std::size_t count = total - begin;
    if (h.binary && !h.compressed) {
        // Sizes are checked before a byte of data is read or allocated.
        const std::size_t expected = payload_bytes(h);
        const std::string header_name = h.local ? "the header" : "the header " + path.filename().string();
        if (count < expected)
            throw IoError(file.string() + ": truncated: " + std::to_string(count) + " bytes of data, " + header_name +
                          " (" + describe(h) + ") needs " + std::to_string(expected));
        if (count > expected && h.header_size != -1)
            throw InvalidInputError(file.string() + ": " + std::to_string(count) + " bytes of data, but " + header_name +
                                    " (" + describe(h) + ") describes " + std::to_string(expected) +
                                    ": the header and the data disagree");
        if (h.channels == 1) // HeaderSize = -1: the data is the last `expected` bytes
            return one(read_raw_direct(h, file, begin + count - expected));
    }
    return decode_payload(h, read_bytes(file, begin, count), file.string());
}

// --- writing -----------------------------------------------------------------------------------

// The ITK orientation code of the nearest axis-aligned orientation ("RAI" for identity in LPS).
std::string orientation_code(const core::ImageGeometry& g, int ndims)
{
    std::string code;
    for (int a = 0; a < ndims; ++a) {
        const core::Vec3 ax = g.axis(a);
        int best = 0;
        for (int c = 1; c < 3; ++c)
            if (std::abs(ax[c]) > std::abs(ax[best]))
                best = c;
        static const char pos[3] = {'R', 'A', 'I'};
        static const char neg[3] = {'L', 'P', 'S'};
        code += ax[best] >= 0 ? pos[best] : neg[best];
    }
    return code;
}

int choose_ndims(const core::ImageGeometry& g, int requested)
{
    if (requested == 2 || requested == 3)
        return requested;
    if (requested != 0)
        throw InvalidInputError("write_metaimage: ndims must be 0, 2 or 3, not " + std::to_string(requested));
    const bool planar = g.size[2] == 1 && g.origin[2] == 0.0 && g.direction[2] == 0.0 && g.direction[5] == 0.0 &&
                        g.direction[6] == 0.0 && g.direction[7] == 0.0 && g.direction[8] == 1.0 && g.spacing[2] == 1.0;
    return planar ? 2 : 3;
}

std::string join_numbers(const double* v, int n)
{
    std::string s;
    for (int i = 0; i < n; ++i) {
        if (i)
            s += ' ';
        s += detail::format_number(v[i]);
    }
    return s;
}

// The image's bytes in little-endian order: a view of the pixels themselves on a little-endian
// host (no copy of a 40 MiB CT), else a byte-swapped copy held in `swapped`.
std::string_view payload_of(const core::AnyImage& image, std::string& swapped)
{
    return std::visit(
        [&swapped](const auto& im) {
            using T = typename std::decay_t<decltype(im)>::value_type;
            const std::string_view bytes(reinterpret_cast<const char*>(im.data.data()), im.data.size() * sizeof(T));
            if (sizeof(T) == 1 || !host_is_big_endian())
                return bytes;
            swapped.assign(bytes);
            for (std::size_t i = 0; i < swapped.size(); i += sizeof(T))
                std::reverse(swapped.begin() + static_cast<std::ptrdiff_t>(i),
                             swapped.begin() + static_cast<std::ptrdiff_t>(i + sizeof(T)));
            return std::string_view(swapped);
        },
        image);
}

std::string deflate_payload(std::string_view raw, int level, const std::string& where)
{
    if (level < 1 || level > 9)
        throw InvalidInputError(where + ": compression_level must be 1..9, not " + std::to_string(level));
    z_stream zs{};
    if (deflateInit(&zs, level) != Z_OK)
        throw IoError(where + ": cannot initialise zlib");
    std::string out;
    std::array<char, 1 << 16> buf{};
    std::size_t in_left = raw.size();
    zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(raw.data()));
    constexpr std::size_t kStep = std::size_t(1) << 30;
    int rc = Z_OK;
    do {
        if (zs.avail_in == 0 && in_left > 0) {
            zs.avail_in = static_cast<uInt>(std::min(in_left, kStep));
            in_left -= zs.avail_in;
        }
        zs.next_out = reinterpret_cast<Bytef*>(buf.data());
        zs.avail_out = static_cast<uInt>(buf.size());
        rc = deflate(&zs, in_left == 0 ? Z_FINISH : Z_NO_FLUSH);
        out.append(buf.data(), buf.size() - zs.avail_out);
    } while (rc == Z_OK || rc == Z_BUF_ERROR);
    deflateEnd(&zs);
    if (rc != Z_STREAM_END)
        throw IoError(where + ": zlib compression failed");
    return out;
}

void write_file(const std::filesystem::path& p, std::string_view a, std::string_view b = {})
{
    std::ofstream out(p, std::ios::binary | std::ios::trunc);
    if (!out)
        throw IoError(p.string() + ": cannot open for writing");
    out.write(a.data(), static_cast<std::streamsize>(a.size()));
    out.write(b.data(), static_cast<std::streamsize>(b.size()));
    out.flush();
    if (!out)
        throw IoError(p.string() + ": write failed (disk full?)");
}

} // namespace

MetaImageHeader parse_metaimage_header(std::string_view text, const std::filesystem::path& name)
{
    return HeaderParser(text, name).parse();
}

MetaImageHeader read_metaimage_header(const std::filesystem::path& path)
{
    const std::string text = read_header_text(path);
    return parse_metaimage_header(text, path);
}

std::vector<core::AnyImage> read_metaimage_channels(const std::filesystem::path& path)
{
    return read_all(path);
}

core::AnyImage read_metaimage(const std::filesystem::path& path)
{
    auto channels = read_all(path);
    if (channels.size() != 1)
        throw InvalidInputError(path.string() + ": has ElementNumberOfChannels = " + std::to_string(channels.size()) +
                                "; read it with read_metaimage_channels");
    return std::move(channels.front());
}

std::vector<core::AnyImage> decode_metaimage(std::string_view bytes, const std::filesystem::path& name)
{
    const MetaImageHeader h = parse_metaimage_header(bytes, name);
    if (!h.local)
        throw InvalidInputError(name.string() + ": decode_metaimage needs ElementDataFile = LOCAL");
    std::size_t begin = h.data_offset + static_cast<std::size_t>(std::max<std::int64_t>(h.header_size, 0));
    if (begin > bytes.size())
        throw IoError(name.string() + ": truncated: no data after the header");
    return decode_payload(h, bytes.substr(begin), name.string());
}

void write_metaimage(const std::filesystem::path& path, const core::AnyImage& image, const MetaImageWriteParams& params)
{
    const std::string ext = lower(path.extension().string());
    if (ext != ".mha" && ext != ".mhd")
        throw InvalidInputError(path.string() + ": a MetaImage file name must end in .mha or .mhd");
    const core::ImageGeometry& g = core::geometry(image);
    core::validate_geometry(g, path.string());
    if (std::visit([](const auto& im) { return im.data.size(); }, image) != g.voxel_count())
        throw InvalidInputError(path.string() + ": the image holds " +
                                std::to_string(std::visit([](const auto& im) { return im.data.size(); }, image)) +
                                " values for " + std::to_string(g.voxel_count()) + " voxels");
    const int n = choose_ndims(g, params.ndims);
    if (n == 2 && g.size[2] != 1)
        throw InvalidInputError(path.string() + ": cannot write a 2-D MetaImage of an image with " +
                                std::to_string(g.size[2]) + " slices");

    std::string swapped, compressed;
    std::string_view payload = payload_of(image, swapped);
    if (params.compress) {
        compressed = deflate_payload(payload, params.compression_level, path.string());
        payload = compressed;
    }

    double dir[9];
    for (int r = 0; r < n; ++r) // axis r, component c (see the reader)
        for (int c = 0; c < n; ++c)
            dir[r * n + c] = g.direction[static_cast<std::size_t>(c * 3 + r)];
    double size_d[3], zero[3] = {0, 0, 0};
    for (int a = 0; a < 3; ++a)
        size_d[a] = g.size[a];

    std::ostringstream hdr;
    hdr << "ObjectType = Image\n"
        << "NDims = " << n << "\n"
        << "BinaryData = True\n"
        << "BinaryDataByteOrderMSB = False\n"
        << "CompressedData = " << (params.compress ? "True" : "False") << "\n";
    if (params.compress)
        hdr << "CompressedDataSize = " << payload.size() << "\n";
    hdr << "TransformMatrix = " << join_numbers(dir, n * n) << "\n"
        << "Offset = " << join_numbers(g.origin.data(), n) << "\n"
        << "CenterOfRotation = " << join_numbers(zero, n) << "\n"
        << "AnatomicalOrientation = " << orientation_code(g, n) << "\n"
        << "ElementSpacing = " << join_numbers(g.spacing.data(), n) << "\n"
        << "DimSize = " << join_numbers(size_d, n) << "\n"
        << "ElementType = " << element_type_name(core::pixel_type(image)) << "\n";

    if (ext == ".mha") {
        hdr << "ElementDataFile = LOCAL\n";
        detail::AtomicOutput out(path);
        write_file(out.temp_path(), hdr.str(), payload);
        out.commit();
        return;
    }
    std::filesystem::path data_path = path;
    data_path.replace_extension(params.compress ? ".zraw" : ".raw");
    hdr << "ElementDataFile = " << data_path.filename().string() << "\n";
    detail::AtomicOutput data_out(data_path);
    detail::AtomicOutput header_out(path);
    write_file(data_out.temp_path(), payload);
    write_file(header_out.temp_path(), hdr.str());
    data_out.commit(); // data first: a header never points at a missing data file
    header_out.commit();
}

} // namespace lobe::io
