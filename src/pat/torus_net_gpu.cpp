// TorusNet on a Vulkan device (docs/torusnet.md, "GPU kernels"). The cloud is uploaded once in
// kd-tree order; points then stream through in chunks (gpu::stream, three in flight), each chunk
// one submission: torus_net_knn (neighborhoods) → barrier → torus_net (features, transformer,
// coefficients) → copy back.
#include "pat/torus_net_gpu.hpp"
#include "pat/torus_net_gpu_check.hpp"

#include "gpu/device_tree.hpp"
#include "gpu/runtime.hpp"
#include "gpu/stream.hpp"
#include "push_constants.h"
#include "spatial/box_tree.hpp"

#include <gsd/gpu.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace gsd::pat {

namespace {

using gpu::Buffer;
using gpu::Memory;

constexpr int kMaxK = 64;  // the kNN kernel keeps K distances per invocation

// The kernel's sizes for one model on one device (spec. constants of torus_net.comp).
struct NetPlan {
    int k = 0, width = 0, heads = 0, mlp = 0, blocks = 0;
    int fc = 0;     ///< MLP columns per pass
    int tile_rows = 4, tile_cols = 2;  ///< matrix-product tile (rows, vec4 columns)
    int pool = 0;   ///< workspace vec4s per point
    bool global = false;  ///< workspace in device memory (model too big for shared memory)
    std::size_t shared_bytes = 0;
};

std::string dims(const TorusNetModel& m) {
    return "k=" + std::to_string(m.k) + ", width " + std::to_string(m.width) + ", " + std::to_string(m.heads) +
           " heads, MLP " + std::to_string(m.mlp);
}

NetPlan plan(const TorusNetModel& m, const gpu::Context& ctx, bool force_global) {
    NetPlan p;
    p.k = m.k;
    p.width = m.width;
    p.heads = m.heads;
    p.mlp = m.mlp;
    p.blocks = m.blocks;
    if (m.blocks < 1 || m.k < 2 || m.heads < 1 || m.width % m.heads != 0)
        throw Error("TorusNet model (" + dims(m) + ", " + std::to_string(m.blocks) + " blocks) is not runnable");
    if (m.k > kMaxK)
        throw Error("the TorusNet GPU kernels support k ≤ " + std::to_string(kMaxK) + "; this model has k = " +
                    std::to_string(m.k) + " (use device \"cpu\")");
    const int d = m.width / m.heads;
    // The kernels read vec4s: k, width, width/heads and the MLP width must be multiples of 4.
    if (m.k % 4 != 0 || m.width % 4 != 0 || d % 4 != 0 || m.mlp % 4 != 0)
        throw Error("the TorusNet GPU kernels need k, width, width/heads and MLP width to be multiples of 4 (" +
                    dims(m) + "; use device \"cpu\")");
    // The workspace in vec4s (torus_net.comp, "workspace layout"): X and Y, then a scratch area
    // for the features, one head's q|k|v with its scores, or a pass of the MLP.
    const int k = m.k, xs = m.width / 4 + 1, qs = 3 * d / 4 + 1, ss = k / 4 + 1;
    const int scratch = std::max(k * qs + k * ss, 2 * k);
    // The MLP runs in passes of fc hidden columns that fit the same scratch (fc | mlp, 4 | fc).
    p.fc = 4;
    for (int c = 4; c <= m.mlp; c += 4)
        if (m.mlp % c == 0 && k * (c / 4 + 1) <= scratch) p.fc = c;
    p.pool = 2 * k * xs + std::max(scratch, k * (p.fc / 4 + 1));
    // Tiles of the GPU build's matrix products (measured, docs/gpu.md): 4 rows × 1 vec4 on GPUs
    // (more, smaller tiles keep more threads busy: on an H100 1.6× the throughput of 4 × 2);
    // 8 × 2 on a software device that the software build does not fit, which reads the weights
    // lane by lane there (snail.ply: 2.0 s of kernel against 2.2 for 4 × 2 and 2.8 for 4 × 4).
    // $GSD_TORUSNET_TILE=rows,cols overrides.
    if (ctx.info().is_software()) {
        p.tile_rows = k % 8 == 0 ? 8 : 4;
        p.tile_cols = 2;
    } else {
        p.tile_cols = 1;
    }
    if (const char* v = std::getenv("GSD_TORUSNET_TILE"); v && *v) {
        int r = 0, c = 0;
        if (std::sscanf(v, "%d,%d", &r, &c) != 2 || r < 1 || r > 16 || k % r != 0 || c < 1 || c > 4)
            throw Error("GSD_TORUSNET_TILE", "expected rows,cols with rows in 1..16 dividing k = " + std::to_string(k) +
                                                 " and cols in 1..4, got '" + v + "'");
        p.tile_rows = r;
        p.tile_cols = c;
    }
    const std::size_t small = 4 * (3 * std::size_t(k) + 2);  // row statistics, distances, m
    p.shared_bytes = 16 * std::size_t(p.pool) + small;
    const std::size_t limit = ctx.limits().maxComputeSharedMemorySize;
    p.global = force_global || p.shared_bytes > limit;
    if (p.global) p.shared_bytes = 16 + small;
    if (p.shared_bytes > limit)
        throw Error("TorusNet model (" + dims(m) + ") needs " + std::to_string(p.shared_bytes) +
                    " bytes of shared memory; " + ctx.info().name + " has " + std::to_string(limit) + " (use device \"cpu\")");
    return p;
}

// The weights in the kernel's layout (torus_net.comp, "weights layout"): Linear weights
// transposed to [in][out]; qkv regrouped per head as [W][q_h | k_h | v_h].
std::vector<float> pack_weights(const TorusNetModel& m) {
    const int W = m.width, F = m.mlp, H = m.heads, D = W / H;
    const float* P = m.params.data();
    std::vector<float> out;
    auto transposed = [&](const NetLinear& l) {  // [out][in] → [in][out], then the bias
        for (int i = 0; i < l.in; ++i)
            for (int o = 0; o < l.out; ++o) out.push_back(P[l.weight + std::size_t(o) * std::size_t(l.in) + std::size_t(i)]);
        out.insert(out.end(), P + l.bias, P + l.bias + l.out);
    };
    auto norm = [&](const NetNorm& n) {
        out.insert(out.end(), P + n.weight, P + n.weight + n.width);
        out.insert(out.end(), P + n.bias, P + n.bias + n.width);
    };
    transposed(m.embed);  // [7][W], then a zero row: the kernel reads 8 inputs
    out.insert(out.end() - W, std::size_t(W), 0.0f);
    norm(m.embed_norm);
    std::size_t block_floats = 0;
    for (const NetBlock& b : m.block) {
        const std::size_t start = out.size();
        norm(b.norm1);
        for (int h = 0; h < H; ++h) {
            auto row = [&](int x) { return std::size_t((x / D) * W + h * D + x % D); };  // x < 3D
            for (int i = 0; i < W; ++i)
                for (int x = 0; x < 3 * D; ++x) out.push_back(P[b.qkv.weight + row(x) * std::size_t(W) + std::size_t(i)]);
            for (int x = 0; x < 3 * D; ++x) out.push_back(P[b.qkv.bias + row(x)]);
        }
        transposed(b.proj);
        norm(b.norm2);
        transposed(b.fc1);
        transposed(b.fc2);
        block_floats = out.size() - start;
    }
    norm(m.final_norm);
    out.insert(out.end(), P + m.head.weight, P + m.head.weight + 6 * std::size_t(W));
    out.insert(out.end(), P + m.head.bias, P + m.head.bias + 6);
    out.resize(out.size() + 2);
    // The same sizes as the shader's constants (BLK, BLK0, HD_B).
    const std::size_t blk = std::size_t(2 * W + H * (W * 3 * D + 3 * D) + W * W + W + 2 * W + W * F + F + F * W + W);
    const std::size_t blk0 = std::size_t(8 * W + 3 * W);
    if (block_floats != blk || out.size() != blk0 + m.block.size() * blk + 2 * std::size_t(W) + 6 * std::size_t(W) + 8)
        throw Error("gpu", "TorusNet weight packing does not match torus_net.comp");
    return out;
}

// A cloud (or the neighborhoods of the test entry) on the device, in upload order: float32
// positions (the kNN search), fixed-point positions (exact differences for the features), unit
// normals with tangent_of's axis.
struct DeviceCloud {
    Buffer pts, fixed, nrm;
};

// The smallest power-of-two exponent e such that every |x| ≤ reach is within ±2^29 units of 2^e:
// the difference of any two positions then fits an int32 exactly.
int unit_exponent(double reach) {
    return reach > 0 ? int(std::ceil(std::log2(reach))) - 29 : 0;
}

// `positions` are centered (so float32 and the fixed-point grid both resolve them finely).
// Rows [g·group, (g+1)·group) of the upload share a fixed-point unit (group 0: all rows), so
// the test entry can give each neighborhood its own.
DeviceCloud upload_cloud(gpu::Context& ctx, const Points& positions, const Points& normals,
                         const std::vector<std::uint32_t>& order, std::size_t group, bool with_float_points) {
    const std::size_t n = order.size();
    if (group == 0) group = std::max<std::size_t>(n, 1);
    std::vector<float> pts(with_float_points ? 4 * n : 0), nr(4 * n);
    std::vector<std::int32_t> fx(4 * n);
    std::vector<int> exponent((n + group - 1) / group);
    if (exponent.size() == 1) exponent[0] = unit_exponent(positions.cwiseAbs().maxCoeff());
    else
        for (std::size_t g = 0; g < exponent.size(); ++g) {
            double reach = 0;
            for (std::size_t k = g * group; k < std::min(n, (g + 1) * group); ++k)
                reach = std::max(reach, positions.row(Eigen::Index(order[k])).cwiseAbs().maxCoeff());
            exponent[g] = unit_exponent(reach);
        }
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t kk = 0; kk < std::ptrdiff_t(n); ++kk) {
        const auto k = std::size_t(kk);
        const int e = exponent[k / group];
        const auto i = Eigen::Index(order[k]);
        const Eigen::Vector3d nn = normals.row(i).transpose().normalized();
        for (int a = 0; a < 3; ++a) {
            const double x = positions(i, a);
            if (with_float_points) pts[4 * k + std::size_t(a)] = float(x);
            fx[4 * k + std::size_t(a)] = std::int32_t(std::llround(std::ldexp(x, -e)));
            nr[4 * k + std::size_t(a)] = float(nn[a]);
        }
        fx[4 * k + 3] = e;
        nr[4 * k + 3] = float(tangent_axis(nn));
    }
    DeviceCloud dc;
    if (with_float_points) dc.pts = gpu::upload(ctx, pts.data(), pts.size() * 4);
    dc.fixed = gpu::upload(ctx, fx.data(), fx.size() * 4);
    dc.nrm = gpu::upload(ctx, nr.data(), nr.size() * 4);
    return dc;
}

