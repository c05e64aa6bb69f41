// The renderer on a Vulkan device: render_pat.comp (blended fields, over the field's own device
// data) and render_grid.comp (a grid uploaded for the picture) march every pixel; the hits come
// back in chunks and are shaded on the host exactly as the CPU reference's are. On software
// devices a blend is marched as a wavefront of blend_eval dispatches instead
// (march_blend_wavefront), and for both a blend's empty space is found on the device first
// (empty_space.cpp).
//
// The kernels take rays in tile order, a subgroup a tile of `rays_per_lane` rays a lane
// (render_march.glsl: with more than one, a lane whose ray has ended takes the tile's next one).
#include "render/render.hpp"

#include "blend/blend.hpp"
#include "gpu/runtime.hpp"
#include "gpu/on_device.hpp"
#include "gpu/stream.hpp"
#include "push_constants.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <future>
#include <system_error>

namespace gsd::render {

namespace {

struct RenderParams {  // `RenderParams` in render_march.glsl (std430)
    float eye[4], forward[4], right[4], up[4], box_min[4], box_max[4];
    std::uint32_t size[4];  // width, height, max_steps, bisection steps
    float march[4];         // step_scale, hit_eps, min_step, unused
    std::uint32_t tile[4];  // tile width, height, rays per lane, unused
    float empty[4];         // the empty-space grid's low corner, cell side
    std::uint32_t cells[4]; // its cells along x, y, z; the words of its empty bits (0: rays skip nothing)
};

// How a device's subgroups share the rays: a tile of subgroup size × rays_per_lane pixels each,
// as square as a power of two allows (8×4 for 32 rays, 16×8 for 128).
struct Tiling {
    std::uint32_t width = 1, height = 1, rays_per_lane = 1;
};

Tiling tiling_for(const gpu::Context& ctx) {
    Tiling t;
    // One ray a lane: the tile alone. A lane that takes its tile's next ray when its own ends
    // (rays_per_lane > 1) keeps its lanes busy, but the subgroup's rays then lie farther apart and
    // at different depths, and their shared walks open more of the tree: measured on an H200
    // (gsd-gpu-bench --full, 1920×1080, 10⁶ points), 0.57 s at 1 ray a lane, 1.26 s at 4, 1.91 s
    // at 8. On lavapipe more rays a lane also pass its loop limit (marched on the CPU instead).
    // GSD_RENDER_RAYS_PER_LANE overrides (a power of two).
    t.rays_per_lane = 1;
    if (const char* e = std::getenv("GSD_RENDER_RAYS_PER_LANE")) {
        const long v = std::strtol(e, nullptr, 10);
        if (v >= 1 && v <= 64 && (v & (v - 1)) == 0) t.rays_per_lane = std::uint32_t(v);
    }
    std::uint32_t sub = ctx.info().subgroup_size;
    if (sub == 0 || (sub & (sub - 1)) != 0) sub = 32;
    const std::uint32_t rays = sub * t.rays_per_lane;
    int bits = 0;
    while ((1u << (bits + 1)) <= rays) ++bits;
    t.height = 1u << (bits / 2);
    t.width = rays / t.height;
    return t;
}

// t = −2.0f: a ray the kernel did not finish (llvmpipe's loop limit; render_march.glsl).
constexpr std::uint32_t kRedoWord = 0xC0000000u;

// Ray p's pixel (x, y) in tile order: render_march.glsl's tile_pixel.
std::size_t tile_pixel(std::size_t p, std::size_t W, std::size_t H, const Tiling& t) {
    const std::size_t TW = t.width, TH = t.height;
    const std::size_t ty = p / (W * TH), r = p - ty * (W * TH);
    const std::size_t h = std::min(TH, H - ty * TH);
    const std::size_t tiles_x = (W + TW - 1) / TW;
    const std::size_t tx = std::min(r / (TW * h), tiles_x - 1);
    const std::size_t w = tx + 1 < tiles_x ? TW : W - tx * TW;
    const std::size_t off = r - tx * TW * h;
    return (ty * TH + off / w) * W + tx * TW + off % w;
}

gpu::Buffer upload_params(gpu::Context& ctx, const Camera& cam, const March& m, const Tiling& tiles) {
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
    p.tile[0] = tiles.width;
    p.tile[1] = tiles.height;
    p.tile[2] = tiles.rays_per_lane;
    if (m.empty) {
        put(p.empty, m.empty->lo);
        p.empty[3] = float(m.empty->h);
        for (int a = 0; a < 3; ++a) p.cells[a] = std::uint32_t(m.empty->n[a]);
        p.cells[3] = std::uint32_t(m.empty->words());
    }
    return gpu::upload(ctx, &p, sizeof(p));
}

// Runs `record(rec, hits, first, count)` over the image's rays (tile order) in chunks of m.chunk
// and puts each ray's hit at its pixel. Chunks keep each submission short (a long one can trip a
// display driver's watchdog).
void march_chunks(gpu::Context& ctx, const Camera& cam, const March& m, const Tiling& tiles, std::vector<float>& hits,
                  const ProgressFn& progress,
                  const std::function<void(gpu::Recorder&, const gpu::Buffer&, std::uint32_t, std::uint32_t)>& record) {
    const std::size_t n = std::size_t(cam.width) * std::size_t(cam.height);
    // A GPU wants many rays in flight (2^20: 8192 workgroups of 128 lanes); a software device,
    // shorter submissions for smooth progress.
    const std::size_t chunk = std::clamp<std::size_t>(m.chunk ? m.chunk : gpu::default_chunk(ctx), 1, std::max<std::size_t>(n, 1));
    hits.resize(4 * n);
    gpu::Buffer out(ctx, chunk * 16, gpu::Memory::Device);
    gpu::Buffer down(ctx, chunk * 16, gpu::Memory::Download);
    gpu::Recorder rec(ctx);
    for (std::size_t first = 0; first < n; first += chunk) {
        const auto count = std::uint32_t(std::min(chunk, n - first));
        rec.begin();
        rec.fill(out, 0, VkDeviceSize(count) * 16, kRedoWord);  // a ray the kernel leaves: t = −2
        rec.barrier();
        record(rec, out, std::uint32_t(first), count);
        rec.barrier();
        rec.copy(out, 0, down, 0, VkDeviceSize(count) * 16);
        rec.barrier();
        rec.submit();
        rec.wait();
        const float* got = static_cast<const float*>(down.mapped());
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t j = 0; j < std::ptrdiff_t(count); ++j)
            std::memcpy(hits.data() + 4 * tile_pixel(first + std::size_t(j), std::size_t(cam.width), std::size_t(cam.height), tiles),
                        got + 4 * j, 16);
        if (progress) progress("march", double(first + count) / double(n));
    }
}

// ∇φ at the rays' hits, into hits[4p + 1..3]: render_pat.comp marches φ alone (its march would
// otherwise carry the blend's gradient sums at every step, a lane's own condition deciding), and
// the hits, about a fifth of the rays, are evaluated here as queries (blend_eval.comp, in Morton
// order). Rays the kernel left unfinished (t = −2) are marched, and shaded, on the CPU.
void gradients_at_hits(blend::GpuField& field, blend::Params p, const Camera& cam, std::vector<float>& hits,
                       const ProgressFn& progress) {
    p.exact = false;
    p.gradient = true;
    std::vector<std::size_t> hit;
    for (std::size_t i = 0; 4 * i < hits.size(); ++i)
        if (hits[4 * i] >= 0.0f) hit.push_back(i);
    // In blocks of hits (48 bytes each on the host while evaluated), so that a picture of 10⁸
    // rays does not hold them all at once.
    constexpr std::size_t kBlock = std::size_t(1) << 22;
    for (std::size_t first = 0; first < hit.size(); first += kBlock) {
        const std::size_t n = std::min(kBlock, hit.size() - first);
        Points at(Eigen::Index(n), 3);
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t j = 0; j < std::ptrdiff_t(n); ++j) {
            const std::size_t i = hit[first + std::size_t(j)];
            const Eigen::Vector3d d = cam.ray(int(i % std::size_t(cam.width)), int(i / std::size_t(cam.width)));
            at.row(j) = (cam.eye + double(hits[4 * i]) * d).transpose();
        }
        std::vector<float> phi(n), grad(3 * n);
        const double done = double(first), total = double(hit.size());
        blend::evaluate_gpu(field, p, blend::Queries(PointsView(at)), blend::Output{phi.data(), grad.data()}, 0,
                            progress ? ProgressFn([&](std::string_view, double f) { progress("shade", (done + f * double(n)) / total); })
                                     : ProgressFn());
        for (std::size_t j = 0; j < n; ++j)
            for (int c = 0; c < 3; ++c) hits[4 * hit[first + j] + 1 + std::size_t(c)] = grad[3 * j + std::size_t(c)];
    }
}

