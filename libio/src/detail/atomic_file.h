#pragma once
// Writers never leave a half-written file: they write to a temporary sibling and rename it into
// place only once everything is written (rename is atomic within one filesystem).

#include "lobe/core/errors.h"

#include <atomic>
#include <filesystem>
#include <string>
#include <system_error>
#include <unistd.h>

namespace lobe::io::detail {

class AtomicOutput {
public:
    //! The temporary keeps the final name as its suffix, so libraries that choose a format
    //! from the extension (assimp, nifti's .nii.gz) still see it.
    explicit AtomicOutput(std::filesystem::path final_path) : final_(std::move(final_path))
    {
        static std::atomic<unsigned> counter{0};
        const auto dir = final_.has_parent_path() ? final_.parent_path() : std::filesystem::path(".");
        std::error_code ec;
        if (!std::filesystem::is_directory(dir, ec))
            throw core::IoError(final_.string() + ": cannot write: directory '" + dir.string() +
                                "' does not exist");
        temp_ = dir / (".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++) + "-" +
                       final_.filename().string());
    }
    AtomicOutput(const AtomicOutput&) = delete;
    AtomicOutput& operator=(const AtomicOutput&) = delete;
    ~AtomicOutput()
    {
        if (!committed_) {
            std::error_code ec;
            std::filesystem::remove(temp_, ec);
        }
    }

    const std::filesystem::path& temp_path() const { return temp_; }
    const std::filesystem::path& final_path() const { return final_; }

    //! Moves the finished temporary into place. \throw core::IoError if the rename fails.
    void commit()
    {
        std::error_code ec;
        std::filesystem::rename(temp_, final_, ec);
        if (ec)
            throw core::IoError(final_.string() + ": cannot move the finished file into place: " + ec.message());
        committed_ = true;
    }

private:
    std::filesystem::path final_;
    std::filesystem::path temp_;
    bool committed_ = false;
};

} // namespace lobe::io::detail
