#include "common/background.h"

#include <string>
#include <utility>
#if defined(__linux__)
#include <dirent.h>
#include <sched.h>
#include <sys/types.h>
#endif

namespace lobe::tools {
namespace {

#if defined(__linux__)
// Whether this process may take a thread out of SCHED_IDLE again. The kernel is the authority
// (CAP_SYS_NICE, RLIMIT_NICE, a container's seccomp profile): ask it on a throwaway thread,
// since a thread that fails to leave SCHED_IDLE stays there.
bool idle_can_be_undone()
{
    bool ok = false;
    std::thread probe([&ok] {
        const sched_param none{};
        if (sched_setscheduler(0, SCHED_IDLE, &none) == 0)
            ok = sched_setscheduler(0, SCHED_OTHER, &none) == 0;
    });
    probe.join();
    return ok;
}

// Every thread of this process at SCHED_IDLE back to SCHED_OTHER (its nice value is kept): the
// work's thread and the OpenMP threads it started. The tools set SCHED_IDLE nowhere else.
void undo_idle()
{
    DIR* dir = opendir("/proc/self/task");
    if (!dir)
        return;
    const sched_param none{};
    while (const dirent* e = readdir(dir)) {
        if (e->d_name[0] < '0' || e->d_name[0] > '9')
            continue;
        const auto tid = static_cast<pid_t>(std::stol(e->d_name));
        if (sched_getscheduler(tid) == SCHED_IDLE)
            (void)sched_setscheduler(tid, SCHED_OTHER, &none);
    }
    closedir(dir);
}
#endif

} // namespace

BackgroundWork::BackgroundWork(std::function<void()> work)
{
    thread_ = std::thread([this, work = std::move(work)] {
#if defined(__linux__)
        if (idle_can_be_undone()) {
            const std::lock_guard<std::mutex> lock(mutex_);
            const sched_param none{};
            if (!raise_requested_)
                started_idle_ = sched_setscheduler(0, SCHED_IDLE, &none) == 0;
        }
#endif
        try {
            work();
        } catch (...) {
            failure_ = std::current_exception();
        }
    });
}

BackgroundWork::~BackgroundWork()
{
    try {
        wait();
    } catch (...) { // the caller is unwinding from its own failure, or chose not to look
    }
}

void BackgroundWork::raise()
{
    const std::lock_guard<std::mutex> lock(mutex_);
    raise_requested_ = true;
#if defined(__linux__)
    if (started_idle_)
        undo_idle();
#endif
}

void BackgroundWork::wait()
{
    if (!thread_.joinable())
        return;
    raise();
    thread_.join();
    if (failure_)
        std::rethrow_exception(std::exchange(failure_, nullptr));
}

bool BackgroundWork::started_idle() const
{
    const std::lock_guard<std::mutex> lock(mutex_);
    return started_idle_;
}

} // namespace lobe::tools
