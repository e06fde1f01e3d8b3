#pragma once
// Small text helpers the header parsers and writers share.

#include <array>
#include <cctype>
#include <charconv>
#include <string>
#include <string_view>

namespace lobe::io::detail {

inline std::string trim(std::string_view s)
{
    std::size_t b = 0, e = s.size();
    while (b < e && std::isspace(static_cast<unsigned char>(s[b])))
        ++b;
    while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1])))
        --e;
    return std::string(s.substr(b, e - b));
}

//! At most `max` characters of `s`, non-printable bytes shown as '?', for error messages about
//! files that may be binary garbage.
inline std::string printable(std::string_view s, std::size_t max)
{
    std::string out;
    for (std::size_t i = 0; i < s.size() && i < max; ++i) {
        const auto c = static_cast<unsigned char>(s[i]);
        out += std::isprint(c) ? static_cast<char>(c) : '?';
    }
    if (s.size() > max)
        out += "...";
    return out;
}

//! The shortest decimal text that reads back as exactly `v` (so geometry round-trips bit-exact).
inline std::string format_number(double v)
{
    std::array<char, 64> buf{};
    const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), v);
    return std::string(buf.data(), r.ptr);
}

} // namespace lobe::io::detail
