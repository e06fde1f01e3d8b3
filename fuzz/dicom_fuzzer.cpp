// Feeds arbitrary bytes to the DICOM reader as a one-file series. GDCM as Debian builds it keeps
// its assert()s, so a malformed file that reached GDCM unchecked would abort: the reader's own
// structural check must turn every such file into a lobe::core::Error.
#include "lobe/io/dicom.h"

#include "shm_input.h"

#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const std::string path = lobe::fuzz::shm_input(data, size, "dicom", ".dcm");
    if (path.empty())
        return 0;
    try {
        const auto series = lobe::io::read_dicom_files({path});
        (void)series;
    } catch (const lobe::core::Error&) {
    }
    return 0;
}
