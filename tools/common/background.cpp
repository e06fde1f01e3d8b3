#include "common/background.h"

#include <utility>
#if defined(__linux__)
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

namespace lobe::tools {

std::future<void> run_when_idle(std::function<void()> work)
{
    return std::async(std::launch::async, [work = std::move(work)] {
#if defined(__linux__)
        // Linux gives each thread its own policy and nice value. SCHED_IDLE, not nice 19: at
        // nice 19 the writer still slowed lseg liver's segmentation (docs/benchmarks.md). Best
        // effort: if neither can be set the work still runs, only without yielding to the caller.
        sched_param none{};
        if (sched_setscheduler(0, SCHED_IDLE, &none) != 0)
            (void)setpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid)), 19);
#endif
        work();
    });
}

} // namespace lobe::tools
