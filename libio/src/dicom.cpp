#include "lobe/io/dicom.h"

#include "detail/checks.h"
#include "lobe/io/limits.h"

#include <gdcmDataElement.h>
#include <gdcmDataSet.h>
#include <gdcmFile.h>
#include <gdcmImage.h>
#include <gdcmItem.h>
#include <gdcmPixelFormat.h>
#include <gdcmReader.h>
#include <gdcmSequenceOfFragments.h>
#include <gdcmSequenceOfItems.h>
#include <gdcmTrace.h>
#include <gdcmTransferSyntax.h>
#include <gdcmUIDs.h>
#include <zlib.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <istream>
#include <limits>
#include <mutex>
#include <optional>
#include <sstream>
#include <streambuf>
#include <system_error>
#include <utility>

namespace lobe::io {
namespace {

namespace fs = std::filesystem;
using core::InvalidInputError;
using core::IoError;
using core::Vec3;

// Tolerances; docs/formats/dicom.md explains each choice.
// Slice positions must lie on the regular grid to within max(0.01 mm, 1% of the spacing):
// 0.01 mm absorbs positions rounded to two decimals (the coarsest scanners write), and 1%
// keeps every slice within a hundredth of a voxel of where the volume puts it.
constexpr double kPositionTolMm = 0.01;
constexpr double kPositionTolRel = 0.01;
// Direction cosines are written with 4-6 decimals; 1e-3 (0.06 degrees) tells real
// differences from rounding.
constexpr double kCosineTol = 1e-3;
// Pixel spacings of slices of one series must agree to 0.1%.
constexpr double kPixelSpacingTolRel = 1e-3;
// Deeper nesting than this is not found in images; refusing it keeps recursion bounded.
constexpr int kMaxNesting = 16;
// A DICOM file larger than this cannot hold an image we accept (kMaxVoxels of 32-bit pixels).
constexpr std::uintmax_t kMaxFileBytes = std::uintmax_t(kMaxVoxels) * 4 + (std::uintmax_t(1) << 26);

const char* const kRtDoseStorage = "1.2.840.10008.5.1.4.1.1.481.2";

std::string tag_name(std::uint16_t group, std::uint16_t element)
{
    char buf[16];
    std::snprintf(buf, sizeof buf, "(%04x,%04x)", unsigned(group), unsigned(element));
    return buf;
}

std::string fmt(double v)
{
    std::ostringstream s;
    s.precision(10);
    s << v;
    return s.str();
}

// A DS value as DICOM writes it: a\b\c.
template <std::size_t N> std::string fmt(const std::array<double, N>& v)
{
    std::string s;
    for (std::size_t i = 0; i < N; ++i)
        s += (i ? "\\" : "") + fmt(v[i]);
    return s;
}

// ---------------------------------------------------------------------------------------------
// GDCM's messages: Debian's GDCM prints warnings and errors on stderr. A library must not, so
// they are captured while we call GDCM and quoted in our exceptions. GDCM's streams are global;
// the mutex keeps two threads from swapping them under each other.

std::recursive_mutex& gdcm_mutex()
{
    static std::recursive_mutex m;
    return m;
}

class GdcmMessages {
  public:
    GdcmMessages()
        : lock_(gdcm_mutex()), warning_(&gdcm::Trace::GetWarningStream()), error_(&gdcm::Trace::GetErrorStream())
    {
        gdcm::Trace::SetWarningStream(text_);
        gdcm::Trace::SetErrorStream(text_);
    }
    ~GdcmMessages()
    {
        gdcm::Trace::SetWarningStream(*warning_);
        gdcm::Trace::SetErrorStream(*error_);
    }
    GdcmMessages(const GdcmMessages&) = delete;
    GdcmMessages& operator=(const GdcmMessages&) = delete;

    // The last non-empty line GDCM wrote, as " (GDCM: ...)", or "" if it wrote nothing.
    std::string last() const
    {
        std::istringstream in(text_.str());
        std::string line, last_line;
        while (std::getline(in, line))
            if (line.find_first_not_of(" \t\r") != std::string::npos)
                last_line = line;
        return last_line.empty() ? std::string() : " (GDCM: " + last_line + ")";
    }

  private:
    std::lock_guard<std::recursive_mutex> lock_;
    std::ostream* warning_;
    std::ostream* error_;
    std::ostringstream text_;
};

// A read-only, seekable stream over bytes in memory, so that GDCM parses exactly the bytes the
// structure check has seen.
class MemoryBuffer : public std::streambuf {
  public:
    explicit MemoryBuffer(std::vector<char>& bytes) { setg(bytes.data(), bytes.data(), bytes.data() + bytes.size()); }

  protected:
    pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode which) override
    {
        if (!(which & std::ios_base::in))
            return pos_type(off_type(-1));
        const off_type size = egptr() - eback();
        const off_type base = dir == std::ios_base::beg ? 0 : dir == std::ios_base::cur ? gptr() - eback() : size;
        const off_type pos = base + off;
        if (pos < 0 || pos > size)
            return pos_type(off_type(-1));
        setg(eback(), eback() + pos, egptr());
        return pos_type(pos);
    }
    pos_type seekpos(pos_type pos, std::ios_base::openmode which) override
    {
        return seekoff(off_type(pos), std::ios_base::beg, which);
    }
};

// ---------------------------------------------------------------------------------------------
// Reading files.

bool has_dicm_marker(const fs::path& path)
{
    std::ifstream f(path, std::ios::binary);
    char buf[132];
    if (!f.read(buf, sizeof buf))
        return false;
    return std::memcmp(buf + 128, "DICM", 4) == 0;
}

std::vector<char> load_bytes(const fs::path& path)
{
    std::error_code ec;
    const auto status = fs::status(path, ec);
    if (!fs::exists(status))
        throw IoError(path.string() + ": does not exist");
    if (fs::is_directory(status))
        throw IoError(path.string() + ": is a folder, not a DICOM file");
    const std::uintmax_t size = fs::file_size(path, ec);
    if (ec)
        throw IoError(path.string() + ": cannot read: " + ec.message());
    if (size > kMaxFileBytes)
        throw IoError(path.string() + ": " + std::to_string(size) + " bytes is larger than any DICOM image lobe reads");
    std::ifstream f(path, std::ios::binary);
    if (!f)
        throw IoError(path.string() + ": cannot open for reading");
    std::vector<char> bytes(static_cast<std::size_t>(size));
    if (!f.read(bytes.data(), static_cast<std::streamsize>(size)))
        throw IoError(path.string() + ": could not read its " + std::to_string(size) + " bytes");
    return bytes;
}

// ---------------------------------------------------------------------------------------------
// Structure check. GDCM 3.0 as Debian builds it keeps its assert()s, and its parser aborts the
// whole process on a file cut inside its header (e.g. MR_small.dcm cut at 1000 bytes fails
// the assertion in FileMetaInformation::ReadCompat), and it reads a file cut inside its pixel
// data without complaint (MR_truncated.dcm decodes, its last rows zero). So before GDCM sees
// a file, this walk over the element lengths checks that every element, item and fragment
// ends inside the file, and the few encoding details GDCM asserts on. It interprets no value;
// GDCM still does all the parsing.

struct Structure {
    std::string transfer_syntax; // (0002,0010), trimmed
    bool pixel_data = false;     // top-level (7FE0,0010) present
    bool float_pixel_data = false;
};

bool dicm_marker(const std::vector<char>& bytes)
{
    return bytes.size() >= 132 && std::memcmp(bytes.data() + 128, "DICM", 4) == 0;
}

class StructureCheck {
  public:
    StructureCheck(const std::vector<char>& bytes, const fs::path& file)
        : data_(reinterpret_cast<const unsigned char*>(bytes.data())), size_(bytes.size()), file_(file)
    {
    }

    // Walks the file; throws core::IoError if an element, item or fragment does not end inside
    // the file (or its item), a delimiter is malformed, or an explicit VR is not one DICOM
    // defines: all cases in which GDCM's parser may abort or read past the data.
    Structure run()
    {
        walk();
        return result_;
    }

  private:
    static constexpr std::uint32_t kUndefined = 0xffffffffu;

    struct Encoding {
        bool big_endian;
        bool explicit_vr;
    };
    struct Element {
        std::uint16_t group = 0, element = 0;
        char vr[2] = {0, 0};
        std::uint32_t length = 0;
        std::size_t value = 0; // offset of the value
    };

