#include "common/cli.h"

#include "lobe/core/errors.h"

#include <cstdio>
#include <iostream>
#include <new>
#include <numeric>

namespace lobe::tools {

int run_tool(CLI::App& app, int argc, char** argv, const std::function<int()>& body)
{
    const std::string name = app.get_name();
    // CLI11 prints help, version and usage errors itself; its own exit codes (105, 106, ...)
    // collapse to ours so that every usage error is 1.
    const auto usage = [&app](const CLI::ParseError& e) {
        const int rc = app.exit(e);
        return rc == 0 ? static_cast<int>(kExitOk) : static_cast<int>(kExitUsage);
    };
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return usage(e);
    }
    try {
        return body();
    } catch (const CLI::ParseError& e) {
        return usage(e);
    } catch (const core::InvalidInputError& e) {
        std::cerr << name << ": error: " << e.what() << "\n";
        return kExitInput;
    } catch (const core::IoError& e) {
        std::cerr << name << ": error: " << e.what() << "\n";
        return kExitInput;
    } catch (const core::SolverError& e) {
        std::cerr << name << ": error: " << e.what() << "\n";
        return kExitAlgorithm;
    } catch (const core::Error& e) {
        std::cerr << name << ": error: " << e.what() << "\n";
        return kExitAlgorithm;
    } catch (const std::bad_alloc&) {
        std::cerr << name << ": error: out of memory\n";
        return kExitInternal;
    } catch (const std::exception& e) {
        std::cerr << name << ": internal error: " << e.what() << "\n";
        return kExitInternal;
    }
}

void add_common_options(CLI::App& app, bool& quiet)
{
    app.add_flag("-q,--quiet", quiet, "Print no progress on stderr (errors are still printed)");
    app.set_version_flag("--version", std::string(app.get_name()) + " (lobe) " + LOBE_VERSION_STRING);
}

void Progress::message(const std::string& text) const
{
    if (!quiet_)
        std::cerr << tool_ << ": " << text << std::endl;
}

double Timings::total() const
{
    return std::accumulate(entries_.begin(), entries_.end(), 0.0,
                           [](double acc, const auto& e) { return acc + e.second; });
}

namespace {

// Adds the value of every option of `app` (and of the subcommand that ran) to `out`.
void collect_options(const CLI::App& app, const std::string& prefix,
                     std::vector<std::pair<std::string, std::string>>& out)
{
    for (const CLI::Option* opt : app.get_options()) {
        std::string name = opt->get_name();
        if (name == "--help" || name == "--version")
            continue;
        name.erase(0, name.find_first_not_of('-'));
        std::string value;
        if (opt->count() > 0) {
            for (const auto& r : opt->results())
                value += (value.empty() ? "" : " ") + r;
            if (value.empty() && opt->get_expected_max() == 0)
                value = "true"; // a flag given without a value
        } else if (!opt->get_default_str().empty()) {
            value = opt->get_default_str();
        } else if (opt->get_expected_max() == 0) {
            value = "false"; // a flag not given
        } else {
            continue; // an optional argument not given and without a default
        }
        out.emplace_back(prefix + name, value);
    }
    for (const CLI::App* sub : app.get_subcommands())
        collect_options(*sub, prefix + sub->get_name() + ".", out);
}

} // namespace

RunRecord::RunRecord(const CLI::App& app, int argc, char** argv)
    : app_(app), command_line_(io::join_command_line(argc, argv)), started_(io::utc_timestamp())
{
}

io::Provenance RunRecord::provenance() const
{
    io::Provenance p;
    p.tool = app_.get_name();
    p.version = LOBE_VERSION_STRING;
    p.command_line = command_line_;
    p.started = started_;
    collect_options(app_, "", p.parameters);
    p.timings = timings.entries();
    return p;
}

} // namespace lobe::tools
