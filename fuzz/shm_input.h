#pragma once
// The file readers take paths: each fuzz input is written to /dev/shm (memory), under a name of
// this process with the reader's extension.

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <unistd.h>

namespace lobe::fuzz {

//! Whether the bytes start with gzip's magic (the readers pick gzip by the name's ".gz").
inline bool starts_gzip(const std::uint8_t* data, std::size_t size)
{
    return size >= 2 && data[0] == 0x1f && data[1] == 0x8b;
}

//! Writes the input to /dev/shm/lobe-TAG-fuzz-PID EXTENSION; "" if it cannot.
inline std::string shm_input(const std::uint8_t* data, std::size_t size, const std::string& tag,
                             const std::string& extension)
{
    const std::string path = "/dev/shm/lobe-" + tag + "-fuzz-" + std::to_string(::getpid()) + extension;
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f)
        return {};
    std::fwrite(data, 1, size, f);
    std::fclose(f);
    return path;
}

} // namespace lobe::fuzz