    void walk()
    {
        std::size_t pos = 132; // preamble + "DICM", checked by the caller
        // File meta information: group 0002, always explicit VR little endian.
        const Encoding meta{false, true};
        while (size_ - pos >= 4 && u16(pos, meta) == 0x0002) {
            const Element e = element(pos, meta, size_);
            if (e.element == 0x0010 && e.length != kUndefined) {
                std::string ts(reinterpret_cast<const char*>(data_ + e.value), e.length);
                while (!ts.empty() && (ts.back() == '\0' || ts.back() == ' '))
                    ts.pop_back();
                result_.transfer_syntax = ts;
            }
            pos = skip_value(e, meta, size_, 0);
        }
        // GDCM aborts on a file that ends inside or right after its meta information.
        if (size_ - pos < 4)
            overrun(pos, "the data set after the file meta information", 8, size_);
        Encoding enc{false, true};
        if (result_.transfer_syntax == "1.2.840.10008.1.2")
            enc.explicit_vr = false;
        else if (result_.transfer_syntax == "1.2.840.10008.1.2.2")
            enc.big_endian = true;
        else if (result_.transfer_syntax.empty())
            corrupt(132, "the file meta information has no Transfer Syntax UID (0002,0010)");
        else if (result_.transfer_syntax == "1.2.840.10008.1.2.1.99") {
            // Deflated: the data set is a raw deflate stream of explicit VR little endian;
            // the walk runs over its inflated bytes.
            const std::vector<char> inflated = inflate_data_set(pos);
            StructureCheck inner(inflated, file_);
            inner.where_ = " of the inflated data set";
            inner.walk_data_set(0, enc);
            result_.pixel_data = inner.result_.pixel_data;
            result_.float_pixel_data = inner.result_.float_pixel_data;
            return;
        }
        walk_data_set(pos, enc);
    }

    void walk_data_set(std::size_t pos, Encoding enc)
    {
        // 1-3 stray bytes after the last element are ignored, as GDCM ignores them.
        while (size_ - pos >= 4) {
            const Element e = element(pos, enc, size_);
            if (e.group == 0x7fe0 && e.element == 0x0010)
                result_.pixel_data = true;
            if (e.group == 0x7fe0 && (e.element == 0x0008 || e.element == 0x0009))
                result_.float_pixel_data = true;
            pos = skip_value(e, enc, size_, 0);
        }
    }

    std::vector<char> inflate_data_set(std::size_t pos) const
    {
        z_stream zs{};
        if (inflateInit2(&zs, -MAX_WBITS) != Z_OK)
            throw IoError(file_.string() + ": zlib cannot inflate");
        std::vector<char> out;
        zs.next_in = const_cast<Bytef*>(data_ + pos); // zlib's API is not const; it only reads
        zs.avail_in = static_cast<uInt>(std::min<std::size_t>(size_ - pos, std::numeric_limits<uInt>::max()));
        int rc = Z_OK;
        while (rc == Z_OK) {
            if (out.size() >= kMaxFileBytes)
                break;
            const std::size_t done = out.size();
            out.resize(done + (std::size_t(1) << 20));
            zs.next_out = reinterpret_cast<Bytef*>(out.data() + done);
            zs.avail_out = 1u << 20;
            rc = inflate(&zs, Z_NO_FLUSH);
            out.resize(done + (std::size_t(1) << 20) - zs.avail_out);
        }
        inflateEnd(&zs);
        if (rc != Z_STREAM_END)
            throw IoError(file_.string() + ": the deflated data set is " +
                          (rc == Z_BUF_ERROR || rc == Z_OK ? "truncated" : "corrupt") +
                          " (zlib: " + (zs.msg ? zs.msg : "stream does not end") + ")");
        return out;
    }

    std::uint16_t u16(std::size_t at, Encoding enc) const
    {
        return enc.big_endian ? static_cast<std::uint16_t>((data_[at] << 8) | data_[at + 1])
                              : static_cast<std::uint16_t>(data_[at] | (data_[at + 1] << 8));
    }
    std::uint32_t u32(std::size_t at, Encoding enc) const
    {
        const std::uint32_t b0 = data_[at], b1 = data_[at + 1], b2 = data_[at + 2], b3 = data_[at + 3];
        return enc.big_endian ? (b0 << 24) | (b1 << 16) | (b2 << 8) | b3 : b0 | (b1 << 8) | (b2 << 16) | (b3 << 24);
    }

    // `need` bytes from `at` do not fit before `end`: the file is cut (end of file) or an
    // element overruns the item that holds it.
    [[noreturn]] void overrun(std::size_t at, const std::string& what, std::uint64_t need, std::size_t end) const
    {
        if (end == size_)
            throw IoError(file_.string() + ": truncated DICOM file: " + what + " at byte " + std::to_string(at) +
                          where_ + " needs " + std::to_string(need) + " bytes, only " + std::to_string(size_ - at) +
                          " remain (size " + std::to_string(size_) + ")");
        corrupt(at, what + " (" + std::to_string(need) + " bytes) runs past the end of the item holding it");
    }
    [[noreturn]] void corrupt(std::size_t at, const std::string& what) const
    {
        throw IoError(file_.string() + ": corrupt DICOM file at byte " + std::to_string(at) + where_ + ": " + what);
    }

    // The element header at `pos`; its value must end by `end` (end of file or of the
    // enclosing defined-length item).
    Element element(std::size_t pos, Encoding enc, std::size_t end) const
    {
        if (end - pos < 8)
            overrun(pos, "an element header", 8, end);
        Element e;
        e.group = u16(pos, enc);
        e.element = u16(pos + 2, enc);
        const std::string name = "element " + tag_name(e.group, e.element);
        std::size_t header = 8;
        if (e.group == 0xfffe)
            corrupt(pos, "item tag " + tag_name(e.group, e.element) + " outside a sequence");
        if (!enc.explicit_vr) {
            e.length = u32(pos + 4, enc);
        } else {
            e.vr[0] = static_cast<char>(data_[pos + 4]);
            e.vr[1] = static_cast<char>(data_[pos + 5]);
            if (!known_vr(e.vr))
                corrupt(pos, "element " + tag_name(e.group, e.element) + " has no valid VR (bytes " +
                                 hex_byte(data_[pos + 4]) + " " + hex_byte(data_[pos + 5]) +
                                 "): the file is damaged, or mixes explicit and implicit VR, which lobe refuses");
            if (long_form(e.vr)) {
                if (end - pos < 12)
                    overrun(pos, name, 12, end);
                e.length = u32(pos + 8, enc);
                header = 12;
            } else {
                e.length = u16(pos + 6, enc);
            }
        }
        e.value = pos + header;
        if (e.length != kUndefined && e.length > end - e.value)
            overrun(pos, name, header + std::uint64_t(e.length), end);
        return e;
    }

    static bool known_sequence(std::uint16_t g, std::uint16_t e)
    {
        return (g == 0x5200 && (e == 0x9229 || e == 0x9230)) || (g == 0x0020 && (e == 0x9113 || e == 0x9116)) ||
               (g == 0x0028 && (e == 0x9110 || e == 0x9145 || e == 0x3000));
    }

    static std::string hex_byte(unsigned char c)
    {
        char buf[8];
        std::snprintf(buf, sizeof buf, "%02x", unsigned(c));
        return buf;
    }

    // GDCM handles an unknown VR through recovery paths that can abort; refusing it is safer.
    static bool known_vr(const char* vr)
    {
        static const char* const all[] = {"AE", "AS", "AT", "CS", "DA", "DS", "DT", "FD", "FL", "IS", "LO", "LT",
                                          "OB", "OD", "OF", "OL", "OV", "OW", "PN", "SH", "SL", "SQ", "SS", "ST",
                                          "SV", "TM", "UC", "UI", "UL", "UN", "UR", "US", "UT", "UV"};
        for (const char* v : all)
            if (vr[0] == v[0] && vr[1] == v[1])
                return true;
        return false;
    }

    static bool long_form(const char* vr)
    {
        static const char* const forms[] = {"OB", "OD", "OF", "OL", "OV", "OW", "SQ",
                                            "SV", "UC", "UN", "UR", "UT", "UV"};
        for (const char* f : forms)
            if (vr[0] == f[0] && vr[1] == f[1])
                return true;
        return false;
    }

    // Position after element `e`'s value, walking into sequences and encapsulated pixel data.
    std::size_t skip_value(const Element& e, Encoding enc, std::size_t end, int depth) const
    {
        // Implicit VR does not say which values are sequences; the ones this reader looks into
        // are known, and GDCM parses them lazily (GetValueAsSQ), so they are walked too.
        const bool is_sq = enc.explicit_vr ? e.vr[0] == 'S' && e.vr[1] == 'Q' : known_sequence(e.group, e.element);
        const bool is_un = enc.explicit_vr && e.vr[0] == 'U' && e.vr[1] == 'N';
        if (e.length == kUndefined) {
            if (e.group == 0x7fe0 && e.element == 0x0010 && depth == 0) {
                if (enc.explicit_vr && !(e.vr[0] == 'O' && (e.vr[1] == 'B' || e.vr[1] == 'W')) && !is_un)
                    corrupt(e.value - 12, "encapsulated pixel data of VR " + std::string(e.vr, 2)); // GDCM asserts
                return skip_fragments(e.value, enc);
            }
            if (is_sq || !enc.explicit_vr)
                return skip_items(e.value, enc, end, kUndefined, depth + 1);
            if (is_un) // CP-246: an undefined-length UN holds implicit VR little endian items
                return skip_items(e.value, Encoding{false, false}, end, kUndefined, depth + 1);
            corrupt(e.value - 12, "element " + tag_name(e.group, e.element) + " of VR " + std::string(e.vr, 2) +
                                      " has an undefined length");
        }
        if (is_sq)
            skip_items(e.value, enc, e.value + e.length, e.length, depth + 1);
        return e.value + e.length;
    }

