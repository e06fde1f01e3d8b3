#pragma once
// Local numbering of a tet's faces and edges, and the packed keys the edit tables use.

#include <algorithm>
#include <array>
#include <cstdint>

namespace lobe::mss::detail {

// Outward faces of a positively oriented tet (a, b, c, d): d lies on the side of face (a, b, c)
// its normal (b - a) x (c - a) points to, so that face is listed reversed.
inline constexpr int kTetFaces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
inline constexpr int kTetEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};

inline std::uint64_t edge_key(std::int32_t a, std::int32_t b)
{
    if (a > b)
        std::swap(a, b);
    return (std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b);
}
inline std::int32_t edge_first(std::uint64_t key) { return std::int32_t(key >> 32); }
inline std::int32_t edge_second(std::uint64_t key) { return std::int32_t(key & 0xffffffffu); }

// Faces pack three sorted 21-bit vertex indices (Model::enable_editing checks the count).
inline constexpr std::int32_t kMaxEditableVertices = (1 << 21) - 1;
inline std::uint64_t face_key(std::int32_t a, std::int32_t b, std::int32_t c)
{
    std::array<std::int32_t, 3> v{a, b, c};
    std::sort(v.begin(), v.end());
    return (std::uint64_t(v[0]) << 42) | (std::uint64_t(v[1]) << 21) | std::uint64_t(v[2]);
}

} // namespace lobe::mss::detail
