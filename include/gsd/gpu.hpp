// gsd/gpu.hpp — which compute device gsd uses, and what it sees.
//
// Every options struct carries a gsd::Device (BlendOptions::device, ShmOptions::device, …),
// resolved by one policy when the work starts (gpu::select):
//   "auto"  a real GPU if there is one, else the CPU path (the default; $GSD_DEVICE overrides
//           an empty choice)
//   "gpu"   any Vulkan device, a software one (lavapipe) included
//   "cpu"   the CPU path
//   N       the Vulkan device with index N (see `gsd info`)
//   text    the first Vulkan device whose name contains the text (case-insensitive)
//   a gpu::Context   that device: one gsd selected before, or an application's own device handed
//                    to gsd with gpu::Context::adopt (gsd/vulkan.hpp)
// "auto" and "gpu" fall back: no Vulkan loader or no usable device runs the work on the CPU and
// one line says so (see set_log_sink). A device named by index or name is a demand: one that
// does not exist or cannot start is an error (gsd::Error, where() "device").
// No Vulkan type appears in this header.
#pragma once

#include <gsd/export.hpp>

#include <cstddef>
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
    bool subgroup_vote = false;    ///< compute shaders may vote across a subgroup (subgroupAny)
    bool subgroup_ballot = false;  ///< ... and broadcast within it (subgroupBroadcast)
    bool subgroup_arithmetic = false;  ///< ... and add across it (subgroupAdd; the renderer needs it)
    bool subgroup_shuffle = false;     ///< ... and shuffle within it (subgroupShuffle; TorusNet and winding numbers on software devices)
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

}  // namespace gpu

/// Where a computation runs: a choice string or a device context (see the top of this file).
/// Converts implicitly from both, so `options.device = "cpu"` and `options.device = context`
/// read naturally.
class GSD_EXPORT Device {
public:
    Device() = default;  ///< "": $GSD_DEVICE, else "auto"
    Device(std::string choice) : choice_(std::move(choice)) {}
    Device(const char* choice) : choice_(choice ? choice : "") {}
    Device(std::shared_ptr<gpu::Context> context);
    static Device cpu() { return Device("cpu"); }

    /// The choice string ("" for a context, or for the default).
    const std::string& choice() const { return choice_; }
    /// The context given, if any.
    const std::shared_ptr<gpu::Context>& context() const { return context_; }
    /// "cpu", "auto", a choice string as given, or the context's device name (for messages).
    std::string describe() const;

private:
    std::string choice_;
    std::shared_ptr<gpu::Context> context_;
};

/// Where a stage runs and in what pieces: the base of every options struct whose work has a GPU
/// path (BlendOptions, TorusNetOptions, ShmOptions, WindingOptions, FieldRenderOptions).
struct Execution {
    /// Where it runs: "auto" | "gpu" | "cpu" | index | name | a gpu::Context; the default
    /// (empty) is $GSD_DEVICE, else auto.
    Device device;
    /// Work items (queries, points, rays) per GPU chunk; 0: chosen from the device's limits.
    /// Results do not depend on it.
    std::size_t chunk_size = 0;
};

namespace gpu {

/// Resolves a device. Contexts gsd creates are shared: one per device per process. Throws
/// gsd::Error ("device") for an index or name that matches no device or whose device cannot
/// start.
GSD_EXPORT Selection select(const Device& device);

/// Name of a context's device.
GSD_EXPORT std::string device_name(const Context& ctx);

/// Number of validation-layer errors reported so far in this process (validation runs when
/// $GSD_VALIDATION=1 and the Khronos layer is installed). Tests require it to stay 0.
GSD_EXPORT std::uint64_t validation_error_count();
/// Whether the validation layer is actually active in this process.
GSD_EXPORT bool validation_active();

}  // namespace gpu
}  // namespace gsd