    // Items of a sequence starting at `pos`: up to the sequence delimiter (undefined length) or
    // exactly `length` bytes.
    std::size_t skip_items(std::size_t pos, Encoding enc, std::size_t end, std::uint32_t length, int depth) const
    {
        if (depth > kMaxNesting)
            corrupt(pos, "sequences nested deeper than " + std::to_string(kMaxNesting));
        const std::size_t stop = length == kUndefined ? end : pos + length;
        while (length == kUndefined || pos < stop) {
            if (stop - pos < 8)
                overrun(pos, "a sequence item", 8, stop);
            const std::uint16_t g = u16(pos, enc), el = u16(pos + 2, enc);
            const std::uint32_t len = u32(pos + 4, enc);
            if (g == 0xfffe && el == 0xe0dd) {
                if (length != kUndefined || len != 0)
                    corrupt(pos, "misplaced sequence delimiter or one with a length");
                return pos + 8;
            }
            if (g != 0xfffe || el != 0xe000)
                corrupt(pos, "expected an item in a sequence, found " + tag_name(g, el));
            pos += 8;
            if (len == kUndefined) {
                pos = skip_dataset_until_delimiter(pos, enc, stop, depth);
            } else {
                if (len > stop - pos)
                    overrun(pos - 8, "a sequence item", 8 + std::uint64_t(len), stop);
                const std::size_t item_end = pos + len;
                while (pos < item_end)
                    pos = skip_value(element(pos, enc, item_end), enc, item_end, depth);
            }
        }
        return pos;
    }

    std::size_t skip_dataset_until_delimiter(std::size_t pos, Encoding enc, std::size_t end, int depth) const
    {
        for (;;) {
            if (end - pos < 8)
                overrun(pos, "an item", 8, end);
            if (u16(pos, enc) == 0xfffe && u16(pos + 2, enc) == 0xe00d) {
                if (u32(pos + 4, enc) != 0)
                    corrupt(pos, "item delimiter with a length");
                return pos + 8;
            }
            pos = skip_value(element(pos, enc, end), enc, end, depth);
        }
    }

    std::size_t skip_fragments(std::size_t pos, Encoding enc) const
    {
        for (;;) {
            if (size_ - pos < 8)
                overrun(pos, "a pixel data fragment", 8, size_);
            const std::uint16_t g = u16(pos, enc), el = u16(pos + 2, enc);
            const std::uint32_t len = u32(pos + 4, enc);
            if (g == 0xfffe && el == 0xe0dd) {
                if (len != 0) // GDCM asserts on it
                    corrupt(pos, "pixel data sequence delimiter with a length");
                return pos + 8;
            }
            if (g != 0xfffe || el != 0xe000 || len == kUndefined)
                corrupt(pos, "expected a pixel data fragment, found " + tag_name(g, el));
            if (len > size_ - pos - 8)
                overrun(pos, "a pixel data fragment", 8 + std::uint64_t(len), size_);
            pos += 8 + len;
        }
    }

    const unsigned char* data_;
    std::size_t size_;
    const fs::path& file_;
    std::string where_; // after byte offsets in messages
    Structure result_;
};

// ---------------------------------------------------------------------------------------------
// Header values. Text values are read from the element bytes (ASCII VRs are the same in every
// transfer syntax); binary US values GDCM has already put in host byte order.

std::string clean_text(const char* p, std::size_t n)
{
    std::string s(p, n);
    while (!s.empty() && (s.back() == '\0' || s.back() == ' '))
        s.pop_back();
    std::size_t b = 0;
    while (b < s.size() && s[b] == ' ')
        ++b;
    return s.substr(b);
}

std::optional<std::string> text(const gdcm::DataSet& ds, const gdcm::Tag& t)
{
    if (!ds.FindDataElement(t))
        return std::nullopt;
    const gdcm::ByteValue* bv = ds.GetDataElement(t).GetByteValue();
    if (!bv || !bv->GetPointer())
        return std::string();
    return clean_text(bv->GetPointer(), bv->GetLength());
}

std::string text_or_empty(const gdcm::DataSet& ds, const gdcm::Tag& t)
{
    return text(ds, t).value_or(std::string());
}

// The numbers of a DS/IS value ("a\b\c"); nullopt if any part is not a finite number.
std::optional<std::vector<double>> numbers(const std::string& s)
{
    std::vector<double> out;
    std::size_t start = 0;
    while (start <= s.size()) {
        const std::size_t stop = std::min(s.find('\\', start), s.size());
        std::string part = clean_text(s.data() + start, stop - start);
        if (!part.empty() && part[0] == '+')
            part.erase(0, 1);
        double v = 0;
        const auto r = std::from_chars(part.data(), part.data() + part.size(), v);
        if (part.empty() || r.ec != std::errc() || r.ptr != part.data() + part.size() || !std::isfinite(v))
            return std::nullopt;
        out.push_back(v);
        start = stop + 1;
    }
    return out;
}

std::optional<std::uint16_t> us_value(const gdcm::DataSet& ds, const gdcm::Tag& t)
{
    if (!ds.FindDataElement(t))
        return std::nullopt;
    const gdcm::ByteValue* bv = ds.GetDataElement(t).GetByteValue();
    if (!bv || bv->GetLength() < 2)
        return std::nullopt;
    std::uint16_t v = 0;
    std::memcpy(&v, bv->GetPointer(), 2);
    return v;
}

// The items of a sequence. The SmartPointer keeps the sequence alive: GetValueAsSQ may build a
// fresh one from bytes (implicit VR files).
struct Items {
    gdcm::SmartPointer<gdcm::SequenceOfItems> sq;
    std::size_t size() const { return sq ? static_cast<std::size_t>(sq->GetNumberOfItems()) : 0; }
    const gdcm::DataSet& at(std::size_t i) const { return sq->GetItem(i + 1).GetNestedDataSet(); }
};

Items items(const gdcm::DataSet& ds, const gdcm::Tag& t)
{
    Items it;
    if (ds.FindDataElement(t) && !ds.GetDataElement(t).IsEmpty())
        it.sq = ds.GetDataElement(t).GetValueAsSQ();
    return it;
}

// Geometry and rescaling of one frame, as written in its file.
struct FrameInfo {
    std::optional<Vec3> position;                       // ImagePositionPatient [mm]
    std::optional<std::array<double, 6>> orientation;   // ImageOrientationPatient
    std::optional<std::array<double, 2>> pixel_spacing; // PixelSpacing: row spacing, column spacing [mm]
    double slope = 1.0, intercept = 0.0;
};

// One DICOM image file's header.
struct SliceFile {
    fs::path path;
    std::string series_uid, modality, description, series_number, transfer_syntax;
    int rows = 0, columns = 0, frames = 1;
    std::uint16_t bits_allocated = 16, bits_stored = 16, high_bit = 15, pixel_representation = 0;
    std::string photometric;           // MONOCHROME1 or MONOCHROME2
    std::vector<FrameInfo> frame;      // one per frame
    double spacing_between_slices = 0; // (0018,0088), 0 if absent
    double slice_thickness = 0;        // (0018,0050), 0 if absent
    std::string geometry_note;         // how multi-frame positions were found, if not per frame
    std::string problem;               // why lobe cannot read this image (full message), or empty
};

const gdcm::Tag kSeriesUid(0x0020, 0x000e), kModality(0x0008, 0x0060), kDescription(0x0008, 0x103e),
    kSeriesNumber(0x0020, 0x0011), kSopClass(0x0008, 0x0016), kRows(0x0028, 0x0010), kColumns(0x0028, 0x0011),
    kFrames(0x0028, 0x0008), kSamples(0x0028, 0x0002), kPhotometric(0x0028, 0x0004), kBitsAllocated(0x0028, 0x0100),
    kBitsStored(0x0028, 0x0101), kHighBit(0x0028, 0x0102), kPixelRepresentation(0x0028, 0x0103),
    kPosition(0x0020, 0x0032), kOrientation(0x0020, 0x0037), kPixelSpacing(0x0028, 0x0030), kIntercept(0x0028, 0x1052),
    kSlope(0x0028, 0x1053), kSliceThickness(0x0018, 0x0050), kSpacingBetween(0x0018, 0x0088),
    kModalityLut(0x0028, 0x3000), kSharedGroups(0x5200, 0x9229), kPerFrameGroups(0x5200, 0x9230),
    kPlanePosition(0x0020, 0x9113), kPlaneOrientation(0x0020, 0x9116), kPixelMeasures(0x0028, 0x9110),
    kValueTransformation(0x0028, 0x9145), kGridFrameOffsets(0x3004, 0x000c), kDoseGridScaling(0x3004, 0x000e);

// Looks a value up where DICOM allows it: in the frame's functional group macro, in the shared
// one, then at the top level (classic single-frame files).
struct ValueLookup {
    const gdcm::DataSet& top;
    const gdcm::DataSet* shared;   // item of (5200,9229), or null
    const gdcm::DataSet* perframe; // item of (5200,9230) for this frame, or null

