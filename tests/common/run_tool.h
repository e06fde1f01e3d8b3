#pragma once
// Runs a tool as a child process and captures its exit code, stdout and stderr.

#include "common/test_data.h"

#include <cstdlib>
#include <filesystem>
#include <string>
#include <sys/wait.h>

namespace lobe::test {

struct ToolRun {
    int exit_code = -1;
    std::string out;
    std::string err;
};

inline std::string shell_quote(const std::string& s)
{
    std::string q = "'";
    for (char c : s) {
        if (c == '\'') q += "'\\''";
        else q += c;
    }
    return q + "'";
}

//! A path, quoted for the shell.
inline std::string q(const std::filesystem::path& p) { return shell_quote(p.string()); }

//! Runs `exe args...` (already quoted by the caller where needed) with stdout and stderr in
//! temporary files beside `scratch`.
inline ToolRun run_tool(const std::string& exe, const std::string& args, const std::filesystem::path& scratch)
{
    const auto out = scratch / "stdout.txt";
    const auto err = scratch / "stderr.txt";
    const std::string cmd = shell_quote(exe) + " " + args + " >" + shell_quote(out.string()) + " 2>" +
                            shell_quote(err.string());
    const int status = std::system(cmd.c_str());
    ToolRun r;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = read_file(out);
    r.err = read_file(err);
    return r;
}

} // namespace lobe::test
