// gsd::Device: a choice string or a context, resolved by gpu::select (runtime.cpp, or
// no_vulkan.cpp in a build without Vulkan).
#include <gsd/gpu.hpp>

namespace gsd {

Device::Device(std::shared_ptr<gpu::Context> context) : context_(std::move(context)) {}

std::string Device::describe() const {
    if (context_) return gpu::device_name(*context_);
    return choice_.empty() ? "auto" : choice_;
}

}  // namespace gsd
