// The Vulkan compute runtime: one Context per device, buffers, cached kernels built from the
// embedded SPIR-V, and a Recorder that records copies, dispatches and barriers into one
// submission. Private to the library; algorithms use it through named kernels only.
#pragma once

#include <gsd/core.hpp>
#include <gsd/gpu.hpp>

#include <volk.h>

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
    std::uint32_t bindings = 0;      ///< storage buffers at set 0, bindings 0..n−1
    std::uint32_t push_bytes = 0;
    std::uint32_t workgroup = 0;
    VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
    VkPipelineLayout layout = VK_NULL_HANDLE;
    VkPipeline pipeline = VK_NULL_HANDLE;
};

/// A buffer range bound to one binding of a dispatch.
struct Binding {
    const Buffer* buffer;
    VkDeviceSize offset = 0;
    VkDeviceSize range = VK_WHOLE_SIZE;
};

class Context {
public:
    Context(VkPhysicalDevice physical, const DeviceInfo& info);
    ~Context();
    Context(const Context&) = delete;
    Context& operator=(const Context&) = delete;

    VkDevice device() const { return device_; }
    /// The device-level Vulkan commands of this device (every vkCmd…, vkCreate…, … on it).
    const VolkDeviceTable& vk() const { return vk_; }
    const DeviceInfo& info() const { return info_; }
    const VkPhysicalDeviceLimits& limits() const { return props_.limits; }
    /// Workgroup size used for 1-D kernels on this device (64 on CPUs, 256 on GPUs).
    std::uint32_t workgroup_size() const { return workgroup_; }
    /// Most workgroups per dispatch along x (larger dispatches continue along y).
    std::uint32_t max_groups_x() const { return max_groups_x_; }
    /// Largest range a storage buffer binding may cover.
    VkDeviceSize max_binding_bytes() const { return props_.limits.maxStorageBufferRange; }
    /// Whether shaders may use float64 (enabled at device creation when supported).
    bool has_float64() const { return has_float64_; }
    /// Bytes of device-local memory in the largest heap.
    VkDeviceSize device_memory_bytes() const { return info_.device_local_bytes; }

    /// The kernel for a shader and its specialization constants (1..n), built once and cached.
    const Kernel& kernel(const std::string& shader, std::uint32_t bindings, std::uint32_t push_bytes,
                         std::initializer_list<std::int32_t> constants = {});

    std::uint32_t memory_type(std::uint32_t type_bits, Memory memory) const;
    VkQueue queue() const { return queue_; }
    std::uint32_t queue_family() const { return queue_family_; }
    std::mutex& queue_mutex() { return queue_mutex_; }

private:
    VkPhysicalDevice physical_;
    DeviceInfo info_;
    VkPhysicalDeviceProperties props_{};
    VkPhysicalDeviceMemoryProperties mem_props_{};
    VkDevice device_ = VK_NULL_HANDLE;
    VolkDeviceTable vk_{};
    VkQueue queue_ = VK_NULL_HANDLE;
    std::uint32_t queue_family_ = 0;
    std::uint32_t workgroup_ = 64;
    bool has_float64_ = false;
    std::uint32_t max_groups_x_ = 65535;
    VkPipelineCache cache_ = VK_NULL_HANDLE;
    std::mutex kernels_mutex_, queue_mutex_;
    std::map<std::string, std::unique_ptr<Kernel>> kernels_;
    std::map<std::string, VkShaderModule> modules_;
};

/// One command buffer and its fence: record, submit, wait; reusable.
class Recorder {
public:
    explicit Recorder(Context& ctx);
    ~Recorder();
    Recorder(const Recorder&) = delete;
    Recorder& operator=(const Recorder&) = delete;

    void begin();
    void copy(const Buffer& src, VkDeviceSize src_offset, const Buffer& dst, VkDeviceSize dst_offset,
              VkDeviceSize bytes);
    /// Zeroes `bytes` (a multiple of 4) of a buffer from `offset`.
    void fill_zero(const Buffer& dst, VkDeviceSize offset, VkDeviceSize bytes);
    /// Records a dispatch of `groups` workgroups (split over y when above the device limit;
    /// kernels compute their linear id as gl_WorkGroupID.y·gl_NumWorkGroups.x + x).
    void dispatch(const Kernel& k, std::initializer_list<Binding> bindings, const void* push,
                  std::uint32_t push_bytes, std::uint32_t groups);
    /// Makes earlier writes (transfer or compute) visible to later reads (transfer, compute, host).
    void barrier();
    /// Ends and submits; returns at once.
    void submit();
    /// Waits for the last submission (no-op if none is pending).
    void wait();
    bool pending() const { return pending_; }

private:
    Context& ctx_;
    VkCommandPool pool_ = VK_NULL_HANDLE;
    VkCommandBuffer cmd_ = VK_NULL_HANDLE;
    VkFence fence_ = VK_NULL_HANDLE;
    bool pending_ = false;
};

/// Copies host data into a new device-local buffer (through a temporary staging buffer; waits).
Buffer upload(Context& ctx, const void* data, std::size_t bytes);
/// Copies a device buffer's first `bytes` back to the host (waits).
void download(Context& ctx, const Buffer& src, void* dst, std::size_t bytes);

/// Throws gsd::Error naming the call if a Vulkan result is an error.
void check(VkResult r, const char* what);

/// Round up to a multiple.
inline std::uint64_t round_up(std::uint64_t v, std::uint64_t m) { return (v + m - 1) / m * m; }

}  // namespace gsd::gpu
