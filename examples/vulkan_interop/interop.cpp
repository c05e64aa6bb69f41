// An engine's view of gsd's Vulkan interop (gsd/vulkan.hpp), also run by the consumer test: the
// application creates its own instance and device with libvulkan, keeps queries and results in
// its own buffers, hands the device to gsd with Context::adopt and orders gsd's work against its
// own with a semaphore. Nothing passes through the host except the final check's read-back.
// Then it pictures the field on that device with gsd's renderer.
#include "interop.hpp"

#include <gsd/pat.hpp>
#include <gsd/render.hpp>
#include <gsd/viz.hpp>
#include <gsd/vulkan.hpp>

#include <vulkan/vulkan.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

int g_validation_errors = 0;

VKAPI_ATTR VkBool32 VKAPI_CALL on_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                          VkDebugUtilsMessageTypeFlagsEXT,
                                          const VkDebugUtilsMessengerCallbackDataEXT* data, void*) {
    if (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) {
        ++g_validation_errors;
        std::fprintf(stderr, "interop: Vulkan validation error: %s\n", data->pMessage);
    }
    return VK_FALSE;
}

void vk_check(VkResult r, const char* what) {
    if (r != VK_SUCCESS) throw std::runtime_error(std::string(what) + " failed (" + std::to_string(int(r)) + ")");
}

bool has_layer(const char* name) {
    std::uint32_t n = 0;
    vkEnumerateInstanceLayerProperties(&n, nullptr);
    std::vector<VkLayerProperties> l(n);
    vkEnumerateInstanceLayerProperties(&n, l.data());
    return std::any_of(l.begin(), l.end(), [&](const VkLayerProperties& p) { return std::strcmp(p.layerName, name) == 0; });
}

bool has_device_extension(VkPhysicalDevice dev, const char* name) {
    std::uint32_t n = 0;
    vkEnumerateDeviceExtensionProperties(dev, nullptr, &n, nullptr);
    std::vector<VkExtensionProperties> e(n);
    vkEnumerateDeviceExtensionProperties(dev, nullptr, &n, e.data());
    return std::any_of(e.begin(), e.end(), [&](const VkExtensionProperties& p) { return std::strcmp(p.extensionName, name) == 0; });
}

// The application's Vulkan objects, torn down in reverse order.
struct App {
    VkInstance instance = VK_NULL_HANDLE;
    VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
    VkPhysicalDevice physical = VK_NULL_HANDLE;
    std::uint32_t family = 0;
    VkDevice device = VK_NULL_HANDLE;
    VkDevice bare_device = VK_NULL_HANDLE;  // created without VK_KHR_push_descriptor
    VkQueue queue = VK_NULL_HANDLE;
    VkPhysicalDeviceMemoryProperties memory{};
    VkPhysicalDeviceLimits limits{};

    ~App() {
        if (device) vkDestroyDevice(device, nullptr);
        if (bare_device) vkDestroyDevice(bare_device, nullptr);
        if (messenger) {
            auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
                vkGetInstanceProcAddr(instance, "vkDestroyDebugUtilsMessengerEXT"));
            destroy(instance, messenger, nullptr);
        }
        if (instance) vkDestroyInstance(instance, nullptr);
    }

    VkDevice make_device(bool push_descriptor) const {
        const float priority = 1;
        VkDeviceQueueCreateInfo q{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
        q.queueFamilyIndex = family;
        q.queueCount = 1;
        q.pQueuePriorities = &priority;
        const char* ext[] = {VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME};
        VkDeviceCreateInfo ci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
        ci.queueCreateInfoCount = 1;
        ci.pQueueCreateInfos = &q;
        ci.enabledExtensionCount = push_descriptor ? 1 : 0;
        ci.ppEnabledExtensionNames = ext;
        VkDevice d = VK_NULL_HANDLE;
        vk_check(vkCreateDevice(physical, &ci, nullptr, &d), "vkCreateDevice");
        return d;
    }
};

// A buffer of the application's with its own memory.
struct AppBuffer {
    VkDevice device = VK_NULL_HANDLE;
    VkBuffer buffer = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    void* mapped = nullptr;