bool subgroups_ready(const gpu::Context& ctx, std::string& why_not) {
    if (ctx.info().subgroup_arithmetic) return true;
    why_not = ctx.info().name + " has no subgroup arithmetic in compute shaders (the renderer's kernels need it)";
    return false;
}

}  // namespace

namespace {

// The empty cells of the blend, their corners evaluated on the device.
std::shared_ptr<const EmptySpace> empty_space_on_device(blend::GpuField& field, blend::Params p, const March& m, int cells) {
    if (cells <= 0) return nullptr;
    p.gradient = false;
    return std::make_shared<EmptySpace>(find_empty_space(m.box, cells, m.step_scale, [&](const GridSpec& g) {
        std::vector<float> phi(g.node_count());
        blend::evaluate_gpu(field, p, blend::Queries(g), blend::Output{phi.data(), nullptr}, 0, {});
        return phi;
    }));
}

// Software devices march a blend as a wavefront (wavefront.cpp), each step's evaluations one
// list of queries for blend_eval.comp: the rays still marching, compacted, so every lane of
// llvmpipe's SIMD groups has a ray. render_pat.comp marches a tile of rays per subgroup, which on
// a SIMD device pays each turn for its slowest ray's lanes: on the 2-core machine (lavapipe),
// a 320×240 picture of snail.ply's PAT field at 2×2 rays a pixel marched in 0.74 s as a
// wavefront, 1.4 s in render_pat. A GPU keeps render_pat: the wavefront's round trip to the
// host at every step would cost it more than the idle lanes. $GSD_RENDER_MARCH=kernel|wavefront
// overrides (tests run both).
bool marches_as_wavefront(const gpu::Context& ctx) {
    if (const char* v = std::getenv("GSD_RENDER_MARCH")) {
        if (std::strcmp(v, "kernel") == 0) return false;
        if (std::strcmp(v, "wavefront") == 0) return true;
    }
    return gpu::software_shaped(ctx);
}

// φ (and ∇φ) of the blend at the rows of x, `sum` filling them for the parameters p with
// the gradient as asked: the device's evaluation or the CPU path's.
template <class Sum>
FieldValues blend_values(const blend::Params& p, const Points& x, bool gradient, Sum&& sum, std::string device) {
    FieldValues v;
    v.phi.resize(std::size_t(x.rows()));
    if (gradient) v.gradient.resize(3 * std::size_t(x.rows()));
    blend::Params q = p;
    q.gradient = gradient;
    sum(q, blend::Queries(PointsView(x)), blend::Output{v.phi.data(), gradient ? v.gradient.data() : nullptr});
    v.device = std::move(device);
    return v;
}

// The march's last few rays take their φ (and the fewest hits their ∇φ) from the blend's CPU
// path (PointEvaluator::evaluate_few): at 128 points or fewer a dispatch's round trip costs
// more than the sums (docs/render.md).
bool march_blend_wavefront(const blend::Engine& engine, blend::GpuField& field, const blend::Params& p, const Camera& cam,
                           const March& m, std::vector<float>& hits, const ProgressFn& progress) {
    PointEvaluator eval;
    eval.has_gradient = true;
    eval.shares_cores = gpu::shares_host_cores(*blend::gpu_field_context(field));
    eval.evaluate = [&](const Points& x, bool gradient) {
        return blend_values(p, x, gradient, [&](const blend::Params& q, const blend::Queries& at, blend::Output out) {
            blend::evaluate_gpu(field, q, at, out, m.chunk, {});
        }, blend::gpu_field_device(field));
    };
    eval.evaluate_few = [&](const Points& x, bool gradient) {
        return blend_values(p, x, gradient, [&](const blend::Params& q, const blend::Queries& at, blend::Output out) {
            blend::evaluate_cpu(engine.source(), engine.search_tree(), q, at, out, {});
        }, "cpu");
    };
    std::string device;
    hits = march_wavefront(eval, cam, m, device, progress);
    return true;
}

}  // namespace

