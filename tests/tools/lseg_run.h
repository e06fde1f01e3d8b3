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

//! The first figure named `key` ("dice", "asd_mm", ...) in `lseg eval --json` output; -1 if
//! there is none.
inline double figure_from_eval(const std::string& out, const std::string& key)
{
    const auto at = out.find("\"" + key + "\"");
    return at == std::string::npos ? -1.0 : std::stod(out.substr(out.find(':', at) + 1));
}

//! The "dice" figure of `lseg eval --json` output; -1 if there is none.
inline double dice_from_eval(const std::string& out)
{
    return figure_from_eval(out, "dice");
}

} // namespace lobe::test