    AppBuffer(const App& app, VkDeviceSize bytes, VkBufferUsageFlags usage, VkMemoryPropertyFlags want)
        : device(app.device) {
        VkBufferCreateInfo bi{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
        bi.size = bytes;
        bi.usage = usage;
        vk_check(vkCreateBuffer(device, &bi, nullptr, &buffer), "vkCreateBuffer");
        VkMemoryRequirements req;
        vkGetBufferMemoryRequirements(device, buffer, &req);
        VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
        ai.allocationSize = req.size;
        ai.memoryTypeIndex = ~0u;
        for (std::uint32_t i = 0; i < app.memory.memoryTypeCount && ai.memoryTypeIndex == ~0u; ++i)
            if ((req.memoryTypeBits & (1u << i)) && (app.memory.memoryTypes[i].propertyFlags & want) == want)
                ai.memoryTypeIndex = i;
        if (ai.memoryTypeIndex == ~0u) throw std::runtime_error("no memory type for a buffer");
        vk_check(vkAllocateMemory(device, &ai, nullptr, &memory), "vkAllocateMemory");
        vk_check(vkBindBufferMemory(device, buffer, memory, 0), "vkBindBufferMemory");
        if (want & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT)
            vk_check(vkMapMemory(device, memory, 0, VK_WHOLE_SIZE, 0, &mapped), "vkMapMemory");
    }
    ~AppBuffer() {
        vkDestroyBuffer(device, buffer, nullptr);
        vkFreeMemory(device, memory, nullptr);
    }
    AppBuffer(const AppBuffer&) = delete;
    AppBuffer& operator=(const AppBuffer&) = delete;
};

void make_app(App& app) {
    VkApplicationInfo info{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    info.pApplicationName = "gsd consumer";
    info.apiVersion = VK_API_VERSION_1_1;
    std::vector<const char*> layers, extensions;
    // The application's own validation (when the Khronos layer is installed) also sees every
    // command gsd records on the adopted device.
    if (has_layer("VK_LAYER_KHRONOS_validation")) {
        layers.push_back("VK_LAYER_KHRONOS_validation");
        extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    }
    VkInstanceCreateInfo ci{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    ci.pApplicationInfo = &info;
    ci.enabledLayerCount = std::uint32_t(layers.size());
    ci.ppEnabledLayerNames = layers.data();
    ci.enabledExtensionCount = std::uint32_t(extensions.size());
    ci.ppEnabledExtensionNames = extensions.data();
    vk_check(vkCreateInstance(&ci, nullptr, &app.instance), "vkCreateInstance");
    if (!layers.empty()) {
        VkDebugUtilsMessengerCreateInfoEXT m{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
        m.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT;
        m.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT;
        m.pfnUserCallback = on_message;
        auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
            vkGetInstanceProcAddr(app.instance, "vkCreateDebugUtilsMessengerEXT"));
        vk_check(create(app.instance, &m, nullptr, &app.messenger), "vkCreateDebugUtilsMessengerEXT");
        std::printf("interop: interop runs under the validation layer\n");
    }
    std::uint32_t n = 0;
    vkEnumeratePhysicalDevices(app.instance, &n, nullptr);
    std::vector<VkPhysicalDevice> devices(n);
    vkEnumeratePhysicalDevices(app.instance, &n, devices.data());
    for (VkPhysicalDevice d : devices) {
        if (app.physical || !has_device_extension(d, VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME)) continue;
        std::uint32_t nf = 0;
        vkGetPhysicalDeviceQueueFamilyProperties(d, &nf, nullptr);
        std::vector<VkQueueFamilyProperties> fam(nf);
        vkGetPhysicalDeviceQueueFamilyProperties(d, &nf, fam.data());
        for (std::uint32_t f = 0; f < nf && !app.physical; ++f)
            if (fam[f].queueFlags & VK_QUEUE_COMPUTE_BIT) {
                app.physical = d;
                app.family = f;
            }
    }
    if (!app.physical) throw std::runtime_error("no Vulkan device with compute and VK_KHR_push_descriptor");
    VkPhysicalDeviceProperties props;
    vkGetPhysicalDeviceProperties(app.physical, &props);
    app.limits = props.limits;
    vkGetPhysicalDeviceMemoryProperties(app.physical, &app.memory);
    app.device = app.make_device(true);
    vkGetDeviceQueue(app.device, app.family, 0, &app.queue);
    std::printf("interop: the application's own device: %s\n", props.deviceName);
}

// gsd evaluates into `results` and signals `ready`; the application's own command buffer
// waits on it and copies the results to a host-visible buffer. Returns φ (and ∇φ).
std::vector<float> evaluate_on_app_device(const App& app, const std::shared_ptr<gsd::gpu::Context>& ctx,
                                          const gsd::TorusField& field, const gsd::Points& queries, bool gradient,
                                          VkDeviceSize offset) {
    const auto n = std::uint64_t(queries.rows());
    const VkDeviceSize stride = gradient ? 16 : 4;
    AppBuffer in(app, offset + n * 16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                 VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
    AppBuffer out(app, offset + n * stride, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                  VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    AppBuffer back(app, n * stride, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                   VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
    auto* q = reinterpret_cast<float*>(static_cast<char*>(in.mapped) + offset);
    for (std::uint64_t i = 0; i < n; ++i) {
        for (int c = 0; c < 3; ++c) q[4 * i + std::uint64_t(c)] = float(queries(Eigen::Index(i), c));
        q[4 * i + 3] = 0;
    }

    VkSemaphore ready = VK_NULL_HANDLE;
    VkSemaphoreCreateInfo si{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
    vk_check(vkCreateSemaphore(app.device, &si, nullptr, &ready), "vkCreateSemaphore");
    VkFence done = VK_NULL_HANDLE;
    VkFenceCreateInfo fi{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    vk_check(vkCreateFence(app.device, &fi, nullptr, &done), "vkCreateFence");
    VkCommandPool pool = VK_NULL_HANDLE;
    VkCommandPoolCreateInfo pi{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pi.queueFamilyIndex = app.family;
    vk_check(vkCreateCommandPool(app.device, &pi, nullptr, &pool), "vkCreateCommandPool");

    gsd::gpu::DeviceQueries job;
    job.queries = {in.buffer, offset};
    job.results = {out.buffer, offset};
    job.count = n;
    job.gradient = gradient;
    gsd::gpu::SubmitSync sync;
    sync.signal = {ready};
    gsd::gpu::evaluate_into(field, ctx, job, sync);  // returns once submitted

    VkCommandBuffer cmd = VK_NULL_HANDLE;
    VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    ai.commandPool = pool;
    ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    ai.commandBufferCount = 1;
    vk_check(vkAllocateCommandBuffers(app.device, &ai, &cmd), "vkAllocateCommandBuffers");
    VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    vk_check(vkBeginCommandBuffer(cmd, &bi), "vkBeginCommandBuffer");
    VkBufferCopy region{offset, 0, n * stride};
    vkCmdCopyBuffer(cmd, out.buffer, back.buffer, 1, &region);
    VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    mb.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    mb.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &mb, 0, nullptr, 0, nullptr);
    vk_check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
    const VkPipelineStageFlags stage = VK_PIPELINE_STAGE_TRANSFER_BIT;
    VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    submit.waitSemaphoreCount = 1;
    submit.pWaitSemaphores = &ready;
    submit.pWaitDstStageMask = &stage;
    submit.commandBufferCount = 1;
    submit.pCommandBuffers = &cmd;
    vk_check(vkQueueSubmit(app.queue, 1, &submit, done), "vkQueueSubmit");
    vk_check(vkWaitForFences(app.device, 1, &done, VK_TRUE, UINT64_MAX), "vkWaitForFences");

    std::vector<float> result(n * stride / 4);
    std::memcpy(result.data(), back.mapped, result.size() * 4);
    vkDestroyCommandPool(app.device, pool, nullptr);
    vkDestroyFence(app.device, done, nullptr);
    vkDestroySemaphore(app.device, ready, nullptr);
    return result;
}

}  // namespace

// The field's zero set pictured on the application's device and on the CPU: they must agree.
bool picture_check(const std::shared_ptr<gsd::gpu::Context>& ctx, const gsd::TorusField& field,
                   const gsd::Points& points, const std::string& path) {
    gsd::FieldRenderOptions o;
    o.width = 160;
    o.height = 120;
    o.device = ctx;  // the adopted context is a device like any other
    const gsd::Box box = gsd::padded_cube(gsd::bounding_box(points));
    const gsd::RenderedField on_app = gsd::render_field(field, box, o);
    o.device = "cpu";
    const gsd::RenderedField on_cpu = gsd::render_field(field, box, o);
    gsd::write_png(path, on_app.image);
    std::size_t off = 0;
    for (std::size_t i = 0; i < on_app.image.rgb.size(); ++i)
        off += std::abs(int(on_app.image.rgb[i]) - int(on_cpu.image.rgb[i])) > 8;
    const double share = double(off) / double(on_app.image.rgb.size());
    std::printf("interop: rendered on %s into %s (%.1f %% of rays hit); image bytes off from the CPU's by > 8: %.2f %%\n",
                on_app.device.c_str(), path.c_str(), 100 * on_app.hit_fraction, 100 * share);
    if (on_app.device != ctx->info().name || on_app.hit_fraction < 0.05 || share > 0.01) {
        std::fprintf(stderr, "interop: FAIL: the picture on the adopted device\n");
        return false;
    }
    return true;
}

bool interop_check(const gsd::FittedTori& tori, const gsd::Points& queries, const std::string& picture) {
    App app;
    bool ok = true;
    try {
        make_app(app);
        std::shared_ptr<gsd::gpu::Context> ctx = gsd::gpu::Context::adopt(
            app.instance, app.physical, app.device, app.family, app.queue, vkGetInstanceProcAddr);
        std::printf("interop: gsd adopted %s\n", ctx->info().name.c_str());
        {
            gsd::BlendOptions cpu_options;
            cpu_options.device = "cpu";
            const gsd::TorusField field(tori, cpu_options);  // its evaluate() stays on the CPU
            const gsd::FieldValues ref = field.evaluate(queries, true);
            const auto n = std::size_t(queries.rows());

            // φ and ∇φ, at offset 0.
            const std::vector<float> got = evaluate_on_app_device(app, ctx, field, queries, true, 0);
            double phi_err = 0, grad_err = 0;
            for (std::size_t i = 0; i < n; ++i) {
                phi_err = std::max(phi_err, double(std::abs(got[4 * i] - ref.phi[i])));
                for (std::size_t c = 0; c < 3; ++c)
                    grad_err = std::max(grad_err, double(std::abs(got[4 * i + 1 + c] - ref.gradient[3 * i + c])));
            }
            // φ alone, both buffers at a non-zero (aligned) offset.
            const VkDeviceSize offset = std::max<VkDeviceSize>(app.limits.minStorageBufferOffsetAlignment, 16) * 3;
            const std::vector<float> phi = evaluate_on_app_device(app, ctx, field, queries, false, offset);
            for (std::size_t i = 0; i < n; ++i) phi_err = std::max(phi_err, double(std::abs(phi[i] - ref.phi[i])));
            std::printf("interop: adopted device vs CPU: max |dphi| = %.3g, max |dgrad| = %.3g\n", phi_err, grad_err);
            if (!(phi_err <= 1e-4 && grad_err <= 1e-3)) {
                std::fprintf(stderr, "interop: FAIL: the adopted device disagrees with the CPU\n");
                ok = false;
            }

            // The adopted context as an ordinary device choice: host in, host out, same field.
            gsd::BlendOptions on_app_device;
            on_app_device.device = ctx;
            const gsd::FieldValues host = gsd::TorusField(tori, on_app_device).evaluate(queries, true);
            double host_err = 0;
            for (std::size_t i = 0; i < n; ++i) host_err = std::max(host_err, double(std::abs(host.phi[i] - ref.phi[i])));
            std::printf("interop: options.device = the adopted context: ran on %s, max |dphi| = %.3g\n",
                        host.device.c_str(), host_err);
            if (host.device != ctx->info().name || !(host_err <= 1e-4)) {
                std::fprintf(stderr, "interop: FAIL: evaluation with the adopted context as device\n");
                ok = false;
            }

            if (!picture.empty()) ok = picture_check(ctx, field, tori.points, picture) && ok;

            // A null buffer and a misaligned offset are refused before anything is recorded.
            AppBuffer scratch(app, 4096, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                              VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
            const VkDeviceSize align = app.limits.minStorageBufferOffsetAlignment;
            for (int c = 0; c < (align > 1 ? 2 : 1); ++c) {
                gsd::gpu::DeviceQueries bad;
                bad.queries = {c == 0 ? VK_NULL_HANDLE : scratch.buffer, 0};
                bad.results = {scratch.buffer, c == 0 ? 0 : align / 2};
                bad.count = 1;
                try {
                    gsd::gpu::evaluate_into(field, ctx, bad);
                    std::fprintf(stderr, "interop: FAIL: a bad span (case %d) was accepted\n", c);
                    ok = false;
                } catch (const gsd::Error& e) {
                    std::printf("interop: refused as expected: %s: %s\n", e.where().c_str(), e.what());
                }
            }
        }  // the field (and its data on the device) goes before the device

        // A device without VK_KHR_push_descriptor is refused with a clear error.
        app.bare_device = app.make_device(false);
        VkQueue bare_queue = VK_NULL_HANDLE;
        vkGetDeviceQueue(app.bare_device, app.family, 0, &bare_queue);
        try {
            (void)gsd::gpu::Context::adopt(app.instance, app.physical, app.bare_device, app.family, bare_queue,
                                           vkGetInstanceProcAddr);
            std::fprintf(stderr, "interop: FAIL: a device without push descriptors was adopted\n");
            ok = false;
        } catch (const gsd::Error& e) {
            std::printf("interop: refused as expected: %s\n", e.what());
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "interop: FAIL: interop: %s\n", e.what());
        ok = false;
    }
    if (g_validation_errors) {
        std::fprintf(stderr, "interop: FAIL: %d validation errors on the application's device\n", g_validation_errors);
        ok = false;
    }
    return ok;
}