/// A bound on the loop iterations one subgroup of torus_net.comp runs for a point when the
/// workgroup has `wg` invocations, all loops together, as llvmpipe counts them against its
/// limit of 65 535 (docs/gpu.md): each loop's passes plus its final test, the loops with a
/// constant count of a few passes unrolled. It follows the kernel's loops one by one.
std::uint64_t net_loop_iterations(const NetPlan& p, std::uint64_t wg) {
    using U = std::uint64_t;
    const U K = U(p.k), W4 = U(p.width) / 4, D = U(p.width / p.heads), D4 = D / 4, K4 = K / 4, H = U(p.heads);
    const U F = U(p.mlp), FC = U(p.fc), TR = U(p.tile_rows), TC = U(p.tile_cols);
    auto passes = [&](U items) { return (items + wg - 1) / wg + 1; };  // a strided loop over items
    auto gemm = [&](U R, U rt, U I4, U N) { return passes((R / rt) * ((N / 4 + TC - 1) / TC)) * (I4 + 1); };
    auto scores = [&](U R, U rt) { return passes((R / rt) * ((K + 7) / 8)) * (D4 + 1); };
    auto layer_norm = [&](U R) { return passes(R) * (2 * W4 + 2) + passes(R * W4); };
    auto softmax = [&](U R) { return passes(R) * (3 * K4 + 3); };
    auto block = [&](bool last) {  // the last block's rows that go on: one row tile
        const U R = last ? TR : K;
        U n = layer_norm(K) + layer_norm(R) + H + 1;
        for (U h = 0; h < H; ++h) {
            n += gemm(R, TR, W4, D) + gemm(K, TR, W4, 2 * D);
            n += scores(R, TR) + softmax(R) + gemm(R, TR, K4, D) + gemm(R, TR, D4, 4 * W4);
        }
        return n + (F / FC + 1) * (gemm(R, TR, W4, FC) + gemm(R, TR, FC / 4, 4 * W4));
    };
    const U features = 2 * passes(K) + passes(K) * (K + 1);
    const U blocks = U(p.blocks - 1) * block(false) + block(true) + U(p.blocks) + 1;
    return features + gemm(K, TR, 2, 4 * W4) + 2 * layer_norm(K) + blocks + W4 + 1;
}

