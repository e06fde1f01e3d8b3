// INRIMAGE-4 reading through zlib's gz* calls, which read plain and gzipped files alike.
#include "lobe/io/inrimage.h"

#include "lobe/core/errors.h"
#include "lobe/io/limits.h"

#include "detail/checks.h"

#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <sstream>
#include <string>

namespace lobe::io {

namespace {

struct GzCloser {
    void operator()(gzFile_s* f) const { gzclose(f); }
};

// The file must be able to hold what the header promises before anything is allocated: a plain
// file its bytes after the header, a gzipped one no more than deflate can expand to (a 400-byte
// file claiming 10^9 voxels would otherwise cost gigabytes; found by fuzz/inrimage_fuzzer).
void check_data_size(gzFile f, const std::filesystem::path& path, std::size_t header_bytes, std::size_t data_bytes)
{
    std::error_code ec;
    const std::uintmax_t file = std::filesystem::file_size(path, ec);
    if (ec)
        return; // not a regular file (a pipe): the reads below find a truncation
    const std::string what = "the header promises " + std::to_string(data_bytes) + " bytes of voxels";
    if (gzdirect(f)) {
        const std::uintmax_t have = file > header_bytes ? file - header_bytes : 0;
        if (have < data_bytes)
            throw core::InvalidInputError(path.string() + ": truncated INRIMAGE data: " + what + " but the file holds " +
                                          std::to_string(have) + " after its header");
    } else if (static_cast<double>(data_bytes + header_bytes) > static_cast<double>(file) * detail::kMaxDeflateRatio) {
        throw core::InvalidInputError(path.string() + ": truncated or corrupt INRIMAGE: " + what + " but a gzip stream of " +
                                      std::to_string(file) + " bytes cannot expand to that many");
    }
}

template <class T>
core::AnyImage read_voxels(gzFile f, const core::ImageGeometry& g, bool swap, const std::filesystem::path& path,
                           std::size_t header_bytes)
{
    const std::string name = path.string();
    check_data_size(f, path, header_bytes, g.voxel_count() * sizeof(T));
    core::Image3D<T> img(g, T{});
    const std::size_t bytes = img.data.size() * sizeof(T);
    // gzread takes an unsigned count: read in chunks below 1 GiB.
    auto* out = reinterpret_cast<unsigned char*>(img.data.data());
    for (std::size_t done = 0; done < bytes;) {
        const auto chunk = static_cast<unsigned>(std::min<std::size_t>(bytes - done, std::size_t{1} << 30));
        const int got = gzread(f, out + done, chunk);
        if (got <= 0)
            throw core::InvalidInputError(name + ": truncated INRIMAGE data (" + std::to_string(done) + " of " +
                                          std::to_string(bytes) + " bytes)");
        done += static_cast<std::size_t>(got);
    }
    if (swap && sizeof(T) > 1)
        for (auto& v : img.data) {
            auto* b = reinterpret_cast<unsigned char*>(&v);
            std::reverse(b, b + sizeof(T));
        }
    return img;
}

} // namespace

core::AnyImage read_inrimage(const std::filesystem::path& path)
{
    const std::string name = path.string();
    std::unique_ptr<gzFile_s, GzCloser> f(gzopen(name.c_str(), "rb"));
    if (!f)
        throw core::IoError(name + ": cannot open");
    std::string header;
    char block[256];
    while (header.find("##}") == std::string::npos) {
        if (gzread(f.get(), block, sizeof block) != static_cast<int>(sizeof block))
            throw core::InvalidInputError(name + ": truncated INRIMAGE header");
        header.append(block, sizeof block);
        if (header.rfind("#INRIMAGE-4#{", 0) != 0)
            throw core::InvalidInputError(name + ": not an INRIMAGE-4 file (no \"#INRIMAGE-4#{\" at its start)");
        if (header.size() > 64 * sizeof block)
            throw core::InvalidInputError(name + ": no end of the INRIMAGE header (\"##}\") in 16 KiB");
    }
    std::map<std::string, std::string> kv;
    std::istringstream lines(header);
    for (std::string line; std::getline(lines, line);)
        if (const auto eq = line.find('='); eq != std::string::npos)
            kv[line.substr(0, eq)] = line.substr(eq + 1);
    auto number = [&](const std::string& key, double fallback) {
        const auto it = kv.find(key);
        if (it == kv.end())
            return fallback;
        try {
            return std::stod(it->second);
        } catch (const std::exception&) {
            throw core::InvalidInputError(name + ": INRIMAGE " + key + "=" + it->second + " is not a number");
        }
    };
    core::ImageGeometry g;
    for (int a = 0; a < 3; ++a) {
        const double n = number(std::string(1, static_cast<char>('X' + a)) + "DIM", 0);
        if (!(n >= 1 && n <= static_cast<double>(kMaxVoxels)))
            throw core::InvalidInputError(name + ": INRIMAGE " + std::string(1, static_cast<char>('X' + a)) +
                                          "DIM missing or out of range");
        g.size[static_cast<std::size_t>(a)] = static_cast<int>(n);
        const double s = number(std::string("V") + static_cast<char>('X' + a), 1);
        if (!(s > 0))
            throw core::InvalidInputError(name + ": INRIMAGE voxel size V" + std::string(1, static_cast<char>('X' + a)) +
                                          " must be positive");
        g.spacing[static_cast<std::size_t>(a)] = s;
    }
    if (number("VDIM", 1) != 1)
        throw core::InvalidInputError(name + ": a vector INRIMAGE (VDIM=" + kv["VDIM"] + "); only scalar images are read");
    if (g.voxel_count() > kMaxVoxels)
        throw core::InvalidInputError(name + ": INRIMAGE of " + std::to_string(g.voxel_count()) + " voxels, above the limit");
    const std::string type = kv["TYPE"], cpu = kv.count("CPU") ? kv["CPU"] : "decm";
    const int bits = static_cast<int>(number("PIXSIZE", 8)); // "8 bits": stod stops at the space
    bool big;
    if (cpu == "decm" || cpu == "pc" || cpu == "alpha")
        big = false;
    else if (cpu == "sun" || cpu == "sgi")
        big = true;
    else
        throw core::InvalidInputError(name + ": unknown INRIMAGE byte order CPU=" + cpu);
    const bool swap = big != (__BYTE_ORDER__ == __ORDER_BIG_ENDIAN__);
    gzFile in = f.get();
    if (type == "unsigned fixed") {
        if (bits == 8)
            return read_voxels<std::uint8_t>(in, g, swap, path, header.size());
        if (bits == 16)
            return read_voxels<std::uint16_t>(in, g, swap, path, header.size());
        if (bits == 32)
            return read_voxels<std::uint32_t>(in, g, swap, path, header.size());
    } else if (type == "signed fixed") {
        if (bits == 8)
            return read_voxels<std::int8_t>(in, g, swap, path, header.size());
        if (bits == 16)
            return read_voxels<std::int16_t>(in, g, swap, path, header.size());
        if (bits == 32)
            return read_voxels<std::int32_t>(in, g, swap, path, header.size());
    } else if (type == "float") {
        if (bits == 32)
            return read_voxels<float>(in, g, swap, path, header.size());
        if (bits == 64)
            return read_voxels<double>(in, g, swap, path, header.size());
    }
    throw core::InvalidInputError(name + ": unsupported INRIMAGE pixel type TYPE=" + type +
                                  " PIXSIZE=" + std::to_string(bits) + " bits");
}

} // namespace lobe::io
