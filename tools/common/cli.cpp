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
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e);
    }
    try {
        return body();
    } catch (const CLI::ParseError& e) {
        return app.exit(e);
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

std::string command_line(int argc, char** argv)
{
    std::string s;
    for (int i = 0; i < argc; ++i) {
        std::string a = argv[i];
        const bool plain = !a.empty() && a.find_first_of(" \t\n'\"\\$`*?;&|<>()") == std::string::npos;
        if (i) s += ' ';
        if (plain) {
            s += a;
        } else {
            s += '\'';
            for (char c : a) {
                if (c == '\'') s += "'\\''";
                else s += c;
            }
            s += '\'';
        }
    }
    return s;
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

} // namespace lobe::tools
