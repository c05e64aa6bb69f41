// gsd/gpu.hpp — which compute device gsd uses, and what it sees.
//
// Algorithms pick their device through a choice string (an options field, else $GSD_DEVICE):
//   "auto"  a real GPU if there is one, else the CPU path (the default)
//   "gpu"   any Vulkan device, a software one (lavapipe) included
//   "cpu"   the CPU path
//   N       the Vulkan device with index N (see `gsd info`)
//   text    the first Vulkan device whose name contains the text (case-insensitive)
// No Vulkan loader or no usable device is not an error for "auto" and "gpu": the work runs on
// the CPU and one line says so (see set_log_sink). An index or name that matches nothing is.
// No Vulkan type appears in this header.
#pragma once

#include <gsd/export.hpp>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace gsd {

/// Where gsd's one-line notices go (device fallback and the like). Default: stderr,
/// prefixed "gsd: ". Pass an empty function to silence them.
GSD_EXPORT void set_log_sink(std::function<void(std::string_view)> sink);
/// Emits a notice through the sink, once per distinct message per process.
GSD_EXPORT void log_once(const std::string& message);

namespace gpu {

struct DeviceInfo {
    std::uint32_t index = 0;
    std::string name;
    std::string type;  ///< "discrete", "integrated", "virtual", "cpu" or "other"
    std::string api_version;
    std::uint64_t device_local_bytes = 0;
    std::uint32_t subgroup_size = 0;
    std::uint64_t max_storage_buffer_range = 0;
    bool usable = false;      ///< has what gsd needs (compute queue, push descriptors, Vulkan 1.1)
    std::string why_not;      ///< if not usable
    bool is_software() const { return type == "cpu"; }
};

struct Inventory {
    bool loader_found = false;
    std::string problem;  ///< why no devices are listed, if none are
    std::vector<DeviceInfo> devices;
};

/// Lists the Vulkan devices (safe to call without a loader: reports it).
GSD_EXPORT Inventory list_devices();

class Context;

/// The outcome of resolving a device choice.
struct Selection {
    std::shared_ptr<Context> context;  ///< null: use the CPU path
    std::string device_name;           ///< "cpu" or the Vulkan device name
    std::string note;                  ///< why the CPU path was chosen when a GPU was asked for
};

/// Resolves a choice string ("" means $GSD_DEVICE, else "auto"). Contexts are shared: one per
/// device per process. Throws gsd::Error for an index or name that matches no device.
GSD_EXPORT Selection select(const std::string& choice);

/// Name of a context's device.
GSD_EXPORT std::string device_name(const Context& ctx);

/// Number of validation-layer errors reported so far in this process (validation runs when
/// $GSD_VALIDATION=1 and the Khronos layer is installed). Tests require it to stay 0.
GSD_EXPORT std::uint64_t validation_error_count();
/// Whether the validation layer is actually active in this process.
GSD_EXPORT bool validation_active();

}  // namespace gpu
}  // namespace gsd
