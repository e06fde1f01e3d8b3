// Feeds arbitrary bytes to the NIfTI-1 reader: lobe's checks in front of nifti_clib's header
// parser and znzlib's gzip I/O. The bytes are a .nii file, or a .nii.gz when they start with
// gzip's magic. Every volume of a series is asked for through NiftiReadParams::volume. Any
// lobe::core::Error is a correct rejection; a crash, a sanitizer report, a leak or an
// allocation beyond libFuzzer's -rss_limit_mb is a bug.
#include "lobe/io/nifti.h"

#include "shm_input.h"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const std::string path =
        lobe::fuzz::shm_input(data, size, "nifti", lobe::fuzz::starts_gzip(data, size) ? ".nii.gz" : ".nii");
    if (path.empty())
        return 0;
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
