// Vulkan runtime: instance and device selection (through volk, so a machine without a loader
// still runs), buffers, kernels from the embedded SPIR-V, and command recording.
// Long (~900 lines) because it is the whole runtime behind one header (runtime.hpp): its parts
// are each short and all share Context::State.
#include "gpu/runtime.hpp"

#include "core/uninitialized.hpp"
#include "gpu/device_choice.hpp"
#include "gpu/on_device.hpp"

#include "gsd_shader_registry.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <dlfcn.h>
#include <sched.h>
#include <thread>
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

bool has_extension(const InstanceFunctions& fn, VkPhysicalDevice dev, const char* name) {
    std::uint32_t n = 0;
    fn.vkEnumerateDeviceExtensionProperties(dev, nullptr, &n, nullptr);
    std::vector<VkExtensionProperties> ext(n);
    fn.vkEnumerateDeviceExtensionProperties(dev, nullptr, &n, ext.data());
    for (const auto& e : ext)
        if (std::strcmp(e.extensionName, name) == 0) return true;
    return false;
}

std::vector<VkQueueFamilyProperties> queue_families(const InstanceFunctions& fn, VkPhysicalDevice dev) {
    std::uint32_t n = 0;
    fn.vkGetPhysicalDeviceQueueFamilyProperties(dev, &n, nullptr);
    std::vector<VkQueueFamilyProperties> q(n);
    fn.vkGetPhysicalDeviceQueueFamilyProperties(dev, &n, q.data());
    return q;
}

bool find_compute_queue(const InstanceFunctions& fn, VkPhysicalDevice dev, std::uint32_t& family) {
    const std::vector<VkQueueFamilyProperties> q = queue_families(fn, dev);
    // Prefer a compute queue without graphics (a dedicated async compute family).
    for (int pass = 0; pass < 2; ++pass)
        for (std::uint32_t i = 0; i < q.size(); ++i) {
            const bool compute = q[i].queueFlags & VK_QUEUE_COMPUTE_BIT;
            const bool graphics = q[i].queueFlags & VK_QUEUE_GRAPHICS_BIT;
            if (compute && (pass == 1 || !graphics)) { family = i; return true; }
        }
    return false;
}

}  // namespace

#define GSD_LOAD_DEVICE_COMMAND(name)                                                   \
    name = reinterpret_cast<PFN_##name>(get_device_proc_addr(device, #name));          \
    if (!name && !missing) missing = #name;

const char* DeviceFunctions::load(VkDevice device, PFN_vkGetDeviceProcAddr get_device_proc_addr) {
    const char* missing = nullptr;
    GSD_DEVICE_COMMANDS(GSD_LOAD_DEVICE_COMMAND)
    return missing;
}

#define GSD_LOAD_INSTANCE_COMMAND(name)                                                 \
    name = reinterpret_cast<PFN_##name>(get_instance_proc_addr(instance, #name));      \
    if (!name && !missing) missing = #name;

const char* InstanceFunctions::load(VkInstance instance, PFN_vkGetInstanceProcAddr get_instance_proc_addr) {
    const char* missing = nullptr;
    GSD_INSTANCE_COMMANDS(GSD_LOAD_INSTANCE_COMMAND)
    vkGetPhysicalDeviceProperties2 = reinterpret_cast<PFN_vkGetPhysicalDeviceProperties2>(
        get_instance_proc_addr(instance, "vkGetPhysicalDeviceProperties2"));
    return missing;
}

DeviceInfo describe_device(const InstanceFunctions& fn, VkPhysicalDevice dev, std::uint32_t index) {
    VkPhysicalDeviceSubgroupProperties sub{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_PROPERTIES};
    VkPhysicalDeviceProperties2 p2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
    p2.pNext = &sub;
    if (fn.vkGetPhysicalDeviceProperties2) fn.vkGetPhysicalDeviceProperties2(dev, &p2);
    else fn.vkGetPhysicalDeviceProperties(dev, &p2.properties);
    const VkPhysicalDeviceProperties& p = p2.properties;
    VkPhysicalDeviceMemoryProperties mem{};
    fn.vkGetPhysicalDeviceMemoryProperties(dev, &mem);

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
    const bool compute = sub.supportedStages & VK_SHADER_STAGE_COMPUTE_BIT;
    d.subgroup_vote = compute && (sub.supportedOperations & VK_SUBGROUP_FEATURE_VOTE_BIT);
    d.subgroup_ballot = compute && (sub.supportedOperations & VK_SUBGROUP_FEATURE_BALLOT_BIT);
    d.subgroup_arithmetic = compute && (sub.supportedOperations & VK_SUBGROUP_FEATURE_ARITHMETIC_BIT);
    d.subgroup_shuffle = compute && (sub.supportedOperations & VK_SUBGROUP_FEATURE_SHUFFLE_BIT);
    d.max_storage_buffer_range = p.limits.maxStorageBufferRange;
    std::uint32_t family = 0;
    if (p.apiVersion < VK_API_VERSION_1_1) d.why_not = "needs Vulkan 1.1";
    else if (!find_compute_queue(fn, dev, family)) d.why_not = "no compute queue";
    else if (!has_extension(fn, dev, VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME)) d.why_not = "no VK_KHR_push_descriptor";
    else if (!d.subgroup_vote || !d.subgroup_ballot)
        d.why_not = "no subgroup vote and ballot in compute shaders (the tree walks vote per node)";
    d.usable = d.why_not.empty();
    return d;
}

