#pragma once
//! \file
//! \brief Command-line helpers shared by the benchmark programs.

#include <sstream>
#include <string>
#include <vector>

namespace lobe::bench {

//! The non-empty items of a comma-separated list ("k50,,k48" -> {"k50", "k48"}).
inline std::vector<std::string> split(const std::string& s)
{
    std::vector<std::string> out;
    std::stringstream ss(s);
    std::string item;
    while (std::getline(ss, item, ','))
        if (!item.empty())
            out.push_back(item);
    return out;
}

} // namespace lobe::bench
