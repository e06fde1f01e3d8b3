// Uses one function of each installed library and checks that they agree on the version.
#include "lobe/core/image3d.h"
#include "lobe/io/metaimage.h"
#include "lobe/mesh/version.h"
#include "lobe/mss/version.h"
#include "lobe/seg/version.h"

#include <cstdio>
#include <cstring>
#include <filesystem>

int main(int argc, char** argv)
{
    if (std::strcmp(lobe::seg::version(), lobe::mesh::version()) != 0 ||
        std::strcmp(lobe::seg::version(), lobe::mss::version()) != 0)
        return 1;
    // Round-trip a tiny image through the installed libio.
    lobe::core::ImageGeometry g;
    g.size = {3, 2, 2};
    lobe::core::Image3D<short> img(g, 7);
    const std::filesystem::path out = argc > 1 ? argv[1] : "downstream.mha";
    lobe::io::write_metaimage(out, img);
    const auto back = lobe::io::read_metaimage(out);
    const auto& s = std::get<lobe::core::Image3D<short>>(back);
    std::printf("lobe %s: read back %zu voxels\n", lobe::seg::version(), s.data.size());
    return s.data == img.data ? 0 : 2;
}
