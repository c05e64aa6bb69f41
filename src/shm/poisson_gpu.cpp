// Geometric multigrid for the grid Poisson problem on a Vulkan device. The hierarchy, smoother
// (red-black Gauss–Seidel, 2 pre + 2 post sweeps), transfers and coarsest solve are those of
// the CPU reference (grid_poisson.cpp), in float32; the finest level's solution and residual
// are float64, so each cycle is one step of mixed-precision iterative refinement and the
// solver reaches relative residuals far below float32's. One submission per cycle; the only
// read-back per cycle is one partial sum per workgroup for the residual norm.
#include "shm/poisson_gpu.hpp"

#include "gpu/runtime.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <numeric>

namespace gsd::shm_detail {

namespace {

struct AxisEntry {  // `AxisEntry` in shaders/mg_common.glsl
    float size;
    std::int32_t c0, c1;
    float w0, w1;
    std::int32_t g_begin, g_end;
    float center;
};
static_assert(sizeof(AxisEntry) == 32);

struct GatherEntry {
    std::int32_t index;
    float weight;
};

struct MgPush {  // `Push` in shaders/mg_common.glsl
    std::uint32_t dims[3], color;
    std::uint32_t axes_off[3], pad0;
    std::uint32_t odims[3], pad1;
    std::uint32_t oaxes_off[3], pad2;
    float inv_h2[3];
    std::uint32_t pad3;
};
static_assert(sizeof(MgPush) == 80);

class VulkanMultigrid final : public GpuMultigrid {
public:
    VulkanMultigrid(std::shared_ptr<gpu::Context> ctx, const Hierarchy& h) : ctx_(std::move(ctx)), H_(h) {
        gpu::Context& c = *ctx_;
        // Axis tables of every level, and the restriction gathers.
        std::vector<AxisEntry> axes;
        std::vector<GatherEntry> gathers;
        for (std::size_t l = 0; l < H_.levels.size(); ++l) {
            std::array<std::uint32_t, 3> off{};
            for (std::size_t a = 0; a < 3; ++a) {
                const AxisLevel& ax = H_.levels[l].axis[a];
                off[a] = std::uint32_t(axes.size());
                for (int i = 0; i < ax.n; ++i) {
                    AxisEntry e{};
                    e.size = float(ax.size[std::size_t(i)]);
                    e.center = float(ax.center[std::size_t(i)]);
                    if (!ax.c0.empty()) {
                        e.c0 = ax.c0[std::size_t(i)];
                        e.c1 = ax.c1[std::size_t(i)];
                        e.w0 = float(ax.w0[std::size_t(i)]);
                        e.w1 = float(ax.w1[std::size_t(i)]);
                    }
                    if (!ax.offsets.empty()) {
                        e.g_begin = std::int32_t(gathers.size()) + ax.offsets[std::size_t(i)];
                        e.g_end = std::int32_t(gathers.size()) + ax.offsets[std::size_t(i) + 1];
                    }
                    axes.push_back(e);
                }
                // The entries above point into this block (their g_begin counted from here).
                for (std::size_t g = 0; g < ax.gather_index.size(); ++g)
                    gathers.push_back({ax.gather_index[g], float(ax.gather_weight[g])});
            }
            axes_off_.push_back(off);
        }
        if (gathers.empty()) gathers.push_back({0, 0});
        for (const Level& lv : H_.levels)
            for (const AxisLevel& ax : lv.axis)
                for (std::size_t i = 0; i + 1 < ax.offsets.size(); ++i)
                    max_taps_ = std::max(max_taps_, ax.offsets[i + 1] - ax.offsets[i]);
        axes_ = gpu::upload(c, axes.data(), axes.size() * sizeof(AxisEntry));
        gathers_ = gpu::upload(c, gathers.data(), gathers.size() * sizeof(GatherEntry));
        std::vector<float> pinv(H_.coarse_pinv.begin(), H_.coarse_pinv.end());
        pinv_ = gpu::upload(c, pinv.data(), pinv.size() * 4);
        for (const Level& lv : H_.levels) {
            const std::size_t n = lv.count();
            r_.emplace_back(c, n * 4, gpu::Memory::Device);
            e_.emplace_back(c, n * 4, gpu::Memory::Device);
            t_.emplace_back(c, n * 4, gpu::Memory::Device);
            save_.emplace_back(c, n * 4, gpu::Memory::Device);
        }
        const std::size_t n0 = H_.levels[0].count();
        phi_ = gpu::Buffer(c, n0 * 8, gpu::Memory::Device);
        b_ = gpu::Buffer(c, n0 * 8, gpu::Memory::Device);
        // mg_refine's workgroups: a row of cells along z each (dispatch_rows), one partial sum each.
        const Level& fine = H_.levels[0];
        const auto row_groups = std::uint32_t((fine.axis[2].n + c.workgroup_size() - 1) / c.workgroup_size());
        groups0_ = row_groups * std::uint32_t(fine.axis[1].n) * std::uint32_t(fine.axis[0].n);
        partial_ = gpu::Buffer(c, std::size_t(groups0_) * 8, gpu::Memory::Device);
        partial_down_ = gpu::Buffer(c, std::size_t(groups0_) * 8, gpu::Memory::Download);
    }

