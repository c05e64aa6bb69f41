// Uploading the SumTree and the winding-number kernel (shaders/sums_winding.comp).
#include "spatial/morton.hpp"
#include "sums/sums_gpu.hpp"

#include "gpu/device_tree.hpp"
#include "gpu/stream.hpp"
#include "push_constants.h"
#include "sums/sum_tree.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace gsd::sums {

namespace {

constexpr std::size_t kMomentVec4 = 9;  // per node: c, ρ | m0, area | m1 (9) m2 (18) pad

// Rounds a box outward to float so every float32 corner stays inside it.
void outward(const double* lo, const double* hi, gpu::DeviceNode& out) {
    for (int a = 0; a < 3; ++a) {
        const float l = float(lo[a]), h = float(hi[a]);
        out.lo[a] = double(l) > lo[a] ? std::nextafter(l, -INFINITY) : l;
        out.hi[a] = double(h) < hi[a] ? std::nextafter(h, INFINITY) : h;
    }
}

// Which kinds of element records (3 vec4 each: (a, v.x), (b, v.y), (c, v.z)) hold, as the
// kernels test them: bit 0 triangles, bit 1 points (a = b = c).
std::int32_t element_kinds(const float* records, std::size_t count) {
    std::int32_t kinds = 0;
    for (std::size_t j = 0; j < count && kinds != 3; ++j) {
        const float* e = records + 12 * j;
        const bool point = std::equal(e, e + 3, e + 4) && std::equal(e, e + 3, e + 8);
        kinds |= point ? 2 : 1;
    }
    return kinds;
}

}  // namespace

std::string gpu_unfit(const gpu::Context& ctx, const sums::SumTree& tree) {
    // float32 squares distances: beyond ~1e19 they overflow. Keep a wide margin.
    const auto& root = tree.nodes()[0];
    for (int a = 0; a < 3; ++a)
        if (std::max(std::abs(root.lo[a]), std::abs(root.hi[a])) > 1e15)
            return "coordinates beyond ±1e15 are outside float32's safe range; the sums run on the CPU";
    const std::size_t bytes = std::max(tree.size() * 48, tree.nodes().size() * kMomentVec4 * 16);
    if (bytes > ctx.max_binding_bytes())
        return "the source (" + std::to_string(tree.size()) + " elements) exceeds " + ctx.info().name +
               "'s storage buffer range; the sums run on the CPU";
    return {};
}

DeviceSumTree upload(gpu::Context& ctx, const sums::SumTree& tree) {
    const auto& nodes = tree.nodes();
    std::vector<gpu::DeviceNode> dn(nodes.size());
    std::vector<float> mom(nodes.size() * kMomentVec4 * 4, 0.0f);
    for (std::size_t i = 0; i < nodes.size(); ++i) {
        const auto& n = nodes[i];
        outward(n.lo, n.hi, dn[i]);
        dn[i].begin = n.begin;
        dn[i].end = n.end;
        float* m = &mom[i * kMomentVec4 * 4];
        for (int a = 0; a < 3; ++a) {
            m[a] = float(n.c[a]);
            m[4 + a] = float(n.m0[a]);
        }
        // The radius rounded up so float distances never accept a node too close.
        m[3] = float(n.rho) < n.rho ? std::nextafter(float(n.rho), INFINITY) : float(n.rho);
        m[7] = float(n.area);
        for (int k = 0; k < 9; ++k) m[8 + k] = float(n.m1[k]);
        for (int k = 0; k < 18; ++k) m[17 + k] = float(n.m2[k]);
    }
    std::vector<float> el(tree.size() * 12);
    for (std::size_t j = 0; j < tree.size(); ++j) {
        const double* p = tree.corners(j);
        const double* v = tree.vector(j);
        for (int k = 0; k < 3; ++k) {
            for (int a = 0; a < 3; ++a) el[12 * j + std::size_t(4 * k + a)] = float(p[3 * k + a]);
            el[12 * j + std::size_t(4 * k + 3)] = float(v[k]);
        }
    }
    DeviceSumTree d;
    d.element_kinds = element_kinds(el.data(), tree.size());
    d.nodes = gpu::upload(ctx, dn.data(), dn.size() * sizeof(gpu::DeviceNode));
    d.moments = gpu::upload(ctx, mom.data(), mom.size() * 4);
    d.elements = gpu::upload(ctx, el.data(), el.size() * 4);
    d.first_leaf = tree.first_leaf();
    return d;
}

