#pragma once
// Work that overlaps a tool's main computation without slowing it down.

#include <functional>
#include <future>

namespace lobe::tools {

//! Runs `work` on a new thread at the lowest CPU priority (on Linux the SCHED_IDLE policy, or
//! nice 19 where that is refused; the OpenMP threads it starts inherit it), so that it takes
//! only the time the caller's own threads leave idle and runs at full speed once the caller
//! waits for it. The future rethrows what `work` threw;
//! its destructor waits for the work to end.
std::future<void> run_when_idle(std::function<void()> work);

} // namespace lobe::tools
