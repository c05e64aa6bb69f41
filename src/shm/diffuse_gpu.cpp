// SHM step 1–2 on a Vulkan device: the SumTree of the source lives on the device
// (sums_gpu.hpp); query points stream through shm_diffuse.comp in chunks (gpu::stream).
#include "shm/diffuse.hpp"

#include "gpu/runtime.hpp"
#include "spatial/morton.hpp"
#include "gpu/stream.hpp"
#include "push_constants.h"
#include "sums/sum_tree.hpp"
#include "sums/sums_gpu.hpp"

#include <algorithm>
#include <cstdlib>
#include <string>
#include <vector>

namespace gsd::shm {

namespace {

using kernels::DiffusePush;  // `Push` in shm_diffuse.comp

class GpuEvaluator final : public DirectionEvaluator {
public:
    GpuEvaluator(std::shared_ptr<gpu::Context> ctx, sums::SumTree tree, const KernelParams& k, std::size_t chunk)
        : ctx_(std::move(ctx)), k_(k), chunk_(chunk), host_(std::move(tree)), tree_(sums::upload(*ctx_, host_)) {}

    std::size_t evaluate(const Points& x, std::vector<float>& y, std::vector<double>& r_min,
                         const ProgressFn& progress) override {
        const auto n = std::size_t(x.rows());
        y.assign(3 * n, 0.0f);
        r_min.assign(n, 0.0);
        std::size_t terms = 0;
        // A subgroup walks together and counts its loop iterations against llvmpipe's limit
        // (gpu::software_loop_cap): on a software device a workgroup is one subgroup.
        const bool software = ctx_->info().is_software();
        // The subgroup walks together on software devices, each lane alone on GPUs (shm_diffuse.comp);
        // $GSD_SHM_WALK=alone|together overrides (tests, measurements).
        bool together = software;
        if (const char* w = std::getenv("GSD_SHM_WALK")) {
            if (std::string(w) == "together") together = true;
            if (std::string(w) == "alone") together = false;
        }
        // Software devices read the tree, its moments and the elements as texel buffers.
        const gpu::Kernel& k = gpu::kernel(*ctx_, gpu::kernel_table::shm_diffuse, {together ? 1 : 0, tree_.element_kinds},
                                           gpu::loop_capped_workgroup(*ctx_));
        const std::uint32_t cap = gpu::software_loop_cap(*ctx_);
        std::vector<char> redo(n, 0);
        std::vector<float> device_terms(n, 0.0f);  // summed at the end over the queries not redone
        gpu::StreamJob job;
        job.count = n;
        job.in_bytes = 16;
        job.out_bytes = 32;
        job.stage = "diffuse";
        if (chunk_) job.chunk = chunk_;
        // The nodes go to the device in Morton order (they come in storage order: a subgroup would
        // take a run along z), so that a subgroup's lanes are a compact block and their walk
        // together opens fewer nodes; results go back in the caller's order.
        std::vector<std::uint32_t> order;
        if (n > 1 && spatial::sort_queries_for_device()) order = spatial::morton_order(x);
        auto index = [&](std::size_t i) { return order.empty() ? i : std::size_t(order[i]); };
        job.fill = [&](std::size_t first, std::size_t m, void* dst) { gpu::fill_vec4(x, order, first, m, dst); };
        job.record = [&](gpu::Recorder& rec, const gpu::Buffer& in, const gpu::Buffer& out, std::size_t m) {
            const DiffusePush push{std::uint32_t(m), tree_.first_leaf, float(k_.lambda), float(k_.cutoff), float(k_.r_floor),
                                   float(k_.sum_tolerance * 2 * M_PI / k_.lambda), cap};
            rec.dispatch(k, {{&tree_.nodes}, {&tree_.moments}, {&tree_.elements}, {&in, 0, m * 16}, {&out, 0, m * 32}}, &push,
                         sizeof(push), std::uint32_t((m + k.workgroup - 1) / k.workgroup));
        };
        job.drain = [&](std::size_t first, std::size_t m, const void* src) {
            const float* r = static_cast<const float*>(src);
            for (std::size_t i = 0; i < m; ++i) {
                const std::size_t q = index(first + i);
                for (int a = 0; a < 3; ++a) y[3 * q + std::size_t(a)] = r[8 * i + std::size_t(a)];
                r_min[q] = r[8 * i + 3];
                device_terms[q] = r[8 * i + 4];
                if (r[8 * i + 5] != 0) redo[q] = 1;  // cut short with its subgroup, or a wide element
            }
        };
        gpu::stream(*ctx_, job, progress);
        // Queries a software device may have cut short, and queries that met an element wider
        // than their reach (shm_diffuse.comp leaves those to the CPU's clipping): the CPU
        // reference, in double, from a list (a dynamic schedule over every node cost more).
        std::vector<std::uint32_t> again;
        for (std::size_t q = 0; q < n; ++q) {
            if (redo[q]) again.push_back(std::uint32_t(q));
            else terms += std::size_t(device_terms[q]);
        }
        const sums::SumTree::Screened s = screened_params(k_);
#pragma omp parallel for schedule(dynamic, 16) reduction(+ : terms)
        for (std::size_t i = 0; i < again.size(); ++i) {
            const std::size_t q = again[i];
            const Eigen::Vector3d X = host_.screened(x.row(Eigen::Index(q)).transpose(), s, r_min[q], terms);
            const double len = X.norm();
            for (int a = 0; a < 3; ++a) y[3 * q + std::size_t(a)] = len > 0 ? float(X[a] / len) : 0.0f;
        }
        if (!again.empty())
            log_once("step 1: nodes past " + ctx_->info().name +
                     "'s loop limit, or near an element wider than their reach, were summed on the CPU");
        return terms;
    }

    std::string device() const override { return ctx_->info().name; }

private:
    std::shared_ptr<gpu::Context> ctx_;
    KernelParams k_;
    std::size_t chunk_ = 0;
    sums::SumTree host_;
    sums::DeviceSumTree tree_;
};

}  // namespace

std::unique_ptr<DirectionEvaluator> make_gpu_evaluator(const std::shared_ptr<gpu::Context>& ctx, const ShmSource& src,
                                                       const KernelParams& k, std::size_t chunk_size, std::string& why_not) {
    if (!ctx->info().subgroup_arithmetic) {
        why_not = ctx->info().name + " has no subgroup arithmetic in compute shaders; step 1 runs on the CPU";
        return nullptr;
    }
    sums::SumTree tree(src.elements);
    why_not = sums::gpu_unfit(*ctx, tree);
    if (!why_not.empty()) return nullptr;
    return std::make_unique<GpuEvaluator>(ctx, std::move(tree), k, chunk_size);
}

}  // namespace gsd::shm