namespace {

using kernels::WindingPush;  // `Push` in sums_winding.comp

/// The tree as sums_winding.comp walks it: a vec4 per node, the float32 walk's test (all a walk
/// reads of a node it does not sum: kept together, siblings side by side), then 7 vec4 per node
/// (its element range and the float32 walk's expansion); and 3 vec4 per element; all in the
/// float walk's normalized coordinates (vector areas scaled by scale², so that a point's dipole
/// v·y/|y|³ is unchanged).
struct DeviceWindingTree {
    // What the records were made for: the device (first, so that it outlives the buffers), β and
    // the reach scale (reach² depends on them).
    std::shared_ptr<gpu::Context> ctx;
    float beta = 0, reach_scale = 0;
    gpu::Buffer nodes, elements;
    std::uint32_t first_leaf = 0, widest_leaf = 0, node_count = 0;
    std::int32_t element_kinds = 0;  ///< bit 0: triangles, bit 1: points (a = b = c)
};

DeviceWindingTree upload_winding(gpu::Context& ctx, const sums::SumTree& tree, float beta, float reach_scale) {
    const auto& nodes = tree.nodes();
    const auto* tests = tree.winding_tests_f();
    const auto* expansions = tree.winding_nodes_f();
    static_assert(sizeof(sums::SumTree::WindingNodeT<float>) == 23 * sizeof(float), "23 floats");
    DeviceWindingTree d;
    const std::size_t n = nodes.size();
    std::vector<float> nd(n * 4 + n * 28, 0.0f);
    for (std::size_t i = 0; i < n; ++i) {
        float* test = &nd[4 * i];
        const auto& t = tests[i];
        test[0] = t.c[0], test[1] = t.c[1], test[2] = t.c[2];
        test[3] = sums::winding_reach2(t.rho, t.q, beta, reach_scale);
        float* r = &nd[4 * n + 28 * i];
        std::memcpy(&r[0], &nodes[i].begin, 4);
        std::memcpy(&r[1], &nodes[i].end, 4);
        std::memcpy(&r[4], &expansions[i], sizeof(expansions[i]));
        if (i >= tree.first_leaf()) d.widest_leaf = std::max(d.widest_leaf, nodes[i].end - nodes[i].begin);
    }
    const double* origin = tree.winding_origin();
    const double scale = tree.winding_scale();
    std::vector<float> el(tree.size() * 12);
    for (std::size_t j = 0; j < tree.size(); ++j) {
        const double* p = tree.corners(j);
        const double* v = tree.vector(j);
        for (int k = 0; k < 3; ++k) {
            for (int a = 0; a < 3; ++a) el[12 * j + std::size_t(4 * k + a)] = float((p[3 * k + a] - origin[a]) * scale);
            el[12 * j + std::size_t(4 * k + 3)] = float(v[k] * scale * scale);
        }
    }
    d.element_kinds = element_kinds(el.data(), tree.size());
    d.nodes = gpu::upload(ctx, nd.data(), nd.size() * 4);
    d.elements = gpu::upload(ctx, el.data(), el.size() * 4);
    d.first_leaf = tree.first_leaf();
    d.node_count = std::uint32_t(n);
    d.beta = beta;
    d.reach_scale = reach_scale;
    return d;
}

/// The tree's records on this device for (β, reach scale): uploaded once per tree and kept with
/// it (SumTree::device_copy), so that a field evaluated again (chunks of a render, a grid in
/// slabs, the bench's repeated calls) does not upload again.
std::shared_ptr<const DeviceWindingTree> device_tree(const std::shared_ptr<gpu::Context>& ctx, const sums::SumTree& tree,
                                                     float beta, float reach_scale) {
    std::lock_guard<std::mutex> lock(tree.device_copy_mutex());
    auto cached = std::static_pointer_cast<DeviceWindingTree>(tree.device_copy());
    if (cached && cached->ctx == ctx && cached->beta == beta && cached->reach_scale == reach_scale) return cached;
    auto made = std::make_shared<DeviceWindingTree>(upload_winding(*ctx, tree, beta, reach_scale));
    made->ctx = ctx;
    tree.device_copy() = made;
    return made;
}

// The winding kernel for the tree on this device, and the queries a workgroup of its software
// build sums (`group`).
struct WindingKernel {
    const gpu::Kernel* kernel = nullptr;
    std::uint32_t group = 8;
};

WindingKernel winding_kernel(gpu::Context& ctx, const DeviceWindingTree& d) {
    // One subgroup walks together. On a software device a workgroup is one subgroup, so that
    // llvmpipe's loop limit (65535 iterations per SIMD group) is the subgroup's own count.
    const std::uint32_t workgroup = gpu::loop_capped_workgroup(ctx);
    // Software devices: a group of queries a workgroup, the lanes sharing out the tree's nodes
    // (the tree and the elements read as texel buffers, bindings 0 and 1). A stack entry holds a
    // node index above the group's bits: 16 queries while node indices fit 16 bits, 12 while they
    // fit 20, else 8 (measured on lavapipe, 10⁶ random queries around a 7.9·10³-face mesh: the
    // kernel took 338, 311 and 284 ms for groups of 8, 12 and 16; 32 in two-word entries 302).
    // Each lane has its own spare slots (64 lanes at most): past those, the GPUs' kernel.
    std::uint32_t software_group = d.node_count <= (1u << 16) ? 16u : d.node_count <= (1u << 20) ? 12u : 8u;
    // GSD_WINDING_GROUP=8 or 12 takes smaller groups (the tests run every size on small trees);
    // a larger group than the tree allows, or any other value, is ignored.
    if (const char* v = std::getenv("GSD_WINDING_GROUP")) {
        const std::string g = v;
        if (g == "8") software_group = 8;
        if (g == "12" && software_group >= 12) software_group = 12;
    }
    // Its workgroup is one subgroup of at most 64 lanes (none on hardware: loop_capped_workgroup
    // is 0 there), which add up each query's sum by shuffles.
    const bool fits_shaped = d.node_count <= (1u << 24) && workgroup > 0 && workgroup <= 64 && ctx.info().subgroup_shuffle;
    const bool want_shaped = gpu::software_shaped(ctx) && fits_shaped;
    // (The GPUs' build has no group: one value, so that trees of every size share its pipeline.)
    const gpu::Kernel& k = gpu::kernel(ctx, gpu::kernel_table::sums_winding,
                                       {d.element_kinds, std::int32_t(want_shaped ? software_group : 8u)}, workgroup,
                                       want_shaped);
    return {&k, software_group};
}

}  // namespace

