#pragma once
// Plumbing every lobe tool shares: exit codes, error reporting, progress on stderr, timings and
// the provenance (parameters, timings) each tool records in the files it writes.

#include "lobe/io/hdf5.h"

#include <CLI/CLI.hpp>

#include <chrono>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace lobe::tools {

//! Exit codes shared by every tool (docs/architecture.md).
enum ExitCode : int {
    kExitOk = 0,
    kExitUsage = 1,     //!< bad command line
    kExitInput = 2,     //!< unreadable or invalid input, or an output that cannot be written
    kExitAlgorithm = 3, //!< a method failed (e.g. did not converge where it must)
    kExitInternal = 4,  //!< an unexpected exception: a bug
};

//! Runs a tool's body and turns every exception into a one-line message on stderr, prefixed
//! by the tool's name, and the matching exit code. CLI11's --help and parse errors go
//! through CLI::App::exit.
int run_tool(CLI::App& app, int argc, char** argv, const std::function<int()>& body);

//! Adds the options every tool has: --quiet and --version.
void add_common_options(CLI::App& app, bool& quiet);


//! Progress and status lines on stderr, silenced by --quiet.
class Progress {
public:
    Progress(std::string tool, bool quiet) : tool_(std::move(tool)), quiet_(quiet) {}
    void message(const std::string& text) const;
    bool quiet() const { return quiet_; }

private:
    std::string tool_;
    bool quiet_;
};

//! Named wall-clock timings in seconds, in the order they were taken.
class Timings {
public:
    //! Runs `step`, records how long it took under `name`, and returns what it returned.
    template <class F>
    auto time(const std::string& name, F&& step)
    {
        const auto t0 = std::chrono::steady_clock::now();
        if constexpr (std::is_void_v<decltype(step())>) {
            step();
            record(name, t0);
        } else {
            auto r = step();
            record(name, t0);
            return r;
        }
    }
    const std::vector<std::pair<std::string, double>>& entries() const { return entries_; }
    double total() const;

private:
    void record(const std::string& name, std::chrono::steady_clock::time_point t0)
    {
        entries_.emplace_back(name, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    std::vector<std::pair<std::string, double>> entries_;
};

//! What a run records in the files it writes (docs/file-format.md, /provenance): the tool,
//! version, command line, start time, the value of every option (given or default) and the
//! timings. Construct it at the start of main; call provenance() when writing.
class RunRecord {
public:
    RunRecord(const CLI::App& app, int argc, char** argv);

    //! The record, with options read from the (parsed) app now. Options of the subcommand that
    //! ran are prefixed with its name ("convert.type"); positional arguments keep their name.
    io::Provenance provenance() const;

    Timings timings;

private:
    const CLI::App& app_;
    std::string command_line_;
    std::string started_;
};

} // namespace lobe::tools
