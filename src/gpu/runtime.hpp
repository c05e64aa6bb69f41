// The Vulkan compute runtime: one Context per device, buffers, cached kernels built from the
// embedded SPIR-V, and a Recorder that records copies, dispatches and barriers into one
// submission. Private to the library; algorithms use it through named kernels only.
#pragma once

#include <gsd/core.hpp>
#include <gsd/gpu.hpp>

#include <volk.h>

#include <gsd/vulkan.hpp>

#include "gpu/kernel_table.hpp"

#include <cstdint>
#include <initializer_list>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace gsd::gpu {

class Context;

/// Where a buffer lives: on the device only, or host-visible for uploads / read-backs.
enum class Memory { Device, Upload, Download };

/// A buffer with its own memory allocation (gsd uses few, large buffers).
class Buffer {
public:
    Buffer() = default;
    Buffer(Context& ctx, VkDeviceSize bytes, Memory memory);
    ~Buffer();
    Buffer(Buffer&& o) noexcept;
    Buffer& operator=(Buffer&& o) noexcept;
    Buffer(const Buffer&) = delete;
    Buffer& operator=(const Buffer&) = delete;

    VkBuffer handle() const { return buffer_; }
    VkDeviceSize size() const { return size_; }
    /// Host pointer for Upload / Download buffers (persistently mapped, coherent).
    void* mapped() const { return mapped_; }
    explicit operator bool() const { return buffer_ != VK_NULL_HANDLE; }

private:
    void release();
    void advise_software_memory(Context& ctx, std::uint32_t type, VkDeviceSize bytes);
    Context* ctx_ = nullptr;
    VkBuffer buffer_ = VK_NULL_HANDLE;
    VkDeviceMemory memory_ = VK_NULL_HANDLE;
    VkDeviceSize size_ = 0;
    void* mapped_ = nullptr;
};

/// A compute pipeline built from an embedded shader with given specialization constants.
/// Constant 0 is always the workgroup size (local_size_x_id = 0); the rest are the shader's.
struct Kernel {
    std::string name;
    std::uint32_t bindings = 0;      ///< buffers at set 0, bindings 0..n−1
    /// The bindings that are uniform texel buffers, not storage buffers.
    TexelBindings texel_bindings;
    std::uint32_t push_bytes = 0;
    std::uint32_t workgroup = 0;
    VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
    VkPipelineLayout layout = VK_NULL_HANDLE;
    VkPipeline pipeline = VK_NULL_HANDLE;
};

/// A buffer range bound to one binding of a dispatch.
struct Binding {
    Binding(const Buffer* b, VkDeviceSize off = 0, VkDeviceSize r = VK_WHOLE_SIZE)
        : buffer(b->handle()), offset(off), range(r), size(b->size()) {}
    /// A range of a buffer gsd does not own (an application's, see evaluate_into).
    Binding(VkBuffer b, VkDeviceSize off, VkDeviceSize r) : buffer(b), offset(off), range(r) {}
    VkBuffer buffer;
    VkDeviceSize offset;
    VkDeviceSize range;
    VkDeviceSize size = 0;  ///< the whole buffer's bytes, where gsd owns it (texel views need it)
};

// The Vulkan commands gsd calls on a device, loaded through that device's own
// vkGetDeviceProcAddr: never global pointers, so gsd's own devices and an application's adopted
// one each get the entry points their driver returned, and nothing clashes with an
// application's loader or volk.
#define GSD_DEVICE_COMMANDS(X)                                                                       \
    X(vkAllocateCommandBuffers) X(vkAllocateMemory) X(vkBeginCommandBuffer) X(vkBindBufferMemory)     \
    X(vkCmdBindPipeline) X(vkCmdCopyBuffer) X(vkCmdDispatch) X(vkCmdFillBuffer)                      \
    X(vkCmdPipelineBarrier) X(vkCmdPushConstants) X(vkCmdPushDescriptorSetKHR) X(vkCreateBuffer)      \
    X(vkCreateCommandPool) X(vkCreateComputePipelines) X(vkCreateDescriptorSetLayout)                \
    X(vkCreateFence) X(vkCreatePipelineCache) X(vkCreatePipelineLayout) X(vkCreateShaderModule)      \
    X(vkDestroyBuffer) X(vkDestroyCommandPool) X(vkDestroyDescriptorSetLayout) X(vkDestroyDevice)    \
    X(vkDestroyFence) X(vkDestroyPipeline) X(vkDestroyPipelineCache) X(vkDestroyPipelineLayout)      \
    X(vkDestroyShaderModule) X(vkDeviceWaitIdle) X(vkEndCommandBuffer) X(vkFreeMemory)               \
    X(vkGetBufferMemoryRequirements) X(vkGetDeviceQueue) X(vkGetFenceStatus) X(vkMapMemory)          \
    X(vkQueueSubmit) X(vkResetCommandBuffer) X(vkResetFences) X(vkUnmapMemory) X(vkWaitForFences)     \
    X(vkCreateQueryPool) X(vkDestroyQueryPool) X(vkCmdResetQueryPool) X(vkCmdWriteTimestamp)         \
    X(vkGetQueryPoolResults) X(vkCreateBufferView) X(vkDestroyBufferView)