void gpu_prepare_winding(const std::shared_ptr<gpu::Context>& ctx, const sums::SumTree& tree, const WindingOptions& opt) {
    if (!gpu_unfit(*ctx, tree).empty()) return;
    const std::shared_ptr<const DeviceWindingTree> kept =
        device_tree(ctx, tree, float(opt.beta), float(sums::winding_reach_scale(opt.tolerance)));
    winding_kernel(*ctx, *kept);
}

bool gpu_winding(const std::shared_ptr<gpu::Context>& ctx, const sums::SumTree& tree, PointsView queries,
                 const std::vector<std::uint32_t>& morton, const WindingOptions& opt, WindingResult& out, const ProgressFn& progress, std::string& why_not) {
    why_not = gpu_unfit(*ctx, tree);
    if (!why_not.empty()) return false;
    auto clock = [] { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); };
    const double t_start = clock();
    const std::shared_ptr<const DeviceWindingTree> kept =
        device_tree(ctx, tree, float(opt.beta), float(sums::winding_reach_scale(opt.tolerance)));
    const DeviceWindingTree& d = *kept;
    const double t_uploaded = clock();
    const WindingKernel chosen = winding_kernel(*ctx, d);
    const gpu::Kernel& k = *chosen.kernel;
    const std::uint32_t software_group = chosen.group;
    const bool shaped = k.texel_bindings.all() != 0;
    // The loop cap, less what one step of the walk may still iterate after the check: a leaf's
    // elements, or (software-shaped) a round and the sums of both lists (at most 65 chunks of
    // expansions and 33 of leaves, with 4 lanes or more).
    const std::uint32_t step = shaped ? 1024u + 34u * (d.widest_leaf + 2u) : 64u + d.widest_leaf;
    // The software-shaped kernel sums a group of queries a workgroup, whatever its width; the
    // GPUs' one query an invocation.
    const std::size_t per_group = shaped ? software_group : k.workgroup;
    const std::uint32_t limit = gpu::software_loop_cap(*ctx);  // 0 on hardware: no limit
    const std::uint32_t cap = limit == 0 ? 0u : limit > step ? limit - step : 1u;
    const auto n = std::size_t(queries.rows());
    // Morton order, so that a subgroup's queries are neighbours; results go back in input order.
    std::vector<std::uint32_t> input_order;
    if (!spatial::sort_queries_for_device()) {
        input_order.resize(n);
        for (std::size_t i = 0; i < n; ++i) input_order[i] = std::uint32_t(i);
    }
    const std::vector<std::uint32_t>& order = input_order.empty() ? morton : input_order;
    if (order.size() != n) throw Error("gpu_winding", "the queries' order has " + std::to_string(order.size()) +
                                                         " entries for " + std::to_string(n) + " queries");
    const double t_kernel = clock();
    const double* origin = tree.winding_origin();
    const double scale = tree.winding_scale();
    // Queries so far out that float32's expansion terms could overflow, and those the loop
    // limit cut short, are summed on the CPU (which walks far queries in double).
    constexpr double kDeviceReach = 1e6;  // root radii
    std::vector<char> redo(n, 0);
    std::size_t terms = 0;
    gpu::StreamJob job;
    job.count = n;
    job.in_bytes = 16;
    job.out_bytes = 8;
    job.stage = "winding";
    job.chunk = opt.chunk_size ? opt.chunk_size : gpu::default_chunk(*ctx);
    job.granule = shaped ? per_group : 1;
    // Fill and drain gather and scatter through the order, in parallel: one thread waits on
    // memory for most of a random access, and at 10⁷ queries that was most of a run. (On a
    // software device they run on one thread, gpu::stream: there the prefetch, kAhead queries
    // ahead, took the fill of 10⁶ queries from ~23 to ~15 ms.)
    constexpr std::size_t kAhead = 16;
    job.fill = [&](std::size_t first, std::size_t m, void* dst) {
        float* up = static_cast<float*>(dst);
#pragma omp parallel for schedule(static)
        for (std::size_t i = 0; i < m; ++i) {
            const auto q = Eigen::Index(order[first + i]);
            if (i + kAhead < m) __builtin_prefetch(queries.data() + Eigen::Index(order[first + i + kAhead]) * queries.outerStride());
            double far = 0;
            for (int a = 0; a < 3; ++a) {
                const double u = (queries(q, a) - origin[a]) * scale;
                far = std::max(far, std::abs(u));
                up[4 * i + std::size_t(a)] = float(u);
            }
            up[4 * i + 3] = 0;
            if (far > kDeviceReach) {
                redo[std::size_t(q)] = 1;
                for (int a = 0; a < 3; ++a) up[4 * i + std::size_t(a)] = 0;  // a cheap stand-in
            }
        }
    };
    job.record = [&](gpu::Recorder& rec, const gpu::Buffer& in, const gpu::Buffer& o, std::size_t m) {
        const WindingPush push{std::uint32_t(m), d.first_leaf, cap, d.node_count};
        rec.dispatch(k, {{&d.nodes}, {&d.elements}, {&in, 0, m * 16}, {&o, 0, m * 8}}, &push, sizeof(push),
                     std::uint32_t((m + per_group - 1) / per_group));
    };
    job.drain = [&](std::size_t first, std::size_t m, const void* src) {
        const float* r = static_cast<const float*>(src);
        std::size_t chunk_terms = 0;
#pragma omp parallel for schedule(static) reduction(+ : chunk_terms)
        for (std::size_t i = 0; i < m; ++i) {
            const std::uint32_t q = order[first + i];
            out.w[q] = r[2 * i];
            if (r[2 * i + 1] < 0) redo[q] = 1;
            else if (!redo[q]) chunk_terms += std::size_t(r[2 * i + 1]);
        }
        terms += chunk_terms;
    };
    gpu::stream(*ctx, job, progress);
    const double t_streamed = clock();
    // The queries to sum on the CPU, listed first (a dynamic schedule over all 10⁷ indices
    // cost more than the device's whole walk).
    std::vector<std::uint32_t> again;
    for (std::size_t q = 0; q < n; ++q)
        if (redo[q]) again.push_back(std::uint32_t(q));
    const std::size_t redone = again.size();
#pragma omp parallel for schedule(dynamic, 16) reduction(+ : terms)
    for (std::size_t i = 0; i < again.size(); ++i) {
        const auto q = Eigen::Index(again[i]);
        out.w[std::size_t(q)] = tree.winding(queries.row(q).transpose(), opt.beta, opt.tolerance, terms);
    }
    if (ctx->state().profile)
        std::fprintf(stderr, "gsd: winding host: tree upload %.1f ms, kernel %.1f ms, stream %.1f ms, CPU redo %.1f ms (%zu queries)\n",
                     1e3 * (t_uploaded - t_start), 1e3 * (t_kernel - t_uploaded), 1e3 * (t_streamed - t_kernel),
                     1e3 * (clock() - t_streamed), redone);
    if (redone) log_once("winding: " + std::to_string(redone) + " queries far outside the source or past " + ctx->info().name +
                         "'s loop limit were summed on the CPU");
    out.terms = terms;
    out.device = ctx->info().name;
    return true;
}

}  // namespace gsd::sums
