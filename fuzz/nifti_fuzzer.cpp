// Feeds arbitrary bytes to the NIfTI-1 reader: lobe's checks in front of nifti_clib's header
// parser and znzlib's gzip I/O. The bytes are a .nii file, or a .nii.gz when they start with
// gzip's magic. Every volume of a series is asked for through NiftiReadParams::volume. Any
// lobe::core::Error is a correct rejection; a crash, a sanitizer report, a leak or an
// allocation beyond libFuzzer's -rss_limit_mb is a bug.
#include "lobe/io/nifti.h"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <unistd.h>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    // The reader takes files; /dev/shm keeps them in memory.
    const bool gz = size >= 2 && data[0] == 0x1f && data[1] == 0x8b;
    static const std::string base = "/dev/shm/lobe-nifti-fuzz-" + std::to_string(::getpid());
    const std::string path = base + (gz ? ".nii.gz" : ".nii");
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f)
        return 0;
    std::fwrite(data, 1, size, f);
    std::fclose(f);
    try {
        const lobe::io::NiftiHeader h = lobe::io::read_nifti_header(path);
        for (int v = 0; v < std::min(h.volumes, 3); ++v) {
            lobe::io::NiftiReadParams params;
            params.volume = v;
            const auto image = lobe::io::read_nifti(path, params);
            (void)image;
        }
    } catch (const lobe::core::Error&) {
    }
    std::remove(path.c_str());
    return 0;
}
