// The blend engine on a Vulkan device: the cloud is uploaded once in kd-tree order (points,
// per-point terms, tree nodes), then queries stream through in chunks with several chunks in
// flight: while chunk i computes, chunk i+1 is uploaded and chunk i−1 read back.
#include <gsd/baselines.hpp>
#include <gsd/vulkan.hpp>

#include "spatial/morton.hpp"
#include "blend/blend.hpp"
#include "gpu/device_tree.hpp"
#include "gpu/field_device.hpp"
#include "gpu/runtime.hpp"
#include "gpu/stream.hpp"
#include "push_constants.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <numeric>
#include <optional>

namespace gsd::blend {

namespace {

/// $GSD_SHARED_KNN=0|1 if set, else `choice`.
int shared_knn_override(int choice) {
    if (const char* v = std::getenv("GSD_SHARED_KNN"); v && (v[0] == '0' || v[0] == '1')) return v[0] - '0';
    return choice;
}

/// Whether the k-nearest fallback is walked per subgroup (blend_field.glsl, knn_together): on
/// hardware GPUs, where a lane's own walk keeps its stack and list in slow memory and waits on
/// its neighbours' branches; not on software devices (their loop limit). $GSD_SHARED_KNN=0|1
/// overrides, to measure it.
int shared_knn(const gpu::Context& c) {
    return shared_knn_override(c.info().is_software() ? 0 : 1);
}

/// The renderer walks each lane's own fallback everywhere. On a hardware GPU rays of a tile
/// reach the fallback at different points of their march, and walked together the render took
/// twice as long on an H200 (4.1 s against 2.0 s at 1920×1080). On a software device each
/// lane's walk is knn_listed (blend_field.glsl), whose loops the guard of render_march.glsl
/// counts as exactly as the walk together's: on the bench's 320×240 picture no ray passed it
/// (11 868 of 76 800 did walked together) and the device rate rose from 0.51× to 0.69× the CPU
/// path's on lavapipe. $GSD_SHARED_KNN=1 walks it together, to measure.
int render_shared_knn() {
    return shared_knn_override(0);
}


constexpr int kMaxFallbackK = 32;  // K_MAX in blend_eval.comp

/// Points per leaf of the kd-tree a software device walks (BoxTree's leaf_size; the CPU path and
/// GPUs keep 8). There each lane walks the tree on its own (the listed walks of blend_field.glsl),
/// and a step of a walk, or a pass over a leaf, costs about as much as a point in it: fewer,
/// larger leaves did better. gsd-gpu-bench --device gpu --stages pat,render on lavapipe, leaves of
/// 8, 16, 24, 32: PAT 3.4, 3.9, 3.9–4.0, 3.9–4.0·10⁵ queries/s; the render 8.6, 9.4, 9.8–10, 9.7·10⁴
/// pixels/s (d3208d6). Once the render's march stopped carrying gradient sums (5440a81), 16, 24,
/// 32: the render 0.91–0.95, 0.96–0.99, 1.00 of the CPU path's rate; PAT alike. 32 is the most a
/// pass of mark_points takes.
constexpr std::uint32_t kSoftwareLeafSize = 32;

using kernels::BlendPush;  // `Push` in blend_eval.comp

/// blend_eval for these specialization constants: on software devices its build that reads the
/// tree's points, terms and nodes (bindings 0–2) as texel buffers (gpu::kernel, kernel_table::blend_eval).
const gpu::Kernel& blend_kernel(gpu::Context& c, std::initializer_list<std::int32_t> constants) {
    return gpu::kernel(c, gpu::kernel_table::blend_eval, constants);
}

std::vector<float> jet_records(const Points& points, const Points& normals, const Points& tangents,
                               const std::vector<Jet>& jets, const std::vector<std::uint32_t>& order) {
    std::vector<float> rec(order.size() * 16);
    for (std::size_t k = 0; k < order.size(); ++k) {
        const auto i = Eigen::Index(order[k]);
        const Jet& j = jets[std::size_t(i)];
        float* r = &rec[16 * k];
        const double v[16] = {points(i, 0),   points(i, 1),   points(i, 2),   j.a00,
                              normals(i, 0),  normals(i, 1),  normals(i, 2),  j.a10,
                              tangents(i, 0), tangents(i, 1), tangents(i, 2), j.a01,
                              j.a11,          j.a20,          j.a02,          0.0};
        for (int c = 0; c < 16; ++c) r[c] = float(v[c]);
    }
    return rec;
}

// Runs torus_from_jet over `count` records already on the device.
void record_tori(gpu::Context& ctx, gpu::Recorder& rec, const gpu::Buffer& jets, const gpu::Buffer& tori,
                 std::uint32_t count) {
    const kernels::CountPush push{count};
    const gpu::Kernel& k = gpu::kernel(ctx, gpu::kernel_table::torus_from_jet);
    rec.dispatch(k, {{&jets}, {&tori}}, &push, sizeof(push), (count + k.workgroup - 1) / k.workgroup);
}

// Items [first, first + n) of a grid's bricks, f(m, ijk, linear, real) for item first + m, in
// blocks a thread walks with a cursor (GridBricks::Cursor: no division per item).
template <class F>
void for_brick_items(const spatial::GridBricks& bricks, std::size_t first, std::size_t n, F&& f) {
    constexpr std::size_t kBlock = 4096;
    const auto blocks = std::ptrdiff_t((n + kBlock - 1) / kBlock);
#pragma omp parallel for schedule(static) if (blocks > 1)
    for (std::ptrdiff_t b = 0; b < blocks; ++b) {
        const std::size_t begin = std::size_t(b) * kBlock, end = std::min(n, begin + kBlock);
        spatial::GridBricks::Cursor at(bricks, first + begin);
        for (std::size_t m = begin; m < end; ++m, at.next()) {
            int ijk[3];
            std::size_t linear = 0;
            const bool real = at.node(ijk, linear);
            f(m, ijk, linear, real);
        }
    }
}

}  // namespace

class GpuField {
public:
    GpuField(std::shared_ptr<gpu::Context> ctx, const Source& src, const spatial::BoxTree& tree)
        : ctx_(std::move(ctx)), kind_(src.kind) {
        gpu::Context& c = *ctx_;
        const auto n = std::size_t(src.points.rows());
        const std::vector<std::uint32_t>& order = tree.order();
        first_leaf_ = tree.first_leaf();
        point_count_ = std::uint32_t(n);
        dmin_ = float(1e-6 * src.spacing);

        std::vector<float> pts(4 * n);
        for (std::size_t k = 0; k < n; ++k)
            for (int a = 0; a < 3; ++a) pts[4 * k + std::size_t(a)] = float(src.points(Eigen::Index(order[k]), a));
        points_ = gpu::upload(c, pts.data(), pts.size() * 4);
        const std::vector<gpu::DeviceNode> nodes = gpu::device_nodes(tree);
        nodes_ = gpu::upload(c, nodes.data(), nodes.size() * sizeof(gpu::DeviceNode));

        if (kind_ == Kind::Pat) {
            // Tori are built on the device from the jets, the same pipeline TorusNet feeds.
            const std::vector<float> jets = jet_records(src.points, src.normals, src.tangents, src.jets, order);
            gpu::Buffer jet_buffer = gpu::upload(c, jets.data(), jets.size() * 4);
            terms_ = gpu::Buffer(c, n * 12 * 4, gpu::Memory::Device);
            gpu::Recorder rec(c);
            rec.begin();
            record_tori(c, rec, jet_buffer, terms_, point_count_);
            rec.barrier();
            rec.submit();
            rec.wait();
        } else {
            std::vector<float> t(4 * n);
            for (std::size_t k = 0; k < n; ++k) {
                const auto i = Eigen::Index(order[k]);
                for (int a = 0; a < 3; ++a) t[4 * k + std::size_t(a)] = float(src.normals(i, a));
                t[4 * k + 3] = float(src.areas[std::size_t(i)]);
            }
            terms_ = gpu::upload(c, t.data(), t.size() * 4);
        }
    }