// The instance-level commands a Context needs about its physical device.
#define GSD_INSTANCE_COMMANDS(X)                                                                     \
    X(vkGetPhysicalDeviceProperties) X(vkGetPhysicalDeviceMemoryProperties)                          \
    X(vkGetPhysicalDeviceFeatures) X(vkGetPhysicalDeviceQueueFamilyProperties)                       \
    X(vkEnumerateDeviceExtensionProperties) X(vkGetDeviceProcAddr) X(vkCreateDevice)

#define GSD_DECLARE_COMMAND(name) PFN_##name name = nullptr;

struct DeviceFunctions {
    GSD_DEVICE_COMMANDS(GSD_DECLARE_COMMAND)
    /// Loads every command; returns the name of the first one the device does not provide
    /// (its extension not enabled), or nullptr.
    const char* load(VkDevice device, PFN_vkGetDeviceProcAddr get_device_proc_addr);
};

struct InstanceFunctions {
    GSD_INSTANCE_COMMANDS(GSD_DECLARE_COMMAND)
    /// Optional (Vulkan 1.1 instances): subgroup size in DeviceInfo.
    PFN_vkGetPhysicalDeviceProperties2 vkGetPhysicalDeviceProperties2 = nullptr;
    /// Returns the name of the first command the instance does not provide, or nullptr.
    const char* load(VkInstance instance, PFN_vkGetInstanceProcAddr get_instance_proc_addr);
};

// A Context's state (gsd/vulkan.hpp declares the class; its data stays here).
struct Context::State {
    InstanceFunctions instance;
    VkPhysicalDevice physical = VK_NULL_HANDLE;
    DeviceInfo info;
    VkPhysicalDeviceProperties props{};
    VkPhysicalDeviceMemoryProperties mem_props{};
    VkDevice device = VK_NULL_HANDLE;
    bool owns_device = true;  ///< false for an adopted device: never destroyed or idled by gsd
    DeviceFunctions vk{};
    VkQueue queue = VK_NULL_HANDLE;
    std::uint32_t queue_family = 0;
    std::uint32_t workgroup = 64;
    bool has_float64 = false;
    std::uint32_t max_groups_x = 65535;
    VkPipelineCache cache = VK_NULL_HANDLE;
    /// A kernel per key, built once by the first caller, under its slot's own lock: another
    /// kernel can be built at the same time on another thread (a pipeline built ahead, in the
    /// background), and a thread asking for one already built waits at most for a lookup (or a
    /// shader module's making, under kernels_mutex), never for a pipeline's build.
    struct KernelSlot {
        std::mutex building;
        std::unique_ptr<Kernel> kernel;  // null until built (and after a build that threw)
    };
    std::mutex kernels_mutex, queue_mutex;  // kernels_mutex: the two maps below
    std::map<std::string, std::unique_ptr<KernelSlot>> kernels;
    std::map<std::string, VkShaderModule> modules;
    /// $GSD_GPU_PROFILE=1 (and the queue has timestamps): every dispatch and copy is timed on
    /// the device, summed per kernel, and printed when the context ends (docs/gpu.md).
    bool profile = false;
    double timestamp_ns = 1;  ///< nanoseconds per timestamp tick
    std::mutex profile_mutex;
    std::map<std::string, std::pair<double, std::size_t>> device_ns;  ///< kernel → (ns, count)
    /// Host time creating pipelines (profile only): kernel → (ns, count). On software devices
    /// the driver compiles the shader here, which a short run pays in full.
    std::map<std::string, std::pair<double, std::size_t>> pipeline_ns;
    ~State();
};

