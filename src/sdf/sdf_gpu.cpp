// sdf_gpu.cpp — see sdf_gpu.hpp. The tree goes up as the fast sums upload it (sums_gpu.hpp: its
// nodes and triangles, float32, tree order); queries stream through sdf_nearest.comp in chunks.
#include "sdf/sdf_gpu.hpp"

#include "gpu/runtime.hpp"
#include "gpu/stream.hpp"
#include "push_constants.h"
#include "spatial/morton.hpp"
#include "sums/sum_tree.hpp"
#include "sums/sums_gpu.hpp"

namespace gsd::sdf {

bool gpu_nearest(const std::shared_ptr<gpu::Context>& ctx, const sums::SumTree& tree, PointsView queries,
                 std::size_t chunk_size, std::vector<std::uint32_t>& nearest, const ProgressFn& progress,
                 std::string& why_not) {
    why_not = sums::gpu_unfit(*ctx, tree);
    if (!why_not.empty()) return false;
    if (ctx->info().is_software() && !ctx->info().subgroup_arithmetic) {
        why_not = ctx->info().name + " has no subgroup operations in compute shaders";
        return false;
    }
    const sums::DeviceSumTree device_tree = sums::upload(*ctx, tree);
    const gpu::Kernel& k = gpu::kernel(*ctx, gpu::kernel_table::sdf_nearest, {}, gpu::loop_capped_workgroup(*ctx));
    const std::uint32_t cap = gpu::software_loop_cap(*ctx);
    const auto n = std::size_t(queries.rows());
    nearest.assign(n, 0);
    std::vector<std::uint32_t> again;  // cut short at a software device's loop limit
    gpu::StreamJob job;
    job.count = n;
    job.in_bytes = 16;
    job.out_bytes = 8;
    job.stage = "distance";
    job.chunk = chunk_size ? chunk_size : gpu::default_chunk(*ctx);
    // In Morton order, so that a subgroup's lanes are neighbours and walk nearly the same nodes
    // (in the input's order, 10⁵ random queries took 4.4× as long with the software-shaped kernel
    // on lavapipe, 1.2× with the GPUs' one: docs/sdf.md); results go back to their queries' places.
    std::vector<std::uint32_t> order;
    if (spatial::sort_queries_for_device()) order = spatial::morton_order(queries);
    else {  // $GSD_QUERY_ORDER=input: to measure what the order is worth
        order.resize(n);
        for (std::size_t i = 0; i < n; ++i) order[i] = std::uint32_t(i);
    }
    job.fill = [&](std::size_t first, std::size_t m, void* dst) { gpu::fill_vec4(queries, order, first, m, dst); };
    job.record = [&](gpu::Recorder& rec, const gpu::Buffer& in, const gpu::Buffer& out, std::size_t m) {
        const kernels::SdfNearestPush push{std::uint32_t(m), device_tree.first_leaf, cap};
        rec.dispatch(k, {{&device_tree.nodes}, {&device_tree.elements}, {&in, 0, m * 16}, {&out, 0, m * 8}}, &push,
                     sizeof(push), std::uint32_t((m + k.workgroup - 1) / k.workgroup));
    };
    job.drain = [&](std::size_t first, std::size_t m, const void* src) {
        const auto* r = static_cast<const std::uint32_t*>(src);
        for (std::size_t i = 0; i < m; ++i) {
            const std::uint32_t q = order[first + i];
            nearest[q] = r[2 * i];
            if (r[2 * i + 1] != 0 || r[2 * i] >= tree.size()) again.push_back(q);
        }
    };
    gpu::stream(*ctx, job, progress);
    if (!again.empty()) log_once("distance: queries past " + ctx->info().name + "'s loop limit were searched on the CPU");
#pragma omp parallel for schedule(dynamic, 64)
    for (std::ptrdiff_t k2 = 0; k2 < std::ptrdiff_t(again.size()); ++k2) {
        const std::uint32_t q = again[std::size_t(k2)];
        double p[3] = {queries(q, 0), queries(q, 1), queries(q, 2)}, r;
        std::uint32_t start = std::uint32_t(tree.size()), each;
        tree.nearest_triangles(p, 1, &start, &r, &each);
        nearest[q] = each;
    }
    return true;
}

}  // namespace gsd::sdf
