// Feeds arbitrary bytes to the DICOM reader as a one-file series. GDCM as Debian builds it keeps
// its assert()s, so a malformed file that reached GDCM unchecked would abort: the reader's own
// structural check must turn every such file into a lobe::core::Error.
#include "lobe/io/dicom.h"

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <unistd.h>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    // The reader takes files; /dev/shm keeps them in memory.
    static const std::string path = "/dev/shm/lobe-dicom-fuzz-" + std::to_string(::getpid()) + ".dcm";
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f)
        return 0;
    std::fwrite(data, 1, size, f);
    std::fclose(f);
    try {
        const auto series = lobe::io::read_dicom_files({path});
        (void)series;
    } catch (const lobe::core::Error&) {
    }
    return 0;
}