/// Describes a physical device (what `gsd info` lists) through an instance's commands.
DeviceInfo describe_device(const InstanceFunctions& fn, VkPhysicalDevice dev, std::uint32_t index);

/// One command buffer and its fence: record, submit, wait; reusable.
class Recorder {
    static constexpr std::uint32_t kTimedCommands = 256;  ///< timed per submission (profiling)
public:
    explicit Recorder(Context& ctx);
    ~Recorder();
    Recorder(const Recorder&) = delete;
    Recorder& operator=(const Recorder&) = delete;

    /// How often what is recorded is submitted: once, or again and again (each submit() after
    /// the first, without a begin() between, waits for the last submission and submits the same
    /// commands again; a recording made for once refuses that).
    enum class Reuse { Once, Again };
    /// Waits for the last submission and starts recording anew.
    void begin(Reuse reuse = Reuse::Once);
    void copy(const Buffer& src, VkDeviceSize src_offset, const Buffer& dst, VkDeviceSize dst_offset,
              VkDeviceSize bytes);
    /// Zeroes `bytes` (a multiple of 4) of a buffer from `offset`.
    void fill_zero(const Buffer& dst, VkDeviceSize offset, VkDeviceSize bytes);
    /// Sets `bytes` (a multiple of 4) of a buffer from `offset` to the 32-bit pattern `word`.
    void fill(const Buffer& dst, VkDeviceSize offset, VkDeviceSize bytes, std::uint32_t word);
    /// Records a dispatch of `groups` workgroups (split over y when above the device limit;
    /// kernels compute their linear id as gl_WorkGroupID.y·gl_NumWorkGroups.x + x).
    void dispatch(const Kernel& k, std::initializer_list<Binding> bindings, const void* push,
                  std::uint32_t push_bytes, std::uint32_t groups);
    /// Records a dispatch of x × y × z workgroups as given (y, z ≤ 65 535, the least every
    /// device allows): for kernels that read their cell from gl_WorkGroupID.yz.
    void dispatch_grid(const Kernel& k, std::initializer_list<Binding> bindings, const void* push,
                       std::uint32_t push_bytes, std::uint32_t x, std::uint32_t y, std::uint32_t z);
    /// Makes earlier writes (transfer or compute) visible to later reads (transfer, compute, host).
    void barrier();
    /// Makes writes by anything earlier on the queue (an application's commands, transfers,
    /// host writes) visible to the compute shaders recorded next.
    void barrier_after_external();
    /// Makes the compute shaders' writes visible to anything later on the queue and to the host.
    void barrier_before_external();
    /// Ends the recording (the first time after begin()) and submits; returns at once.
    void submit();
    /// Ends and submits with an application's semaphores and fence (see SubmitSync); this
    /// recorder's own fence still tracks the work, so wait() and done() keep working.
    void submit(const SubmitSync& sync);
    /// Whether the last submission has finished (true if none is pending).
    bool done() const;
    /// Waits for the last submission (no-op if none is pending).
    void wait();
    bool pending() const { return pending_; }

private:
    /// Binds the kernel's pipeline, buffers and push constants for a dispatch.
    void bind(const Kernel& k, std::initializer_list<Binding> bindings, const void* push, std::uint32_t push_bytes);
    /// Profiling: a timestamp before and after a command, labeled (State::profile).
    void time_start();
    void time_end(const std::string& label);
    void collect_times();
    /// Ends the recording before its first submission; before a later one, waits for the last
    /// (or refuses, for a recording made for once).
    void end_for_submit();
    Context& ctx_;
    VkCommandPool pool_ = VK_NULL_HANDLE;
    VkCommandBuffer cmd_ = VK_NULL_HANDLE;
    VkFence fence_ = VK_NULL_HANDLE;
    bool pending_ = false;
    bool ended_ = false;  ///< the recording since begin() is ended (submitted at least once)
    Reuse reuse_ = Reuse::Once;
    VkQueryPool queries_ = VK_NULL_HANDLE;
    std::vector<std::string> timed_;  ///< labels of the timestamp pairs recorded since begin()
    /// Texel views of the bindings recorded since begin(): alive until the submission is done.
    std::vector<VkBufferView> views_;
    void release_views();
    VkBufferView texel_view(const Kernel& k, const Binding& b, std::uint32_t binding);
};

