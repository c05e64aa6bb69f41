// gsd/vulkan.hpp — running gsd on an engine's own Vulkan device, into the engine's own buffers.
//
// The only public header that includes Vulkan (<vulkan/vulkan_core.h>; define VK_NO_PROTOTYPES
// first if the application loads Vulkan through volk). Installed only when gsd is built with
// Vulkan (GSD_WITH_VULKAN, the default).
//
//   auto ctx = gsd::gpu::Context::adopt(instance, physical, device, family, queue,
//                                       vkGetInstanceProcAddr);
//   gsd::gpu::DeviceQueries job;
//   job.queries = {query_buffer, 0};    // count × vec4: x, y, z, (unused), float32
//   job.results = {result_buffer, 0};   // count × float φ, or count × vec4 (φ, ∇φ) with gradient
//   job.count = n;
//   gsd::gpu::SubmitSync sync;
//   sync.signal = {results_ready};      // the engine waits on it before reading the results
//   gsd::gpu::evaluate_into(field, ctx, job, sync);
//
// gsd records its own command buffer and submits it to the adopted queue, so the results never
// pass through host memory. See docs/embedding.md ("Vulkan interop") for the contract: what the
// device must have enabled, buffer usage and alignment, queue access, lifetimes.
#pragma once

#include <gsd/export.hpp>
#include <gsd/gpu.hpp>

#include <vulkan/vulkan_core.h>

#include <cstdint>
#include <initializer_list>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace gsd {

class Field;

namespace gpu {

struct Kernel;

/// The bindings of a kernel that it reads as uniform texel buffers (software_shaped kernels),
/// by what one texel of the view is. A plain mask means vec4s.
struct TexelBindings {
    constexpr TexelBindings(std::uint32_t vec4_mask = 0) : vec4(vec4_mask) {}  // NOLINT: a mask is the common case
    constexpr TexelBindings(std::uint32_t vec4_mask, std::uint32_t float1_mask, std::uint32_t double1_mask = 0,
                            std::uint32_t double2_mask = 0)
        : vec4(vec4_mask), float1(float1_mask), double1(double1_mask), double2(double2_mask) {}
    std::uint32_t vec4 = 0;     ///< a vec4 of float32 (R32G32B32A32_SFLOAT): trees, tables
    std::uint32_t float1 = 0;   ///< one float32 (R32_SFLOAT): a grid's values
    std::uint32_t double1 = 0;  ///< one float64, fetched as a uvec2 (R32G32_UINT) for packDouble2x32
    std::uint32_t double2 = 0;  ///< two float64, fetched as a uvec4 (R32G32B32A32_UINT)
    constexpr std::uint32_t all() const { return vec4 | float1 | double1 | double2; }
    /// Whether no binding has two formats.
    constexpr bool disjoint() const {
        return (vec4 & float1) == 0 && (vec4 & double1) == 0 && (vec4 & double2) == 0 && (float1 & double1) == 0 &&
               (float1 & double2) == 0 && (double1 & double2) == 0;
    }
};

struct DeviceFunctions;
struct InstanceFunctions;
enum class Memory;

/// What gsd cannot discover about an adopted device (Vulkan has no query for enabled features).
struct AdoptOptions {
    /// The device was created with VkPhysicalDeviceFeatures::shaderFloat64 enabled. Only the
    /// grid SHM multigrid uses it (for its residual); without it that solver stays on the CPU.
    bool float64_enabled = false;
};

/// A Vulkan device gsd computes on: one gsd created itself (gpu::select) or an engine's device
/// handed to it with adopt(). Shared: every gsd object that keeps data on the device holds it.
class Context {
public:
    /// Runs gsd on an engine's device. The device must have been created from `physical` with
    /// VK_KHR_push_descriptor enabled and a queue in `queue_family` with compute; `instance`
    /// must be Vulkan 1.1 or newer. gsd neither destroys nor idles the device; it creates its
    /// own pipelines, command pools, fences and (for a field's data) buffers on it, and frees
    /// them when the last gsd object holding this context goes. Throws gsd::Error ("device")
    /// when the device lacks what gsd needs.
    GSD_EXPORT static std::shared_ptr<Context> adopt(VkInstance instance, VkPhysicalDevice physical,
                                                     VkDevice device, std::uint32_t queue_family,
                                                     VkQueue queue,
                                                     PFN_vkGetInstanceProcAddr get_instance_proc_addr,
                                                     const AdoptOptions& options = {});
    GSD_EXPORT ~Context();
    Context(const Context&) = delete;
    Context& operator=(const Context&) = delete;

    GSD_EXPORT VkDevice device() const;
    GSD_EXPORT VkPhysicalDevice physical_device() const;
    GSD_EXPORT VkQueue queue() const;
    GSD_EXPORT std::uint32_t queue_family() const;
    GSD_EXPORT const DeviceInfo& info() const;
    /// Whether the device belongs to the application (adopt) rather than to gsd.
    GSD_EXPORT bool adopted() const;

