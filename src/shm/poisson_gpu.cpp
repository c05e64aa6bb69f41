// Geometric multigrid for the grid Poisson problem on a Vulkan device. The hierarchy, smoother
// (red-black Gauss–Seidel, 2 pre + 2 post sweeps), transfers and coarsest solve are those of
// the CPU reference (grid_poisson.cpp), in float32; the finest level's solution and residual
// are float64, so each cycle is one step of mixed-precision iterative refinement and the
// solver reaches relative residuals far below float32's. One submission per cycle; the only
// read-back per cycle is the residual norm's partial sums (per workgroup, or per subgroup). On software
// devices every kernel but the coarsest solve takes four cells a lane (shaders/mg_common.glsl):
// every level stores each row in blocks of 8 cells, even ones then odd ones (`stored_cell`),
// padded to whole blocks, the padding holding zeros; nothing is cleared and nothing copied
// (docs/gpu.md, "No clears, no copies").
#include "shm/poisson_gpu.hpp"

#include "core/uninitialized.hpp"
#include "gpu/runtime.hpp"
#include "push_constants.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <numeric>
#include <string>
#include <utility>

namespace gsd::shm {

namespace {

// One cell of one axis of a level: four vec4s (`AxisCell` in shaders/mg_common.glsl). Integers
// are stored as floats (exact below 2²⁴), so that one table is one vec4 texel buffer.
struct AxisCell {
    float size, link_prev, link_next, unused;  // couplings toward the previous / next cell (0: none)
    float c0, c1, w0, w1;                      // prolongation from the coarser level
    float g[4], gw[4];                         // restriction: finer cells gathered, their weights
};
static_assert(sizeof(AxisCell) == 64);

// Restriction gathers at most 4 finer cells per axis: coarse cell I's sources are finer cells
// whose interpolation pair includes I, and pairs merge, so they lie in 2I−1 … 2I+2.
constexpr int kMaxTaps = 4;

// Invocations per workgroup of the stencil kernels on a software device (RowShape).
constexpr std::uint32_t kSoftwareInvocations = 512;

AxisCell axis_cell(const AxisLevel& ax, int i) {
    const auto u = std::size_t(i);
    AxisCell e{};
    e.size = float(ax.size[u]);
    e.link_prev = i > 0 ? float(ax.link[u - 1]) : 0.0f;
    e.link_next = i + 1 < ax.n ? float(ax.link[u]) : 0.0f;
    if (!ax.c0.empty()) e.c0 = float(ax.c0[u]), e.c1 = float(ax.c1[u]), e.w0 = float(ax.w0[u]), e.w1 = float(ax.w1[u]);
    if (!ax.offsets.empty()) {
        const int first = ax.offsets[u], taps = ax.offsets[u + 1] - first;
        for (int t = 0; t < kMaxTaps; ++t) {  // unused slots gather the first source with weight 0
            const auto g = std::size_t(first + (t < taps ? t : 0));
            e.g[t] = float(ax.gather_index[g]);
            e.gw[t] = t < taps ? float(ax.gather_weight[g]) : 0.0f;
        }
    }
    return e;
}

// Whether every coarse cell i of the axis gathers fine cells within 2i − 1 … 2i + 2 (Hierarchy
// coarsens so; checked, not assumed, as the software build's restriction relies on it).
bool taps_at_fixed_places(const AxisLevel& ax) {
    for (std::size_t i = 0; i + 1 < ax.offsets.size(); ++i)
        for (int g = ax.offsets[i]; g < ax.offsets[i + 1]; ++g) {
            const int j = ax.gather_index[std::size_t(g)] - (2 * int(i) - 1);
            if (j < 0 || j >= kMaxTaps) return false;
        }
    return true;
}

// The software build's restriction takes coarse quads (shaders/mg_restrict.comp): along z its
// table holds, for coarse cell i, the weights of fine cells 2i − 1 + j (j = 0 … 3) at those
// fixed places, not a list of the cells gathered (the software build is chosen only where
// taps_at_fixed_places holds).
AxisCell fixed_z_taps(const AxisLevel& ax, int i) {
    AxisCell e = axis_cell(ax, i);
    for (int t = 0; t < kMaxTaps; ++t) e.g[t] = 0, e.gw[t] = 0;
    if (ax.offsets.empty()) return e;
    const auto u = std::size_t(i);
    for (int g = ax.offsets[u]; g < ax.offsets[u + 1]; ++g) {
        e.gw[ax.gather_index[std::size_t(g)] - (2 * i - 1)] += float(ax.gather_weight[std::size_t(g)]);
    }
    return e;
}

using MgPush = kernels::MultigridPush;  // `Push` in shaders/mg_common.glsl

// φ, the float64 residual and the finest r in host memory: on a software device, whose memory is the host's, unless
// $GSD_GPU_HOST_GRIDS=0 (tests: the GPUs' way, device memory with staging copies).
bool host_grids(const gpu::Context& ctx) {
    const char* v = std::getenv("GSD_GPU_HOST_GRIDS");
    return ctx.info().is_software() && !(v && v[0] == '0');
}

// Where the software build stores cell k of a row (`stored_cell` in shaders/mg_common.glsl):
// blocks of 8 cells, the 4 even ones then the 4 odd ones.
constexpr std::size_t stored_cell(std::size_t k) { return (k & ~std::size_t(7)) + ((k & 1) << 2) + ((k & 7) >> 1); }
constexpr std::uint32_t kBlock = 8;

// An axis of a level as the software build's stencils take it from the push constants: every
// cell of `size` and every link `link`, but the last cell and the last link.
struct RegularAxis {
    float size = 0, link = 0, last_size = 0, last_link = 0;
};

RegularAxis regular_axis(const AxisLevel& ax) {
    const auto n = std::size_t(ax.n);
    RegularAxis r;
    r.size = float(ax.size[0]);
    r.last_size = float(ax.size[n - 1]);
    if (n >= 2) r.link = float(ax.link[0]), r.last_link = float(ax.link[n - 2]);
    return r;
}

// Whether regular_axis describes the axis exactly (Hierarchy coarsens so that only an odd
// last cell differs; checked, not assumed).
bool is_regular(const AxisLevel& ax) {
    const RegularAxis r = regular_axis(ax);
    const auto n = std::size_t(ax.n);
    for (std::size_t i = 0; i + 1 < n; ++i)
        if (float(ax.size[i]) != r.size || (i + 2 < n && float(ax.link[i]) != r.link)) return false;
    return true;
}

class VulkanMultigrid final : public GpuMultigrid {
public:
    VulkanMultigrid(std::shared_ptr<gpu::Context> ctx, const Hierarchy& h, bool software)
        : ctx_(std::move(ctx)), H_(h), software_(software), host_grids_(host_grids(*ctx_)) {
        gpu::Context& c = *ctx_;
        // The axis tables of every level, one after the other.
        std::vector<AxisCell> axes;
        for (const Level& lv : H_.levels) {
            std::array<std::uint32_t, 3> off{};
            for (std::size_t a = 0; a < 3; ++a) {
                off[a] = std::uint32_t(axes.size());
                for (int i = 0; i < lv.axis[a].n; ++i) {
                    AxisCell cell = axis_cell(lv.axis[a], i);
                    if (software_ && a == 2) cell = fixed_z_taps(lv.axis[a], i);
                    axes.push_back(cell);
                }
            }
            axes_off_.push_back(off);
        }
        axes_ = gpu::upload(c, axes.data(), axes.size() * sizeof(AxisCell));
        for (std::size_t l = 0; l < H_.levels.size(); ++l) {
            const auto nz = std::uint32_t(H_.levels[l].axis[2].n);
            stride_.push_back(software_ ? (nz + kBlock - 1) / kBlock * kBlock : nz);
            const std::size_t n = cells(l);
            // On a software device the finest r is host memory: the first residual is b, written in place.
            r_.emplace_back(c, n * 4, host_grids_ && l == 0 ? gpu::Memory::Download : gpu::Memory::Device);
            e_.emplace_back(c, n * 4, gpu::Memory::Device);
            t_.emplace_back(c, n * 4, gpu::Memory::Device);
            // The F-cycle's second correction, on the levels between the finest and the coarsest.
            save_.emplace_back();
            if (l > 0 && l + 1 < H_.levels.size()) save_.back() = gpu::Buffer(c, n * 4, gpu::Memory::Device);
        }
        upload_coarse_pinv();
        // A software device's memory is the host's: φ and b are read and written in place there
        // (no staging buffer, no copy).
        const gpu::Memory grid_memory = host_grids_ ? gpu::Memory::Download : gpu::Memory::Device;
        phi_ = gpu::Buffer(c, cells(0) * 8, grid_memory);
        res_ = gpu::Buffer(c, cells(0) * 8, grid_memory);
        // mg_refine's partial sums of r²: one per workgroup (run_rows), on a software device one
        // per subgroup.
        const MgPush fine = push_for(0, 0);
        const RowGroups g = row_groups(fine, row_lanes(0));
        groups0_ = g.x * g.y * g.z;
        if (software_) {  // a partial sum per subgroup (shaders/mg_refine.comp): llvmpipe's are its SIMD width
            const RowShape shape = row_shape(row_lanes(0), fine.dims[1]);
            const std::uint32_t simd = std::max<std::uint32_t>(ctx_->info().subgroup_size, 1);
            groups0_ *= (shape.x * shape.rows + simd - 1) / simd;
        }
        partial_ = gpu::Buffer(c, std::size_t(groups0_) * 8, gpu::Memory::Device);
        partial_down_ = gpu::Buffer(c, std::size_t(groups0_) * 8, gpu::Memory::Download);
        // Every kernel stores every quad of a row, the padding's as zeros, and every value is
        // stored before it is read (e by a level's first half-sweep, which does not read it; φ
        // by the first cycle's refinement, which does not read it), so nothing is cleared: on a
        // software device a clear is one thread's memset, in the solve's path. (prepare()
        // touches the host grids' pages, on a thread of its own, while other work runs.)
        gpu::Recorder rec(c);
        rec.begin();
        // $GSD_GPU_POISON=1 (tests): the scratch buffers start as NaN instead of whatever the
        // allocation held, so that a kernel reading a value before one is stored shows in the
        // result.
        if (const char* v = std::getenv("GSD_GPU_POISON"); v && v[0] == '1') {
            poisoned_ = true;
            for (std::size_t l = 0; l < H_.levels.size(); ++l)
                for (const gpu::Buffer* b : {&r_[l], &e_[l], &t_[l], &save_[l]})
                    if (b->handle()) rec.fill(*b, 0, cells(l) * 4, 0x7fc00000u);  // float32 quiet NaN
            rec.fill(phi_, 0, cells(0) * 8, 0x7ff80000u);  // a float64 NaN in every word pair
            rec.fill(res_, 0, cells(0) * 8, 0x7ff80000u);
        }
        rec.submit();
        rec.wait();
    }