/// The same bound for the software build of torus_net.comp, whose workgroup is one subgroup of
/// `lanes`: its products, attention and LayerNorms loop over rows, everything else unrolled.
std::uint64_t lanes_loop_iterations(const NetPlan& p, std::uint64_t lanes) {
    using U = std::uint64_t;
    const U K = U(p.k), W4 = U(p.width) / 4, H = U(p.heads), F = U(p.mlp), FC = U(p.fc);
    auto passes = [&](U items) { return (items + lanes - 1) / lanes + 1; };
    auto rows = [](U R) { return R + 1; };  // a loop over R rows (gemm_lanes, attention, layer_norm)
    auto block = [&](U R) {
        const U head = 3 + rows(R) + rows(K) + rows(R) + rows(R);  // q | k v, attention, proj
        const U mlp = FC == U(p.width) ? 3 + 2 * rows(R) : 2 * rows(R);
        return rows(K) + rows(R) + (H + 1) + H * head + (F / FC + 1) + (F / FC) * mlp;
    };
    const U features = 2 * passes(K) + passes(K) * (K + 1);
    return features + 2 * rows(K) + U(p.blocks - 1) * block(K) + block(1) + U(p.blocks) + 1 + rows(1) + W4 + 1;
}

/// Whether the software build of torus_net.comp (a point's workgroup one subgroup of L lanes,
/// products and attention through subgroup shuffles) runs this model on this device: a
/// software device with shuffles and 8, 16 or 32 lanes; K a multiple of L and a head's width at
/// most 4L (its rows are read one vec4 a lane); width and MLP pass at most 128 (a product's
/// unrolled input loop has at most 32 passes, llvmpipe's max_unroll_iterations); and the loops under
/// half llvmpipe's limit.
/// Only on software devices: the kernel takes a workgroup of subgroup_size invocations to be one
/// subgroup, which llvmpipe guarantees and Vulkan 1.1 does not (a GPU may compile it narrower).
bool lanes_kernel_fits(const NetPlan& p, const gpu::Context& ctx) {
    const gpu::DeviceInfo& info = ctx.info();
    const int L = int(info.subgroup_size), d = p.width / p.heads;
    return info.is_software() && gpu::software_shaped(ctx) && info.subgroup_shuffle && (L == 8 || L == 16 || L == 32) &&
           p.k % L == 0 && d <= 4 * L && p.width <= 128 && p.fc <= 128 &&
           2 * lanes_loop_iterations(p, std::uint64_t(L)) <= 65535;
}

