#pragma once
// Where the tests find real files, and a scratch folder per test.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace lobe::test {

//! ../shared/data (or $LOBE_DATA_DIR): real scans, never copied into the repository.
inline std::filesystem::path data_dir()
{
    if (const char* env = std::getenv("LOBE_DATA_DIR"))
        return env;
    return LOBE_DATA_DIR;
}

//! ITK's example images, from Debian's insighttoolkit5-examples package.
inline std::filesystem::path itk_data_dir()
{
    return "/usr/share/doc/insighttoolkit5-examples/examples/Data";
}

//! pydicom's test files, from Debian's python3-pydicom package.
inline std::filesystem::path pydicom_data_dir()
{
    return "/usr/lib/python3/dist-packages/pydicom/data/test_files";
}

//! A fresh, empty folder for one test's outputs (removed and re-created on each call), inside
//! the build tree: two clones tested on one machine never share it, and it goes with the build.
inline std::filesystem::path scratch_dir()
{
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::filesystem::path dir = std::filesystem::path(LOBE_BINARY_DIR) / "test-scratch" /
                                (std::string(info->test_suite_name()) + "." + info->name());
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir;
}

//! The whole content of a file ("" if it cannot be read).
inline std::string read_file(const std::filesystem::path& p)
{
    std::ifstream f(p, std::ios::binary);
    std::stringstream s;
    s << f.rdbuf();
    return s.str();
}

//! The names in a folder, sorted.
inline std::vector<std::string> list_dir(const std::filesystem::path& dir)
{
    std::vector<std::string> v;
    for (const auto& e : std::filesystem::directory_iterator(dir))
        v.push_back(e.path().filename().string());
    std::sort(v.begin(), v.end());
    return v;
}

} // namespace lobe::test

//! Skips the current test with a message when `path` does not exist.
#define LOBE_REQUIRE_PATH(path)                                                                  \
    do {                                                                                         \
        if (!std::filesystem::exists(path))                                                      \
            GTEST_SKIP() << "test data absent: " << (path).string()                              \
                         << " (see ../shared/data/README.md or install-deps.sh)";                \
    } while (0)