    std::vector<double> solve(const std::vector<double>& b, double tol, int max_cycles, std::vector<double>* history,
                              bool f_cycle, const ProgressFn& progress, std::vector<double>* storage) override {
        gpu::Context& c = *ctx_;
        const std::size_t n0 = H_.levels[0].count(), stored = cells(0);
        const double bnorm = std::sqrt(std::inner_product(b.begin(), b.end(), b.begin(), 0.0));
        double rel = bnorm > 0 ? 1.0 : 0.0;  // φ = 0: the residual is b
        // The float64 residual starts as b (φ = 0), and so does its float32 copy, the cycle's
        // right-hand side. φ is not cleared: the first cycle's refinement stores φ = e.
        if (host_grids_) {
            // Host memory (a software device): in place.
            to_rows(b.data(), static_cast<double*>(res_.mapped()));
            const double* rows = static_cast<const double*>(res_.mapped());
            float* r0 = static_cast<float*>(r_[0].mapped());
#pragma omp parallel for schedule(static)
            for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(stored); ++i) r0[i] = float(rows[i]);
        } else {
            gpu::Buffer staging(c, stored * 8, gpu::Memory::Upload);
            to_rows(b.data(), static_cast<double*>(staging.mapped()));
            gpu::Recorder rec(c);
            rec.begin();
            rec.copy(staging, 0, res_, 0, stored * 8);
            rec.barrier();
            record_refine(rec, Refine::NoCycle);
            rec.submit();
            rec.wait();
            rel = bnorm > 0 ? std::sqrt(partial_sum()) / bnorm : 0.0;
        }
        // Every cycle's commands are the same but for the first's (φ = e, not φ += e): each
        // kind is recorded once and submitted again, not recorded ~60 dispatches a cycle while
        // the device waits (on lavapipe 27 ms of a 0.6 s solve at 128³).
        gpu::Recorder first(c), again(c);
        bool again_recorded = false;
        int cycles = 0;
        for (int it = 0; it < max_cycles && rel > tol; ++it, ++cycles) {
            gpu::Recorder& rec = it == 0 ? first : again;
            if (it == 0 || !again_recorded) {
                rec.begin(it == 0 ? gpu::Recorder::Reuse::Once : gpu::Recorder::Reuse::Again);
                record_cycle(rec, 0, f_cycle);
                record_refine(rec, it == 0 ? Refine::FromZero : Refine::Add);
                again_recorded = it > 0;
            }
            rec.submit();
            rec.wait();
            rel = std::sqrt(partial_sum()) / bnorm;
            if (!std::isfinite(rel))  // never quietly: the loop would stop as if converged
                throw Error("shm", "the device's multigrid produced a non-finite residual (cycle " + std::to_string(it + 1) +
                                       " on " + ctx_->info().name + "); rerun with --device cpu");
            if (history) history->push_back(rel);
            if (progress) progress("solve", std::min(1.0, std::log(std::max(rel, 1e-300)) / std::log(tol)));
        }
        std::vector<double> phi;
        if (storage && storage->size() == n0) phi.swap(*storage);  // b's, read by now
        else detail::resize_in_huge_pages(phi, n0);
        if (cycles == 0) {  // φ = 0, never stored (φ is not cleared)
            std::fill(phi.begin(), phi.end(), 0.0);
            return phi;
        } else if (host_grids_) {  // in place, in rows
            from_rows(static_cast<const double*>(phi_.mapped()), phi.data());
        } else if (!software_) {  // stored as they are
            gpu::download(c, phi_, phi.data(), n0 * 8);
        } else {
            std::vector<double> rows(stored);
            gpu::download(c, phi_, rows.data(), stored * 8);
            from_rows(rows.data(), phi.data());
        }
        // The sum in one order (an OpenMP reduction adds the threads' parts in the order they
        // finish: φ would differ in its last bits between two equal solves); the rest on every core.
        const double mean = std::accumulate(phi.begin(), phi.end(), 0.0) / double(n0);
        const auto count = std::ptrdiff_t(n0);
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t i = 0; i < count; ++i) phi[std::size_t(i)] -= mean;
        return phi;
    }

