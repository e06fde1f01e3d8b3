// Feeds arbitrary text to lsim's scene parser (tools/lsim/scene.cpp): sections, keys, numbers,
// vectors, instrument paths. Any lobe::core::Error is a correct rejection ("file:line: ...");
// a crash, a sanitizer report or a leak is a bug.
#include "lsim/scene.h"

#include "lobe/core/errors.h"

#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const std::string text(reinterpret_cast<const char*>(data), size);
    try {
        const auto scene = lobe::lsim::parse_scene(text, "fuzz.scene");
        (void)scene;
    } catch (const lobe::core::Error&) {
    }
    return 0;
}
