#include "core/threads.hpp"

#include <cstdlib>
#include <string>
#include <vector>

#include <omp.h>
#ifdef __linux__
#include <pthread.h>
#include <sched.h>
#include <unistd.h>
#endif

namespace gsd::detail {

// Why: on small virtual machines (the 2-core ones CI and benchmarks run on) Linux often keeps
// the OpenMP worker on the CPU of the first thread, and both then share one CPU while the
// other idles: measured, `gsd winding` of a 1.3·10⁵-triangle mesh at 10 queries (reading it
// and building the tree) took 0.13–0.14 s in most runs against 0.09–0.10 s every time with
// the threads bound (OMP_PROC_BIND=true), and 0.13–0.14 s with both threads forced onto one
// CPU (taskset -c 0). Bound threads cannot end up there.
std::string bind_openmp_threads() {
#ifndef __linux__
    return "threads not bound (not Linux)";
#else
    for (const char* v : {"OMP_PROC_BIND", "OMP_PLACES", "GOMP_CPU_AFFINITY"})
        if (std::getenv(v)) return std::string(v) + " is set: threads placed by the OpenMP runtime";
    cpu_set_t mask;
    CPU_ZERO(&mask);
    if (sched_getaffinity(0, sizeof mask, &mask) != 0) return "threads not bound (no affinity mask)";
    std::vector<int> cpus;
    for (int c = 0; c < CPU_SETSIZE; ++c)
        if (CPU_ISSET(c, &mask)) cpus.push_back(c);
    const int n = int(cpus.size());
    if (n < 2 || omp_get_max_threads() != n)
        return "threads not bound (" + std::to_string(omp_get_max_threads()) + " threads, " + std::to_string(n) + " CPUs)";
    const int offset = int(getpid() % n);
    int bound = 0;
#pragma omp parallel num_threads(n) reduction(+ : bound)
    {
        cpu_set_t one;
        CPU_ZERO(&one);
        CPU_SET(cpus[std::size_t((omp_get_thread_num() + offset) % n)], &one);
        bound += pthread_setaffinity_np(pthread_self(), sizeof one, &one) == 0 ? 1 : 0;
    }
    if (bound == n) return std::to_string(n) + " threads bound to one CPU each";
    // All or nothing: threads that did bind get the whole mask back.
#pragma omp parallel num_threads(n)
    pthread_setaffinity_np(pthread_self(), sizeof mask, &mask);
    return "threads not bound (the system refused)";
#endif
}

OneOpenMPThread::OneOpenMPThread(bool active) {
#ifdef _OPENMP
    if (active) {
        saved_ = omp_get_max_threads();
        omp_set_num_threads(1);
    }
#endif
}

OneOpenMPThread::~OneOpenMPThread() {
#ifdef _OPENMP
    if (saved_ > 0) omp_set_num_threads(saved_);
#endif
}

}  // namespace gsd::detail
