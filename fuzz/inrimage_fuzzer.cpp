// Feeds arbitrary bytes to the INRIMAGE-4 reader (its header parser, byte orders, gzip) as an
// .inr file, or an .inr.gz when they start with gzip's magic. Any lobe::core::Error is a correct
// rejection; a crash, a sanitizer report, a leak or an allocation beyond libFuzzer's
// -rss_limit_mb is a bug.
#include "lobe/io/inrimage.h"

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <unistd.h>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const bool gz = size >= 2 && data[0] == 0x1f && data[1] == 0x8b;
    static const std::string base = "/dev/shm/lobe-inr-fuzz-" + std::to_string(::getpid());
    const std::string path = base + (gz ? ".inr.gz" : ".inr");
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f)
        return 0;
    std::fwrite(data, 1, size, f);
    std::fclose(f);
    try {
        const auto image = lobe::io::read_inrimage(path);
        (void)image;
    } catch (const lobe::core::Error&) {
    }
    std::remove(path.c_str());
    return 0;
}
