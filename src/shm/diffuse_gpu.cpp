// SHM step 1–2 on a Vulkan device: the sources live on the device in kd-tree order; query
// points stream through shm_diffuse.comp in chunks (gpu::stream).
#include "shm/diffuse.hpp"

#include "gpu/device_tree.hpp"
#include "gpu/runtime.hpp"
#include "gpu/stream.hpp"
#include "spatial/box_tree.hpp"

namespace gsd::shm_detail {

namespace {

struct DiffusePush {
    std::uint32_t count, first_leaf;
    float lambda, cutoff, r_floor;
};

class GpuEvaluator final : public DirectionEvaluator {
public:
    GpuEvaluator(std::shared_ptr<gpu::Context> ctx, const ShmSource& src, const KernelParams& k, std::size_t chunk)
        : ctx_(std::move(ctx)), k_(k), chunk_(chunk) {
        const detail::BoxTree tree(src.positions);
        const auto n = src.size();
        std::vector<float> p(4 * n), v(4 * n);
        for (std::size_t m = 0; m < n; ++m) {
            const auto i = Eigen::Index(tree.order()[m]);
            for (int a = 0; a < 3; ++a) {
                p[4 * m + std::size_t(a)] = float(src.positions(i, a));
                v[4 * m + std::size_t(a)] = float(src.vectors(i, a));
            }
        }
        points_ = gpu::upload(*ctx_, p.data(), p.size() * 4);
        vectors_ = gpu::upload(*ctx_, v.data(), v.size() * 4);
        const std::vector<gpu::DeviceNode> nodes = gpu::device_nodes(tree);
        nodes_ = gpu::upload(*ctx_, nodes.data(), nodes.size() * sizeof(gpu::DeviceNode));
        first_leaf_ = tree.first_leaf();
    }

    std::size_t evaluate(const Points& x, std::vector<float>& y, std::vector<double>& r_min,
                         const ProgressFn& progress) override {
        const auto n = std::size_t(x.rows());
        y.assign(3 * n, 0.0f);
        r_min.assign(n, 0.0);
        std::size_t terms = 0;
        const gpu::Kernel& k = ctx_->kernel("shm_diffuse", 5, sizeof(DiffusePush));
        gpu::StreamJob job;
        job.count = n;
        job.in_bytes = 16;
        job.out_bytes = 32;
        job.stage = "diffuse";
        if (chunk_) job.chunk = chunk_;
        job.fill = [&](std::size_t first, std::size_t m, void* dst) {
            float* up = static_cast<float*>(dst);
            for (std::size_t i = 0; i < m; ++i) {
                for (int a = 0; a < 3; ++a) up[4 * i + std::size_t(a)] = float(x(Eigen::Index(first + i), a));
                up[4 * i + 3] = 0;
            }
        };
        job.record = [&](gpu::Recorder& rec, const gpu::Buffer& in, const gpu::Buffer& out, std::size_t m) {
            const DiffusePush push{std::uint32_t(m), first_leaf_, float(k_.lambda), float(k_.cutoff), float(k_.r_floor)};
            rec.dispatch(k, {{&points_}, {&vectors_}, {&nodes_}, {&in, 0, m * 16}, {&out, 0, m * 32}}, &push, sizeof(push),
                         std::uint32_t((m + k.workgroup - 1) / k.workgroup));
        };
        job.drain = [&](std::size_t first, std::size_t m, const void* src) {
            const float* r = static_cast<const float*>(src);
            for (std::size_t i = 0; i < m; ++i) {
                for (int a = 0; a < 3; ++a) y[3 * (first + i) + std::size_t(a)] = r[8 * i + std::size_t(a)];
                r_min[first + i] = r[8 * i + 3];
                terms += std::size_t(r[8 * i + 4]);
            }
        };
        gpu::stream(*ctx_, job, progress);
        return terms;
    }

    std::string device() const override { return ctx_->info().name; }

private:
    std::shared_ptr<gpu::Context> ctx_;
    KernelParams k_;
    std::size_t chunk_ = 0;
    gpu::Buffer points_, vectors_, nodes_;
    std::uint32_t first_leaf_ = 0;
};

}  // namespace

std::unique_ptr<DirectionEvaluator> make_gpu_evaluator(const std::shared_ptr<gpu::Context>& ctx, const ShmSource& src,
                                                       const KernelParams& k, std::size_t chunk_size, std::string& why_not) {
    if (src.size() * 16 > ctx->max_binding_bytes() || src.size() >= (1ull << 31)) {
        why_not = "the source (" + std::to_string(src.size()) + " elements) exceeds " + ctx->info().name +
                  "'s storage buffer range; step 1 runs on the CPU";
        return nullptr;
    }
    return std::make_unique<GpuEvaluator>(ctx, src, k, chunk_size);
}

}  // namespace gsd::shm_detail
