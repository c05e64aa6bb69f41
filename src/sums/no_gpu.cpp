// The sums' device entry points in a build without Vulkan: never a device, always a reason.
#include "sums/sums_gpu.hpp"

namespace gsd::sums_detail {

bool gpu_winding(const std::shared_ptr<gpu::Context>&, const detail::SumTree&, PointsView, const WindingOptions&,
                 WindingResult&, const ProgressFn&, std::string& why_not) {
    why_not = "built without Vulkan";
    return false;
}

}  // namespace gsd::sums_detail
