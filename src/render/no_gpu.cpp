// The renderer of a build without Vulkan: the device paths are never taken (gpu::select never
// returns a context), but exist so render.cpp reads the same in both builds.
#include "render/render.hpp"

namespace gsd::render {

bool march_blend_gpu(const blend::Engine&, const std::shared_ptr<gpu::Context>&, const Camera&, const March&,
                     std::vector<float>&, std::string& why_not, const ProgressFn&) {
    why_not = "built without Vulkan";
    return false;
}

bool march_grid_gpu(const GridSpec&, const std::vector<float>&, const std::shared_ptr<gpu::Context>&, const Camera&,
                    const March&, std::vector<float>&, std::string& why_not, const ProgressFn&) {
    why_not = "built without Vulkan";
    return false;
}

}  // namespace gsd::render