namespace {

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
        if (!slot) slot = std::make_shared<Context>(fn_, physical_[index], inventory_.devices[index]);
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
        for (std::uint32_t i = 0; i < n; ++i) inventory_.devices.push_back(describe_device(fn_, physical_[i], i));
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
        if (const char* missing = fn_.load(instance_, vkGetInstanceProcAddr))
            throw Error("gpu", std::string("the Vulkan loader lacks ") + missing);
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
    InstanceFunctions fn_;
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
bool shares_host_cores(const Context& ctx) { return ctx.info().is_software(); }

Selection select(const Device& device) {
    Selection sel;
    if (device.context()) {  // a context in hand: one gsd made, or an application's adopted one
        sel.context = device.context();
        sel.device_name = device.context()->info().name;
        return sel;
    }
    const std::string requested = requested_choice(device);
    const std::string choice = lower(requested);
    sel.device_name = "cpu";
    if (choice == "cpu") return sel;

    // Loading the Vulkan drivers to find out costs 60-70 ms (and twice that in CPU time) where
    // Mesa's are installed; on a machine with no GPU device node "auto" cannot find a GPU.
    if (choice == "auto" && !has_gpu_device_node()) {
        sel.note = "no GPU found (no GPU device node in /dev); using the CPU path (--device gpu runs on a software device)";
        return sel;
    }
    Runtime& rt = Runtime::get();
    const Inventory& inv = rt.inventory();
    const DeviceInfo* pick = nullptr;
    const bool may_fall_back = choice == "auto" || choice == "gpu";
    if (may_fall_back) {
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
        // One policy: a device asked for by index or name must run; auto and gpu fall back.
        if (!may_fall_back) throw Error("device", "could not start " + pick->name + ": " + e.what());
        sel.note = "could not start " + pick->name + " (" + e.what() + "); using the CPU path";
    }
    return sel;
}

// ---- Context -------------------------------------------------------------------------------

Context::Context(std::unique_ptr<State> state) : s_(std::move(state)) {}

Context::Context(const InstanceFunctions& instance, VkPhysicalDevice physical, const DeviceInfo& info)
    : s_(std::make_unique<State>()) {
    State& s = *s_;
    s.instance = instance;
    s.physical = physical;
    s.info = info;
    find_compute_queue(instance, physical, s.queue_family);
    const float priority = 1.0f;
    VkDeviceQueueCreateInfo q{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    q.queueFamilyIndex = s.queue_family;
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
    instance.vkGetPhysicalDeviceFeatures(physical, &supported);
    enabled.shaderFloat64 = supported.shaderFloat64;
    s.has_float64 = supported.shaderFloat64 == VK_TRUE;
    ci.pEnabledFeatures = &enabled;
    check(instance.vkCreateDevice(physical, &ci, nullptr, &s.device), "vkCreateDevice");
    if (const char* missing = s.vk.load(s.device, instance.vkGetDeviceProcAddr))
        throw Error("gpu", info.name + " does not provide " + missing);
    s.vk.vkGetDeviceQueue(s.device, s.queue_family, 0, &s.queue);
    init_common();
}

std::shared_ptr<Context> Context::adopt(VkInstance instance, VkPhysicalDevice physical, VkDevice device,
                                        std::uint32_t queue_family, VkQueue queue,
                                        PFN_vkGetInstanceProcAddr get_instance_proc_addr,
                                        const AdoptOptions& options) {
    if (!instance || !physical || !device || !queue || !get_instance_proc_addr)
        throw Error("device", "Context::adopt needs the instance, physical device, device, queue and "
                              "vkGetInstanceProcAddr (one of them is null)");
    auto s = std::make_unique<State>();
    if (const char* missing = s->instance.load(instance, get_instance_proc_addr))
        throw Error("device", std::string("the instance handed to Context::adopt does not provide ") + missing);
    s->physical = physical;
    s->info = describe_device(s->instance, physical, ~std::uint32_t(0));
    // A device without the extension cannot have enabled it (some layers hand out commands of
    // disabled extensions anyway, so the load below is not the only check).
    if (s->info.why_not == "needs Vulkan 1.1" || s->info.why_not == "no VK_KHR_push_descriptor")
        throw Error("device", s->info.name + " cannot run gsd: " + s->info.why_not);
    if (options.float64_enabled) {
        VkPhysicalDeviceFeatures supported{};
        s->instance.vkGetPhysicalDeviceFeatures(physical, &supported);
        if (!supported.shaderFloat64)
            throw Error("AdoptOptions::float64_enabled", s->info.name + " does not support shaderFloat64");
    }
    const std::vector<VkQueueFamilyProperties> families = queue_families(s->instance, physical);
    if (queue_family >= families.size() || !(families[queue_family].queueFlags & VK_QUEUE_COMPUTE_BIT))
        throw Error("device", "queue family " + std::to_string(queue_family) + " of " + s->info.name +
                                  " has no compute queue");
    s->device = device;
    s->owns_device = false;
    s->queue = queue;
    s->queue_family = queue_family;
    s->has_float64 = options.float64_enabled;
    // A command of an extension the application did not enable loads as null: that is how a
    // device created without VK_KHR_push_descriptor shows.
    if (const char* missing = s->vk.load(device, s->instance.vkGetDeviceProcAddr))
        throw Error("device", std::string("the adopted device does not provide ") + missing +
                                  (std::strstr(missing, "KHR") ? " (create it with VK_KHR_push_descriptor enabled)" : ""));
    s->info.usable = true;
    s->info.why_not.clear();
    std::shared_ptr<Context> ctx(new Context(std::move(s)));
    ctx->init_common();
    return ctx;
}

// What both kinds of context set up once the device and its commands are known.
void Context::init_common() {
    State& s = *s_;
    s.instance.vkGetPhysicalDeviceProperties(s.physical, &s.props);
    s.instance.vkGetPhysicalDeviceMemoryProperties(s.physical, &s.mem_props);
    VkPipelineCacheCreateInfo pc{VK_STRUCTURE_TYPE_PIPELINE_CACHE_CREATE_INFO};
    check(s.vk.vkCreatePipelineCache(s.device, &pc, nullptr, &s.cache), "vkCreatePipelineCache");
    // CPU devices run a workgroup as SIMD lanes over a few threads: small groups keep all cores
    // busy on small jobs. GPUs want enough warps per group to hide latency.
    s.workgroup = s.info.is_software() ? 64u : 128u;
    s.workgroup = std::min<std::uint32_t>(s.workgroup, s.props.limits.maxComputeWorkGroupSize[0]);
    // $GSD_MAX_GROUPS_X lowers the per-dimension group limit so tests can exercise the split of
    // large dispatches over y on small problems.
    s.max_groups_x = s.props.limits.maxComputeWorkGroupCount[0];
    if (const char* v = std::getenv("GSD_GPU_PROFILE"); v && v[0] == '1' && s.props.limits.timestampPeriod > 0) {
        std::uint32_t n = 0;
        s.instance.vkGetPhysicalDeviceQueueFamilyProperties(s.physical, &n, nullptr);
        std::vector<VkQueueFamilyProperties> families(n);
        s.instance.vkGetPhysicalDeviceQueueFamilyProperties(s.physical, &n, families.data());
        s.profile = s.queue_family < n && families[s.queue_family].timestampValidBits > 0;
        s.timestamp_ns = s.props.limits.timestampPeriod;
    }
    if (const char* v = std::getenv("GSD_MAX_GROUPS_X"); v && std::atoi(v) > 0)
        s.max_groups_x = std::min<std::uint32_t>(s.max_groups_x, std::uint32_t(std::atoi(v)));
}

Context::State::~State() {
    if (profile && !device_ns.empty()) {
        std::fprintf(stderr, "gsd: device time on %s (GSD_GPU_PROFILE):\n", info.name.c_str());
        for (const auto& [name, t] : device_ns)
            std::fprintf(stderr, "gsd:   %-16s %10.3f ms in %zu\n", name.c_str(), t.first * 1e-6, t.second);
        std::fprintf(stderr, "gsd: host time creating pipelines (GSD_GPU_PROFILE):\n");
        for (const auto& [name, t] : pipeline_ns)
            std::fprintf(stderr, "gsd:   %-16s %10.3f ms in %zu\n", name.c_str(), t.first * 1e-6, t.second);
    }
    if (!device) return;
    if (!vk.vkDestroyPipelineCache) {  // the device's commands failed to load: only it to free
        auto destroy = reinterpret_cast<PFN_vkDestroyDevice>(instance.vkGetDeviceProcAddr(device, "vkDestroyDevice"));
        if (owns_device && destroy) destroy(device, nullptr);
        return;
    }
    // An application's device is never idled: everything gsd submitted to it was waited for
    // by the objects that submitted it, which hold this context and so went first.
    if (owns_device) vk.vkDeviceWaitIdle(device);
    for (auto& [name, slot] : kernels) {
        const std::unique_ptr<Kernel>& k = slot->kernel;
        if (!k) continue;
        vk.vkDestroyPipeline(device, k->pipeline, nullptr);
        vk.vkDestroyPipelineLayout(device, k->layout, nullptr);
        vk.vkDestroyDescriptorSetLayout(device, k->set_layout, nullptr);
    }
    for (auto& [name, m] : modules) vk.vkDestroyShaderModule(device, m, nullptr);
    if (cache) vk.vkDestroyPipelineCache(device, cache, nullptr);
    if (owns_device) vk.vkDestroyDevice(device, nullptr);
}

Context::~Context() = default;

VkDevice Context::device() const { return s_->device; }
VkPhysicalDevice Context::physical_device() const { return s_->physical; }
VkQueue Context::queue() const { return s_->queue; }
std::uint32_t Context::queue_family() const { return s_->queue_family; }
const DeviceInfo& Context::info() const { return s_->info; }
bool Context::adopted() const { return !s_->owns_device; }
const DeviceFunctions& Context::vk() const { return s_->vk; }
const VkPhysicalDeviceLimits& Context::limits() const { return s_->props.limits; }
std::uint32_t Context::workgroup_size() const { return s_->workgroup; }
std::uint32_t Context::max_groups_x() const { return s_->max_groups_x; }
VkDeviceSize Context::max_binding_bytes() const { return s_->props.limits.maxStorageBufferRange; }
bool Context::has_float64() const { return s_->has_float64; }
VkDeviceSize Context::device_memory_bytes() const { return s_->info.device_local_bytes; }
std::mutex& Context::queue_mutex() { return s_->queue_mutex; }

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
        for (std::uint32_t i = 0; i < s_->mem_props.memoryTypeCount; ++i)
            if ((bits & (1u << i)) && (s_->mem_props.memoryTypes[i].propertyFlags & w) == w) return i;
    throw Error("gpu", "no suitable memory type on " + s_->info.name);
}

namespace {

// The shader embedded under `name` (cmake/EmbedShaders.cmake), or an error.
const detail::EmbeddedShader& embedded_shader(const std::string& name) {
    for (const auto& s : detail::kEmbeddedShaders)
        if (name == s.name) return s;
    throw Error("gpu", "no embedded shader named '" + name + "'");
}

// One more than the highest `binding` a shader's SPIR-V decorates (OpDecorate … Binding n); 0
// when it has none.
std::uint32_t spirv_binding_count(const detail::EmbeddedShader& s) {
    constexpr std::uint32_t kOpDecorate = 71, kDecorationBinding = 33;
    std::uint32_t count = 0;
    for (std::size_t i = 5; i < s.word_count;) {  // past the 5-word header
        const std::uint32_t words = s.words[i] >> 16, op = s.words[i] & 0xffffu;
        if (words == 0) break;  // malformed: stop rather than loop
        if (op == kOpDecorate && words >= 4 && s.words[i + 2] == kDecorationBinding)
            count = std::max(count, s.words[i + 3] + 1);
        i += words;
    }
    return count;
}

}  // namespace

const Kernel& Context::kernel(const std::string& shader, std::uint32_t bindings, std::uint32_t push_bytes,
                              std::initializer_list<std::int32_t> constants, std::uint32_t workgroup,
                              TexelBindings texel_bindings) {
    State& st = *s_;
    if (workgroup == 0) workgroup = st.workgroup;
    const TexelBindings& t = texel_bindings;
    if (!t.disjoint() || (bindings < 32 && (t.all() >> bindings) != 0))
        throw Error("gpu", "kernel " + shader + ": its texel bindings overlap or name a binding it does not have");
    std::string key = shader + "@" + std::to_string(workgroup) + "/" + std::to_string(texel_bindings.vec4) + "." +
                      std::to_string(texel_bindings.float1) + "." + std::to_string(texel_bindings.double1) + "." +
                      std::to_string(texel_bindings.double2);
    for (auto c : constants) key.append(",").append(std::to_string(c));
    const std::uint32_t threads = dispatch_threads(*this);
    key.append("|").append(std::to_string(threads));
    State::KernelSlot* slot = nullptr;
    {
        std::lock_guard<std::mutex> lock(st.kernels_mutex);
        std::unique_ptr<State::KernelSlot>& s = st.kernels[key];
        if (!s) s = std::make_unique<State::KernelSlot>();
        slot = s.get();
    }
    std::lock_guard<std::mutex> building(slot->building);
    if (slot->kernel) return *slot->kernel;

    const detail::EmbeddedShader& code = embedded_shader(shader);
    // The binding count a caller states must be the shader's own (a miscount shows otherwise only
    // under the validation layer, or as a crash).
    if (const std::uint32_t declared = spirv_binding_count(code); declared != bindings)
        throw Error("gpu", "kernel " + shader + " is called with " + std::to_string(bindings) + " bindings; its shader declares " +
                               std::to_string(declared));
    VkShaderModule module = VK_NULL_HANDLE;
    {
        std::lock_guard<std::mutex> lock(st.kernels_mutex);
        VkShaderModule& kept = st.modules[shader];
        if (!kept) {
            VkShaderModuleCreateInfo mi{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
            mi.codeSize = code.word_count * sizeof(std::uint32_t);
            mi.pCode = code.words;
            check(st.vk.vkCreateShaderModule(st.device, &mi, nullptr, &kept), "vkCreateShaderModule");
        }
        module = kept;
    }

    auto k = std::make_unique<Kernel>();
    // A step that throws leaves the slot empty (the next caller tries again); what the steps
    // before it made is destroyed here, not leaked.
    struct Unfinished {
        State& st;
        Kernel* k;
        ~Unfinished() {
            if (!k) return;
            if (k->pipeline) st.vk.vkDestroyPipeline(st.device, k->pipeline, nullptr);
            if (k->layout) st.vk.vkDestroyPipelineLayout(st.device, k->layout, nullptr);
            if (k->set_layout) st.vk.vkDestroyDescriptorSetLayout(st.device, k->set_layout, nullptr);
        }
    } unfinished{st, k.get()};
    k->name = shader;
    k->bindings = bindings;
    k->push_bytes = push_bytes;
    k->workgroup = workgroup;
    k->texel_bindings = texel_bindings;
    std::vector<VkDescriptorSetLayoutBinding> b(bindings);
    for (std::uint32_t i = 0; i < bindings; ++i)
        b[i] = {i, (texel_bindings.all() >> i) & 1u ? VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1,
                VK_SHADER_STAGE_COMPUTE_BIT, nullptr};
    VkDescriptorSetLayoutCreateInfo dl{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    dl.flags = VK_DESCRIPTOR_SET_LAYOUT_CREATE_PUSH_DESCRIPTOR_BIT_KHR;
    dl.bindingCount = bindings;
    dl.pBindings = b.data();
    check(st.vk.vkCreateDescriptorSetLayout(st.device, &dl, nullptr, &k->set_layout), "vkCreateDescriptorSetLayout");
    VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, push_bytes};
    VkPipelineLayoutCreateInfo pl{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    pl.setLayoutCount = 1;
    pl.pSetLayouts = &k->set_layout;
    pl.pushConstantRangeCount = push_bytes ? 1 : 0;
    pl.pPushConstantRanges = &range;
    check(st.vk.vkCreatePipelineLayout(st.device, &pl, nullptr, &k->layout), "vkCreatePipelineLayout");

    std::vector<std::int32_t> values{std::int32_t(workgroup)};
    values.insert(values.end(), constants.begin(), constants.end());
    std::vector<VkSpecializationMapEntry> entries(values.size());
    for (std::uint32_t i = 0; i < values.size(); ++i) entries[i] = {i, i * 4, 4};
    // Every kernel gets the device's dispatch threads (workgroup_order.glsl); a shader without
    // that constant ignores the entry.
    values.push_back(std::int32_t(threads));
    entries.push_back({kDispatchThreadsConstant, std::uint32_t(entries.size() * 4), 4});
    VkSpecializationInfo spec{std::uint32_t(entries.size()), entries.data(), values.size() * 4, values.data()};
    VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    ci.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    ci.stage.module = module;
    ci.stage.pName = "main";
    ci.stage.pSpecializationInfo = &spec;
    ci.layout = k->layout;
    const auto start = std::chrono::steady_clock::now();
    check(st.vk.vkCreateComputePipelines(st.device, st.cache, 1, &ci, nullptr, &k->pipeline), "vkCreateComputePipelines");
    if (st.profile) {
        std::lock_guard<std::mutex> plock(st.profile_mutex);
        auto& t = st.pipeline_ns[shader];
        t.first += std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start).count();
        ++t.second;
    }
    unfinished.k = nullptr;
    slot->kernel = std::move(k);
    return *slot->kernel;
}

// ---- Buffer --------------------------------------------------------------------------------

Buffer::Buffer(Context& ctx, VkDeviceSize bytes, Memory memory) : ctx_(&ctx), size_(std::max<VkDeviceSize>(bytes, 16)) {
    VkBufferCreateInfo bi{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    bi.size = size_;
    bi.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT |
               VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
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
        advise_software_memory(ctx, ai.memoryTypeIndex, ai.allocationSize);
    } catch (...) {
        release();
        throw;
    }
}

// A software device's memory is host memory, as a rule not touched yet: where it is large,
// huge pages spare the page faults its first use would take, a thread of the device's at a
// time (~11 µs a 4 KiB page on the virtual machines measured; core/uninitialized.hpp).
// `gsd shm grid tooth.ply --grid 128` on lavapipe: 33.5–34.0k → 28.7–29.9k page faults, its
// multigrid (step 3) 0.64–0.65 → 0.61–0.62 s, three runs in turn.
void Buffer::advise_software_memory(Context& ctx, std::uint32_t type, VkDeviceSize bytes) {
    if (!ctx.info().is_software() || bytes < gsd::detail::kLargeBlock) return;
    void* at = mapped_;
    const bool visible = (ctx.state().mem_props.memoryTypes[type].propertyFlags & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT) != 0;
    if (!at && visible &&
        ctx.vk().vkMapMemory(ctx.device(), memory_, 0, VK_WHOLE_SIZE, 0, &at) != VK_SUCCESS)
        return;
    if (at) gsd::detail::advise_huge_pages(at, std::size_t(bytes));
    if (at && !mapped_) ctx.vk().vkUnmapMemory(ctx.device(), memory_);
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
    release_views();
    if (queries_) ctx_.vk().vkDestroyQueryPool(ctx_.device(), queries_, nullptr);
    ctx_.vk().vkDestroyFence(ctx_.device(), fence_, nullptr);
    ctx_.vk().vkDestroyCommandPool(ctx_.device(), pool_, nullptr);
}

void Recorder::begin(Reuse reuse) {
    wait();
    release_views();
    check(ctx_.vk().vkResetCommandBuffer(cmd_, 0), "vkResetCommandBuffer");
    VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    bi.flags = reuse == Reuse::Once ? VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT : 0;
    ended_ = false;
    reuse_ = reuse;
    check(ctx_.vk().vkBeginCommandBuffer(cmd_, &bi), "vkBeginCommandBuffer");
    timed_.clear();
    if (ctx_.state().profile) {
        if (!queries_) {
            VkQueryPoolCreateInfo qi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
            qi.queryType = VK_QUERY_TYPE_TIMESTAMP;
            qi.queryCount = 2 * kTimedCommands;
            check(ctx_.vk().vkCreateQueryPool(ctx_.device(), &qi, nullptr, &queries_), "vkCreateQueryPool");
        }
        ctx_.vk().vkCmdResetQueryPool(cmd_, queries_, 0, 2 * kTimedCommands);
    }
}

void Recorder::time_start() {
    if (!queries_ || timed_.size() >= kTimedCommands) return;
    // Written once everything before it has finished: the command's own start, barriers or not.
    ctx_.vk().vkCmdWriteTimestamp(cmd_, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries_, std::uint32_t(2 * timed_.size()));
}

void Recorder::time_end(const std::string& label) {
    if (!queries_ || timed_.size() >= kTimedCommands) return;
    ctx_.vk().vkCmdWriteTimestamp(cmd_, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries_, std::uint32_t(2 * timed_.size() + 1));
    timed_.push_back(label);
}

void Recorder::collect_times() {
    if (!queries_ || timed_.empty()) return;
    std::vector<std::uint64_t> ticks(2 * timed_.size());
    check(ctx_.vk().vkGetQueryPoolResults(ctx_.device(), queries_, 0, std::uint32_t(ticks.size()), ticks.size() * 8, ticks.data(), 8,
                                          VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
          "vkGetQueryPoolResults");
    Context::State& s = ctx_.state();
    std::lock_guard<std::mutex> lock(s.profile_mutex);
    for (std::size_t i = 0; i < timed_.size(); ++i) {
        auto& t = s.device_ns[timed_[i]];
        t.first += double(ticks[2 * i + 1] - ticks[2 * i]) * s.timestamp_ns;
        ++t.second;
    }
    // timed_ is kept until the next begin(): a recording submitted again times the same commands.
}

void Recorder::copy(const Buffer& src, VkDeviceSize so, const Buffer& dst, VkDeviceSize d, VkDeviceSize bytes) {
    if (bytes == 0) return;
    VkBufferCopy region{so, d, bytes};
    time_start();
    ctx_.vk().vkCmdCopyBuffer(cmd_, src.handle(), dst.handle(), 1, &region);
    time_end("(copy)");
}

void Recorder::dispatch(const Kernel& k, std::initializer_list<Binding> bindings, const void* push,
                        std::uint32_t push_bytes, std::uint32_t groups) {
    if (groups == 0) return;
    bind(k, bindings, push, push_bytes);
    const std::uint32_t max_x = ctx_.max_groups_x();
    const std::uint32_t x = std::min(groups, max_x);
    const std::uint32_t y = (groups + x - 1) / x;
    time_start();
    ctx_.vk().vkCmdDispatch(cmd_, x, y, 1);
    time_end(k.name);
}

void Recorder::dispatch_grid(const Kernel& k, std::initializer_list<Binding> bindings, const void* push,
                             std::uint32_t push_bytes, std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    if (x == 0 || y == 0 || z == 0) return;
    if (x > ctx_.max_groups_x() || std::max(y, z) > 65535u)
        throw Error("gpu", "kernel " + k.name + ": more workgroups along an axis than the device allows");
    bind(k, bindings, push, push_bytes);
    time_start();
    ctx_.vk().vkCmdDispatch(cmd_, x, y, z);
    time_end(k.name);
}

void Recorder::bind(const Kernel& k, std::initializer_list<Binding> bindings, const void* push, std::uint32_t push_bytes) {
    if (bindings.size() != k.bindings) throw Error("gpu", "kernel " + k.name + ": wrong number of buffers");
    if (push_bytes != k.push_bytes) throw Error("gpu", "kernel " + k.name + ": wrong push-constant size");
    ctx_.vk().vkCmdBindPipeline(cmd_, VK_PIPELINE_BIND_POINT_COMPUTE, k.pipeline);
    std::vector<VkDescriptorBufferInfo> infos;
    std::vector<VkBufferView> views(bindings.size(), VK_NULL_HANDLE);
    infos.reserve(bindings.size());
    for (const Binding& b : bindings) {
        if ((k.texel_bindings.all() >> infos.size()) & 1u) views[infos.size()] = texel_view(k, b, std::uint32_t(infos.size()));
        infos.push_back({b.buffer, b.offset, b.range});
    }
    std::vector<VkWriteDescriptorSet> writes(infos.size());
    for (std::uint32_t i = 0; i < infos.size(); ++i) {
        writes[i] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
        writes[i].dstBinding = i;
        writes[i].descriptorCount = 1;
        if (views[i]) {
            writes[i].descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
            writes[i].pTexelBufferView = &views[i];
        } else {
            writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
            writes[i].pBufferInfo = &infos[i];
        }
    }
    ctx_.vk().vkCmdPushDescriptorSetKHR(cmd_, VK_PIPELINE_BIND_POINT_COMPUTE, k.layout, 0, std::uint32_t(writes.size()), writes.data());
    if (push_bytes) ctx_.vk().vkCmdPushConstants(cmd_, k.layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, push_bytes, push);
}

VkBufferView Recorder::texel_view(const Kernel& k, const Binding& b, std::uint32_t binding) {
    const VkPhysicalDeviceLimits& lim = ctx_.limits();
    const TexelBindings& t = k.texel_bindings;
    VkFormat format = VK_FORMAT_R32G32B32A32_SFLOAT;
    VkDeviceSize texel = 16;
    if ((t.float1 >> binding) & 1u) format = VK_FORMAT_R32_SFLOAT, texel = 4;
    if ((t.double1 >> binding) & 1u) format = VK_FORMAT_R32G32_UINT, texel = 8;
    if ((t.double2 >> binding) & 1u) format = VK_FORMAT_R32G32B32A32_UINT, texel = 16;
    if (b.size == 0) throw Error("gpu", "kernel " + k.name + ": a texel binding needs a buffer gsd owns");
    const VkDeviceSize bytes = b.range == VK_WHOLE_SIZE ? (b.size - b.offset) / texel * texel : b.range;
    if (b.offset % std::max<VkDeviceSize>(lim.minTexelBufferOffsetAlignment, 1) != 0 || bytes == 0 || bytes % texel != 0 ||
        b.offset + bytes > b.size || bytes / texel > lim.maxTexelBufferElements)
        throw Error("gpu", "kernel " + k.name + ": a texel binding of " + std::to_string(bytes) + " bytes at " +
                               std::to_string(b.offset) + " is more than or not aligned as the device allows");
    VkBufferViewCreateInfo vi{VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO};
    vi.buffer = b.buffer;
    vi.format = format;
    vi.offset = b.offset;
    vi.range = bytes;
    VkBufferView view = VK_NULL_HANDLE;
    check(ctx_.vk().vkCreateBufferView(ctx_.device(), &vi, nullptr, &view), "vkCreateBufferView");
    views_.push_back(view);
    return view;
}

void Recorder::release_views() {
    for (VkBufferView v : views_) ctx_.vk().vkDestroyBufferView(ctx_.device(), v, nullptr);
    views_.clear();
}

void Recorder::fill_zero(const Buffer& dst, VkDeviceSize offset, VkDeviceSize bytes) {
    fill(dst, offset, bytes, 0);
}

void Recorder::fill(const Buffer& dst, VkDeviceSize offset, VkDeviceSize bytes, std::uint32_t word) {
    ctx_.vk().vkCmdFillBuffer(cmd_, dst.handle(), offset, bytes, word);
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

void Recorder::end_for_submit() {
    if (ended_) {
        if (reuse_ == Reuse::Once) throw Error("gpu", "a recording made for one submission was submitted again");
        wait();  // neither the command buffer nor the fence may be in use twice at once
        return;
    }
    check(ctx_.vk().vkEndCommandBuffer(cmd_), "vkEndCommandBuffer");
    ended_ = true;
}

void Recorder::submit() {
    end_for_submit();
    VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    si.commandBufferCount = 1;
    si.pCommandBuffers = &cmd_;
    std::lock_guard<std::mutex> lock(ctx_.queue_mutex());
    check(ctx_.vk().vkQueueSubmit(ctx_.queue(), 1, &si, fence_), "vkQueueSubmit");
    pending_ = true;
}

void Recorder::barrier_after_external() {
    VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    mb.srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT;
    mb.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT;
    ctx_.vk().vkCmdPipelineBarrier(cmd_, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1,
                                   &mb, 0, nullptr, 0, nullptr);
}

void Recorder::barrier_before_external() {
    VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    mb.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    mb.dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT | VK_ACCESS_HOST_READ_BIT;
    ctx_.vk().vkCmdPipelineBarrier(cmd_, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                                   VK_PIPELINE_STAGE_ALL_COMMANDS_BIT | VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &mb, 0,
                                   nullptr, 0, nullptr);
}

void Recorder::submit(const SubmitSync& sync) {
    if (!sync.wait_stages.empty() && sync.wait_stages.size() != sync.wait.size())
        throw Error("SubmitSync::wait_stages", "needs one stage mask per wait semaphore (" +
                                                   std::to_string(sync.wait.size()) + "), or none");
    std::vector<VkPipelineStageFlags> stages = sync.wait_stages;
    if (stages.empty()) stages.assign(sync.wait.size(), VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
    end_for_submit();
    VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    si.waitSemaphoreCount = std::uint32_t(sync.wait.size());
    si.pWaitSemaphores = sync.wait.data();
    si.pWaitDstStageMask = stages.data();
    si.commandBufferCount = 1;
    si.pCommandBuffers = &cmd_;
    si.signalSemaphoreCount = std::uint32_t(sync.signal.size());
    si.pSignalSemaphores = sync.signal.data();
    std::lock_guard<std::mutex> lock(ctx_.queue_mutex());
    check(ctx_.vk().vkQueueSubmit(ctx_.queue(), 1, &si, sync.fence), "vkQueueSubmit");
    // An empty submission signals its fence once everything before it on the queue is done:
    // gsd's own fence, so this recorder knows when its command buffer is free again. Should it
    // fail, the command buffer may still be running: wait for the whole queue before saying so.
    const VkResult r = ctx_.vk().vkQueueSubmit(ctx_.queue(), 0, nullptr, fence_);
    if (r != VK_SUCCESS) {
        (void)ctx_.vk().vkDeviceWaitIdle(ctx_.device());
        check(r, "vkQueueSubmit");
    }
    pending_ = true;
}

bool Recorder::done() const {
    if (!pending_) return true;
    const VkResult r = ctx_.vk().vkGetFenceStatus(ctx_.device(), fence_);
    if (r == VK_NOT_READY) return false;
    check(r, "vkGetFenceStatus");
    return true;
}

void Recorder::wait() {
    if (!pending_) return;
    pending_ = false;
    check(ctx_.vk().vkWaitForFences(ctx_.device(), 1, &fence_, VK_TRUE, UINT64_MAX), "vkWaitForFences");
    check(ctx_.vk().vkResetFences(ctx_.device(), 1, &fence_), "vkResetFences");
    collect_times();
}

std::uint32_t software_loop_cap(const Context& ctx) {
    if (!ctx.info().is_software()) return 0;
    // $GSD_LOOP_CAP lowers it, so that tests can run the kernels' cut and the host's redo.
    if (const char* v = std::getenv("GSD_LOOP_CAP")) {
        const long cap = std::strtol(v, nullptr, 10);
        if (cap > 0 && cap < 65535 - 1024) return std::uint32_t(cap);
    }
    return 65535u - 1024u;  // room below 65 535 for the few iterations a kernel does not count
}

std::uint32_t dispatch_threads(const Context& ctx) {
    // Only llvmpipe is known to split a dispatch so (SwiftShader and GPUs schedule workgroups as
    // they free up).
    if (!ctx.info().is_software() || ctx.info().name.rfind("llvmpipe", 0) != 0) return 1;
    long threads = 0;
    if (const char* v = std::getenv("GSD_DISPATCH_THREADS")) threads = std::strtol(v, nullptr, 10);  // tests
    else if (const char* lp = std::getenv("LP_NUM_THREADS")) threads = std::strtol(lp, nullptr, 10);
    else {
        // llvmpipe's own count, read once as llvmpipe does: the CPUs the process may run on
        // (Mesa's util_cpu_caps), at most Mesa 22-23's LP_MAX_THREADS.
        static const long cpus = [] {
            cpu_set_t allowed;
            const long n = sched_getaffinity(0, sizeof(allowed), &allowed) == 0 ? CPU_COUNT(&allowed) : long(std::thread::hardware_concurrency());
            return std::min(n, 32L);
        }();
        threads = cpus;
    }
    return std::uint32_t(std::clamp(threads, 1L, 1024L));
}

bool software_shaped(const Context& ctx) {
    if (!ctx.info().subgroup_arithmetic) return false;
    if (const char* v = std::getenv("GSD_SOFTWARE_SHAPED"); v && (v[0] == '0' || v[0] == '1') && v[1] == 0) return v[0] == '1';
    return ctx.info().is_software();
}

const Kernel& kernel(Context& ctx, const KernelSpec& spec, std::initializer_list<std::int32_t> constants,
                     std::uint32_t workgroup) {
    return kernel(ctx, spec, constants, workgroup, spec.has_software_build() && software_shaped(ctx));
}

const Kernel& kernel(Context& ctx, const KernelSpec& spec, std::initializer_list<std::int32_t> constants,
                     std::uint32_t workgroup, bool software) {
    if (software && !spec.has_software_build())
        throw Error("gpu", std::string("kernel ") + spec.shader + " has no build for software devices");
    if (software)
        return ctx.kernel(std::string(spec.shader) + "_software", spec.bindings_of(true), spec.push_bytes, constants, workgroup,
                          spec.texels);
    return ctx.kernel(spec.shader, spec.bindings, spec.push_bytes, constants, workgroup);
}

std::uint32_t shader_binding_count(const std::string& name) { return spirv_binding_count(embedded_shader(name)); }

std::vector<std::string> embedded_shader_names() {
    std::vector<std::string> names;
    for (const auto& s : detail::kEmbeddedShaders) names.emplace_back(s.name);
    return names;
}

std::uint32_t loop_capped_workgroup(const Context& ctx) {
    return ctx.info().is_software() ? std::max<std::uint32_t>(ctx.info().subgroup_size, 1) : 0;
}

void copy_bytes(void* dst, const void* src, std::size_t bytes) {
    // One core copies ~10 GB/s and takes the page faults of a fresh buffer alone; a grid's
    // field at 256³ is 128 MB.
    constexpr std::size_t block = std::size_t(1) << 20;
    if (bytes < 8 * block) {
        std::memcpy(dst, src, bytes);
        return;
    }
    const auto blocks = std::ptrdiff_t((bytes + block - 1) / block);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t b = 0; b < blocks; ++b) {
        const std::size_t first = std::size_t(b) * block;
        std::memcpy(static_cast<char*>(dst) + first, static_cast<const char*>(src) + first, std::min(block, bytes - first));
    }
}

Buffer upload(Context& ctx, const void* data, std::size_t bytes) {
    Buffer dst(ctx, bytes, Memory::Device);
    Buffer staging(ctx, bytes, Memory::Upload);
    copy_bytes(staging.mapped(), data, bytes);
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
    copy_bytes(dst, staging.mapped(), bytes);
}

}  // namespace gsd::gpu
