// The multigrid of GridPoissonSolver on a Vulkan device (poisson_gpu.cpp): the same hierarchy,
// smoother and transfers as the CPU reference, in float32, with the residual and the solution
// in float64 (mixed-precision iterative refinement) so it reaches a relative residual of 1e-6.
#pragma once

#include <gsd/core.hpp>

#include "shm/multigrid.hpp"

#include <memory>
#include <string>
#include <vector>

namespace gsd::gpu { class Context; }

namespace gsd::shm {

class GpuMultigrid {
public:
    virtual ~GpuMultigrid() = default;
    /// `storage`, if given, is a vector of b's size whose memory φ is returned in, written in
    /// parallel (it may be b itself: b is read before φ is written). A fresh vector is zeroed on
    /// one thread, a page fault per 4 KiB page where huge pages are not granted.
    virtual std::vector<double> solve(const std::vector<double>& b, double tol, int max_cycles,
                                      std::vector<double>* history, bool f_cycle, const ProgressFn& progress,
                                      std::vector<double>* storage) = 0;
    /// What solve() would otherwise do first: every pipeline of a cycle made (llvmpipe builds
    /// each from NIR, tens of ms in all), and the grids held in host memory touched (their page
    /// faults). Safe beside other work on the same context (another thread's dispatches).
    virtual void prepare(bool f_cycle) = 0;
};

/// Null (and a reason) when the device cannot run it (no float64 in shaders, memory, limits).
std::unique_ptr<GpuMultigrid> make_gpu_multigrid(const std::shared_ptr<gpu::Context>& ctx, const Hierarchy& h,
                                                 std::string& why_not);

}  // namespace gsd::shm