/// llvmpipe (lavapipe) ends every loop of a shader, silently, once the SIMD group running it has
/// iterated 65 535 times in all. Kernels that may get there on a software device count their
/// subgroup's iterations and stop short of this many (0 on hardware: no limit); the host redoes
/// on the CPU what they flag. On a software device such a kernel runs a workgroup of one
/// subgroup, so that the count is the SIMD group's own. $GSD_LOOP_CAP lowers the cap (tests).
std::uint32_t software_loop_cap(const Context& ctx);
/// Whether kernels should run as shaped for a software device's SIMD lanes (llvmpipe). llvmpipe
/// runs the body of every `if` whether a lane takes it or not and every loop's body at least
/// once, reads a storage buffer inside a loop one lane and one scalar at a time (a branch each,
/// unpredictable where the lane mask is), and writes a private array at a lane's own index the
/// same way. So those kernels read trees through uniform texel buffers (a texel fetch is one
/// vector gather), list their work on every lane unmasked and sum it in loops of their own.
/// Software devices use them; GPUs keep the kernels written for GPUs. A shader built both ways
/// (GSD_SOFTWARE_SHAPED, cmake/EmbedShaders.cmake) is NAME and NAME_software.
/// $GSD_SOFTWARE_SHAPED=0|1 overrides (tests run both against the CPU). The software builds use
/// subgroup arithmetic: a device without it keeps the GPUs' kernels.
bool software_shaped(const Context& ctx);
/// How many threads a dispatch's workgroups are split between, each taking one contiguous
/// block of them (llvmpipe: a dispatch of N workgroups is N / T consecutive ones a thread, T its
/// thread count: $LP_NUM_THREADS, else the CPUs the process may use, at most 32); 1 on every
/// other device, which hands workgroups out as its cores free up. Where a kernel's work varies
/// along its queries' order (Morton order: near the input and far from it), such blocks leave
/// threads idle while the dearest block finishes, so the kernels take their work in the order
/// of workgroup_order.glsl, which spreads every block over the whole dispatch. Every pipeline
/// gets it as specialization constant kDispatchThreadsConstant. $GSD_DISPATCH_THREADS sets it
/// on llvmpipe (tests: results do not depend on it).
std::uint32_t dispatch_threads(const Context& ctx);
constexpr std::uint32_t kDispatchThreadsConstant = 63;  // workgroup_order.glsl: DISPATCH_THREADS
/// The pipeline of a kernel of the table (kernel_table.hpp) for these specialization constants
/// and workgroup size (0: the context's default): for a shader built both ways, NAME_software
/// with the table's texel bindings where software_shaped(ctx), else NAME with storage buffers.
const Kernel& kernel(Context& ctx, const KernelSpec& spec, std::initializer_list<std::int32_t> constants = {},
                     std::uint32_t workgroup = 0);
/// The same with the build chosen by the caller (`software`: NAME_software), for work that
/// decides once, for its own limits, which build all its dispatches take.
const Kernel& kernel(Context& ctx, const KernelSpec& spec, std::initializer_list<std::int32_t> constants,
                     std::uint32_t workgroup, bool software);
/// The names of the shaders embedded in the library (NAME and NAME_software builds).
std::vector<std::string> embedded_shader_names();
/// The buffer bindings an embedded shader's SPIR-V declares (one more than the highest); throws
/// gsd::Error for a name that is not embedded. Needs no device.
std::uint32_t shader_binding_count(const std::string& name);
/// The workgroup size for such a kernel: one subgroup on a software device, 0 (the context's
/// default) elsewhere.
std::uint32_t loop_capped_workgroup(const Context& ctx);
/// memcpy, by several threads when it is large (staging buffers of grids).
void copy_bytes(void* dst, const void* src, std::size_t bytes);
/// Copies host data into a new device-local buffer (through a temporary staging buffer; waits).
Buffer upload(Context& ctx, const void* data, std::size_t bytes);
/// Copies a device buffer's first `bytes` back to the host (waits).
void download(Context& ctx, const Buffer& src, void* dst, std::size_t bytes);

/// Throws gsd::Error naming the call if a Vulkan result is an error.
void check(VkResult r, const char* what);

/// Round up to a multiple.
inline std::uint64_t round_up(std::uint64_t v, std::uint64_t m) { return (v + m - 1) / m * m; }

}  // namespace gsd::gpu