const gpu::Kernel& net_kernel(gpu::Context& ctx, const NetPlan& p, bool debug) {
    const std::initializer_list<std::int32_t> constants = {p.k, p.width, p.heads, p.mlp, p.blocks, p.fc, p.pool,
                                                           p.global ? 1 : 0, debug ? 1 : 0, p.global ? 1 : p.pool,
                                                           p.tile_rows, p.tile_cols, std::int32_t(ctx.info().subgroup_size)};
    if (lanes_kernel_fits(p, ctx))
        return gpu::kernel(ctx, gpu::kernel_table::torus_net, constants, ctx.info().subgroup_size, true);
    // Else the GPUs' kernel. On a software device its workgroup is as small as llvmpipe's loop
    // limit allows (at least 8: the 6 that write the coefficients): the matrix products have 32
    // tiles for a width of 64, and barriers switch between the subgroups of a workgroup. The
    // bound of net_loop_iterations is kept under half the limit; a model too big for that runs
    // at 64.
    std::uint32_t workgroup = 0;
    if (ctx.info().is_software()) {
        workgroup = std::max(8u, ctx.info().subgroup_size);
        while (workgroup < 64 && 2 * net_loop_iterations(p, workgroup) > 65535) workgroup *= 2;
        workgroup = std::min(workgroup, 64u);
    }
    return gpu::kernel(ctx, gpu::kernel_table::torus_net, constants, workgroup, false);
}

