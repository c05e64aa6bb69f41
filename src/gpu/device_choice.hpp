// device_choice.hpp — the device choice as the user gave it, and whether this machine could
// have a hardware GPU at all. Private to the library and its programs.
#pragma once

#include <string>

namespace gsd {
class Device;
}

namespace gsd::gpu {

/// The choice string select() resolves: the device's own, else $GSD_DEVICE, else "auto" (as
/// written: callers compare it lower-cased, and quote it as given). Empty for a context.
std::string requested_choice(const Device& device);

/// Whether the folder `dev` (/dev) holds a node that some GPU's driver works through: DRM
/// (dri/renderD*, dri/card*), NVIDIA's (nvidiactl, nvidia0), WSL's (dxg), or an embedded
/// GPU's (kgsl-3d0, mali0, galcore, pvr_sync). A hardware Vulkan device needs one, so without
/// any, select("auto") does not load the Vulkan drivers at all. True where `dev` is not a
/// readable folder, and on systems other than Linux (nothing can be told).
bool has_gpu_device_node(const std::string& dev = "/dev");

}  // namespace gsd::gpu
