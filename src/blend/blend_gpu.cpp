// The blend engine on a Vulkan device: the cloud is uploaded once in kd-tree order (points,
// per-point terms, tree nodes), then queries stream through in chunks with several chunks in
// flight: while chunk i computes, chunk i+1 is uploaded and chunk i−1 read back.
#include "blend/blend.hpp"
#include "gpu/runtime.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <numeric>

namespace gsd::blend {

namespace {

constexpr int kMaxFallbackK = 32;  // K_MAX in blend_eval.comp

struct GpuNode {  // std430 layout of `Node` in blend_eval.comp
    float lo[3];
    std::uint32_t begin;
    float hi[3];
    std::uint32_t end;
};
static_assert(sizeof(GpuNode) == 32);

struct BlendPush {  // `Push` in blend_eval.comp
    std::uint32_t query_count, point_count, first_leaf, k_fallback;
    float r_eval, C, dmin;
};

// The BoxTree's nodes in float32, boxes rounded outward so every float point stays inside.
std::vector<GpuNode> float_nodes(const detail::BoxTree& tree) {
    std::vector<GpuNode> out(tree.nodes().size());
    for (std::size_t i = 0; i < out.size(); ++i) {
        const detail::BoxTree::Node& n = tree.nodes()[i];
        for (int a = 0; a < 3; ++a) {
            const float lo = float(n.lo[a]), hi = float(n.hi[a]);
            out[i].lo[a] = double(lo) > n.lo[a] ? std::nextafter(lo, -INFINITY) : lo;
            out[i].hi[a] = double(hi) < n.hi[a] ? std::nextafter(hi, INFINITY) : hi;
        }
        out[i].begin = n.begin;
        out[i].end = n.end;
    }
    return out;
}

// Copies host data into a new device-local buffer through a temporary staging buffer.
gpu::Buffer upload(gpu::Context& ctx, const void* data, std::size_t bytes) {
    gpu::Buffer dst(ctx, bytes, gpu::Memory::Device);
    gpu::Buffer staging(ctx, bytes, gpu::Memory::Upload);
    std::memcpy(staging.mapped(), data, bytes);
    gpu::Recorder rec(ctx);
    rec.begin();
    rec.copy(staging, 0, dst, 0, bytes);
    rec.barrier();
    rec.submit();
    rec.wait();
    return dst;
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
    const gpu::Kernel& k = ctx.kernel("torus_from_jet", 2, 4);
    rec.dispatch(k, {{&jets}, {&tori}}, &count, 4, (count + k.workgroup - 1) / k.workgroup);
}

}  // namespace

class GpuField {
public:
    GpuField(std::shared_ptr<gpu::Context> ctx, const Source& src, const detail::BoxTree& tree)
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
        points_ = upload(c, pts.data(), pts.size() * 4);
        const std::vector<GpuNode> nodes = float_nodes(tree);
        nodes_ = upload(c, nodes.data(), nodes.size() * sizeof(GpuNode));

        if (kind_ == Kind::Pat) {
            // Tori are built on the device from the jets, the same pipeline TorusNet feeds.
            const std::vector<float> jets = jet_records(src.points, src.normals, src.tangents, src.jets, order);
            gpu::Buffer jet_buffer = upload(c, jets.data(), jets.size() * 4);
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
            terms_ = upload(c, t.data(), t.size() * 4);
        }
    }

    void evaluate(const Params& p, const Queries& q, Output out, std::size_t chunk_size, const ProgressFn& progress);
    std::string device_name() const { return ctx_->info().name; }

private:
    std::size_t default_chunk(const Params& p) const {
        const std::size_t wg = ctx_->workgroup_size();
        // The exact sum costs O(N) per query: smaller chunks keep progress and latency smooth.
        std::size_t chunk = p.exact ? std::clamp<std::size_t>((std::size_t(1) << 27) / std::max<std::uint32_t>(point_count_, 1),
                                                             4096, 65536)
                                    : 65536;
        return (chunk + wg - 1) / wg * wg;
    }

    std::shared_ptr<gpu::Context> ctx_;
    Kind kind_;
    gpu::Buffer points_, terms_, nodes_;
    std::uint32_t first_leaf_ = 0, point_count_ = 0;
    float dmin_ = 0;
};

