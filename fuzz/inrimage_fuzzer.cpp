// Feeds arbitrary bytes to the INRIMAGE-4 reader (its header parser, byte orders, gzip) as an
// .inr file, or an .inr.gz when they start with gzip's magic. Any lobe::core::Error is a correct
// rejection; a crash, a sanitizer report, a leak or an allocation beyond libFuzzer's
// -rss_limit_mb is a bug.
#include "lobe/io/inrimage.h"

#include "shm_input.h"

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const std::string path =
        lobe::fuzz::shm_input(data, size, "inr", lobe::fuzz::starts_gzip(data, size) ? ".inr.gz" : ".inr");
    if (path.empty())
        return 0;
    try {
        const auto image = lobe::io::read_inrimage(path);
        (void)image;
    } catch (const lobe::core::Error&) {
    }
    std::remove(path.c_str());
    return 0;
}