    std::optional<std::string> find(const gdcm::Tag& macro, const gdcm::Tag& t) const
    {
        for (const gdcm::DataSet* group : {perframe, shared}) {
            if (!group)
                continue;
            const Items m = items(*group, macro);
            if (m.size() > 0)
                if (auto v = text(m.at(0), t))
                    return v;
        }
        return text(top, t);
    }
};

template <std::size_t N>
std::optional<std::array<double, N>> fixed_numbers(const std::optional<std::string>& s, const fs::path& file,
                                                   const char* name)
{
    if (!s || s->empty())
        return std::nullopt;
    const auto v = numbers(*s);
    if (!v || v->size() != N)
        throw InvalidInputError(file.string() + ": " + name + " '" + *s + "' is not " + std::to_string(N) + " numbers");
    std::array<double, N> a{};
    std::copy(v->begin(), v->end(), a.begin());
    return a;
}

double single_number(const std::optional<std::string>& s, double fallback, const fs::path& file, const char* name)
{
    if (!s || s->empty())
        return fallback;
    const auto v = numbers(*s);
    if (!v || v->empty())
        throw InvalidInputError(file.string() + ": " + name + " '" + *s + "' is not a number");
    return v->front();
}

void parse_image_header(SliceFile& f, const gdcm::DataSet& ds, const Structure& st);

// Reads the header of a file whose structure was checked; nullopt if it is a DICOM file
// without an image (DICOMDIR, structured report, RT plan...).
std::optional<SliceFile> parse_header(const fs::path& path, std::vector<char>& bytes, const Structure& st)
{
    GdcmMessages messages;
    MemoryBuffer buf(bytes);
    std::istream in(&buf);
    gdcm::Reader reader;
    reader.SetStream(in);
    if (!reader.ReadUpToTag(gdcm::Tag(0x7fe0, 0x0010)))
        throw IoError(path.string() + ": GDCM cannot parse this DICOM file" + messages.last());
    const gdcm::DataSet& ds = reader.GetFile().GetDataSet();
    if (!st.pixel_data && !st.float_pixel_data) {
        if (ds.FindDataElement(kRows) || ds.FindDataElement(kColumns)) // cut between two elements
            throw IoError(path.string() + ": has Rows and Columns but no Pixel Data: the file is truncated or "
                                          "incomplete");
        return std::nullopt;
    }

    SliceFile f;
    f.path = path;
    f.transfer_syntax = st.transfer_syntax;
    f.series_uid = text_or_empty(ds, kSeriesUid);
    f.modality = text_or_empty(ds, kModality);
    f.description = text_or_empty(ds, kDescription);
    f.series_number = text_or_empty(ds, kSeriesNumber);
    // Content lobe cannot read is fatal only for the series asked for: a folder often holds a
    // colour dose report beside the CT.
    try {
        parse_image_header(f, ds, st);
    } catch (const InvalidInputError& e) {
        f.problem = e.what();
    }
    return f;
}

void parse_image_header(SliceFile& f, const gdcm::DataSet& ds, const Structure& st)
{
    const fs::path& path = f.path;
    const std::string what = path.string();

    if (st.float_pixel_data)
        throw InvalidInputError(what + ": float pixel data (7fe0,0008/0009) is not supported");
    const auto rows = us_value(ds, kRows), columns = us_value(ds, kColumns);
    if (!rows || !columns || *rows == 0 || *columns == 0)
        throw InvalidInputError(what + ": Rows (0028,0010) and Columns (0028,0011) must be present and positive");
    f.rows = *rows;
    f.columns = *columns;
    if (const auto nf = text(ds, kFrames); nf && !nf->empty()) {
        const auto v = numbers(*nf);
        if (!v || v->size() != 1 || v->front() < 1 || v->front() != std::floor(v->front()) ||
            v->front() > double(kMaxVoxels))
            throw InvalidInputError(what + ": NumberOfFrames '" + *nf + "' is not a positive integer");
        f.frames = static_cast<int>(v->front());
    } else if (ds.FindDataElement(gdcm::Tag(0x0028, 0x0009))) {
        // GDCM asserts on a Frame Increment Pointer without NumberOfFrames (rtdose_1frame.dcm).
        throw InvalidInputError(what + ": has a FrameIncrementPointer (0028,0009) but no NumberOfFrames (0028,0008)");
    }
    detail::checked_voxel_count({f.columns, f.rows, f.frames}, what);

    const auto samples = us_value(ds, kSamples).value_or(1);
    const std::string photometric = text_or_empty(ds, kPhotometric);
    if (samples != 1 || (photometric != "MONOCHROME1" && photometric != "MONOCHROME2"))
        throw InvalidInputError(what + ": colour images are not supported (SamplesPerPixel " + std::to_string(samples) +
                                ", PhotometricInterpretation '" + photometric + "'); lobe reads grey-level CT and MR");
    const auto bits = us_value(ds, kBitsAllocated);
    if (!bits || (*bits != 8 && *bits != 16 && *bits != 32))
        throw InvalidInputError(what + ": BitsAllocated " + (bits ? std::to_string(*bits) : std::string("missing")) +
                                " is not supported (8, 16 or 32)");
    f.bits_allocated = *bits;
    f.bits_stored = us_value(ds, kBitsStored).value_or(*bits);
    f.high_bit = us_value(ds, kHighBit).value_or(static_cast<std::uint16_t>(f.bits_stored - 1));
    f.pixel_representation = us_value(ds, kPixelRepresentation).value_or(0);
    // Pixels stored elsewhere than in the low bits (HighBit above BitsStored - 1) were retired
    // from DICOM; GDCM does not shift them down.
    if (f.bits_stored == 0 || f.bits_stored > f.bits_allocated || f.high_bit + 1 != f.bits_stored ||
        f.pixel_representation > 1)
        throw InvalidInputError(what + ": unsupported pixel cell: BitsAllocated " + std::to_string(f.bits_allocated) +
                                ", BitsStored " + std::to_string(f.bits_stored) + ", HighBit " +
                                std::to_string(f.high_bit) + ", PixelRepresentation " +
                                std::to_string(f.pixel_representation));
    f.photometric = photometric;
    if (ds.FindDataElement(kModalityLut))
        throw InvalidInputError(what + ": has a Modality LUT Sequence (0028,3000), which lobe does not apply; "
                                       "its values would be wrong");

    f.slice_thickness = single_number(text(ds, kSliceThickness), 0.0, path, "SliceThickness");
    f.spacing_between_slices = single_number(text(ds, kSpacingBetween), 0.0, path, "SpacingBetweenSlices");

    const Items shared = items(ds, kSharedGroups);
    const Items perframe = items(ds, kPerFrameGroups);
    if (perframe.size() != 0 && perframe.size() != static_cast<std::size_t>(f.frames))
        throw InvalidInputError(what + ": the Per-frame Functional Groups Sequence has " +
                                std::to_string(perframe.size()) + " items for " + std::to_string(f.frames) + " frames");
    const bool rt_dose = text_or_empty(ds, kSopClass) == kRtDoseStorage;
    f.frame.resize(static_cast<std::size_t>(f.frames));
    for (std::size_t k = 0; k < f.frame.size(); ++k) {
        const ValueLookup look{ds, shared.size() ? &shared.at(0) : nullptr,
                               perframe.size() ? &perframe.at(k) : nullptr};
        FrameInfo& fr = f.frame[k];
        // A multi-frame file's top-level position is its first frame's; the others have their
        // own in the per-frame groups, or are placed below from the first.
        const auto position_text = perframe.size() ? look.find(kPlanePosition, kPosition)
                                   : k == 0        ? text(ds, kPosition)
                                                   : std::nullopt;
        if (const auto p = fixed_numbers<3>(position_text, path, "ImagePositionPatient"))
            fr.position = Vec3{(*p)[0], (*p)[1], (*p)[2]};
        fr.orientation = fixed_numbers<6>(look.find(kPlaneOrientation, kOrientation), path, "ImageOrientationPatient");
        fr.pixel_spacing = fixed_numbers<2>(look.find(kPixelMeasures, kPixelSpacing), path, "PixelSpacing");
        if (fr.pixel_spacing && !((*fr.pixel_spacing)[0] > 0 && (*fr.pixel_spacing)[1] > 0))
            throw InvalidInputError(what + ": PixelSpacing " + fmt(*fr.pixel_spacing) + " is not positive");
        fr.intercept = single_number(look.find(kValueTransformation, kIntercept), 0.0, path, "RescaleIntercept");
        const auto slope_text = look.find(kValueTransformation, kSlope);
        if (slope_text && !slope_text->empty())
            fr.slope = single_number(slope_text, 1.0, path, "RescaleSlope");
        else if (rt_dose) // RT Dose scales its values by DoseGridScaling instead (to Gy)
            fr.slope = single_number(text(ds, kDoseGridScaling), 1.0, path, "DoseGridScaling");
        if (fr.slope == 0.0)
            throw InvalidInputError(what + ": RescaleSlope is 0");
    }

    // Multi-frame files without per-frame positions (RT Dose, NM, GDCM's own 3-D writes) place
    // their frames along the normal from the first position.
    if (f.frames > 1 && f.frame[0].position && f.frame[0].orientation &&
        std::any_of(f.frame.begin() + 1, f.frame.end(), [](const FrameInfo& x) { return !x.position; })) {
        const auto& o = *f.frame[0].orientation;
        const Vec3 normal = core::normalized(core::cross({o[0], o[1], o[2]}, {o[3], o[4], o[5]}));
        std::vector<double> offsets;
        if (const auto g = text(ds, kGridFrameOffsets); g && !g->empty()) {
            const auto v = numbers(*g);
            if (!v || v->size() != f.frame.size())
                throw InvalidInputError(what +
                                        ": GridFrameOffsetVector (3004,000c) does not hold one number per frame");
            // Relative offsets start at 0; absolute ones start at the first frame's z. Both
            // are distances along the normal from the first frame once the first is subtracted.
            for (double x : *v)
                offsets.push_back(x - v->front());
            f.geometry_note = "frame positions from GridFrameOffsetVector";
        } else {
            const double dz = f.spacing_between_slices > 0 ? f.spacing_between_slices : 1.0;
            for (std::size_t k = 0; k < f.frame.size(); ++k)
                offsets.push_back(static_cast<double>(k) * dz);
            f.geometry_note = f.spacing_between_slices > 0
                                  ? "no per-frame positions: frames placed SpacingBetweenSlices apart"
                                  : "no per-frame positions nor SpacingBetweenSlices: frames placed 1 mm apart";
        }
        const Vec3 p0 = *f.frame[0].position;
        for (std::size_t k = 0; k < f.frame.size(); ++k) {
            f.frame[k].position = p0 + normal * offsets[k];
            if (!f.frame[k].orientation)
                f.frame[k].orientation = f.frame[0].orientation;
            if (!f.frame[k].pixel_spacing)
                f.frame[k].pixel_spacing = f.frame[0].pixel_spacing;
        }
    }
}

// Classifies and reads one file's header. Returns nullopt for a file that is not a DICOM image
// (no 'DICM' marker, or DICOM without pixels); throws for a DICOM file that is broken.
std::optional<SliceFile> read_slice_header(const fs::path& path)
{
    if (!has_dicm_marker(path))
        return std::nullopt;
    std::vector<char> bytes = load_bytes(path);
    if (!dicm_marker(bytes))
        return std::nullopt;
    const Structure st = StructureCheck(bytes, path).run();
    return parse_header(path, bytes, st);
}

// ---------------------------------------------------------------------------------------------
// Series: grouping, choosing, checking and sorting.

struct Series {
    std::string uid;
    std::vector<SliceFile> files;
    // Why the series cannot be read (the first file's problem), or empty.
    std::string problem() const
    {
        for (const auto& f : files)
            if (!f.problem.empty())
                return f.problem;
        return {};
    }
    int frames() const
    {
        int n = 0;
        for (const auto& f : files)
            n += f.frames;
        return n;
    }
};

std::vector<Series> group_by_series(std::vector<SliceFile> files)
{
    std::vector<Series> out;
    for (auto& f : files) {
        auto it = std::find_if(out.begin(), out.end(), [&](const Series& s) { return s.uid == f.series_uid; });
        if (it == out.end()) {
            out.push_back({f.series_uid, {}});
            it = out.end() - 1;
        }
        it->files.push_back(std::move(f));
    }
    return out;
}

std::string uid_text(const std::string& uid)
{
    return uid.empty() ? std::string("(no SeriesInstanceUID)") : uid;
}

std::string describe(const Series& s)
{
    const SliceFile& f = s.files.front();
    std::string d = "  " + uid_text(s.uid) + ": " + (f.modality.empty() ? std::string("?") : f.modality);
    if (!f.series_number.empty())
        d += " #" + f.series_number;
    if (!f.description.empty())
        d += " \"" + f.description + "\"";
    d += ", " + std::to_string(s.frames()) + " slices of " + std::to_string(f.columns) + " x " +
         std::to_string(f.rows) + " in " + std::to_string(s.files.size()) + " files";
    if (!s.problem().empty())
        d += " (unreadable: " + s.problem() + ")";
    return d;
}

// The series asked for, or the only readable one; notes name the unreadable ones passed over.
Series choose_series(std::vector<Series> all, const std::string& uid, const std::string& source,
                     std::vector<std::string>& notes)
{
    std::string listing;
    for (const auto& s : all)
        listing += "\n" + describe(s);
    auto chosen = all.end();
    if (!uid.empty()) {
        chosen = std::find_if(all.begin(), all.end(), [&](const Series& s) { return s.uid == uid; });
        if (chosen == all.end())
            throw InvalidInputError(source + ": no series with SeriesInstanceUID " + uid + "; found:" + listing);
    } else {
        const auto readable =
            std::count_if(all.begin(), all.end(), [](const Series& s) { return s.problem().empty(); });
        if (readable > 1)
            throw InvalidInputError(source + ": holds " + std::to_string(readable) +
                                    " DICOM series; choose one by its SeriesInstanceUID (the tools' --series option, "
                                    "DicomReadParams::series_uid):" +
                                    listing);
        chosen = readable == 1
                     ? std::find_if(all.begin(), all.end(), [](const Series& s) { return s.problem().empty(); })
                     : all.begin();
        for (const auto& s : all)
            if (&s != &*chosen)
                notes.push_back(source + ": passed over series " + uid_text(s.uid) + ": " + s.problem());
    }
    if (!chosen->problem().empty())
        throw InvalidInputError(chosen->problem());
    return std::move(*chosen);
}

// One frame of the series, where it comes from and where it goes.
struct FrameRef {
    std::size_t file = 0; // index into Series::files
    int frame = 0;        // frame within the file
    const FrameInfo* info = nullptr;
    double along = 0; // position along the normal [mm]
};

std::string frame_name(const Series& s, const FrameRef& r)
{
    const SliceFile& f = s.files[r.file];
    return f.frames > 1 ? f.path.string() + " frame " + std::to_string(r.frame + 1) : f.path.string();
}

struct Layout {
    core::ImageGeometry geometry;
    std::vector<FrameRef> order; // frames sorted along the normal
    std::vector<std::string> notes;
};

// Checks that the frames form one regular grid and sorts them along the normal.
Layout layout_frames(const Series& s, const std::string& source)
{
    Layout out;
    for (std::size_t i = 0; i < s.files.size(); ++i)
        for (int k = 0; k < s.files[i].frames; ++k)
            out.order.push_back({i, k, &s.files[i].frame[static_cast<std::size_t>(k)], 0.0});
    const SliceFile& first = s.files.front();
    for (const SliceFile& f : s.files) {
        if (f.rows != first.rows || f.columns != first.columns)
            throw InvalidInputError(f.path.string() + ": slice size " + std::to_string(f.columns) + " x " +
                                    std::to_string(f.rows) + " differs from " + first.path.string() + " (" +
                                    std::to_string(first.columns) + " x " + std::to_string(first.rows) +
                                    "); the slices of one series must have one size");
        if (!f.geometry_note.empty())
            out.notes.push_back(f.path.string() + ": " + f.geometry_note);
    }
    const std::size_t n = out.order.size();
    const FrameRef& r0 = out.order.front();
    const FrameInfo& g0 = *r0.info;

    // Geometry a single image may lack (e.g. a secondary capture); a volume may not.
    std::array<double, 6> iop{1, 0, 0, 0, 1, 0};
    std::array<double, 2> ps{1.0, 1.0};
    for (const FrameRef& r : out.order) {
        const char* missing = !r.info->position        ? "ImagePositionPatient (0020,0032)"
                              : !r.info->orientation   ? "ImageOrientationPatient (0020,0037)"
                              : !r.info->pixel_spacing ? "PixelSpacing (0028,0030)"
                                                       : nullptr;
        if (missing && n > 1)
            throw InvalidInputError(frame_name(s, r) + ": " + missing +
                                    " is missing; without it the slices cannot be placed in a volume");
        if (missing)
            out.notes.push_back(frame_name(s, r) + ": " + missing + " missing; " +
                                (r.info->position ? "" : "origin (0,0,0), ") +
                                (r.info->orientation ? "" : "identity direction, ") +
                                (r.info->pixel_spacing ? "" : "1 mm pixels, ") + "assumed");
    }
    if (g0.orientation)
        iop = *g0.orientation;
    if (g0.pixel_spacing)
        ps = *g0.pixel_spacing;

    const Vec3 row_raw{iop[0], iop[1], iop[2]}, col_raw{iop[3], iop[4], iop[5]};
    if (std::abs(core::norm(row_raw) - 1) > kCosineTol || std::abs(core::norm(col_raw) - 1) > kCosineTol ||
        std::abs(core::dot(row_raw, col_raw)) > kCosineTol)
        throw InvalidInputError(frame_name(s, r0) + ": ImageOrientationPatient " + fmt(iop) +
                                " is not two orthogonal unit vectors");
    const Vec3 row = core::normalized(row_raw), col = core::normalized(col_raw);
    const Vec3 normal = core::normalized(core::cross(row, col));

    for (FrameRef& r : out.order) {
        const FrameInfo& g = *r.info;
        if (g.orientation) {
            for (int c = 0; c < 6; ++c)
                if (std::abs((*g.orientation)[static_cast<std::size_t>(c)] - iop[static_cast<std::size_t>(c)]) >
                    kCosineTol)
                    throw InvalidInputError(frame_name(s, r) + ": ImageOrientationPatient " + fmt(*g.orientation) +
                                            " differs from " + frame_name(s, r0) + " (" + fmt(iop) +
                                            "); the slices of one series must share one orientation");
        }
        if (g.pixel_spacing)
            for (std::size_t c = 0; c < 2; ++c)
                if (std::abs((*g.pixel_spacing)[c] - ps[c]) > kPixelSpacingTolRel * ps[c])
                    throw InvalidInputError(frame_name(s, r) + ": PixelSpacing " + fmt(*g.pixel_spacing) +
                                            " differs from " + frame_name(s, r0) + " (" + fmt(ps) + ")");
        r.along = g.position ? core::dot(*g.position, normal) : 0.0;
    }

    // Ties keep the file order, so that the duplicate message names the files as listed.
    std::stable_sort(out.order.begin(), out.order.end(),
                     [](const FrameRef& a, const FrameRef& b) { return a.along < b.along; });

    double dz = 1.0;
    if (n > 1) {
        for (std::size_t k = 1; k < n; ++k)
            if (out.order[k].along - out.order[k - 1].along <= kPositionTolMm)
                throw InvalidInputError(source + ": " + frame_name(s, out.order[k - 1]) + " and " +
                                        frame_name(s, out.order[k]) +
                                        " lie at the same position along the slice normal (" + fmt(out.order[k].along) +
                                        " mm): duplicate slices, e.g. two acquisitions or "
                                        "echoes in one series");
        dz = (out.order.back().along - out.order.front().along) / static_cast<double>(n - 1);
        // Slices must be stacked along the normal; a shift within the plane (gantry tilt)
        // would make the volume sheared, which a direction matrix cannot express.
        const Vec3 p0 = *out.order.front().info->position;
        const double inplane_tol = std::max(kPositionTolMm, kPositionTolRel * std::min(ps[0], ps[1]));
        for (const FrameRef& r : out.order) {
            const Vec3 d = *r.info->position - p0;
            const double shift = core::norm(d - normal * core::dot(d, normal));
            if (shift > inplane_tol)
                throw InvalidInputError(source + ": " + frame_name(s, r) + " is shifted " + fmt(shift) +
                                        " mm within the slice plane from " + frame_name(s, out.order.front()) +
                                        " (tolerance " + fmt(inplane_tol) +
                                        " mm): the slices are not stacked along their normal (gantry tilt?)");
        }
        // Every slice within tol of the regular grid bounds the placement error everywhere.
        const double tol = std::max(kPositionTolMm, kPositionTolRel * dz);
        double worst = 0;
        std::size_t worst_gap = 0;
        bool off_grid = false;
        for (std::size_t k = 0; k < n; ++k) {
            const double dev = out.order[k].along - (out.order.front().along + static_cast<double>(k) * dz);
            off_grid = off_grid || std::abs(dev) > tol;
            if (k > 0) {
                const double gap_dev = std::abs(out.order[k].along - out.order[k - 1].along - dz);
                if (gap_dev > worst) {
                    worst = gap_dev;
                    worst_gap = k;
                }
            }
        }
        if (off_grid)
            throw InvalidInputError(source + ": non-uniform slice spacing: " + frame_name(s, out.order[worst_gap - 1]) +
                                    " and " + frame_name(s, out.order[worst_gap]) + " are " +
                                    fmt(out.order[worst_gap].along - out.order[worst_gap - 1].along) +
                                    " mm apart, the series' mean spacing is " + fmt(dz) + " mm (tolerance " + fmt(tol) +
                                    " mm): a missing slice or a mixed acquisition");
    } else {
        const SliceFile& f = s.files.front();
        dz = f.spacing_between_slices > 0 ? f.spacing_between_slices : f.slice_thickness > 0 ? f.slice_thickness : 1.0;
    }

    core::ImageGeometry& g = out.geometry;
    g.size = {first.columns, first.rows, static_cast<int>(n)};
    // PixelSpacing is (between rows, between columns): x (along a row) is the second value.
    g.spacing = {ps[1], ps[0], dz};
    const FrameInfo& lowest = *out.order.front().info;
    const Vec3 origin = lowest.position ? *lowest.position : Vec3{};
    g.origin = {origin.x, origin.y, origin.z};
    g.direction = {row.x, col.x, normal.x, row.y, col.y, normal.y, row.z, col.z, normal.z};
    core::validate_geometry(g, source);
    return out;
}

// ---------------------------------------------------------------------------------------------
// Pixels.

// Decoded stored values of one file, in GDCM's pixel format.
struct Decoded {
    std::vector<char> bytes;
    gdcm::PixelFormat::ScalarType type = gdcm::PixelFormat::UNKNOWN;
    std::size_t frame_voxels = 0;
};

std::size_t bytes_of(gdcm::PixelFormat::ScalarType t)
{
    switch (t) {
    case gdcm::PixelFormat::UINT8:
    case gdcm::PixelFormat::INT8:
        return 1;
    case gdcm::PixelFormat::UINT16:
    case gdcm::PixelFormat::INT16:
        return 2;
    case gdcm::PixelFormat::UINT32:
    case gdcm::PixelFormat::INT32:
        return 4;
    default:
        return 0;
    }
}

template <class T> T load(const char* p, std::size_t i)
{
    T v;
    std::memcpy(&v, p + i * sizeof(T), sizeof(T));
    return v;
}

// Calls f(index, stored value as int64) for the voxels of one frame.
template <class F> void for_each_stored(const Decoded& d, int frame, F&& f)
{
    const char* p = d.bytes.data() + static_cast<std::size_t>(frame) * d.frame_voxels * bytes_of(d.type);
    const std::size_t n = d.frame_voxels;
    switch (d.type) {
    case gdcm::PixelFormat::UINT8:
        for (std::size_t i = 0; i < n; ++i)
            f(i, std::int64_t{load<std::uint8_t>(p, i)});
        break;
    case gdcm::PixelFormat::INT8:
        for (std::size_t i = 0; i < n; ++i)
            f(i, std::int64_t{load<std::int8_t>(p, i)});
        break;
    case gdcm::PixelFormat::UINT16:
        for (std::size_t i = 0; i < n; ++i)
            f(i, std::int64_t{load<std::uint16_t>(p, i)});
        break;
    case gdcm::PixelFormat::INT16:
        for (std::size_t i = 0; i < n; ++i)
            f(i, std::int64_t{load<std::int16_t>(p, i)});
        break;
    case gdcm::PixelFormat::UINT32:
        for (std::size_t i = 0; i < n; ++i)
            f(i, std::int64_t{load<std::uint32_t>(p, i)});
        break;
    case gdcm::PixelFormat::INT32:
        for (std::size_t i = 0; i < n; ++i)
            f(i, std::int64_t{load<std::int32_t>(p, i)});
        break;
    default:
        break;
    }
}

std::string syntax_name(const std::string& uid)
{
    gdcm::UIDs u;
    if (!uid.empty() && u.SetFromUID(uid.c_str()) && u.GetName())
        return uid + " (" + u.GetName() + ")";
    return uid.empty() ? std::string("unknown transfer syntax") : uid;
}

// Compressed frames: the decoders GDCM calls trust the codestream's own image size, and GDCM
// copies what they return into a buffer sized from Rows and Columns; a codestream that
// disagrees overruns that buffer (J2K: heap corruption) or fails an assertion (JPEG-LS). So
// the few header bytes that give each codestream's size are compared with the DICOM header
// first. The codestreams themselves are left to the decoders.

std::uint32_t be16(const unsigned char* p)
{
    return (std::uint32_t(p[0]) << 8) | p[1];
}
std::uint32_t be32(const unsigned char* p)
{
    return (be16(p) << 16) | be16(p + 2);
}
std::uint32_t le32(const unsigned char* p)
{
    return p[0] | (std::uint32_t(p[1]) << 8) | (std::uint32_t(p[2]) << 16) | (std::uint32_t(p[3]) << 24);
}

enum class Codec { Jpeg, JpegLs, J2k, Rle, Other };

Codec codec_of(const std::string& ts)
{
    const std::string jpeg = "1.2.840.10008.1.2.4.";
    if (ts == "1.2.840.10008.1.2.5")
        return Codec::Rle;
    if (ts.compare(0, jpeg.size(), jpeg) != 0)
        return Codec::Other;
    const std::string n = ts.substr(jpeg.size());
    if (n == "50" || n == "51" || n == "57" || n == "70")
        return Codec::Jpeg;
    if (n == "80" || n == "81")
        return Codec::JpegLs;
    if (n == "90" || n == "91" || n == "92" || n == "93" || n == "201" || n == "202" || n == "203")
        return Codec::J2k;
    return Codec::Other;
}

struct FrameHeader {
    std::uint32_t columns = 0, rows = 0, components = 0, precision = 0;
};

// SOFn / SOF55 of a JPEG or JPEG-LS stream starting with SOI; nullopt if the markers up to the
// start of scan are not back to back with exactly one frame header among them. (libjpeg only
// warns about bytes between markers, and GDCM asserts on any warning.)
std::optional<FrameHeader> jpeg_frame_header(const unsigned char* p, std::size_t n, bool ls)
{
    std::optional<FrameHeader> frame;
    std::size_t pos = 2; // after FF D8
    while (pos + 4 <= n) {
        if (p[pos] != 0xff)
            return std::nullopt;
        const unsigned m = p[pos + 1];
        if (m == 0xff) { // fill byte
            ++pos;
            continue;
        }
        if (m == 0x01 || (m >= 0xd0 && m <= 0xd8)) // markers without a length
            return std::nullopt;                   // (none belongs before the first scan)
        const std::uint32_t len = be16(p + pos + 2);
        if (len < 2 || pos + 2 + len > n)
            return std::nullopt;
        const bool sof = ls ? m == 0xf7 : (m >= 0xc0 && m <= 0xcf && m != 0xc4 && m != 0xc8 && m != 0xcc);
        if (sof) {
            if (frame || len < 8)
                return std::nullopt;
            frame = FrameHeader{be16(p + pos + 7), be16(p + pos + 5), p[pos + 9], p[pos + 4]};
        }
        if (m == 0xda) // start of scan: the entropy-coded data follows
            return frame;
        pos += 2 + len;
    }
    return std::nullopt;
}

// SIZ of a JPEG 2000 codestream (SOC SIZ ...), possibly inside a JP2 file's jp2c box.
std::optional<FrameHeader> j2k_frame_header(const unsigned char* p, std::size_t n)
{
    static const unsigned char jp2[] = {0, 0, 0, 0x0c, 'j', 'P', ' ', ' '};
    if (n >= 8 && std::memcmp(p, jp2, 8) == 0) {
        std::size_t pos = 0;
        while (pos + 8 <= n) {
            std::uint64_t len = be32(p + pos);
            std::size_t header = 8;
            if (len == 1 && pos + 16 <= n) {
                len = (std::uint64_t(be32(p + pos + 8)) << 32) | be32(p + pos + 12);
                header = 16;
            } else if (len == 0) {
                len = n - pos;
            }
            if (std::memcmp(p + pos + 4, "jp2c", 4) == 0)
                return j2k_frame_header(p + pos + header, n - pos - header);
            if (len < header || len > n - pos)
                return std::nullopt;
            pos += static_cast<std::size_t>(len);
        }
        return std::nullopt;
    }
    if (n < 43 || be16(p) != 0xff4f || be16(p + 2) != 0xff51)
        return std::nullopt;
    const std::uint32_t x = be32(p + 8), y = be32(p + 12), x0 = be32(p + 16), y0 = be32(p + 20);
    if (x0 > x || y0 > y)
        return std::nullopt;
    return FrameHeader{x - x0, y - y0, be16(p + 40), (p[42] & 0x7fu) + 1};
}

void check_codestreams(const SliceFile& f, const gdcm::SequenceOfFragments& frags, const std::string& ts)
{
    const Codec codec = codec_of(ts);
    if (codec == Codec::Other)
        return;
    const std::string what = f.path.string() + ": ";
    std::size_t frames_seen = 0;
    for (std::size_t i = 0; i < frags.GetNumberOfFragments(); ++i) {
        const gdcm::ByteValue* bv = frags.GetFragment(static_cast<unsigned>(i)).GetByteValue();
        if (!bv || !bv->GetPointer())
            continue;
        const auto* p = reinterpret_cast<const unsigned char*>(bv->GetPointer());
        const std::size_t n = bv->GetLength();
        if (codec == Codec::Rle) {
            // One fragment per frame, a 64-byte header: segment count (one per byte of a
            // pixel), then offsets that must run forward inside the fragment.
            const std::uint32_t segments = n >= 64 ? le32(p) : 0;
            bool ok = segments == f.bits_allocated / 8u && le32(p + 4) == 64;
            for (std::uint32_t k = 1; ok && k < segments; ++k)
                ok = le32(p + 4 + 4 * k) > le32(p + 4 * k) && le32(p + 4 + 4 * k) < n;
            if (!ok)
                throw IoError(what + "RLE frame " + std::to_string(i + 1) + " has a damaged header");
            ++frames_seen;
            continue;
        }
        std::optional<FrameHeader> h;
        if (codec == Codec::J2k && n >= 4 && (be16(p) == 0xff4f || p[4] == 'j'))
            h = j2k_frame_header(p, n);
        else if (codec != Codec::J2k && n >= 2 && be16(p) == 0xffd8)
            h = jpeg_frame_header(p, n, codec == Codec::JpegLs);
        else
            continue; // the continuation of a frame split over fragments
        if (!h)
            throw IoError(what + "compressed frame in fragment " + std::to_string(i + 1) +
                          " has no readable image header");
        if (h->columns != static_cast<std::uint32_t>(f.columns) || h->rows != static_cast<std::uint32_t>(f.rows) ||
            h->components != 1 || h->precision > f.bits_allocated)
            throw IoError(what + "compressed frame in fragment " + std::to_string(i + 1) + " is " +
                          std::to_string(h->columns) + " x " + std::to_string(h->rows) + " pixels with " +
                          std::to_string(h->components) + " component(s) of " + std::to_string(h->precision) +
                          " bits; the DICOM header says " + std::to_string(f.columns) + " x " + std::to_string(f.rows) +
                          ", one component of at most " + std::to_string(f.bits_allocated) + " bits");
        ++frames_seen;
    }
    // Each frame starts a codestream; fragments that continue one were skipped above.
    if (frames_seen != static_cast<std::size_t>(f.frames))
        throw IoError(what + "the encapsulated pixel data holds " + std::to_string(frames_seen) +
                      " compressed frames for " + std::to_string(f.frames) + " frames");
}

// Decodes the pixels of a file whose header parse_header has read. GDCM's ImageReader would
// also interpret the header, through code full of assert()s on its content (the Debian build
// aborts on, e.g., a stray Recognition Code); the pixel format is already known and checked
// here, so only GDCM's codecs are used: an Image set up from the header, then GetBuffer.
Decoded decode_file(const SliceFile& f)
{
    const std::string what = f.path.string();
    std::vector<char> bytes = load_bytes(f.path);
    if (!dicm_marker(bytes))
        throw IoError(what + ": is no longer a DICOM file");
    const Structure st = StructureCheck(bytes, f.path).run();

    GdcmMessages messages;
    MemoryBuffer buf(bytes);
    std::istream in(&buf);
    gdcm::Reader reader;
    reader.SetStream(in);
    if (!reader.Read())
        throw IoError(what + ": GDCM cannot parse this DICOM file" + messages.last());
    const gdcm::DataSet& ds = reader.GetFile().GetDataSet();
    const gdcm::Tag pixel_tag(0x7fe0, 0x0010);
    if (!ds.FindDataElement(pixel_tag) || ds.GetDataElement(pixel_tag).IsEmpty())
        throw IoError(what + ": has no Pixel Data");
    const gdcm::TransferSyntax& ts = reader.GetFile().GetHeader().GetDataSetTransferSyntax();

    gdcm::Image image;
    image.SetNumberOfDimensions(f.frames > 1 ? 3 : 2);
    image.SetDimension(0, static_cast<unsigned>(f.columns));
    image.SetDimension(1, static_cast<unsigned>(f.rows));
    if (f.frames > 1)
        image.SetDimension(2, static_cast<unsigned>(f.frames));
    image.SetPixelFormat(gdcm::PixelFormat(1, f.bits_allocated, f.bits_stored, f.high_bit, f.pixel_representation));
    image.SetPhotometricInterpretation(f.photometric == "MONOCHROME1" ? gdcm::PhotometricInterpretation::MONOCHROME1
                                                                      : gdcm::PhotometricInterpretation::MONOCHROME2);
    image.SetTransferSyntax(ts);
    image.SetDataElement(ds.GetDataElement(pixel_tag));

    Decoded d;
    d.type = image.GetPixelFormat().GetScalarType();
    d.frame_voxels = static_cast<std::size_t>(f.columns) * static_cast<std::size_t>(f.rows);
    const std::size_t expected = d.frame_voxels * static_cast<std::size_t>(f.frames) * bytes_of(d.type);
    if (bytes_of(d.type) == 0 || image.GetBufferLength() != expected)
        throw InvalidInputError(what + ": unsupported pixel format (" + std::to_string(f.bits_allocated) +
                                " bits allocated)");
    if (!ts.IsEncapsulated()) {
        // Native pixel data shorter than the image (possible in a complete file) would leave
        // the image partly undefined.
        const gdcm::ByteValue* bv = image.GetDataElement().GetByteValue();
        const std::size_t held = bv ? static_cast<std::size_t>(bv->GetLength()) : 0;
        if (held < expected)
            throw IoError(what + ": pixel data holds " + std::to_string(held) + " bytes, " + std::to_string(f.columns) +
                          " x " + std::to_string(f.rows) + " x " + std::to_string(f.frames) + " pixels need " +
                          std::to_string(expected));
    } else if (const gdcm::SequenceOfFragments* frags = image.GetDataElement().GetSequenceOfFragments()) {
        check_codestreams(f, *frags, st.transfer_syntax);
    } else {
        throw IoError(what + ": transfer syntax " + syntax_name(st.transfer_syntax) +
                      " is compressed but the pixel data is not encapsulated");
    }
    d.bytes.resize(expected);
    if (!image.GetBuffer(d.bytes.data()))
        throw IoError(what + ": GDCM cannot decode the pixel data of transfer syntax " +
                      syntax_name(st.transfer_syntax) + messages.last());
    return d;
}

bool integral(double v)
{
    return std::abs(v) < 2147483648.0 && v == std::floor(v);
}

DicomSeries read_series(Series s, const std::string& source, std::vector<std::string> notes)
{
    Layout layout = layout_frames(s, source);
    const core::ImageGeometry& g = layout.geometry;
    detail::checked_voxel_count({g.size[0], g.size[1], g.size[2]}, source);

    std::vector<Decoded> decoded;
    decoded.reserve(s.files.size());
    for (const SliceFile& f : s.files)
        decoded.push_back(decode_file(f));

    // int16 when it holds every value exactly, float32 otherwise (see dicom.md).
    bool fits_int16 = true;
    for (const FrameRef& r : layout.order) {
        const FrameInfo& fr = *r.info;
        if (!integral(fr.slope) || !integral(fr.intercept)) {
            fits_int16 = false;
            break;
        }
        std::int64_t lo = std::numeric_limits<std::int64_t>::max(), hi = std::numeric_limits<std::int64_t>::min();
        for_each_stored(decoded[r.file], r.frame, [&](std::size_t, std::int64_t v) {
            lo = std::min(lo, v);
            hi = std::max(hi, v);
        });
        const auto slope = static_cast<std::int64_t>(fr.slope), intercept = static_cast<std::int64_t>(fr.intercept);
        const std::int64_t a = lo * slope + intercept, b = hi * slope + intercept;
        if (std::min(a, b) < std::numeric_limits<std::int16_t>::min() ||
            std::max(a, b) > std::numeric_limits<std::int16_t>::max()) {
            fits_int16 = false;
            break;
        }
    }

    DicomSeries out;
    const std::size_t slice = static_cast<std::size_t>(g.size[0]) * static_cast<std::size_t>(g.size[1]);
    auto fill = [&](auto& img) {
        using T = typename std::decay_t<decltype(img)>::value_type;
        for (std::size_t k = 0; k < layout.order.size(); ++k) {
            const FrameRef& r = layout.order[k];
            T* dst = img.data.data() + k * slice;
            if constexpr (std::is_integral_v<T>) {
                const auto slope = static_cast<std::int64_t>(r.info->slope),
                           intercept = static_cast<std::int64_t>(r.info->intercept);
                for_each_stored(decoded[r.file], r.frame,
                                [&](std::size_t i, std::int64_t v) { dst[i] = static_cast<T>(v * slope + intercept); });
            } else {
                const double slope = r.info->slope, intercept = r.info->intercept;
                for_each_stored(decoded[r.file], r.frame, [&](std::size_t i, std::int64_t v) {
                    dst[i] = static_cast<T>(static_cast<double>(v) * slope + intercept);
                });
            }
        }
    };
    if (fits_int16) {
        core::Image3D<std::int16_t> img(g);
        fill(img);
        out.image = std::move(img);
    } else {
        core::Image3D<float> img(g);
        fill(img);
        out.image = std::move(img);
    }

    const SliceFile& first = s.files.front();
    out.series_uid = s.uid;
    out.modality = first.modality;
    out.description = first.description;
    for (const FrameRef& r : layout.order)
        if (std::find(out.files.begin(), out.files.end(), s.files[r.file].path) == out.files.end())
            out.files.push_back(s.files[r.file].path);
    out.notes = std::move(notes);
    out.notes.insert(out.notes.end(), layout.notes.begin(), layout.notes.end());
    return out;
}

// The DICOM images of a folder (not its subfolders), in name order; notes name what was skipped.
std::vector<SliceFile> scan_folder(const fs::path& dir, std::vector<std::string>& notes)
{
    std::error_code ec;
    std::vector<fs::path> paths;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
        if (it->is_regular_file(ec))
            paths.push_back(it->path());
    if (ec)
        throw IoError(dir.string() + ": cannot list the folder: " + ec.message());
    std::sort(paths.begin(), paths.end());

    std::vector<SliceFile> files;
    std::vector<std::string> skipped;
    for (const auto& p : paths) {
        if (auto f = read_slice_header(p))
            files.push_back(std::move(*f));
        else
            skipped.push_back(p.filename().string());
    }
    if (files.empty())
        throw IoError(dir.string() + ": no DICOM image files in this folder (" + std::to_string(paths.size()) +
                      " files looked at" + (paths.empty() ? std::string() : ", none a DICOM image") +
                      "; subfolders are not searched)");
    if (!skipped.empty()) {
        std::string list;
        for (std::size_t i = 0; i < skipped.size() && i < 5; ++i)
            list += (i ? ", " : "") + skipped[i];
        if (skipped.size() > 5)
            list += ", ...";
        notes.push_back(dir.string() + ": skipped " + std::to_string(skipped.size()) +
                        " files that are not DICOM images (" + list + ")");
    }
    return files;
}

SliceFile require_image(const fs::path& path)
{
    std::error_code ec;
    if (!fs::exists(path, ec))
        throw IoError(path.string() + ": does not exist");
    if (fs::is_directory(path, ec))
        throw IoError(path.string() + ": is a folder, not a DICOM file");
    if (!has_dicm_marker(path))
        throw IoError(path.string() + ": is not a DICOM file (no 'DICM' marker at byte 128)");
    auto f = read_slice_header(path);
    if (!f)
        throw InvalidInputError(path.string() + ": is a DICOM file without an image (no Pixel Data)");
    return std::move(*f);
}

std::vector<SliceFile> scan(const fs::path& folder_or_file, std::vector<std::string>& notes)
{
    std::error_code ec;
    if (!fs::exists(folder_or_file, ec))
        throw IoError(folder_or_file.string() + ": does not exist");
    if (fs::is_directory(folder_or_file, ec))
        return scan_folder(folder_or_file, notes);
    std::vector<SliceFile> one;
    one.push_back(require_image(folder_or_file));
    return one;
}

} // namespace

