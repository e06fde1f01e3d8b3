#include "common/files.h"

#include "lobe/core/errors.h"

#include <atomic>
#include <fstream>
#include <string>
#include <system_error>
#include <unistd.h>

namespace lobe::tools {

void write_file_atomically(const std::filesystem::path& path, std::string_view bytes)
{
    static std::atomic<unsigned> counter{0};
    const auto dir = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
    std::error_code ec;
    if (!std::filesystem::is_directory(dir, ec))
        throw core::IoError(path.string() + ": cannot write: directory '" + dir.string() + "' does not exist");
    const auto temp = dir / (".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++) + "-" +
                             path.filename().string());
    {
        std::ofstream f(temp, std::ios::binary | std::ios::trunc);
        if (f)
            f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
        if (!f || !f.flush()) {
            f.close();
            std::filesystem::remove(temp, ec);
            throw core::IoError(path.string() + ": cannot write (disk full or no permission?)");
        }
    }
    try {
        move_file(temp, path);
    } catch (...) {
        std::filesystem::remove(temp, ec);
        throw;
    }
}

void move_file(const std::filesystem::path& from, const std::filesystem::path& to)
{
    std::error_code ec;
    std::filesystem::rename(from, to, ec);
    if (ec)
        throw core::IoError(to.string() + ": cannot move the finished file into place: " + ec.message());
}

} // namespace lobe::tools