    void prepare(bool f_cycle) override {
        // A cycle recorded and dropped: recording makes the pipelines (and nothing runs).
        gpu::Recorder rec(*ctx_);
        rec.begin();
        record_cycle(rec, 0, f_cycle);
        record_refine(rec, Refine::FromZero);
        record_refine(rec, Refine::NoCycle);
        // One thread's memset, while step 1 runs for many times as long (its page faults are
        // what is worth moving out of the solve). Poisoned: their NaN kept, for the tests.
        if (host_grids_ && !poisoned_)
            for (const gpu::Buffer* b : {&phi_, &res_, &r_[0]}) std::memset(b->mapped(), 0, std::size_t(b->size()));
    }

private:
    // The coarsest level's dense pseudo-inverse over its stored cells (0 on the padding's rows
    // and columns, so that the padding stays 0), as float32.
    void upload_coarse_pinv() {
        const std::size_t last = H_.levels.size() - 1, m = H_.levels[last].count(), stored = cells(last);
        const auto nz = std::size_t(H_.levels[last].axis[2].n);
        auto at = [&](std::size_t p) { return p / nz * stride_[last] + cell_in_row(p % nz); };  // natural -> stored
        std::vector<float> pinv(stored * stored, 0.0f);
        for (std::size_t p = 0; p < m; ++p)
            for (std::size_t q = 0; q < m; ++q) pinv[at(p) * stored + at(q)] = float(H_.coarse_pinv[p * m + q]);
        pinv_ = gpu::upload(*ctx_, pinv.data(), pinv.size() * 4);
    }

