#pragma once
// Work that overlaps a tool's main computation without slowing it down.

#include <exception>
#include <functional>
#include <mutex>
#include <thread>

namespace lobe::tools {

//! Runs `work` on a thread of its own at the lowest CPU priority (Linux's SCHED_IDLE; the OpenMP
//! threads it starts inherit it), so that it takes only the time the caller's threads leave
//! idle. `wait()` raises it (and those OpenMP threads) back to normal priority before waiting:
//! on a busy machine a SCHED_IDLE thread gets almost no CPU at all, and once the caller waits
//! the work is all there is left to do (beside a compiler, `lseg liver` on the demo phantom
//! waited 178 s for a write of half a second). Linux lets a process leave SCHED_IDLE only with
//! CAP_SYS_NICE or an RLIMIT_NICE that allows nice 0; where it cannot, the work runs at normal
//! priority from the start rather than risk that wait.
class BackgroundWork {
  public:
    explicit BackgroundWork(std::function<void()> work);
    BackgroundWork(const BackgroundWork&) = delete;
    BackgroundWork& operator=(const BackgroundWork&) = delete;
    //! Waits as wait() does; a failure of the work is then dropped (call wait() to see it).
    ~BackgroundWork();

    //! Raises the work to normal priority, waits for it to end and rethrows what it threw.
    //! Later calls return at once.
    void wait();

    //! Whether the work started at SCHED_IDLE (false where its priority could not be raised
    //! again, or off Linux). Valid once the work has begun; wait() first to be sure.
    bool started_idle() const;

  private:
    void raise();

    mutable std::mutex mutex_;
    bool raise_requested_ = false; // once set, the work does not lower itself any more
    bool started_idle_ = false;
    std::exception_ptr failure_;
    std::thread thread_;
};

} // namespace lobe::tools
