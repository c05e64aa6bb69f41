// The gpu module of a build without Vulkan (GSD_WITH_VULKAN=OFF): every choice is the CPU path.
#include <gsd/core.hpp>
#include <gsd/gpu.hpp>

namespace gsd::gpu {

class Context {};

Inventory list_devices() {
    Inventory inv;
    inv.problem = "gsd was built without Vulkan (GSD_WITH_VULKAN=OFF)";
    return inv;
}

Selection select(const std::string& choice) {
    Selection s;
    s.device_name = "cpu";
    if (choice != "cpu") s.note = "built without Vulkan; using the CPU path";
    return s;
}

std::string device_name(const Context&) { return "cpu"; }
std::uint64_t validation_error_count() { return 0; }
bool validation_active() { return false; }

}  // namespace gsd::gpu
