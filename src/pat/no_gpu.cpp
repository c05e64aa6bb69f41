// The PAT device entry points of a build without Vulkan (GSD_WITH_VULKAN=OFF): gpu::select never
// returns a context there, so this is never reached; it only keeps TorusNet's dispatch the same.
#include "pat/torus_net_gpu.hpp"
#include "pat/torus_net_gpu_check.hpp"

namespace gsd::detail {

void predict_jets_gpu(const TorusNetModel&, const PointCloud&, gpu::Context&, std::vector<Jet>&, Points&,
                      std::size_t, const ProgressFn&) {
    throw Error("gsd was built without Vulkan (GSD_WITH_VULKAN=OFF)");
}

TorusNetGpuTrace torusnet_gpu_neighborhoods(const TorusNetModel&, gpu::Context&, const Points&, const Points&, bool) {
    throw Error("gsd was built without Vulkan (GSD_WITH_VULKAN=OFF)");
}

}  // namespace gsd::detail
