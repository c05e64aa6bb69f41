// gsd::Device: a choice string or a context, resolved by gpu::select (runtime.cpp, or
// no_vulkan.cpp in a build without Vulkan).
#include <gsd/gpu.hpp>

#include "gpu/device_choice.hpp"

#include <cstdlib>
#include <filesystem>
#include <system_error>

namespace gsd {

Device::Device(std::shared_ptr<gpu::Context> context) : context_(std::move(context)) {}

std::string Device::describe() const {
    if (context_) return gpu::device_name(*context_);
    return choice_.empty() ? "auto" : choice_;
}

}  // namespace gsd

namespace gsd::gpu {

std::string requested_choice(const Device& device) {
    if (device.context()) return {};
    if (!device.choice().empty()) return device.choice();
    const char* env = std::getenv("GSD_DEVICE");
    return env && *env ? env : "auto";
}

bool has_gpu_device_node(const std::string& dev) {
#ifndef __linux__
    (void)dev;
    return true;  // the node names are Linux's: elsewhere (MoltenVK, Windows) look for devices
#else
    std::error_code ec;
    if (!std::filesystem::is_directory(dev, ec)) return true;  // cannot tell: look for devices
    for (const char* node : {"nvidiactl", "nvidia0", "dxg", "kgsl-3d0", "mali0", "galcore", "pvr_sync"})
        if (std::filesystem::exists(dev + "/" + node, ec)) return true;
    for (const auto& entry : std::filesystem::directory_iterator(dev + "/dri", ec)) {
        const std::string name = entry.path().filename().string();
        if (name.rfind("renderD", 0) == 0 || name.rfind("card", 0) == 0) return true;
    }
    return false;
#endif
}

}  // namespace gsd::gpu
