// Feeds arbitrary bytes to the MetaImage reader (header parser, LOCAL data, zlib, ASCII data).
// Any lobe::core::Error is a correct rejection; a crash, a sanitizer report, a leak, or an
// allocation beyond libFuzzer's -rss_limit_mb is a bug.
#include "lobe/io/metaimage.h"

#include <cstddef>
#include <cstdint>
#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const std::string_view bytes(reinterpret_cast<const char*>(data), size);
    try {
        const auto images = lobe::io::decode_metaimage(bytes, "fuzz.mha");
        (void)images;
    } catch (const lobe::core::Error&) {
    }
    return 0;
}
