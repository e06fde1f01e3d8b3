#pragma once
// Atomic file output for the tools' own files (JSON reports, PNGs, staged folders); libio's
// writers do the same for the formats they write.

#include <filesystem>
#include <string_view>

namespace lobe::tools {

//! Writes `bytes` to a temporary sibling of `path` and renames it into place, so a failed run
//! never leaves a half-written file. \throw core::IoError naming the file.
void write_file_atomically(const std::filesystem::path& path, std::string_view bytes);

//! Renames `from` to `to`. \throw core::IoError naming `to`.
void move_file(const std::filesystem::path& from, const std::filesystem::path& to);

} // namespace lobe::tools