void GpuField::evaluate(const Params& p, const Queries& q, Output out, std::size_t chunk_size,
                        const ProgressFn& progress) {
    gpu::Context& c = *ctx_;
    const std::size_t total = q.size();
    if (total == 0) return;
    std::size_t chunk = chunk_size ? chunk_size : default_chunk(p);
    const std::size_t out_floats = p.gradient ? 4 : 1;
    chunk = std::min<std::size_t>(chunk, c.max_binding_bytes() / 16);
    chunk = std::min(chunk, total);
    const gpu::Kernel& k = c.kernel("blend_eval", 5, sizeof(BlendPush),
                                    {int(kind_), p.exact ? 1 : 0, p.gradient ? 1 : 0});

    // Three slots: one computing, one being filled, one being read back.
    struct Slot {
        gpu::Buffer up, queries, result, down;
        std::unique_ptr<gpu::Recorder> rec;
        std::size_t first = 0, count = 0;
    };
    constexpr int kSlots = 3;
    std::array<Slot, kSlots> slots;
    for (Slot& s : slots) {
        s.up = gpu::Buffer(c, chunk * 16, gpu::Memory::Upload);
        s.queries = gpu::Buffer(c, chunk * 16, gpu::Memory::Device);
        s.result = gpu::Buffer(c, chunk * out_floats * 4, gpu::Memory::Device);
        s.down = gpu::Buffer(c, chunk * out_floats * 4, gpu::Memory::Download);
        s.rec = std::make_unique<gpu::Recorder>(c);
    }
    std::size_t done = 0;
    auto drain = [&](Slot& s) {
        if (!s.rec->pending()) return;
        s.rec->wait();
        const float* r = static_cast<const float*>(s.down.mapped());
        for (std::size_t m = 0; m < s.count; ++m) {
            out.phi[s.first + m] = r[out_floats * m];
            if (out.gradient)
                for (int a = 0; a < 3; ++a) out.gradient[3 * (s.first + m) + std::size_t(a)] = r[4 * m + 1 + std::size_t(a)];
        }
        done += s.count;
        if (progress) progress("evaluate", double(done) / double(total));
    };

    std::size_t index = 0;
    for (std::size_t first = 0; first < total; first += chunk, ++index) {
        Slot& s = slots[index % kSlots];
        drain(s);
        s.first = first;
        s.count = std::min(chunk, total - first);
        float* up = static_cast<float*>(s.up.mapped());
        for (std::size_t m = 0; m < s.count; ++m) {
            const Eigen::Vector3d x = q.at(first + m);
            up[4 * m] = float(x.x());
            up[4 * m + 1] = float(x.y());
            up[4 * m + 2] = float(x.z());
            up[4 * m + 3] = 0.0f;
        }
        const BlendPush push{std::uint32_t(s.count), point_count_, first_leaf_, std::uint32_t(p.fallback_k),
                             float(p.r_eval), float(p.C), dmin_};
        const VkDeviceSize qbytes = s.count * 16, rbytes = s.count * out_floats * 4;
        s.rec->begin();
        s.rec->copy(s.up, 0, s.queries, 0, qbytes);
        s.rec->barrier();
        s.rec->dispatch(k, {{&points_}, {&terms_}, {&nodes_}, {&s.queries, 0, qbytes}, {&s.result, 0, rbytes}},
                        &push, sizeof(push), std::uint32_t((s.count + k.workgroup - 1) / k.workgroup));
        s.rec->barrier();
        s.rec->copy(s.result, 0, s.down, 0, rbytes);
        s.rec->barrier();
        s.rec->submit();
    }
    for (std::size_t m = 0; m < kSlots; ++m) drain(slots[(index + m) % kSlots]);
}

std::shared_ptr<GpuField> make_gpu_field(const std::shared_ptr<gpu::Context>& ctx, const Source& src,
                                         const detail::BoxTree& tree, const Params& params, std::string& why_not) {
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
    return std::make_shared<GpuField>(ctx, src, tree);
}

void evaluate_gpu(GpuField& field, const Params& params, const Queries& queries, Output out,
                  std::size_t chunk_size, const ProgressFn& progress) {
    field.evaluate(params, queries, out, chunk_size, progress);
}

std::string gpu_field_device(const GpuField& field) { return field.device_name(); }

std::vector<float> tori_on_device(gpu::Context& ctx, const Points& points, const Points& normals,
                                  const Points& tangents, const std::vector<Jet>& jets) {
    const auto n = std::size_t(points.rows());
    std::vector<std::uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    const std::vector<float> rec = jet_records(points, normals, tangents, jets, order);
    gpu::Buffer in = upload(ctx, rec.data(), rec.size() * 4);
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