    std::vector<double> solve(const std::vector<double>& b, double tol, int max_cycles, std::vector<double>* history,
                              bool f_cycle, const ProgressFn& progress) override {
        gpu::Context& c = *ctx_;
        const std::size_t n0 = H_.levels[0].count();
        {
            gpu::Buffer staging(c, n0 * 8, gpu::Memory::Upload);
            gpu::copy_bytes(staging.mapped(), b.data(), n0 * 8);
            gpu::Recorder rec(c);
            rec.begin();
            rec.copy(staging, 0, b_, 0, n0 * 8);
            rec.fill_zero(phi_, 0, n0 * 8);
            rec.fill_zero(e_[0], 0, n0 * 4);
            rec.barrier();
            record_refine(rec, false);
            rec.submit();
            rec.wait();
        }
        const double bnorm = std::sqrt(std::inner_product(b.begin(), b.end(), b.begin(), 0.0));
        double rel = bnorm > 0 ? std::sqrt(partial_sum()) / bnorm : 0.0;
        gpu::Recorder rec(c);
        for (int it = 0; it < max_cycles && rel > tol; ++it) {
            rec.begin();
            record_cycle(rec, 0, f_cycle);
            record_refine(rec, true);
            rec.submit();
            rec.wait();
            rel = std::sqrt(partial_sum()) / bnorm;
            if (history) history->push_back(rel);
            if (progress) progress("solve", std::min(1.0, std::log(std::max(rel, 1e-300)) / std::log(tol)));
        }
        std::vector<double> phi(n0);
        gpu::download(c, phi_, phi.data(), n0 * 8);
        const double mean = std::accumulate(phi.begin(), phi.end(), 0.0) / double(n0);
        for (double& v : phi) v -= mean;
        return phi;
    }

private:
    MgPush push_for(std::size_t l, std::size_t other) const {
        MgPush p{};
        for (int a = 0; a < 3; ++a) {
            p.dims[a] = std::uint32_t(H_.levels[l].axis[std::size_t(a)].n);
            p.axes_off[a] = axes_off_[l][std::size_t(a)];
            p.odims[a] = std::uint32_t(H_.levels[other].axis[std::size_t(a)].n);
            p.oaxes_off[a] = axes_off_[other][std::size_t(a)];
            p.inv_h2[a] = float(H_.inv_h2[std::size_t(a)]);
        }
        return p;
    }

    std::uint32_t groups(std::size_t l) const {
        return std::uint32_t((H_.levels[l].count() + ctx_->workgroup_size() - 1) / ctx_->workgroup_size());
    }

    // The stencil kernels take a row of cells along z per workgroup (x: `cells` of the row,
    // y: j, z: i), so that they need no division to find a cell (mg_smooth.comp).
    void dispatch_rows(gpu::Recorder& rec, const gpu::Kernel& k, std::initializer_list<gpu::Binding> bindings,
                       const MgPush& p, std::uint32_t cells) {
        rec.dispatch_grid(k, bindings, &p, sizeof(p), (cells + k.workgroup - 1) / k.workgroup, p.dims[1], p.dims[0]);
    }

    void smooth(gpu::Recorder& rec, std::size_t l, std::uint32_t color) {
        const gpu::Kernel& k = ctx_->kernel("mg_smooth", 3, sizeof(MgPush));
        MgPush p = push_for(l, l);
        p.color = color;
        dispatch_rows(rec, k, {{&axes_}, {&r_[l]}, {&e_[l]}}, p, (p.dims[2] + 1) / 2);  // the row's cells of one color
        rec.barrier();
    }

    void residual(gpu::Recorder& rec, std::size_t l) {
        const gpu::Kernel& k = ctx_->kernel("mg_residual", 4, sizeof(MgPush));
        const MgPush p = push_for(l, l);
        dispatch_rows(rec, k, {{&axes_}, {&r_[l]}, {&e_[l]}, {&t_[l]}}, p, p.dims[2]);
        rec.barrier();
    }

