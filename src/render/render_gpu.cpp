// The renderer on a Vulkan device: render_pat.comp (blended fields, over the field's own device
// data) and render_grid.comp (a grid uploaded for the picture) march every pixel; the hits come
// back in chunks and are shaded on the host exactly as the CPU reference's are.
#include "render/render.hpp"

#include "blend/blend.hpp"
#include "gpu/runtime.hpp"

#include <algorithm>
#include <cstring>

namespace gsd::render {

namespace {

struct RenderParams {  // `RenderParams` in render_march.glsl (std430)
    float eye[4], forward[4], right[4], up[4], box_min[4], box_max[4];
    std::uint32_t size[4];  // width, height, max_steps, bisection steps
    float march[4];         // step_scale, hit_eps, min_step, unused
};

gpu::Buffer upload_params(gpu::Context& ctx, const Camera& cam, const March& m) {
    RenderParams p{};
    auto put = [](float* dst, const Eigen::Vector3d& v) {
        for (int a = 0; a < 3; ++a) dst[a] = float(v[a]);
    };
    put(p.eye, cam.eye);
    put(p.forward, cam.forward);
    put(p.right, cam.right);
    put(p.up, cam.up);
    put(p.box_min, m.box.lo);
    put(p.box_max, m.box.hi);
    p.size[0] = std::uint32_t(cam.width);
    p.size[1] = std::uint32_t(cam.height);
    p.size[2] = std::uint32_t(m.max_steps);
    p.size[3] = std::uint32_t(m.bisection);
    p.march[0] = float(m.step_scale);
    p.march[1] = float(m.hit_eps);
    p.march[2] = float(m.min_step);
    return gpu::upload(ctx, &p, sizeof(p));
}

// Runs `record(rec, hits, first, count)` over the image in chunks of m.chunk rays and gathers the
// hits. Chunks keep each submission short (a long one can trip a display driver's watchdog).
void march_chunks(gpu::Context& ctx, const Camera& cam, const March& m, std::vector<float>& hits,
                  const ProgressFn& progress,
                  const std::function<void(gpu::Recorder&, const gpu::Buffer&, std::uint32_t, std::uint32_t)>& record) {
    const std::size_t n = std::size_t(cam.width) * std::size_t(cam.height);
    const std::size_t chunk = std::clamp<std::size_t>(m.chunk, 1, std::max<std::size_t>(n, 1));
    hits.resize(4 * n);
    gpu::Buffer out(ctx, chunk * 16, gpu::Memory::Device);
    gpu::Buffer down(ctx, chunk * 16, gpu::Memory::Download);
    gpu::Recorder rec(ctx);
    for (std::size_t first = 0; first < n; first += chunk) {
        const auto count = std::uint32_t(std::min(chunk, n - first));
        rec.begin();
        record(rec, out, std::uint32_t(first), count);
        rec.barrier();
        rec.copy(out, 0, down, 0, VkDeviceSize(count) * 16);
        rec.barrier();
        rec.submit();
        rec.wait();
        std::memcpy(hits.data() + 4 * first, down.mapped(), std::size_t(count) * 16);
        if (progress) progress("march", double(first + count) / double(n));
    }
}

}  // namespace

bool march_blend_gpu(const blend::Engine& engine, const std::shared_ptr<gpu::Context>& ctx, const Camera& cam,
                     const March& m, std::vector<float>& hits, std::string& why_not, const ProgressFn& progress) {
    std::shared_ptr<blend::GpuField> field;
    try {
        field = engine.on_device(ctx);
    } catch (const Error& e) {
        why_not = e.what();
        return false;
    }
    blend::Params p = engine.params(false);
    p.exact = false;
    const gpu::Buffer params = upload_params(*ctx, cam, m);
    march_chunks(*ctx, cam, m, hits, progress, [&](gpu::Recorder& rec, const gpu::Buffer& out, std::uint32_t first, std::uint32_t count) {
        blend::record_render(*field, rec, p, params, out, first, count);
    });
    return true;
}

bool march_grid_gpu(const GridSpec& grid, const std::vector<float>& values, const std::shared_ptr<gpu::Context>& ctx,
                    const Camera& cam, const March& m, std::vector<float>& hits, std::string& why_not,
                    const ProgressFn& progress) {
    gpu::Context& c = *ctx;
    const std::uint64_t bytes = std::uint64_t(values.size()) * 4;
    if (bytes > c.max_binding_bytes() || (c.device_memory_bytes() && 2 * bytes > c.device_memory_bytes())) {
        why_not = "the grid (" + std::to_string(bytes >> 20) + " MiB) does not fit " + c.info().name + "'s buffers";
        return false;
    }
    struct GridPush {  // `Push` in render_grid.comp
        std::uint32_t first_pixel, pixel_count, nx, ny, nz;
        float x0, y0, z0, hx, hy, hz;
    };
    const gpu::Buffer data = gpu::upload(c, values.data(), bytes);
    const gpu::Buffer params = upload_params(c, cam, m);
    const gpu::Kernel& k = c.kernel("render_grid", 3, sizeof(GridPush));
    const Eigen::Vector3d h = grid.box.extent().cwiseQuotient(Eigen::Vector3d(grid.nx - 1, grid.ny - 1, grid.nz - 1));
    march_chunks(c, cam, m, hits, progress, [&](gpu::Recorder& rec, const gpu::Buffer& out, std::uint32_t first, std::uint32_t count) {
        const GridPush push{first, count, std::uint32_t(grid.nx), std::uint32_t(grid.ny), std::uint32_t(grid.nz),
                            float(grid.box.lo.x()), float(grid.box.lo.y()), float(grid.box.lo.z()),
                            float(h.x()), float(h.y()), float(h.z())};
        rec.dispatch(k, {{&data}, {&params}, {&out, 0, VkDeviceSize(count) * 16}}, &push, sizeof(push),
                     (count + k.workgroup - 1) / k.workgroup);
    });
    return true;
}

}  // namespace gsd::render
