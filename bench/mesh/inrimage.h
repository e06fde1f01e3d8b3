#pragma once
// INRIMAGE-4 reader for the benchmark's labelled liver (CGAL's Mesh_3 example data): a text
// header of 256-byte blocks ("#INRIMAGE-4#{" ... "##}") then raw voxels, x fastest, optionally
// gzipped. Only what that file needs: scalar unsigned 8-bit data.

#include "lobe/core/errors.h"
#include "lobe/core/image3d.h"

#include <zlib.h>

#include <filesystem>
#include <map>
#include <sstream>
#include <string>

namespace lobe::bench {

inline core::LabelImage3D read_inrimage(const std::filesystem::path& path)
{
    gzFile f = gzopen(path.string().c_str(), "rb");
    if (!f)
        throw core::IoError(path.string() + ": cannot open");
    std::string header;
    char block[256];
    while (header.find("##}") == std::string::npos) {
        if (gzread(f, block, 256) != 256) {
            gzclose(f);
            throw core::InvalidInputError(path.string() + ": truncated INRIMAGE header");
        }
        header.append(block, 256);
        if (header.size() > 64 * 256) {
            gzclose(f);
            throw core::InvalidInputError(path.string() + ": no end of INRIMAGE header");
        }
    }
    if (header.rfind("#INRIMAGE-4#{", 0) != 0) {
        gzclose(f);
        throw core::InvalidInputError(path.string() + ": not an INRIMAGE-4 file");
    }
    std::map<std::string, std::string> kv;
    std::istringstream lines(header);
    for (std::string line; std::getline(lines, line);) {
        const auto eq = line.find('=');
        if (eq != std::string::npos)
            kv[line.substr(0, eq)] = line.substr(eq + 1);
    }
    auto num = [&](const std::string& k, double def) { return kv.count(k) ? std::stod(kv[k]) : def; };
    core::ImageGeometry g;
    g.size = {static_cast<int>(num("XDIM", 0)), static_cast<int>(num("YDIM", 0)), static_cast<int>(num("ZDIM", 0))};
    g.spacing = {num("VX", 1), num("VY", 1), num("VZ", 1)};
    if (num("VDIM", 1) != 1 || kv["TYPE"] != "unsigned fixed" || kv["PIXSIZE"].rfind("8 bits", 0) != 0 ||
        g.size[0] <= 0 || g.size[1] <= 0 || g.size[2] <= 0 || g.voxel_count() > (std::size_t{1} << 31)) {
        gzclose(f);
        throw core::InvalidInputError(path.string() + ": only scalar unsigned 8-bit INRIMAGEs of sane size are read");
    }
    core::LabelImage3D img(g, 0);
    const auto n = static_cast<unsigned>(img.data.size());
    const int got = gzread(f, img.data.data(), n);
    gzclose(f);
    if (got != static_cast<int>(n))
        throw core::InvalidInputError(path.string() + ": truncated INRIMAGE data");
    return img;
}

} // namespace lobe::bench