    // Cells stored for level l (its rows `stride_[l]` cells apart).
    std::size_t cells(std::size_t l) const {
        const Level& lv = H_.levels[l];
        return std::size_t(lv.axis[0].n) * std::size_t(lv.axis[1].n) * stride_[l];
    }
    // Where cell k of a row is stored, from the row's start.
    std::size_t cell_in_row(std::size_t k) const { return software_ ? stored_cell(k) : k; }
    // The finest level's values from the natural order into stored rows (the padding 0), and back.
    // Row by row on every core: on a software device these are a solve's largest host parts.
    void to_rows(const double* natural, double* rows) const {
        const auto nz = std::ptrdiff_t(H_.levels[0].axis[2].n), count = std::ptrdiff_t(H_.levels[0].count()) / nz;
        const auto stride = std::ptrdiff_t(stride_[0]);
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t r = 0; r < count; ++r) {
            double* row = rows + r * stride;
            // The padding: the last block, partly filled (cells keep to their block), then the cells.
            std::fill(row + nz / std::ptrdiff_t(kBlock) * std::ptrdiff_t(kBlock), row + stride, 0.0);
            for (std::ptrdiff_t k = 0; k < nz; ++k) row[cell_in_row(std::size_t(k))] = natural[r * nz + k];
        }
    }
    void from_rows(const double* rows, double* natural) const {
        const auto nz = std::ptrdiff_t(H_.levels[0].axis[2].n), count = std::ptrdiff_t(H_.levels[0].count()) / nz;
        const auto stride = std::ptrdiff_t(stride_[0]);
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t r = 0; r < count; ++r)
            for (std::ptrdiff_t k = 0; k < nz; ++k) natural[r * nz + k] = rows[r * stride + std::ptrdiff_t(cell_in_row(std::size_t(k)))];
    }

    MgPush push_for(std::size_t l, std::size_t other) const {
        MgPush p{};
        p.zstride = stride_[l];
        p.ozstride = stride_[other];
        for (int a = 0; a < 3; ++a) {
            const AxisLevel& ax = H_.levels[l].axis[std::size_t(a)];
            p.dims[a] = std::uint32_t(ax.n);
            p.axes_off[a] = axes_off_[l][std::size_t(a)];
            p.odims[a] = std::uint32_t(H_.levels[other].axis[std::size_t(a)].n);
            p.oaxes_off[a] = axes_off_[other][std::size_t(a)];
            p.inv_h2[a] = float(H_.inv_h2[std::size_t(a)]);
            const RegularAxis r = regular_axis(ax);
            p.cell_size[a] = r.size, p.link[a] = r.link, p.last_size[a] = r.last_size, p.last_link[a] = r.last_link;
        }
        return p;
    }

    // Lanes along a row of level l for the stencil kernels: its quads on a software device.
    std::uint32_t row_lanes(std::size_t l) const {
        return software_ ? stride_[l] / 4 : std::uint32_t(H_.levels[l].axis[2].n);
    }

    // The stencil kernels take rows of cells along z (x: `cells` of a row, y: rows j, z: slabs
    // i), so that they need no division to find a cell (mg_common.glsl). GPUs run a row per
    // workgroup. llvmpipe allocates and frees memory for every workgroup it runs, so there a
    // workgroup takes several rows, each no wider than it needs (rounded up to the SIMD width):
    // the coarse levels' rows are short.
    struct RowShape {
        std::uint32_t x, rows;
    };
    RowShape row_shape(std::uint32_t cells, std::uint32_t rows) const {
        const std::uint32_t widest = ctx_->workgroup_size();
        if (!software_) return {widest, 1};
        const std::uint32_t simd = std::max<std::uint32_t>(ctx_->info().subgroup_size, 1);
        std::uint32_t x = simd;
        while (x < cells && x < widest) x *= 2;
        x = std::min(x, widest);
        // (The GPUs' mg_refine keeps one partial sum per subgroup in shared memory, 256 of them:
        // the same bound serves both builds.) The rows
        // per workgroup do not follow the level's (lanes past its rows idle): llvmpipe compiles
        // a pipeline for every shape on first use, which a short solve pays for.
        const std::uint32_t most = std::min(kSoftwareInvocations, 256 * simd);
        std::uint32_t y = 1;
        while (x * y * 2 <= most) y *= 2;
        return {x, y};
    }

    // The workgroups over the level of `p` with rows of `cells` (row_shape).
    struct RowGroups {
        std::uint32_t x, y, z;
    };
    RowGroups row_groups(const MgPush& p, std::uint32_t cells) const {
        const RowShape shape = row_shape(cells, p.dims[1]);
        return {(cells + shape.x - 1) / shape.x, (p.dims[1] + shape.rows - 1) / shape.rows, p.dims[0]};
    }

    // Runs the stencil kernel `spec` over the level of `p` with rows of `cells`: the build shaped
    // for software devices where software_ (the table's texel bindings: the axis table as vec4s,
    // the grids as floats or doubles), else the GPUs' build; then a barrier.
    void run_rows(gpu::Recorder& rec, const gpu::KernelSpec& spec, std::initializer_list<gpu::Binding> bindings,
                  const MgPush& p, std::uint32_t cells) {
        const RowShape shape = row_shape(cells, p.dims[1]);
        const gpu::Kernel& k = gpu::kernel(*ctx_, spec, {std::int32_t(shape.rows)}, shape.x, software_);
        const RowGroups g = row_groups(p, cells);
        rec.dispatch_grid(k, bindings, &p, sizeof(p), g.x, g.y, g.z);
        rec.barrier();
    }

    // Lanes along a row of level l for a kernel that takes one color's cells: a block of 8 cells
    // a lane on a software device, else a pair of cells.
    std::uint32_t color_lanes(std::size_t l) const {
        return software_ ? stride_[l] / kBlock : (std::uint32_t(H_.levels[l].axis[2].n) + 1) / 2;
    }

    // One half-sweep of `color`; `first`: the level's first of a cycle, which takes e as 0.
    void smooth(gpu::Recorder& rec, std::size_t l, std::uint32_t color, bool first = false) {
        MgPush p = push_for(l, l);
        p.color = color;
        p.first_sweep = first ? 1 : 0;
        // e read (the other color) and written (this one). The lanes take the row's cells of one
        // color: on a software device a block's quad of them a lane.
        if (software_)
            run_rows(rec, gpu::kernel_table::mg_smooth, {{&r_[l]}, {&e_[l]}, {&e_[l]}}, p, color_lanes(l));
        else
            run_rows(rec, gpu::kernel_table::mg_smooth, {{&axes_}, {&r_[l]}, {&e_[l]}, {&e_[l]}}, p, color_lanes(l));
    }

    // t = r − A e on level l into `t` (which may be r itself: each cell reads its own r only),
    // after a half-sweep of the smoother of color `last_swept`: its cells' t is 0 but for
    // rounding, and stored as 0 (the CPU reference computes it; the cycles converge alike).
    void residual(gpu::Recorder& rec, std::size_t l, const gpu::Buffer& t, std::uint32_t last_swept) {
        MgPush p = push_for(l, l);
        p.color = 1 - last_swept;  // the cells computed
        if (software_)
            run_rows(rec, gpu::kernel_table::mg_residual, {{&r_[l]}, {&e_[l]}, {&t}}, p, color_lanes(l));
        else
            run_rows(rec, gpu::kernel_table::mg_residual, {{&axes_}, {&r_[l]}, {&e_[l]}, {&t}}, p, color_lanes(l));
    }

    void record_cycle(gpu::Recorder& rec, std::size_t l, bool f_cycle) {
        const std::size_t last = H_.levels.size() - 1;
        if (l == last) {
            const gpu::Kernel& k = gpu::kernel(*ctx_, gpu::kernel_table::mg_coarse);
            const auto m = std::uint32_t(cells(l));  // the padding's rows of A⁺ are 0
            const kernels::CountPush push_m{m};
            rec.dispatch(k, {{&pinv_}, {&r_[l]}, {&e_[l]}}, &push_m, sizeof(push_m), (m + k.workgroup - 1) / k.workgroup);
            rec.barrier();
            return;
        }
        for (int s = 0; s < 2; ++s) { smooth(rec, l, 0, s == 0); smooth(rec, l, 1); }
        residual(rec, l, t_[l], 1);
        {
            MgPush p = push_for(l + 1, l);
            p.color = 1;  // t's cells of color 1 hold 0 (the software build reads only the others)
            // The software build: a coarse quad a lane.
            run_rows(rec, gpu::kernel_table::mg_restrict, {{&axes_}, {&t_[l]}, {&r_[l + 1]}}, p,
                     software_ ? row_lanes(l + 1) : p.dims[2]);
        }
        record_cycle(rec, l + 1, f_cycle);
        if (f_cycle && l + 2 <= last) {
            // F-cycle: one more V-cycle on level l+1 against its remaining residual, which
            // replaces r there (r is not read again this cycle); its correction goes into
            // save, then e += save.
            const std::size_t c = l + 1;
            residual(rec, c, r_[c], 0);  // the post-smoothing ends with color 0
            std::swap(e_[c], save_[c]);
            record_cycle(rec, c, false);
            std::swap(e_[c], save_[c]);
            const gpu::Kernel& add = gpu::kernel(*ctx_, gpu::kernel_table::mg_add);
            const kernels::CountPush push_m{std::uint32_t(cells(c))};
            rec.dispatch(add, {{&e_[c]}, {&save_[c]}}, &push_m, sizeof(push_m),
                         std::uint32_t((cells(c) + add.workgroup - 1) / add.workgroup));
            rec.barrier();
        }
        {
            // The post-smoothing starts with color 1, which reads only color 0's e and overwrites
            // its own: only color 0 is prolonged. e of level l twice: read and written (each
            // cell its own).
            MgPush p = push_for(l, l + 1);
            p.color = 0;
            run_rows(rec, gpu::kernel_table::mg_prolong, {{&axes_}, {&e_[l + 1]}, {&e_[l]}, {&e_[l]}}, p, color_lanes(l));
        }
        for (int s = 0; s < 2; ++s) { smooth(rec, l, 1); smooth(rec, l, 0); }
    }

    // What the refinement does before the residual's norm (its pc.first_sweep, shaders/mg_refine.comp).
    enum class Refine : std::uint32_t { Add = 0, FromZero = 1, NoCycle = 2 };

    // After a cycle, φ += e (Add) or φ = e (FromZero: φ not cleared) and r −= A e in float64,
    // r copied as float32 for the next cycle (NoCycle: only that copy); then the residual's
    // partial norms, read back.
    void record_refine(gpu::Recorder& rec, Refine what) {
        MgPush p = push_for(0, 0);
        p.first_sweep = std::uint32_t(what);
        // The float64 residual and φ twice: read and written (each cell its own).
        run_rows(rec, gpu::kernel_table::mg_refine,
                 {{&e_[0]}, {&res_}, {&phi_}, {&res_}, {&phi_}, {&r_[0]}, {&partial_}}, p, row_lanes(0));
        rec.copy(partial_, 0, partial_down_, 0, std::size_t(groups0_) * 8);
        rec.barrier();
    }

    double partial_sum() const {
        const double* p = static_cast<const double*>(partial_down_.mapped());
        double s = 0;
        for (std::uint32_t i = 0; i < groups0_; ++i) s += p[i];
        return s;
    }

    std::shared_ptr<gpu::Context> ctx_;
    const Hierarchy& H_;
    std::vector<std::array<std::uint32_t, 3>> axes_off_;
    std::vector<std::uint32_t> stride_;  // cells stored per row of each level
    bool software_;  // the kernels shaped for software devices (gpu::software_shaped)
    bool host_grids_;  // φ, the float64 residual and the finest r in host memory (a software device)
    bool poisoned_ = false;  // $GSD_GPU_POISON: the scratch buffers start as NaN
    gpu::Buffer axes_, pinv_, phi_, partial_, partial_down_;
    gpu::Buffer res_;  // the finest level's residual in float64: b, then b − Aφ after every cycle
    std::vector<gpu::Buffer> r_, e_, t_, save_;
    std::uint32_t groups0_ = 0;  // mg_refine's partial sums (per workgroup; per subgroup on a software device)
};

}  // namespace

