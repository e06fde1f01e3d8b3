#pragma once
// What the lseg tool tests share: running lseg, and reading a provenance parameter back.

#include "lobe/io/hdf5.h"

#include "common/run_tool.h"

#include <filesystem>
#include <string>

namespace lobe::test {

inline ToolRun run_lseg(const std::string& args, const std::filesystem::path& scratch)
{
    return run_tool(LSEG_EXE, args, scratch);
}

//! The value recorded for `key` in a provenance record ("" if none).
inline std::string parameter(const io::Provenance& p, const std::string& key)
{
    for (const auto& [k, v] : p.parameters)
        if (k == key)
            return v;
    return {};
}

} // namespace lobe::test
