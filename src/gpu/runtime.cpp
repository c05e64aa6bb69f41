// Vulkan runtime: instance and device selection (through volk, so a machine without a loader
// still runs), buffers, kernels from the embedded SPIR-V, and command recording.
#include "gpu/runtime.hpp"

#include "gsd_shader_registry.h"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <dlfcn.h>
#include <sstream>
#include <utility>

namespace gsd::gpu {

void check(VkResult r, const char* what) {
    if (r == VK_SUCCESS) return;
    std::ostringstream s;
    s << "Vulkan call " << what << " failed (VkResult " << int(r) << ")";
    if (r == VK_ERROR_OUT_OF_DEVICE_MEMORY || r == VK_ERROR_OUT_OF_HOST_MEMORY) s << ": out of memory";
    throw Error("gpu", s.str());
}

namespace {

std::atomic<std::uint64_t> g_validation_errors{0};
bool g_validation_active = false;

VKAPI_ATTR VkBool32 VKAPI_CALL on_validation_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                     VkDebugUtilsMessageTypeFlagsEXT,
                                                     const VkDebugUtilsMessengerCallbackDataEXT* data, void*) {
    if (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) {
        ++g_validation_errors;
        std::fprintf(stderr, "gsd: Vulkan validation error: %s\n", data->pMessage);
    } else if (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT) {
        std::fprintf(stderr, "gsd: Vulkan validation warning: %s\n", data->pMessage);
    }
    return VK_FALSE;
}

std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return s;
}

const char* type_name(VkPhysicalDeviceType t) {
    switch (t) {
        case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return "discrete";
        case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return "integrated";
        case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return "virtual";
        case VK_PHYSICAL_DEVICE_TYPE_CPU: return "cpu";
        default: return "other";
    }
}

bool has_extension(VkPhysicalDevice dev, const char* name) {
    std::uint32_t n = 0;
    vkEnumerateDeviceExtensionProperties(dev, nullptr, &n, nullptr);
    std::vector<VkExtensionProperties> ext(n);
    vkEnumerateDeviceExtensionProperties(dev, nullptr, &n, ext.data());
    for (const auto& e : ext)
        if (std::strcmp(e.extensionName, name) == 0) return true;
    return false;
}

bool find_compute_queue(VkPhysicalDevice dev, std::uint32_t& family) {
    std::uint32_t n = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(dev, &n, nullptr);
    std::vector<VkQueueFamilyProperties> q(n);
    vkGetPhysicalDeviceQueueFamilyProperties(dev, &n, q.data());
    // Prefer a compute queue without graphics (a dedicated async compute family).
    for (int pass = 0; pass < 2; ++pass)
        for (std::uint32_t i = 0; i < n; ++i) {
            const bool compute = q[i].queueFlags & VK_QUEUE_COMPUTE_BIT;
            const bool graphics = q[i].queueFlags & VK_QUEUE_GRAPHICS_BIT;
            if (compute && (pass == 1 || !graphics)) { family = i; return true; }
        }
    return false;
}

DeviceInfo describe(VkPhysicalDevice dev, std::uint32_t index) {
    VkPhysicalDeviceSubgroupProperties sub{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_PROPERTIES};
    VkPhysicalDeviceProperties2 p2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
    p2.pNext = &sub;
    vkGetPhysicalDeviceProperties2(dev, &p2);
    const VkPhysicalDeviceProperties& p = p2.properties;
    VkPhysicalDeviceMemoryProperties mem{};
    vkGetPhysicalDeviceMemoryProperties(dev, &mem);

    DeviceInfo d;
    d.index = index;
    d.name = p.deviceName;
    d.type = type_name(p.deviceType);
    d.api_version = std::to_string(VK_API_VERSION_MAJOR(p.apiVersion)) + "." +
                    std::to_string(VK_API_VERSION_MINOR(p.apiVersion)) + "." +
                    std::to_string(VK_API_VERSION_PATCH(p.apiVersion));
    for (std::uint32_t h = 0; h < mem.memoryHeapCount; ++h)
        if (mem.memoryHeaps[h].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT)
            d.device_local_bytes = std::max<std::uint64_t>(d.device_local_bytes, mem.memoryHeaps[h].size);
    d.subgroup_size = sub.subgroupSize;
    d.max_storage_buffer_range = p.limits.maxStorageBufferRange;
    std::uint32_t family = 0;
    if (p.apiVersion < VK_API_VERSION_1_1) d.why_not = "needs Vulkan 1.1";
    else if (!find_compute_queue(dev, family)) d.why_not = "no compute queue";
    else if (!has_extension(dev, VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME)) d.why_not = "no VK_KHR_push_descriptor";
    d.usable = d.why_not.empty();
    return d;
}

