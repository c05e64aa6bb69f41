// threads.hpp — placing the OpenMP threads of a program (the gsd CLI) on the CPUs. Private;
// the library never calls this: an application embedding gsd owns its threads.
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
std::string bind_openmp_threads();

}  // namespace gsd::detail