    // ---- gsd's own use (the library's kernels); not for applications ----------------------
    /// A context on a device gsd creates itself (gpu::select).
    Context(const InstanceFunctions& instance, VkPhysicalDevice physical, const DeviceInfo& info);
    /// The device-level Vulkan commands of this device (every vkCmd…, vkCreate…, … on it).
    const DeviceFunctions& vk() const;
    const VkPhysicalDeviceLimits& limits() const;
    /// Workgroup size used for 1-D kernels on this device (64 on CPUs, 128 on GPUs).
    std::uint32_t workgroup_size() const;
    /// Most workgroups per dispatch along x (larger dispatches continue along y).
    std::uint32_t max_groups_x() const;
    /// Largest range a storage buffer binding may cover.
    VkDeviceSize max_binding_bytes() const;
    /// Whether shaders may use float64.
    bool has_float64() const;
    /// Bytes of device-local memory in the largest heap.
    VkDeviceSize device_memory_bytes() const;
    /// The kernel for a shader and its specialization constants (1..n), built once and cached.
    /// `workgroup`: its workgroup size (constant 0); 0 takes workgroup_size(). `texel_bindings`:
    /// the bindings that are uniform texel buffers, and what a texel of each is.
    const Kernel& kernel(const std::string& shader, std::uint32_t bindings, std::uint32_t push_bytes,
                         std::initializer_list<std::int32_t> constants = {}, std::uint32_t workgroup = 0,
                         TexelBindings texel_bindings = {});
    std::uint32_t memory_type(std::uint32_t type_bits, Memory memory) const;
    /// Held around every vkQueueSubmit gsd makes (Vulkan requires queue access to be serialized).
    std::mutex& queue_mutex();

    struct State;
    /// The context's state (its definition is private to the library: src/gpu/runtime.hpp).
    State& state() const { return *s_; }

private:
    explicit Context(std::unique_ptr<State> state);
    void init_common();
    std::unique_ptr<State> s_;
};

/// A place in a caller's buffer. The buffer must have been created on the adopted device with
/// VK_BUFFER_USAGE_STORAGE_BUFFER_BIT; `offset` must be a multiple of the device's
/// minStorageBufferOffsetAlignment.
struct BufferSpan {
    VkBuffer buffer = VK_NULL_HANDLE;
    VkDeviceSize offset = 0;
};

/// Queries in one of the caller's buffers and where their results go.
struct DeviceQueries {
    /// `count` records of 16 bytes: x, y, z as float32, then 4 bytes gsd does not read.
    BufferSpan queries;
    /// `count` float32 φ; with `gradient`, `count` records of 16 bytes: φ, ∂φ/∂x, ∂φ/∂y, ∂φ/∂z.
    BufferSpan results;
    std::uint64_t count = 0;
    bool gradient = false;
};

/// How gsd's submission orders against the caller's work; passed to vkQueueSubmit as given.
/// With a fence or a signal semaphore the call returns once gsd's work is submitted; with
/// neither it returns when the results are written. Either way gsd's command buffer starts with
/// a barrier that makes earlier writes on the queue visible to it, and ends with one that makes
/// its results visible to later commands on the queue and, once the fence signals, to the host.
struct SubmitSync {
    std::vector<VkSemaphore> wait;                  ///< binary semaphores to wait on first
    std::vector<VkPipelineStageFlags> wait_stages;  ///< one per `wait`; empty: compute shader
    std::vector<VkSemaphore> signal;                ///< signaled when the results are written
    VkFence fence = VK_NULL_HANDLE;                 ///< signaled likewise (unsignaled on entry)
};

/// Evaluates any field at queries already on the device into a buffer on the device. A field
/// with a device program (Field::device_program: PAT, the baselines, composites of
/// gsd/field_algebra.hpp) runs it: the first call on a context uploads the field's data (points,
/// tori or terms, tree) and waits; later calls only record and submit. Results match
/// `field.evaluate` to float32 rounding. A field without one is evaluated by its CPU
/// evaluate(): the queries are copied back, evaluated, and the results copied in (one line says
/// so, once); the call then returns when the results are written. A composite evaluates its
/// leaves into buffers of its own, each by its program or on the CPU, combines them in one pass
/// and returns when the results are written. The field must outlive the work: destroying it
/// waits for its submissions to finish. Throws gsd::Error for bad spans or counts, or for
/// `job.gradient` with a field that has no ∇φ. Everything goes into one submission per leaf:
/// with BlendOptions::exact (O(queries × points)) keep each call's count modest, since a display
/// driver may reset a device busy for seconds.
GSD_EXPORT void evaluate_into(const Field& field, const std::shared_ptr<Context>& context, const DeviceQueries& job,
                              const SubmitSync& sync = {});

}  // namespace gpu
}  // namespace gsd
