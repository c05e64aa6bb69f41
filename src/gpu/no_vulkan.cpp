// The gpu module of a build without Vulkan (GSD_WITH_VULKAN=OFF): every choice is the CPU path.
#include <gsd/core.hpp>
#include <gsd/gpu.hpp>

#include "gpu/device_choice.hpp"
#include "gpu/on_device.hpp"

#include <algorithm>
#include <cctype>

namespace gsd::gpu {

class Context {};

Inventory list_devices() {
    Inventory inv;
    inv.problem = "gsd was built without Vulkan (GSD_WITH_VULKAN=OFF)";
    return inv;
}

Selection select(const Device& device) {
    Selection s;
    s.device_name = "cpu";
    std::string choice = requested_choice(device);
    std::transform(choice.begin(), choice.end(), choice.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    if (choice == "cpu") return s;
    // The policy of the Vulkan build: auto and gpu fall back, a named device is a demand.
    if (choice != "auto" && choice != "gpu")
        throw Error("device", "no Vulkan device matches '" + choice + "': gsd was built without Vulkan");
    s.note = "built without Vulkan; using the CPU path";
    return s;
}

std::string device_name(const Context&) { return "cpu"; }
bool shares_host_cores(const Context&) { return false; }
std::uint64_t validation_error_count() { return 0; }
bool validation_active() { return false; }

}  // namespace gsd::gpu