bool march_blend_gpu(const blend::Engine& engine, const std::shared_ptr<gpu::Context>& ctx, const Camera& cam,
                     March& m, int empty_cells, std::vector<float>& hits, std::string& why_not, const ProgressFn& progress) {
    if (!subgroups_ready(*ctx, why_not)) return false;
    std::shared_ptr<blend::GpuField> field;
    try {
        field = engine.on_device(ctx);
    } catch (const Error& e) {
        why_not = e.what();
        return false;
    }
    blend::Params p = engine.params(false);
    p.exact = false;
    // ∇φ at the hits takes a kernel of its own: built on a thread of its own while this one
    // builds φ's (for the empty space below). On lavapipe each is ~50 ms of one core; built
    // later, beside the rays' set-up, it held that up (320×240 picture of a 2048-point PAT
    // field: 0.98× the time, farm-bench). (Its errors come again, and are reported, from the
    // evaluation that needs it.)
    blend::Params with_gradient = p;
    with_gradient.gradient = true;
    std::future<void> gradient_kernel;  // waited for on the way out
    try {
        gradient_kernel = std::async(std::launch::async, [field, with_gradient] {
            try {
                blend::prepare_gpu(*field, with_gradient);
            } catch (const std::exception&) {
            }
        });
    } catch (const std::system_error&) {  // no thread: the evaluation builds it
    }
    m.empty = empty_space_on_device(*field, p, m, empty_cells);
    if (marches_as_wavefront(*ctx)) return march_blend_wavefront(engine, *field, p, cam, m, hits, progress);
    const std::uint32_t no_cells = 0;
    const gpu::Buffer empty = m.empty ? gpu::upload(*ctx, m.empty->bits.data(), m.empty->bits.size() * 4) : gpu::upload(*ctx, &no_cells, 4);
    const Tiling tiles = tiling_for(*ctx);
    const gpu::Buffer params = upload_params(*ctx, cam, m, tiles);
    march_chunks(*ctx, cam, m, tiles, hits, progress, [&](gpu::Recorder& rec, const gpu::Buffer& out, std::uint32_t first, std::uint32_t count) {
        blend::record_render(*field, rec, p, params, empty, out, first, count, tiles.rays_per_lane, gpu::software_loop_cap(*ctx));
    });
    gradients_at_hits(*field, engine.params(true), cam, hits, progress);
    return true;
}