std::unique_ptr<GpuMultigrid> make_gpu_multigrid(const std::shared_ptr<gpu::Context>& ctx, const Hierarchy& h,
                                                 std::string& why_not) {
    if (!ctx->has_float64() || !ctx->info().subgroup_arithmetic) {
        why_not = ctx->info().name + " has no float64 or no subgroup arithmetic in shaders; the multigrid runs on the CPU";
        return nullptr;
    }
    const std::uint64_t n0 = h.levels[0].count();
    if (h.levels[0].axis[0].n > 65535 || h.levels[0].axis[1].n > 65535) {  // rows are workgroups (run_rows)
        why_not = "the grid has more than 65535 nodes along x or y; the multigrid runs on the CPU";
        return nullptr;
    }
    // The axis tables hold cell indices as float32 (AxisCell), exact below 2^24; a row's
    // workgroups along x must fit one dispatch.
    const auto nz = std::uint32_t(h.levels[0].axis[2].n);
    if (nz > (1u << 24) || (nz + ctx->workgroup_size() - 1) / ctx->workgroup_size() > ctx->max_groups_x()) {
        why_not = "the grid has too many nodes along z for the device's multigrid; it runs on the CPU";
        return nullptr;
    }
    if (n0 * 8 > ctx->max_binding_bytes()) {
        why_not = "the grid (" + std::to_string(n0) + " nodes) exceeds " + ctx->info().name +
                  "'s storage buffer range; the multigrid runs on the CPU";
        return nullptr;
    }
    if (ctx->device_memory_bytes() && n0 * 40 > ctx->device_memory_bytes()) {
        why_not = "the grid does not fit in " + ctx->info().name + "'s memory; the multigrid runs on the CPU";
        return nullptr;
    }
    for (const Level& lv : h.levels)
        for (const AxisLevel& ax : lv.axis)
            for (std::size_t i = 0; i + 1 < ax.offsets.size(); ++i)
                if (ax.offsets[i + 1] - ax.offsets[i] > kMaxTaps)
                    throw Error("shm", "internal: a restriction gathers more than 4 cells per axis");
    // The software build reads the grids through texel buffers, the cells' couplings from the
    // push constants (regular axes), and pads every level's rows to whole blocks of 8 cells.
    const std::uint64_t padded = std::uint64_t(h.levels[0].axis[0].n) * std::uint64_t(h.levels[0].axis[1].n) *
                                 std::uint64_t((nz + kBlock - 1) / kBlock * kBlock);
    bool software = gpu::software_shaped(*ctx) && padded <= ctx->limits().maxTexelBufferElements &&
                    padded * 8 <= ctx->max_binding_bytes();
    for (const Level& lv : h.levels) {
        for (const AxisLevel& ax : lv.axis) software = software && is_regular(ax);
        software = software && taps_at_fixed_places(lv.axis[2]);
    }
    return std::make_unique<VulkanMultigrid>(ctx, h, software);
}

}  // namespace gsd::shm
