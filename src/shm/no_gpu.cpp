// The SHM device entry points of a build without Vulkan: never a device, always a reason.
#include "shm/diffuse.hpp"
#include "shm/poisson_gpu.hpp"

namespace gsd::shm_detail {

std::unique_ptr<DirectionEvaluator> make_gpu_evaluator(const std::shared_ptr<gpu::Context>&, const ShmSource&,
                                                       const KernelParams&, std::size_t, std::string& why_not) {
    why_not = "built without Vulkan";
    return nullptr;
}

std::unique_ptr<GpuMultigrid> make_gpu_multigrid(const std::shared_ptr<gpu::Context>&, const Hierarchy&,
                                                 std::string& why_not) {
    why_not = "built without Vulkan";
    return nullptr;
}

}  // namespace gsd::shm_detail