std::vector<DicomSeriesInfo> list_dicom_series(const std::filesystem::path& folder_or_file)
{
    std::vector<std::string> notes;
    std::vector<DicomSeriesInfo> out;
    for (Series& s : group_by_series(scan(folder_or_file, notes))) {
        DicomSeriesInfo info;
        const SliceFile& f = s.files.front();
        info.series_uid = s.uid;
        info.modality = f.modality;
        info.description = f.description;
        info.series_number = f.series_number;
        info.slices = s.frames();
        info.size = {f.columns, f.rows};
        info.problem = s.problem();
        for (const SliceFile& x : s.files)
            info.files.push_back(x.path);
        out.push_back(std::move(info));
    }
    return out;
}

DicomSeries read_dicom_series(const std::filesystem::path& folder_or_file, const DicomReadParams& params)
{
    std::vector<std::string> notes;
    std::vector<SliceFile> files = scan(folder_or_file, notes);
    Series s = choose_series(group_by_series(std::move(files)), params.series_uid, folder_or_file.string(), notes);
    return read_series(std::move(s), folder_or_file.string(), std::move(notes));
}

DicomSeries read_dicom_files(const std::vector<std::filesystem::path>& files, const DicomReadParams& params)
{
    if (files.empty())
        throw InvalidInputError("read_dicom_files: the list of files is empty");
    std::vector<SliceFile> headers;
    for (const auto& p : files)
        headers.push_back(require_image(p));
    const std::string source = files.size() == 1
                                   ? files.front().string()
                                   : "the " + std::to_string(files.size()) + " files from " + files.front().string();
    std::vector<std::string> notes;
    Series s = choose_series(group_by_series(std::move(headers)), params.series_uid, source, notes);
    return read_series(std::move(s), source, std::move(notes));
}

} // namespace lobe::io
