#include "gpu/stream.hpp"

#include "core/threads.hpp"
#include "gpu/on_device.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <array>
#include <memory>

namespace gsd::gpu {

void stream(Context& c, const StreamJob& job, const ProgressFn& progress) {
    if (job.count == 0) return;
    const std::size_t widest = std::max(job.in_bytes, job.out_bytes);
    std::size_t chunk = std::min(job.chunk, std::size_t(c.max_binding_bytes()) / widest);
    chunk = std::max<std::size_t>(1, std::min(chunk, job.count));
    // Every chunk but the last starts on a multiple of the granule, so a kernel that sums items
    // in groups forms the same groups whatever the chunk size.
    const std::size_t granule = std::max<std::size_t>(1, job.granule);
    if (chunk < job.count) chunk = std::max(granule, chunk / granule * granule);

    struct Slot {
        Buffer up, in, out, down;
        std::unique_ptr<Recorder> rec;
        std::size_t first = 0, count = 0;
    };
    constexpr std::size_t kSlots = 3;
    std::array<Slot, kSlots> slots;
    const std::size_t used = std::min(kSlots, (job.count + chunk - 1) / chunk);
    // Where the host's buffers are the device's own memory (a software device, an integrated
    // GPU), the kernel reads the upload buffer and writes the read-back one: no copies.
    const bool direct = host_buffers_are_device_local(c);
    for (std::size_t i = 0; i < used; ++i) {
        Slot& s = slots[i];
        s.up = Buffer(c, chunk * job.in_bytes, Memory::Upload);
        s.down = Buffer(c, chunk * job.out_bytes, Memory::Download);
        if (!direct) {
            s.in = Buffer(c, chunk * job.in_bytes, Memory::Device);
            s.out = Buffer(c, chunk * job.out_bytes, Memory::Device);
        }
        s.rec = std::make_unique<Recorder>(c);
    }
    // A software device (llvmpipe) runs the kernels on the host's own cores, a thread each, while
    // fill and drain run here: their OpenMP teams would take cores from the device's threads and
    // spin at their barriers waiting for them. There they run on this thread alone (lavapipe, 2
    // cores: gsd winding of a 160³ grid 4.24–4.27 → 3.86–3.94 s, gsd pat eval of a 128³ grid
    // 4.16–4.18 → 3.66–3.69 s, run with OMP_NUM_THREADS=1 against without).
    const detail::OneOpenMPThread serial(shares_host_cores(c));
    std::size_t done = 0;
    // Host time spent filling, waiting and draining (printed with GSD_GPU_PROFILE=1): where a
    // call's time goes when the kernels are not what bounds it.
    const bool profile = c.state().profile;
    double t_fill = 0, t_wait = 0, t_drain = 0;
    auto clock = [] { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); };
    auto drain = [&](Slot& s) {
        if (!s.rec || !s.rec->pending()) return;
        double t0 = clock();
        s.rec->wait();
        const double t1 = clock();
        t_wait += t1 - t0;
        job.drain(s.first, s.count, s.down.mapped());
        t_drain += clock() - t1;
        done += s.count;
        if (progress) progress(job.stage, double(done) / double(job.count));
    };
    std::size_t index = 0;
    for (std::size_t first = 0; first < job.count; first += chunk, ++index) {
        Slot& s = slots[index % used];
        drain(s);
        s.first = first;
        s.count = std::min(chunk, job.count - first);
        const double t0 = clock();
        job.fill(first, s.count, s.up.mapped());
        t_fill += clock() - t0;
        s.rec->begin();
        if (direct) {
            // The submission makes the host's writes visible; the barrier, the kernel's to the host.
            job.record(*s.rec, s.up, s.down, s.count);
            s.rec->barrier();
        } else {
            s.rec->copy(s.up, 0, s.in, 0, s.count * job.in_bytes);
            s.rec->barrier();
            job.record(*s.rec, s.in, s.out, s.count);
            s.rec->barrier();
            s.rec->copy(s.out, 0, s.down, 0, s.count * job.out_bytes);
            s.rec->barrier();
        }
        s.rec->submit();
    }
    for (std::size_t m = 0; m < used; ++m) drain(slots[(index + m) % used]);
    if (profile)
        std::fprintf(stderr, "gsd: %s: %zu items in %zu chunks; host fill %.1f ms, waiting %.1f ms, drain %.1f ms\n", job.stage,
                     job.count, index, 1e3 * t_fill, 1e3 * t_wait, 1e3 * t_drain);
}

bool host_buffers_are_device_local(const Context& ctx) {
    if (const char* v = std::getenv("GSD_STREAM_COPIES"); v && std::string(v) == "1") return false;  // tests: both ways
    const VkPhysicalDeviceMemoryProperties& m = ctx.state().mem_props;
    auto local = [&](Memory kind) {
        return (m.memoryTypes[ctx.memory_type(~0u, kind)].propertyFlags & VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT) != 0;
    };
    return local(Memory::Upload) && local(Memory::Download);
}

std::size_t default_chunk(const Context& ctx) { return ctx.info().is_software() ? 65536 : std::size_t(1) << 20; }

void fill_vec4(PointsView points, const std::vector<std::uint32_t>& order, std::size_t first, std::size_t n, void* dst) {
    float* up = static_cast<float*>(dst);
    // In parallel: through an order each row is a random access, and a thread waits on memory.
#pragma omp parallel for schedule(static) if (n > 4096)
    for (std::size_t i = 0; i < n; ++i) {
        const auto row = Eigen::Index(order.empty() ? first + i : std::size_t(order[first + i]));
        for (int a = 0; a < 3; ++a) up[4 * i + std::size_t(a)] = float(points(row, a));
        up[4 * i + 3] = 0;
    }
}

}  // namespace gsd::gpu