    void evaluate(const Params& p, const Queries& q, Output out, std::size_t chunk_size, const ProgressFn& progress);
    /// Builds the kernel evaluate() runs for p, ahead of the first evaluation.
    void prepare(const Params& p) { blend_kernel(*ctx_, {int(kind_), p.exact ? 1 : 0, p.gradient ? 1 : 0, shared_knn(*ctx_)}); }
    /// Queries in an application's buffer, results into another (gsd/vulkan.hpp).
    void evaluate_into(const Params& p, const gpu::DeviceQueries& job, const gpu::SubmitSync& sync);
    void record_render(gpu::Recorder& rec, const Params& p, const gpu::Buffer& params, const gpu::Buffer& empty, const gpu::Buffer& hits,
                       std::uint32_t first_pixel, std::uint32_t pixel_count, std::uint32_t rays_per_lane,
                       std::uint32_t loop_cap);
    std::string device_name() const { return ctx_->info().name; }
    const gpu::Context* context() const { return ctx_.get(); }

private:
    std::size_t default_chunk(const Params& p) const {
        const std::size_t wg = ctx_->workgroup_size();
        // The exact sum costs O(N) per query: smaller chunks keep progress and latency smooth.
        std::size_t chunk = p.exact ? std::clamp<std::size_t>((std::size_t(1) << 27) / std::max<std::uint32_t>(point_count_, 1),
                                                             4096, 65536)
                                    : gpu::default_chunk(*ctx_);
        return (chunk + wg - 1) / wg * wg;
    }


