#include "lobe/core/big_buffer.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <limits>
#include <numeric>
#include <sstream>
#include <string>

using lobe::core::BigBufferAllocator;
using lobe::core::BigVector;

namespace {
constexpr std::size_t kMiB = std::size_t{1} << 20;

std::string read_first_line(const char* path)
{
    std::ifstream in(path);
    std::string line;
    std::getline(in, line);
    return line;
}

//! AnonHugePages [kB] of the mapping that holds address p, from /proc/self/smaps; -1 if not found.
long huge_kb_of_mapping(const void* p)
{
    std::ifstream in("/proc/self/smaps");
    const auto a = reinterpret_cast<std::uintptr_t>(p);
    std::string line;
    bool inside = false;
    while (std::getline(in, line)) {
        std::uintptr_t lo = 0, hi = 0;
        char dash = 0;
        std::istringstream head(line);
        if (head >> std::hex >> lo >> dash >> hi && dash == '-') {
            inside = lo <= a && a < hi;
            continue;
        }
        if (inside && line.rfind("AnonHugePages:", 0) == 0)
            return std::stol(line.substr(14));
    }
    return -1;
}
} // namespace

TEST(BigBuffer, BigBuffersHoldTheirValues)
{
    // 8 MiB of float: above the 4 MiB threshold, so the advice covers its inner pages; the
    // values written through the whole buffer, ends included, read back.
    BigVector<float> v(2 * kMiB, 1.5f);
    v.back() = 2.5f;
    EXPECT_FLOAT_EQ(v.front(), 1.5f);
    EXPECT_FLOAT_EQ(v[v.size() / 2], 1.5f);
    EXPECT_FLOAT_EQ(v.back(), 2.5f);
}

TEST(BigBuffer, GrowingAcrossTheThresholdKeepsTheValues)
{
    // push_back reallocates from small blocks into advised big ones and back again on
    // shrink_to_fit; under ASan a mismatched free or an advice outside the buffer is reported.
    BigVector<std::int32_t> v;
    const std::size_t n = 3 * kMiB / sizeof(std::int32_t) * 2; // 6 MiB
    for (std::size_t i = 0; i < n; ++i)
        v.push_back(static_cast<std::int32_t>(i));
    std::int64_t sum = std::accumulate(v.begin(), v.end(), std::int64_t{0});
    EXPECT_EQ(sum, static_cast<std::int64_t>(n) * static_cast<std::int64_t>(n - 1) / 2);
    v.resize(10);
    v.shrink_to_fit();
    EXPECT_EQ(v.size(), 10u);
    EXPECT_EQ(v[9], 9);
    BigVector<std::int32_t> empty;
    empty.shrink_to_fit();
    EXPECT_TRUE(empty.empty());
}

TEST(BigBuffer, OverflowingSizeThrows)
{
    BigBufferAllocator<double> a;
    EXPECT_THROW((void)a.allocate(std::numeric_limits<std::size_t>::max() / 4), std::bad_array_new_length);
}

TEST(BigBuffer, LinuxGivesBigBuffersHugePagesWhenTheKernelOffersThem)
{
#if !defined(__linux__)
    GTEST_SKIP() << "transparent huge pages are a Linux feature";
#else
    const std::string mode = read_first_line("/sys/kernel/mm/transparent_hugepage/enabled");
    if (mode.empty() || mode.find("[never]") != std::string::npos)
        GTEST_SKIP() << "transparent huge pages are off on this kernel (" << mode << ")";
    // 64 MiB, touched: with THP in `madvise` or `always` mode the kernel backs most of it with
    // 2 MiB pages. Asking for at least one of 32 leaves room for a fragmented machine; without
    // the advice, `madvise` mode (Debian's default) gives none, so this fails if the advice is lost.
    BigVector<std::uint8_t> v(64 * kMiB, 7);
    const long kb = huge_kb_of_mapping(v.data() + 32 * kMiB);
    ASSERT_GE(kb, 0) << "no mapping in /proc/self/smaps holds the buffer";
    EXPECT_GE(kb, 2048) << "THP mode " << mode << ": the buffer has no huge page";
#endif
}