// Records the network over n points whose tokens are in `tokens`.
void record_net(gpu::Recorder& rec, const gpu::Kernel& k, const Buffer& params, const DeviceCloud& cloud,
                const Buffer& tokens, const Buffer& out, const Buffer& scratch, const Buffer& debug, std::size_t n) {
    const kernels::CountPush push{std::uint32_t(n)};
    rec.dispatch(k, {{&params}, {&cloud.fixed}, {&cloud.nrm}, {&tokens}, {&out}, {&scratch}, {&debug}}, &push,
                 sizeof(push), push.count);
}

Points centered_points(const Points& p) {
    const Eigen::RowVector3d center = 0.5 * (p.colwise().minCoeff() + p.colwise().maxCoeff());
    return p.rowwise() - center;
}

bool force_global_env() {
    const char* v = std::getenv("GSD_TORUSNET_GLOBAL");
    return v && std::string(v) == "1";
}

}  // namespace

bool runs_lanes_kernel(const TorusNetModel& model, gpu::Context& ctx) {
    return lanes_kernel_fits(plan(model, ctx, force_global_env()), ctx);
}

void predict_jets_gpu(const TorusNetModel& model, const PointCloud& cloud, gpu::Context& ctx, std::vector<Jet>& jets,
                      Points& tangents, std::size_t chunk_size, const ProgressFn& progress) {
    const auto n = std::size_t(cloud.size());
    const int K = model.k;
    if (n < std::size_t(K))
        throw Error("TorusNet needs at least k = " + std::to_string(K) + " points; the cloud has " + std::to_string(n));
    const NetPlan p = plan(model, ctx, force_global_env());
    const std::string& dev = ctx.info().name;
    const std::uint64_t max_range = ctx.max_binding_bytes();
    if (n >= (1ull << 31) || 16ull * n > max_range)
        throw Error("the cloud (" + std::to_string(n) + " points) exceeds " + dev + "'s storage buffer range (" +
                    std::to_string(max_range >> 20) + " MiB) for TorusNet (use device \"cpu\")");

    jets.assign(n, Jet{});
    tangents.resize(Eigen::Index(n), 3);
#pragma omp parallel for schedule(static)
    for (Eigen::Index i = 0; i < Eigen::Index(n); ++i)
        tangents.row(i) = tangent_of(cloud.normals.row(i).transpose().normalized()).transpose();

    // The cloud in kd-tree order, centered on its box (float32 keeps more bits of the offsets).
    const Points centered = centered_points(cloud.points);
    const spatial::BoxTree tree(centered);
    const DeviceCloud dc = upload_cloud(ctx, centered, cloud.normals, tree.order(), 0, true);
    const std::vector<gpu::DeviceNode> nodes = gpu::device_nodes(tree);
    const Buffer node_buffer = gpu::upload(ctx, nodes.data(), nodes.size() * sizeof(gpu::DeviceNode));
    const std::vector<float> packed = pack_weights(model);
    const Buffer params = gpu::upload(ctx, packed.data(), packed.size() * 4);
    const Buffer unused(ctx, 16, Memory::Device);

    const gpu::Kernel& knn = gpu::kernel(ctx, gpu::kernel_table::torus_net_knn, {K});
    const gpu::Kernel& net = net_kernel(ctx, p, false);

    // Chunk: many points per submission on a GPU, fewer on a CPU device (smooth progress);
    // the per-chunk buffers (tokens, and the workspace when it is global) within the binding
    // range and, for the workspace, within 1 GiB.
    std::size_t chunk = chunk_size ? chunk_size : (ctx.info().is_software() ? 16384 : 65536);
    const std::size_t token_bytes = 4 * std::size_t(K), pool_bytes = p.global ? 16 * std::size_t(p.pool) : 0;
    chunk = std::min(chunk, std::size_t(max_range) / token_bytes);
    if (p.global) chunk = std::min({chunk, std::size_t(max_range) / pool_bytes, (std::size_t(1) << 30) / pool_bytes});
    chunk = std::max<std::size_t>(1, std::min(chunk, n));

    // Per-chunk device buffers, one set per chunk in flight (gpu::stream runs up to three).
    constexpr std::size_t kSets = 3;
    std::array<Buffer, kSets> tokens, scratch;
    for (std::size_t s = 0; s < kSets; ++s) {
        tokens[s] = Buffer(ctx, chunk * token_bytes, Memory::Device);
        scratch[s] = p.global ? Buffer(ctx, chunk * pool_bytes, Memory::Device) : Buffer(ctx, 16, Memory::Device);
    }
    std::size_t recorded = 0;

    const std::vector<std::uint32_t>& order = tree.order();
    gpu::StreamJob job;
    job.count = n;
    job.in_bytes = 4;    // the chunk's points (tree order)
    job.out_bytes = 24;  // six coefficients
    job.chunk = chunk;
    job.stage = "fit";
    job.fill = [&](std::size_t first, std::size_t count, void* dst) {
        auto* up = static_cast<std::uint32_t*>(dst);
        for (std::size_t m = 0; m < count; ++m) up[m] = std::uint32_t(first + m);
    };
    job.record = [&](gpu::Recorder& rec, const Buffer& in, const Buffer& out, std::size_t count) {
        const std::size_t set = recorded++ % kSets;
        const kernels::TorusNetKnnPush push{std::uint32_t(count), tree.first_leaf()};
        rec.dispatch(knn, {{&dc.pts}, {&node_buffer}, {&in, 0, count * 4}, {&tokens[set], 0, count * token_bytes}},
                     &push, sizeof(push), std::uint32_t((count + knn.workgroup - 1) / knn.workgroup));
        rec.barrier();
        record_net(rec, net, params, dc, tokens[set], out, scratch[set], unused, count);
    };
    job.drain = [&](std::size_t first, std::size_t count, const void* src) {
        const float* r = static_cast<const float*>(src);
        for (std::size_t m = 0; m < count; ++m) {
            const float* c = r + 6 * m;
            jets[order[first + m]] = Jet{c[0], c[1], c[2], c[3], c[4], c[5]};
        }
    };
    gpu::stream(ctx, job, progress);
}