    std::shared_ptr<gpu::Context> ctx_;
    Kind kind_;
    gpu::Buffer points_, terms_, nodes_;
    std::uint32_t first_leaf_ = 0, point_count_ = 0;
    float dmin_ = 0;
    // Command buffers of evaluate_into, reused once their work is done. Declared after the
    // buffers so that destroying the field first waits for the work that reads them.
    std::mutex async_mutex_;
    std::vector<std::unique_ptr<gpu::Recorder>> async_;
};

void GpuField::evaluate(const Params& p, const Queries& q, Output out, std::size_t chunk_size,
                        const ProgressFn& progress) {
    gpu::Context& c = *ctx_;
    const std::size_t out_floats = p.gradient ? 4 : 1;
    const gpu::Kernel& k = blend_kernel(c, {int(kind_), p.exact ? 1 : 0, p.gradient ? 1 : 0, shared_knn(c)});
    gpu::StreamJob job;
    job.in_bytes = 16;
    job.out_bytes = out_floats * 4;
    job.chunk = chunk_size ? chunk_size : default_chunk(p);
    // An explicit list goes to the device in Morton order, and a grid in bricks of 2³ (Morton
    // order within each, bricks in C order), so that the lanes of a subgroup are a compact block
    // of nearby queries: they walk the kd-tree alike and read the same points. A grid's C order
    // gave a subgroup a run along z: on lavapipe (8 lanes) the kernel took 1.15–1.3× as long on
    // a 64³ grid as on the same nodes listed (docs/gpu.md). Bricks of 2 pad a side by one node at
    // most (4 would pad a side of 5 to 8). Results go back in the caller's order.
    std::vector<std::uint32_t> order;
    if (q.is_list() && q.size() > 1 && q.size() < (std::size_t(1) << 32) && spatial::sort_queries_for_device())
        order = spatial::morton_order(q.list());
    std::optional<spatial::GridBricks> bricks;
    if (!q.is_list() && spatial::sort_queries_for_device())
        bricks.emplace(q.grid(), 2);
    job.count = bricks ? bricks->items() : q.size();
    auto index = [&](std::size_t i) { return order.empty() ? i : std::size_t(order[i]); };
    // A grid's node coordinates along each axis, as GridSpec::node makes them (each coordinate
    // depends on its own index only), so that a node costs three reads, not three divisions.
    std::array<std::vector<double>, 3> axis;
    if (bricks) {
        const GridSpec& g = q.grid();
        const int n[3] = {g.nx, g.ny, g.nz};
        for (int a = 0; a < 3; ++a) {
            axis[std::size_t(a)].resize(std::size_t(n[a]));
            for (int i = 0; i < n[a]; ++i) axis[std::size_t(a)][std::size_t(i)] = g.node(a == 0 ? i : 0, a == 1 ? i : 0, a == 2 ? i : 0)[a];
        }
    }
    // Gathers and scatters through the order run in parallel (random accesses: a thread waits
    // on memory for most of each).
    job.fill = [&](std::size_t first, std::size_t n, void* dst) {
        float* up = static_cast<float*>(dst);
        auto put = [up](std::size_t m, double x, double y, double z) {
            up[4 * m] = float(x);
            up[4 * m + 1] = float(y);
            up[4 * m + 2] = float(z);
            up[4 * m + 3] = 0.0f;
        };
        if (bricks) {  // a brick's copy past an odd edge repeats a node
            for_brick_items(*bricks, first, n, [&](std::size_t m, const int ijk[3], std::size_t, bool) {
                put(m, axis[0][std::size_t(ijk[0])], axis[1][std::size_t(ijk[1])], axis[2][std::size_t(ijk[2])]);
            });
            return;
        }
#pragma omp parallel for schedule(static) if (n > 4096)
        for (std::size_t m = 0; m < n; ++m) {
            const Eigen::Vector3d x = q.at(index(first + m));
            put(m, x.x(), x.y(), x.z());
        }
    };
    job.record = [&](gpu::Recorder& rec, const gpu::Buffer& in, const gpu::Buffer& res, std::size_t n) {
        const BlendPush push{std::uint32_t(n), point_count_, first_leaf_, std::uint32_t(p.fallback_k),
                             float(p.r_eval), float(p.C), dmin_};
        rec.dispatch(k, {{&points_}, {&terms_}, {&nodes_}, {&in, 0, n * 16}, {&res, 0, n * out_floats * 4}}, &push,
                     sizeof(push), std::uint32_t((n + k.workgroup - 1) / k.workgroup));
    };
    job.drain = [&](std::size_t first, std::size_t n, const void* src) {
        const float* r = static_cast<const float*>(src);
        auto take = [&](std::size_t m, std::size_t i) {
            out.phi[i] = r[out_floats * m];
            if (out.gradient)
                for (int a = 0; a < 3; ++a) out.gradient[3 * i + std::size_t(a)] = r[4 * m + 1 + std::size_t(a)];
        };
        if (bricks) {
            for_brick_items(*bricks, first, n, [&](std::size_t m, const int*, std::size_t linear, bool real) {
                if (real) take(m, linear);  // a copy is dropped
            });
            return;
        }
#pragma omp parallel for schedule(static) if (n > 4096)
        for (std::size_t m = 0; m < n; ++m) take(m, index(first + m));
    };
    gpu::stream(c, job, progress);
}

void GpuField::evaluate_into(const Params& p, const gpu::DeviceQueries& job, const gpu::SubmitSync& sync) {
    gpu::check_span(*ctx_, job.queries, "DeviceQueries::queries");  // as gpu::evaluate_into does: direct callers too
    gpu::check_span(*ctx_, job.results, "DeviceQueries::results");
    if (job.count >= (1ull << 31)) throw Error("DeviceQueries::count", "at most 2^31 − 1 queries per call");
    gpu::Context& c = *ctx_;
    const VkDeviceSize out_bytes = p.gradient ? 16 : 4;
    const gpu::Kernel& k =
        blend_kernel(c, {int(kind_), p.exact ? 1 : 0, p.gradient ? 1 : 0, shared_knn(c)});
    // Dispatches of whole multiples of 256 queries, so every later binding offset stays a
    // multiple of any storage-buffer alignment a device may ask for (at most 256 bytes).
    const std::uint64_t by_range = c.max_binding_bytes() / 16 / 256 * 256;
    const std::uint64_t chunk = std::max<std::uint64_t>(256, std::min<std::uint64_t>(by_range, 1u << 22));

    std::lock_guard<std::mutex> lock(async_mutex_);
    gpu::Recorder* rec = nullptr;
    for (auto& r : async_)
        if (!rec && r->done()) rec = r.get();
    if (!rec) rec = async_.emplace_back(std::make_unique<gpu::Recorder>(c)).get();
    rec->begin();
    rec->barrier_after_external();
    for (std::uint64_t first = 0; first < job.count; first += chunk) {
        const std::uint64_t n = std::min(chunk, job.count - first);
        const BlendPush push{std::uint32_t(n), point_count_, first_leaf_, std::uint32_t(p.fallback_k),
                             float(p.r_eval), float(p.C), dmin_};
        rec->dispatch(k,
                      {{&points_}, {&terms_}, {&nodes_},
                       {job.queries.buffer, job.queries.offset + first * 16, n * 16},
                       {job.results.buffer, job.results.offset + first * out_bytes, n * out_bytes}},
                      &push, sizeof(push), std::uint32_t((n + k.workgroup - 1) / k.workgroup));
    }
    rec->barrier_before_external();
    rec->submit(sync);
    if (sync.fence == VK_NULL_HANDLE && sync.signal.empty()) rec->wait();
}

void GpuField::record_render(gpu::Recorder& rec, const Params& p, const gpu::Buffer& params, const gpu::Buffer& empty, const gpu::Buffer& hits,
                             std::uint32_t first_pixel, std::uint32_t pixel_count, std::uint32_t rays_per_lane,
                             std::uint32_t loop_cap) {
    using RenderPush = kernels::RenderPatPush;  // `Push` in render_pat.comp: blend_eval's, then the chunk
    const gpu::Kernel& k = gpu::kernel(*ctx_, gpu::kernel_table::render_pat,  // the tree as texel buffers on software devices
                                       {int(kind_), render_shared_knn(), std::int32_t(loop_cap)},
                                       gpu::loop_capped_workgroup(*ctx_));
    const RenderPush push{first_pixel, point_count_, first_leaf_, std::uint32_t(p.fallback_k), float(p.r_eval),
                          float(p.C), dmin_, pixel_count};
    rec.dispatch(k, {{&points_}, {&terms_}, {&nodes_}, {&params}, {&hits, 0, VkDeviceSize(pixel_count) * 16}, {&empty}}, &push,
                 sizeof(push), (pixel_count + k.workgroup * rays_per_lane - 1) / (k.workgroup * rays_per_lane));
}

void record_render(GpuField& field, gpu::Recorder& rec, const Params& p, const gpu::Buffer& params,
                   const gpu::Buffer& empty, const gpu::Buffer& hits, std::uint32_t first_pixel, std::uint32_t pixel_count,
                   std::uint32_t rays_per_lane, std::uint32_t loop_cap) {
    field.record_render(rec, p, params, empty, hits, first_pixel, pixel_count, rays_per_lane, loop_cap);
}

std::shared_ptr<GpuField> make_gpu_field(const std::shared_ptr<gpu::Context>& ctx, const Source& src,
                                         const spatial::BoxTree& tree, const Params& params, std::string& why_not) {
    const std::uint64_t n = std::uint64_t(src.points.rows());
    const std::uint64_t term_bytes = n * (src.kind == Kind::Pat ? 48 : 16);
    const std::uint64_t jet_bytes = src.kind == Kind::Pat ? n * 64 : 0;
    if (params.fallback_k > kMaxFallbackK) {
        why_not = "the GPU kernel supports a fallback of at most " + std::to_string(kMaxFallbackK) +
                  " neighbors; using the CPU path";
        return nullptr;
    }
    if (std::max(term_bytes, jet_bytes) > ctx->max_binding_bytes() || n >= (1ull << 31)) {
        why_not = "the cloud (" + std::to_string(n) + " points) exceeds " + ctx->info().name +
                  "'s storage buffer range; using the CPU path";
        return nullptr;
    }
    if (ctx->device_memory_bytes() && 3 * (term_bytes + jet_bytes + n * 16) > ctx->device_memory_bytes()) {
        why_not = "the cloud does not fit in " + ctx->info().name + "'s memory; using the CPU path";
        return nullptr;
    }
    if (gpu::software_shaped(*ctx)) {
        const spatial::BoxTree wide(src.points, kSoftwareLeafSize);
        return std::make_shared<GpuField>(ctx, src, wide);
    }
    return std::make_shared<GpuField>(ctx, src, tree);
}

void evaluate_gpu(GpuField& field, const Params& params, const Queries& queries, Output out,
                  std::size_t chunk_size, const ProgressFn& progress) {
    field.evaluate(params, queries, out, chunk_size, progress);
}

void prepare_gpu(GpuField& field, const Params& params) { field.prepare(params); }

std::string gpu_field_device(const GpuField& field) { return field.device_name(); }
const gpu::Context* gpu_field_context(const GpuField& field) { return field.context(); }

std::vector<float> tori_on_device(gpu::Context& ctx, const Points& points, const Points& normals,
                                  const Points& tangents, const std::vector<Jet>& jets) {
    const auto n = std::size_t(points.rows());
    std::vector<std::uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    const std::vector<float> rec = jet_records(points, normals, tangents, jets, order);
    gpu::Buffer in = gpu::upload(ctx, rec.data(), rec.size() * 4);
    gpu::Buffer tori(ctx, n * 48, gpu::Memory::Device);
    gpu::Buffer down(ctx, n * 48, gpu::Memory::Download);
    gpu::Recorder r(ctx);
    r.begin();
    record_tori(ctx, r, in, tori, std::uint32_t(n));
    r.barrier();
    r.copy(tori, 0, down, 0, n * 48);
    r.barrier();
    r.submit();
    r.wait();
    std::vector<float> out(n * 12);
    std::memcpy(out.data(), down.mapped(), n * 48);
    return out;
}

}  // namespace gsd::blend

namespace gsd::blend {

void EngineProgram::evaluate_into(const std::shared_ptr<gpu::Context>& ctx, const gpu::DeviceQueries& job,
                                  const gpu::SubmitSync& sync) const {
    if (job.gradient && !gradient_) throw Error("DeviceQueries::gradient", std::string(what_) + " offer no gradient");
    const Params params = engine_.params(job.gradient);
    engine_.on_device(ctx)->evaluate_into(params, job, sync);
}

}  // namespace gsd::blend