// The process-wide Vulkan instance, created on first use. Contexts live here, one per device.
class Runtime {
public:
    static Runtime& get() {
        static Runtime r;
        return r;
    }

    const Inventory& inventory() const { return inventory_; }

    std::shared_ptr<Context> context(std::uint32_t index) {
        std::lock_guard<std::mutex> lock(mutex_);
        auto& slot = contexts_[index];
        if (!slot) slot = std::make_shared<Context>(physical_[index], inventory_.devices[index]);
        return slot;
    }

    ~Runtime() {
        contexts_.clear();
        if (messenger_) vkDestroyDebugUtilsMessengerEXT(instance_, messenger_, nullptr);
        if (instance_) vkDestroyInstance(instance_, nullptr);
    }

private:
    Runtime() {
        if (!load_loader()) return;
        inventory_.loader_found = true;
        try {
            create_instance();
        } catch (const std::exception& e) {
            inventory_.problem = e.what();
            return;
        }
        std::uint32_t n = 0;
        vkEnumeratePhysicalDevices(instance_, &n, nullptr);
        physical_.resize(n);
        vkEnumeratePhysicalDevices(instance_, &n, physical_.data());
        for (std::uint32_t i = 0; i < n; ++i) inventory_.devices.push_back(describe(physical_[i], i));
        if (n == 0) inventory_.problem = "the Vulkan loader reports no devices";
    }

    // $GSD_VULKAN_LOADER names the loader library to use (default: the system's
    // libvulkan.so.1); pointing it at a missing file is how tests exercise "no loader".
    bool load_loader() {
        const char* custom = std::getenv("GSD_VULKAN_LOADER");
        const std::string path = custom && *custom ? custom : "libvulkan.so.1";
        loader_ = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
        if (!loader_) {
            inventory_.problem = "no Vulkan loader (" + path + ") found";
            return false;
        }
        auto gipa = reinterpret_cast<PFN_vkGetInstanceProcAddr>(dlsym(loader_, "vkGetInstanceProcAddr"));
        if (!gipa) {
            inventory_.problem = path + " is not a Vulkan loader";
            return false;
        }
        volkInitializeCustom(gipa);
        return true;
    }

