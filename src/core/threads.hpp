// threads.hpp — the OpenMP threads: placing a program's (the gsd CLI's) on the CPUs, and
// keeping host work to one thread beside a software device's. Private.
#pragma once

#include <string>

namespace gsd::detail {

/// Binds each thread of the OpenMP team to its own CPU of the process's affinity mask, when
/// that is safe and useful:
/// - none of OMP_PROC_BIND, OMP_PLACES, GOMP_CPU_AFFINITY is set (the user's placement rules;
///   OMP_PROC_BIND=false keeps the scheduler's);
/// - the team has one thread per CPU of the mask, at least two (so no CPU is left idle by the
///   parallel loops).
/// Thread t goes to CPU (t + pid) mod n, so that side-by-side processes tend to put their first
/// threads on different CPUs (with two processes on two CPUs they still share one half the
/// time, and their serial parts then share it). Threads created later by the first thread
/// inherit its single CPU — OpenVDB's TBB workers when a grid is written as .vdb — hence only
/// for work that stays on the CPU path. All threads are bound, or none.
/// Returns a line saying what was done, or why not (for -v).
/// The library never calls this: an application embedding gsd owns its threads.
std::string bind_openmp_threads();

/// While it lives (and `active`), parallel regions this thread starts have one thread. For
/// host work between a software device's dispatches: OpenMP's workers, left spinning at their
/// barriers after a region, would take the cores the device's threads run on (gpu::stream says
/// what that cost).
class OneOpenMPThread {
public:
    explicit OneOpenMPThread(bool active);
    ~OneOpenMPThread();
    OneOpenMPThread(const OneOpenMPThread&) = delete;
    OneOpenMPThread& operator=(const OneOpenMPThread&) = delete;

private:
    int saved_ = 0;
};

}  // namespace gsd::detail
