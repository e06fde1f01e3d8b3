#pragma once
// Sanity checks shared by the readers, so that a corrupt header never makes a reader allocate
// absurd memory or overflow an index.

#include "lobe/core/errors.h"
#include "lobe/io/limits.h"

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>

namespace lobe::io::detail {

//! deflate cannot expand data by more than about 1032:1; a header claiming more raw bytes per
//! compressed byte is lying, and believing it would make a reader allocate for nothing.
inline constexpr double kMaxDeflateRatio = 1100.0;

//! Product of the dimensions, checked for overflow and against max_voxels.
//! \throw core::InvalidInputError naming `what`.
inline std::size_t checked_voxel_count(const std::array<std::int64_t, 3>& dims, const std::string& what)
{
    std::size_t n = 1;
    for (int a = 0; a < 3; ++a) {
        const std::int64_t d = dims[a];
        if (d <= 0)
            throw core::InvalidInputError(what + ": dimension " + std::to_string(a) + " is " + std::to_string(d) +
                                          " (must be positive)");
        if (static_cast<std::uint64_t>(d) > kMaxVoxels || n > kMaxVoxels / static_cast<std::size_t>(d))
            throw core::InvalidInputError(what + ": dimensions " + std::to_string(dims[0]) + " x " +
                                          std::to_string(dims[1]) + " x " + std::to_string(dims[2]) +
                                          " exceed the limit of " + std::to_string(kMaxVoxels) + " voxels");
        n *= static_cast<std::size_t>(d);
    }
    return n;
}

} // namespace lobe::io::detail
