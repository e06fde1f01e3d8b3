// tools::run_when_idle: the work runs, its failure reaches the caller, and it runs at the lowest
// priority without lowering the caller's.
#include "common/background.h"

#include <gtest/gtest.h>

#include <stdexcept>
#if defined(__linux__)
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

namespace lobe::tools {
namespace {

#if defined(__linux__)
// The calling thread's policy and nice value (Linux keeps both per thread).
std::pair<int, int> own_priority()
{
    return {sched_getscheduler(0), getpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid)))};
}
#endif

TEST(RunWhenIdle, RunsTheWorkAndRethrowsItsFailure)
{
    int value = 0;
    run_when_idle([&] { value = 42; }).get();
    EXPECT_EQ(value, 42);

    std::future<void> failed = run_when_idle([] { throw std::runtime_error("disk full"); });
    EXPECT_THROW(failed.get(), std::runtime_error);
}

#if defined(__linux__)
// SCHED_IDLE is open to every user, nice 19 (the fallback) too, so one of them must hold; the
// caller keeps its own: the policy and nice value belong to the new thread only.
TEST(RunWhenIdle, RunsAtTheLowestPriorityOnItsOwnThreadOnly)
{
    const auto before = own_priority();
    std::pair<int, int> inside{-1, -1};
    run_when_idle([&] { inside = own_priority(); }).get();
    EXPECT_TRUE(inside.first == SCHED_IDLE || inside.second == 19)
        << "policy " << inside.first << ", nice " << inside.second;
    EXPECT_EQ(own_priority(), before);
}
#endif

} // namespace
} // namespace lobe::tools