TorusNetGpuTrace torusnet_gpu_neighborhoods(const TorusNetModel& model, gpu::Context& ctx, const Points& positions,
                                            const Points& normals, bool global_workspace) {
    const int K = model.k;
    const auto rows = std::size_t(positions.rows());
    if (rows == 0 || rows % std::size_t(K) != 0 || normals.rows() != positions.rows())
        throw Error("torusnet_gpu_neighborhoods: expected k = " + std::to_string(K) + " rows per neighborhood");
    const std::size_t count = rows / std::size_t(K);
    const NetPlan p = plan(model, ctx, global_workspace);
    std::vector<std::uint32_t> identity(rows);
    for (std::size_t i = 0; i < rows; ++i) identity[i] = std::uint32_t(i);
    // Each neighborhood relative to its center (they may come from unrelated clouds and scales).
    Points local = positions;
    for (std::size_t i = 0; i < rows; ++i) local.row(Eigen::Index(i)) -= positions.row(Eigen::Index(i / std::size_t(K) * std::size_t(K)));
    const DeviceCloud dc = upload_cloud(ctx, local, normals, identity, std::size_t(K), false);
    const std::vector<float> packed = pack_weights(model);
    const Buffer params = gpu::upload(ctx, packed.data(), packed.size() * 4);
    const Buffer tokens = gpu::upload(ctx, identity.data(), rows * 4);
    const Buffer out(ctx, count * 24, Memory::Device);
    const Buffer scratch(ctx, p.global ? count * std::size_t(p.pool) * 16 : 16, Memory::Device);
    const std::size_t dbg_floats = count * (7 * std::size_t(K) + 1);
    const Buffer debug(ctx, dbg_floats * 4, Memory::Device);
    const Buffer down(ctx, count * 24 + dbg_floats * 4, Memory::Download);

    gpu::Recorder rec(ctx);
    rec.begin();
    record_net(rec, net_kernel(ctx, p, true), params, dc, tokens, out, scratch, debug, count);
    rec.barrier();
    rec.copy(out, 0, down, 0, count * 24);
    rec.copy(debug, 0, down, count * 24, dbg_floats * 4);
    rec.barrier();
    rec.submit();
    rec.wait();

    TorusNetGpuTrace t;
    t.global_workspace = p.global;
    const float* r = static_cast<const float*>(down.mapped());
    const float* d = r + 6 * count;
    for (std::size_t i = 0; i < count; ++i) {
        const float* c = r + 6 * i;
        t.jets.push_back(Jet{c[0], c[1], c[2], c[3], c[4], c[5]});
        const float* f = d + i * (7 * std::size_t(K) + 1);
        t.features.insert(t.features.end(), f, f + 7 * K);
        t.scale.push_back(f[7 * K]);
    }
    return t;
}

}  // namespace gsd::pat
