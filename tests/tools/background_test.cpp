// tools::BackgroundWork: the work runs, its failure reaches the caller, it runs at the lowest
// priority without lowering the caller's, and waiting for it raises it again, so that a busy
// machine cannot starve it once the caller waits.
#include "common/background.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>
#if defined(__linux__)
#include <omp.h>
#include <sched.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>
#endif

namespace lobe::tools {
namespace {

TEST(BackgroundWork, RunsTheWorkAndRethrowsItsFailure)
{
    int value = 0;
    BackgroundWork ok([&] { value = 42; });
    ok.wait();
    EXPECT_EQ(value, 42);
    EXPECT_NO_THROW(ok.wait()); // a second wait returns at once

    BackgroundWork failed([] { throw std::runtime_error("disk full"); });
    EXPECT_THROW(failed.wait(), std::runtime_error);

    // Not waited for: the destructor waits and drops the failure (the caller is unwinding).
    EXPECT_NO_THROW({ BackgroundWork dropped([] { throw std::runtime_error("ignored"); }); });
}

#if defined(__linux__)
// The caller waits until the work has begun: a wait() before that leaves it at normal priority
// (there is no point in lowering work the caller already waits for).
void until(const std::atomic<bool>& flag)
{
    while (!flag.load())
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

double thread_cpu_seconds()
{
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

// The policy is the work's thread's alone; the caller keeps its own. Whether the work starts
// at SCHED_IDLE depends on the process's right to raise it again (root here, and in CI).
TEST(BackgroundWork, RunsAtTheLowestPriorityOnItsOwnThreadOnly)
{
    const int before = sched_getscheduler(0);
    int inside = -1;
    std::atomic<bool> begun{false};
    BackgroundWork w([&] {
        inside = sched_getscheduler(0);
        begun = true;
    });
    until(begun);
    w.wait();
    EXPECT_EQ(inside, w.started_idle() ? SCHED_IDLE : before);
    EXPECT_EQ(sched_getscheduler(0), before);
    if (!w.started_idle())
        GTEST_SKIP() << "this process may not raise a thread out of SCHED_IDLE: the work ran at normal priority";
}

// The work starts an OpenMP team (as the HDF5 writer's chunk compression does), then waits
// until it finds itself raised. wait() must raise both it and its team's other thread.
TEST(BackgroundWork, WaitRaisesTheWorkAndItsOpenMpThreads)
{
    std::atomic<int> team_tid{0};
    std::atomic<bool> begun{false};
    int policy_after = -1;
    BackgroundWork w([&] {
#pragma omp parallel num_threads(2)
        if (omp_get_thread_num() == 1)
            team_tid = static_cast<int>(::syscall(SYS_gettid));
        begun = true;
        const auto t0 = std::chrono::steady_clock::now();
        while (sched_getscheduler(0) == SCHED_IDLE && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(20))
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
        policy_after = sched_getscheduler(0);
    });
    until(begun);
    w.wait();
    if (!w.started_idle())
        GTEST_SKIP() << "this process may not raise a thread out of SCHED_IDLE: nothing was lowered";
    EXPECT_EQ(policy_after, SCHED_OTHER);
    if (team_tid != 0 && sched_getscheduler(team_tid) != -1) { // the team's thread still exists
        EXPECT_EQ(sched_getscheduler(team_tid), SCHED_OTHER);
    }
}

// The failure this class exists to prevent: a machine whose every core is busy at normal
// priority gives a SCHED_IDLE thread about 0.3 % of a core (weight 3 against 1024), so 0.1 s
// of work would take some 30 s. Raised at the wait, it shares a core fairly: about 0.2 s. The
// 5 s bound leaves room for a loaded CI machine and sanitizers (the work is CPU time, not a
// count of iterations, so a slower build does not lengthen it).
TEST(BackgroundWork, BusyMachineCannotStarveTheWorkOnceWaitedFor)
{
    std::atomic<bool> stop{false};
    std::vector<std::thread> hogs;
    for (unsigned c = 0; c < std::max(1u, std::thread::hardware_concurrency()); ++c)
        hogs.emplace_back([&] {
            volatile unsigned long x = 0;
            while (!stop.load(std::memory_order_relaxed))
                x = x + 1;
        });
    std::atomic<bool> begun{false};
    BackgroundWork w([&] {
        begun = true;
        const double t0 = thread_cpu_seconds();
        volatile unsigned long x = 0;
        while (thread_cpu_seconds() - t0 < 0.1)
            for (int i = 0; i < 10000; ++i)
                x = x + 1;
    });
    until(begun);
    std::this_thread::sleep_for(std::chrono::milliseconds(50)); // the caller's own work
    const auto t0 = std::chrono::steady_clock::now();
    w.wait();
    const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    stop = true;
    for (auto& h : hogs)
        h.join();
    EXPECT_LT(waited, 5.0) << "started at SCHED_IDLE: " << w.started_idle();
}
#endif

} // namespace
} // namespace lobe::tools