    void create_instance() {
        VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
        app.pApplicationName = "gsd";
        app.pEngineName = "gsd";
        app.apiVersion = VK_API_VERSION_1_1;
        std::vector<const char*> layers, extensions;
        const char* want = std::getenv("GSD_VALIDATION");
        if (want && std::string(want) == "1" && layer_available("VK_LAYER_KHRONOS_validation") &&
            instance_extension_available(VK_EXT_DEBUG_UTILS_EXTENSION_NAME)) {
            layers.push_back("VK_LAYER_KHRONOS_validation");
            extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
            g_validation_active = true;
        }
        VkInstanceCreateInfo ci{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
        ci.pApplicationInfo = &app;
        ci.enabledLayerCount = std::uint32_t(layers.size());
        ci.ppEnabledLayerNames = layers.data();
        ci.enabledExtensionCount = std::uint32_t(extensions.size());
        ci.ppEnabledExtensionNames = extensions.data();
        check(vkCreateInstance(&ci, nullptr, &instance_), "vkCreateInstance");
        volkLoadInstance(instance_);
        if (g_validation_active) {
            VkDebugUtilsMessengerCreateInfoEXT m{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
            m.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
            m.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                            VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
            m.pfnUserCallback = on_validation_message;
            check(vkCreateDebugUtilsMessengerEXT(instance_, &m, nullptr, &messenger_), "vkCreateDebugUtilsMessengerEXT");
        }
    }

    static bool layer_available(const char* name) {
        std::uint32_t n = 0;
        vkEnumerateInstanceLayerProperties(&n, nullptr);
        std::vector<VkLayerProperties> l(n);
        vkEnumerateInstanceLayerProperties(&n, l.data());
        for (const auto& x : l)
            if (std::strcmp(x.layerName, name) == 0) return true;
        return false;
    }
    static bool instance_extension_available(const char* name) {
        std::uint32_t n = 0;
        vkEnumerateInstanceExtensionProperties(nullptr, &n, nullptr);
        std::vector<VkExtensionProperties> e(n);
        vkEnumerateInstanceExtensionProperties(nullptr, &n, e.data());
        for (const auto& x : e)
            if (std::strcmp(x.extensionName, name) == 0) return true;
        return false;
    }

    std::mutex mutex_;
    void* loader_ = nullptr;  // kept open for the life of the process
    Inventory inventory_;
    VkInstance instance_ = VK_NULL_HANDLE;
    VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
    std::vector<VkPhysicalDevice> physical_;
    std::map<std::uint32_t, std::shared_ptr<Context>> contexts_;
};

bool is_real_gpu(const DeviceInfo& d) { return d.usable && !d.is_software(); }

std::string device_list(const Inventory& inv) {
    std::string s;
    for (const auto& d : inv.devices) {
        if (!s.empty()) s.append(", ");
        s.append(std::to_string(d.index)).append(": ").append(d.name);
    }
    return s.empty() ? "none" : s;
}

}  // namespace

// ---- public API ----------------------------------------------------------------------------

Inventory list_devices() { return Runtime::get().inventory(); }
std::uint64_t validation_error_count() { return g_validation_errors.load(); }
bool validation_active() {
    Runtime::get();
    return g_validation_active;
}
std::string device_name(const Context& ctx) { return ctx.info().name; }

Selection select(const std::string& requested) {
    std::string choice = requested;
    if (choice.empty()) {
        const char* env = std::getenv("GSD_DEVICE");
        choice = env && *env ? env : "auto";
    }
    choice = lower(choice);
    Selection sel;
    sel.device_name = "cpu";
    if (choice == "cpu") return sel;

    Runtime& rt = Runtime::get();
    const Inventory& inv = rt.inventory();
    const DeviceInfo* pick = nullptr;
    if (choice == "auto" || choice == "gpu") {
        for (const auto& d : inv.devices)
            if (!pick && is_real_gpu(d)) pick = &d;
        if (!pick && choice == "gpu")
            for (const auto& d : inv.devices)
                if (!pick && d.usable) pick = &d;
        if (!pick) {
            if (!inv.problem.empty()) sel.note = inv.problem + "; using the CPU path";
            else if (choice == "auto" && !inv.devices.empty())
                sel.note = "no GPU found (" + device_list(inv) + "); using the CPU path (--device gpu runs on a software device)";
            else sel.note = "no usable Vulkan device (" + device_list(inv) + "); using the CPU path";
            return sel;
        }
    } else {
        const bool numeric = std::all_of(choice.begin(), choice.end(), [](unsigned char c) { return std::isdigit(c); });
        for (const auto& d : inv.devices) {
            if (pick) break;
            if (numeric ? std::to_string(d.index) == choice : lower(d.name).find(choice) != std::string::npos) pick = &d;
        }
        if (!pick)
            throw Error("device", "no Vulkan device matches '" + requested + "' (devices: " + device_list(inv) +
                                        (inv.problem.empty() ? "" : "; " + inv.problem) + ")");
        if (!pick->usable) throw Error("device", pick->name + " cannot run gsd: " + pick->why_not);
    }
    try {
        sel.context = rt.context(pick->index);
        sel.device_name = pick->name;
    } catch (const Error& e) {
        sel.note = "could not start " + pick->name + " (" + e.what() + "); using the CPU path";
    }
    return sel;
}

// ---- Context -------------------------------------------------------------------------------

Context::Context(VkPhysicalDevice physical, const DeviceInfo& info)
    : physical_(physical), info_(info) {
    vkGetPhysicalDeviceProperties(physical_, &props_);
    vkGetPhysicalDeviceMemoryProperties(physical_, &mem_props_);
    find_compute_queue(physical_, queue_family_);
    const float priority = 1.0f;
    VkDeviceQueueCreateInfo q{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    q.queueFamilyIndex = queue_family_;
    q.queueCount = 1;
    q.pQueuePriorities = &priority;
    const char* extensions[] = {VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME};
    VkDeviceCreateInfo ci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    ci.queueCreateInfoCount = 1;
    ci.pQueueCreateInfos = &q;
    ci.enabledExtensionCount = 1;
    ci.ppEnabledExtensionNames = extensions;
    // float64 in shaders where the device has it: the multigrid keeps its residual in double.
    VkPhysicalDeviceFeatures supported{}, enabled{};
    vkGetPhysicalDeviceFeatures(physical_, &supported);
    enabled.shaderFloat64 = supported.shaderFloat64;
    has_float64_ = supported.shaderFloat64 == VK_TRUE;
    ci.pEnabledFeatures = &enabled;
    check(vkCreateDevice(physical_, &ci, nullptr, &device_), "vkCreateDevice");
    // Device commands go through this context's own table, never volk's globals: each device
    // (and an engine's device, later adopted) gets the entry points its driver returned.
    volkLoadDeviceTable(&vk_, device_);
    vk_.vkGetDeviceQueue(device_, queue_family_, 0, &queue_);
    VkPipelineCacheCreateInfo pc{VK_STRUCTURE_TYPE_PIPELINE_CACHE_CREATE_INFO};
    check(vk_.vkCreatePipelineCache(device_, &pc, nullptr, &cache_), "vkCreatePipelineCache");
    // CPU devices run a workgroup as SIMD lanes over a few threads: small groups keep all cores
    // busy on small jobs. GPUs want enough warps per group to hide latency.
    workgroup_ = info_.is_software() ? 64u : 128u;
    workgroup_ = std::min<std::uint32_t>(workgroup_, props_.limits.maxComputeWorkGroupSize[0]);
    // $GSD_MAX_GROUPS_X lowers the per-dimension group limit so tests can exercise the split of
    // large dispatches over y on small problems.
    max_groups_x_ = props_.limits.maxComputeWorkGroupCount[0];
    if (const char* v = std::getenv("GSD_MAX_GROUPS_X"); v && std::atoi(v) > 0)
        max_groups_x_ = std::min<std::uint32_t>(max_groups_x_, std::uint32_t(std::atoi(v)));
}

Context::~Context() {
    if (!device_) return;
    vk_.vkDeviceWaitIdle(device_);
    for (auto& [name, k] : kernels_) {
        vk_.vkDestroyPipeline(device_, k->pipeline, nullptr);
        vk_.vkDestroyPipelineLayout(device_, k->layout, nullptr);
        vk_.vkDestroyDescriptorSetLayout(device_, k->set_layout, nullptr);
    }
    for (auto& [name, m] : modules_) vk_.vkDestroyShaderModule(device_, m, nullptr);
    vk_.vkDestroyPipelineCache(device_, cache_, nullptr);
    vk_.vkDestroyDevice(device_, nullptr);
}

std::uint32_t Context::memory_type(std::uint32_t bits, Memory memory) const {
    // Preferred property sets first, then acceptable ones.
    std::vector<VkMemoryPropertyFlags> wanted;
    constexpr auto kDev = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, kVis = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT,
                   kCoh = VK_MEMORY_PROPERTY_HOST_COHERENT_BIT, kCached = VK_MEMORY_PROPERTY_HOST_CACHED_BIT;
    switch (memory) {
        case Memory::Device: wanted = {kDev, 0}; break;
        case Memory::Upload: wanted = {kVis | kCoh}; break;
        case Memory::Download: wanted = {kVis | kCoh | kCached, kVis | kCoh}; break;
    }
    for (VkMemoryPropertyFlags w : wanted)
        for (std::uint32_t i = 0; i < mem_props_.memoryTypeCount; ++i)
            if ((bits & (1u << i)) && (mem_props_.memoryTypes[i].propertyFlags & w) == w) return i;
    throw Error("gpu", "no suitable memory type on " + info_.name);
}

const Kernel& Context::kernel(const std::string& shader, std::uint32_t bindings, std::uint32_t push_bytes,
                              std::initializer_list<std::int32_t> constants) {
    std::string key = shader;
    for (auto c : constants) key.append(",").append(std::to_string(c));
    std::lock_guard<std::mutex> lock(kernels_mutex_);
    if (auto it = kernels_.find(key); it != kernels_.end()) return *it->second;

    VkShaderModule& module = modules_[shader];
    if (!module) {
        const detail::EmbeddedShader* found = nullptr;
        for (const auto& s : detail::kEmbeddedShaders)
            if (shader == s.name) found = &s;
        if (!found) throw Error("gpu", "no embedded shader named '" + shader + "'");
        VkShaderModuleCreateInfo mi{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
        mi.codeSize = found->word_count * sizeof(std::uint32_t);
        mi.pCode = found->words;
        check(vk_.vkCreateShaderModule(device_, &mi, nullptr, &module), "vkCreateShaderModule");
    }

    auto k = std::make_unique<Kernel>();
    k->name = shader;
    k->bindings = bindings;
    k->push_bytes = push_bytes;
    k->workgroup = workgroup_;
    std::vector<VkDescriptorSetLayoutBinding> b(bindings);
    for (std::uint32_t i = 0; i < bindings; ++i)
        b[i] = {i, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr};
    VkDescriptorSetLayoutCreateInfo dl{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    dl.flags = VK_DESCRIPTOR_SET_LAYOUT_CREATE_PUSH_DESCRIPTOR_BIT_KHR;
    dl.bindingCount = bindings;
    dl.pBindings = b.data();
    check(vk_.vkCreateDescriptorSetLayout(device_, &dl, nullptr, &k->set_layout), "vkCreateDescriptorSetLayout");
    VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, push_bytes};
    VkPipelineLayoutCreateInfo pl{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    pl.setLayoutCount = 1;
    pl.pSetLayouts = &k->set_layout;
    pl.pushConstantRangeCount = push_bytes ? 1 : 0;
    pl.pPushConstantRanges = &range;
    check(vk_.vkCreatePipelineLayout(device_, &pl, nullptr, &k->layout), "vkCreatePipelineLayout");

    std::vector<std::int32_t> values{std::int32_t(workgroup_)};
    values.insert(values.end(), constants.begin(), constants.end());
    std::vector<VkSpecializationMapEntry> entries(values.size());
    for (std::uint32_t i = 0; i < values.size(); ++i) entries[i] = {i, i * 4, 4};
    VkSpecializationInfo spec{std::uint32_t(entries.size()), entries.data(), values.size() * 4, values.data()};
    VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    ci.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    ci.stage.module = module;
    ci.stage.pName = "main";
    ci.stage.pSpecializationInfo = &spec;
    ci.layout = k->layout;
    check(vk_.vkCreateComputePipelines(device_, cache_, 1, &ci, nullptr, &k->pipeline), "vkCreateComputePipelines");
    return *(kernels_[key] = std::move(k));
}

// ---- Buffer --------------------------------------------------------------------------------

Buffer::Buffer(Context& ctx, VkDeviceSize bytes, Memory memory) : ctx_(&ctx), size_(std::max<VkDeviceSize>(bytes, 16)) {
    VkBufferCreateInfo bi{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    bi.size = size_;
    bi.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    bi.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    check(ctx.vk().vkCreateBuffer(ctx.device(), &bi, nullptr, &buffer_), "vkCreateBuffer");
    VkMemoryRequirements req;
    ctx.vk().vkGetBufferMemoryRequirements(ctx.device(), buffer_, &req);
    VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    ai.allocationSize = req.size;
    try {
        ai.memoryTypeIndex = ctx.memory_type(req.memoryTypeBits, memory);
        check(ctx.vk().vkAllocateMemory(ctx.device(), &ai, nullptr, &memory_), "vkAllocateMemory");
        check(ctx.vk().vkBindBufferMemory(ctx.device(), buffer_, memory_, 0), "vkBindBufferMemory");
        if (memory != Memory::Device) check(ctx.vk().vkMapMemory(ctx.device(), memory_, 0, VK_WHOLE_SIZE, 0, &mapped_), "vkMapMemory");
    } catch (...) {
        release();
        throw;
    }
}

void Buffer::release() {
    if (!ctx_) return;
    if (mapped_) ctx_->vk().vkUnmapMemory(ctx_->device(), memory_);
    if (buffer_) ctx_->vk().vkDestroyBuffer(ctx_->device(), buffer_, nullptr);
    if (memory_) ctx_->vk().vkFreeMemory(ctx_->device(), memory_, nullptr);
    buffer_ = VK_NULL_HANDLE;
    memory_ = VK_NULL_HANDLE;
    mapped_ = nullptr;
}

Buffer::~Buffer() { release(); }

Buffer::Buffer(Buffer&& o) noexcept { *this = std::move(o); }

Buffer& Buffer::operator=(Buffer&& o) noexcept {
    if (this != &o) {
        release();
        ctx_ = std::exchange(o.ctx_, nullptr);
        buffer_ = std::exchange(o.buffer_, VK_NULL_HANDLE);
        memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
        size_ = std::exchange(o.size_, 0);
        mapped_ = std::exchange(o.mapped_, nullptr);
    }
    return *this;
}

// ---- Recorder ------------------------------------------------------------------------------

Recorder::Recorder(Context& ctx) : ctx_(ctx) {
    VkCommandPoolCreateInfo pi{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pi.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    pi.queueFamilyIndex = ctx.queue_family();
    check(ctx.vk().vkCreateCommandPool(ctx.device(), &pi, nullptr, &pool_), "vkCreateCommandPool");
    VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    ai.commandPool = pool_;
    ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    ai.commandBufferCount = 1;
    check(ctx.vk().vkAllocateCommandBuffers(ctx.device(), &ai, &cmd_), "vkAllocateCommandBuffers");
    VkFenceCreateInfo fi{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    check(ctx.vk().vkCreateFence(ctx.device(), &fi, nullptr, &fence_), "vkCreateFence");
}

Recorder::~Recorder() {
    try { wait(); } catch (...) {}
    ctx_.vk().vkDestroyFence(ctx_.device(), fence_, nullptr);
    ctx_.vk().vkDestroyCommandPool(ctx_.device(), pool_, nullptr);
}

void Recorder::begin() {
    wait();
    check(ctx_.vk().vkResetCommandBuffer(cmd_, 0), "vkResetCommandBuffer");
    VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    check(ctx_.vk().vkBeginCommandBuffer(cmd_, &bi), "vkBeginCommandBuffer");
}

void Recorder::copy(const Buffer& src, VkDeviceSize so, const Buffer& dst, VkDeviceSize d, VkDeviceSize bytes) {
    if (bytes == 0) return;
    VkBufferCopy region{so, d, bytes};
    ctx_.vk().vkCmdCopyBuffer(cmd_, src.handle(), dst.handle(), 1, &region);
}

void Recorder::dispatch(const Kernel& k, std::initializer_list<Binding> bindings, const void* push,
                        std::uint32_t push_bytes, std::uint32_t groups) {
    if (bindings.size() != k.bindings) throw Error("gpu", "kernel " + k.name + ": wrong number of buffers");
    if (push_bytes != k.push_bytes) throw Error("gpu", "kernel " + k.name + ": wrong push-constant size");
    if (groups == 0) return;
    ctx_.vk().vkCmdBindPipeline(cmd_, VK_PIPELINE_BIND_POINT_COMPUTE, k.pipeline);
    std::vector<VkDescriptorBufferInfo> infos;
    infos.reserve(bindings.size());
    for (const Binding& b : bindings) infos.push_back({b.buffer->handle(), b.offset, b.range});
    std::vector<VkWriteDescriptorSet> writes(infos.size());
    for (std::uint32_t i = 0; i < infos.size(); ++i) {
        writes[i] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
        writes[i].dstBinding = i;
        writes[i].descriptorCount = 1;
        writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        writes[i].pBufferInfo = &infos[i];
    }
    ctx_.vk().vkCmdPushDescriptorSetKHR(cmd_, VK_PIPELINE_BIND_POINT_COMPUTE, k.layout, 0, std::uint32_t(writes.size()), writes.data());
    if (push_bytes) ctx_.vk().vkCmdPushConstants(cmd_, k.layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, push_bytes, push);
    const std::uint32_t max_x = ctx_.max_groups_x();
    const std::uint32_t x = std::min(groups, max_x);
    const std::uint32_t y = (groups + x - 1) / x;
    ctx_.vk().vkCmdDispatch(cmd_, x, y, 1);
}

void Recorder::fill_zero(const Buffer& dst, VkDeviceSize offset, VkDeviceSize bytes) {
    ctx_.vk().vkCmdFillBuffer(cmd_, dst.handle(), offset, bytes, 0);
}

void Recorder::barrier() {
    VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    mb.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
    mb.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_READ_BIT |
                       VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_HOST_READ_BIT;
    ctx_.vk().vkCmdPipelineBarrier(cmd_, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_HOST_BIT,
                         0, 1, &mb, 0, nullptr, 0, nullptr);
}

void Recorder::submit() {
    check(ctx_.vk().vkEndCommandBuffer(cmd_), "vkEndCommandBuffer");
    VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    si.commandBufferCount = 1;
    si.pCommandBuffers = &cmd_;
    std::lock_guard<std::mutex> lock(ctx_.queue_mutex());
    check(ctx_.vk().vkQueueSubmit(ctx_.queue(), 1, &si, fence_), "vkQueueSubmit");
    pending_ = true;
}

void Recorder::wait() {
    if (!pending_) return;
    pending_ = false;
    check(ctx_.vk().vkWaitForFences(ctx_.device(), 1, &fence_, VK_TRUE, UINT64_MAX), "vkWaitForFences");
    check(ctx_.vk().vkResetFences(ctx_.device(), 1, &fence_), "vkResetFences");
}

Buffer upload(Context& ctx, const void* data, std::size_t bytes) {
    Buffer dst(ctx, bytes, Memory::Device);
    Buffer staging(ctx, bytes, Memory::Upload);
    std::memcpy(staging.mapped(), data, bytes);
    Recorder rec(ctx);
    rec.begin();
    rec.copy(staging, 0, dst, 0, bytes);
    rec.barrier();
    rec.submit();
    rec.wait();
    return dst;
}

void download(Context& ctx, const Buffer& src, void* dst, std::size_t bytes) {
    Buffer staging(ctx, bytes, Memory::Download);
    Recorder rec(ctx);
    rec.begin();
    rec.copy(src, 0, staging, 0, bytes);
    rec.barrier();
    rec.submit();
    rec.wait();
    std::memcpy(dst, staging.mapped(), bytes);
}

}  // namespace gsd::gpu