bool march_grid_gpu(const GridSpec& grid, const std::vector<float>& values, const std::shared_ptr<gpu::Context>& ctx,
                    const Camera& cam, const March& m, std::vector<float>& hits, std::string& why_not,
                    const ProgressFn& progress) {
    gpu::Context& c = *ctx;
    if (!subgroups_ready(c, why_not)) return false;
    const std::uint64_t bytes = std::uint64_t(values.size()) * 4;
    if (bytes > c.max_binding_bytes() || (c.device_memory_bytes() && 2 * bytes > c.device_memory_bytes())) {
        why_not = "the grid (" + std::to_string(bytes >> 20) + " MiB) does not fit " + c.info().name + "'s buffers";
        return false;
    }
    using GridPush = kernels::RenderGridPush;  // `Push` in render_grid.comp
    const gpu::Buffer data = gpu::upload(c, values.data(), bytes);
    const Tiling tiles = tiling_for(c);
    const gpu::Buffer params = upload_params(c, cam, m, tiles);
    const gpu::Kernel& k = gpu::kernel(c, gpu::kernel_table::render_grid, {std::int32_t(gpu::software_loop_cap(c))},
                                       gpu::loop_capped_workgroup(c));
    const std::uint32_t rays_per_group = k.workgroup * tiles.rays_per_lane;
    const Eigen::Vector3d h = grid.box.extent().cwiseQuotient(Eigen::Vector3d(grid.nx - 1, grid.ny - 1, grid.nz - 1));
    march_chunks(c, cam, m, tiles, hits, progress, [&](gpu::Recorder& rec, const gpu::Buffer& out, std::uint32_t first, std::uint32_t count) {
        const GridPush push{first, count, std::uint32_t(grid.nx), std::uint32_t(grid.ny), std::uint32_t(grid.nz),
                            float(grid.box.lo.x()), float(grid.box.lo.y()), float(grid.box.lo.z()),
                            float(h.x()), float(h.y()), float(h.z())};
        rec.dispatch(k, {{&data}, {&params}, {&out, 0, VkDeviceSize(count) * 16}}, &push, sizeof(push),
                     (count + rays_per_group - 1) / rays_per_group);
    });
    return true;
}

}  // namespace gsd::render