    void record_cycle(gpu::Recorder& rec, std::size_t l, bool f_cycle) {
        const std::size_t last = H_.levels.size() - 1;
        if (l == last) {
            const gpu::Kernel& k = ctx_->kernel("mg_coarse", 3, 4);
            const std::uint32_t m = std::uint32_t(H_.levels[l].count());
            rec.dispatch(k, {{&pinv_}, {&r_[l]}, {&e_[l]}}, &m, 4, (m + k.workgroup - 1) / k.workgroup);
            rec.barrier();
            return;
        }
        rec.fill_zero(e_[l], 0, H_.levels[l].count() * 4);
        rec.barrier();
        for (int s = 0; s < 2; ++s) { smooth(rec, l, 0); smooth(rec, l, 1); }
        residual(rec, l);
        {
            const gpu::Kernel& k = ctx_->kernel("mg_restrict", 4, sizeof(MgPush), {max_taps_});
            const MgPush p = push_for(l + 1, l);
            dispatch_rows(rec, k, {{&axes_}, {&gathers_}, {&t_[l]}, {&r_[l + 1]}}, p, p.dims[2]);
            rec.barrier();
        }
        record_cycle(rec, l + 1, f_cycle);
        if (f_cycle && l + 2 <= last) {
            // F-cycle: one more V-cycle on level l+1 against its remaining residual.
            const std::size_t c = l + 1, bytes = H_.levels[c].count() * 4;
            residual(rec, c);
            rec.copy(e_[c], 0, save_[c], 0, bytes);
            rec.copy(t_[c], 0, r_[c], 0, bytes);
            rec.barrier();
            record_cycle(rec, c, false);
            const gpu::Kernel& add = ctx_->kernel("mg_add", 2, 4);
            const std::uint32_t m = std::uint32_t(H_.levels[c].count());
            rec.dispatch(add, {{&e_[c]}, {&save_[c]}}, &m, 4, groups(c));
            rec.barrier();
        }
        {
            const gpu::Kernel& k = ctx_->kernel("mg_prolong", 3, sizeof(MgPush));
            const MgPush p = push_for(l, l + 1);
            dispatch_rows(rec, k, {{&axes_}, {&e_[l + 1]}, {&e_[l]}}, p, p.dims[2]);
            rec.barrier();
        }
        for (int s = 0; s < 2; ++s) { smooth(rec, l, 1); smooth(rec, l, 0); }
    }

    // Residual of φ (+ e when `with_correction`) in float64, then φ += e; partial norms read back.
    void record_refine(gpu::Recorder& rec, bool with_correction) {
        const std::size_t n0 = H_.levels[0].count();
        const gpu::Kernel& k = ctx_->kernel("mg_refine", 5, sizeof(MgPush));
        MgPush p = push_for(0, 0);
        p.color = with_correction ? 1 : 0;
        dispatch_rows(rec, k, {{&phi_}, {&b_}, {&e_[0]}, {&r_[0]}, {&partial_}}, p, p.dims[2]);
        rec.barrier();
        if (with_correction) {
            const gpu::Kernel& u = ctx_->kernel("mg_update", 2, 4);
            const std::uint32_t m = std::uint32_t(n0);
            rec.dispatch(u, {{&phi_}, {&e_[0]}}, &m, 4, groups(0));
            rec.barrier();
        }
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
    gpu::Buffer axes_, gathers_, pinv_, phi_, b_, partial_, partial_down_;
    std::vector<gpu::Buffer> r_, e_, t_, save_;
    std::uint32_t groups0_ = 0;  // mg_refine's workgroups (its partial sums)
    std::int32_t max_taps_ = 1;  // the longest restriction gather list (mg_restrict's MAX_TAPS)
};

}  // namespace

std::unique_ptr<GpuMultigrid> make_gpu_multigrid(const std::shared_ptr<gpu::Context>& ctx, const Hierarchy& h,
                                                 std::string& why_not) {
    if (!ctx->has_float64() || !ctx->info().subgroup_arithmetic) {
        why_not = ctx->info().name + " has no float64 or no subgroup arithmetic in shaders; the multigrid runs on the CPU";
        return nullptr;
    }
    const std::uint64_t n0 = h.levels[0].count();
    if (h.levels[0].axis[0].n > 65535 || h.levels[0].axis[1].n > 65535) {  // rows are workgroups (dispatch_rows)
        why_not = "the grid has more than 65535 nodes along x or y; the multigrid runs on the CPU";
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
    return std::make_unique<VulkanMultigrid>(ctx, h);
}

}  // namespace gsd::shm_detail
