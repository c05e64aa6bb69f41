// on_device.hpp — the one way a stage runs on the chosen device or falls back to the CPU.
// Private to the library.
//
//   const gpu::DeviceRun run = gpu::on_device(options.device, [&](const auto& ctx, std::string& why_not) {
//       return winding_on(ctx, ..., why_not);  // true: done on the device; false: why_not says why
//   });
//   if (run) return out;  // run.device names the device
//   ... the CPU path ...
//
// The policy, the same for every stage: gpu::select resolves the choice (the options' device,
// else $GSD_DEVICE, else "auto"); when it falls back to the CPU its note is printed once
// (log_once); a device that refuses the work (the data does not fit it, it lacks float64, ...)
// says why in one line, printed once, and the caller's CPU path runs. An exception from the
// attempt is an error, not a fallback.
//
// The attempt takes the context as `const auto&`: in a build without Vulkan (GSD_WITH_VULKAN=OFF)
// the call below is discarded, the attempt is never instantiated, and the modules' *_gpu.cpp,
// which are not built there, need no stand-ins.
#pragma once

#include <gsd/gpu.hpp>

#include <memory>
#include <string>
#include <string_view>

namespace gsd::gpu {

#if defined(GSD_HAVE_VULKAN)
inline constexpr bool kBuiltWithVulkan = true;
#else
inline constexpr bool kBuiltWithVulkan = false;
#endif

/// Whether the context's device runs its kernels on the host's own cores (a software device
/// such as lavapipe): host work beside its dispatches takes cores from it.
bool shares_host_cores(const Context& ctx);

/// Where a stage ran: the device's name, or empty when the caller's CPU path is to run.
struct DeviceRun {
    std::string device;
    explicit operator bool() const { return !device.empty(); }
};

/// Tries `attempt(const std::shared_ptr<Context>&, std::string& why_not) -> bool` on the device
/// `choice` selects, if any. `fallback` is added to a refusal's line (e.g. "; rendering on the CPU").
template <class Attempt>
DeviceRun on_device(const Device& choice, Attempt&& attempt, std::string_view fallback = {}) {
    const Selection sel = select(choice);
    if (!sel.note.empty()) log_once(sel.note);
    if constexpr (kBuiltWithVulkan) {
        if (sel.context) {
            std::string why_not;
            if (attempt(sel.context, why_not)) return {sel.device_name};
            if (!why_not.empty()) log_once(why_not + std::string(fallback));
        }
    }
    return {};
}

}  // namespace gsd::gpu
