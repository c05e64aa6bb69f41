// GridPoissonSolver: the least-squares Poisson problem of SHM step 3 on a regular grid, with
// geometric multigrid (CPU here, GPU in poisson_gpu.cpp), Jacobi-preconditioned CG, and a
// CHOLMOD direct solve — the last two as CPU references.
#include "gpu/on_device.hpp"
#include <gsd/shm.hpp>

#include "core/uninitialized.hpp"
#include "shm/multigrid.hpp"
#include "shm/poisson_gpu.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/Sparse>

#include <cmath>
#include <numeric>

namespace gsd {

using shm::Hierarchy;
using shm::Level;

namespace {

double dot(const std::vector<double>& a, const std::vector<double>& b) {
    double s = 0;
#pragma omp parallel for reduction(+ : s) schedule(static)
    for (std::size_t i = 0; i < a.size(); ++i) s += a[i] * b[i];
    return s;
}

void remove_mean(std::vector<double>& x) {
    const double mean = std::accumulate(x.begin(), x.end(), 0.0) / double(x.size());
    for (double& v : x) v -= mean;
}

// The stencil of one row (i, j, ·) of a level: the four neighbor rows across x and y with
// their couplings per unit z size (a missing neighbor is the row itself with coupling 0, so the
// inner loops need no branches for it), and the z couplings per unit link. Hoisted out of the
// inner loop: the sweeps below are most of the solve's time.
struct RowStencil {
    std::size_t row, xm, xp, ym, yp;  ///< storage index of k = 0 in each row
    double cxm, cxp, cym, cyp;        ///< × size_z[k]
    double cz;                        ///< × link_z[k] (and link_z[k − 1] below)

    RowStencil(const Level& lv, int i, int j) {
        const auto& X = lv.axis[0];
        const auto& Y = lv.axis[1];
        const int nx = X.n, ny = Y.n;
        const double sx = X.size[std::size_t(i)], sy = Y.size[std::size_t(j)];
        row = lv.index(i, j, 0);
        xm = i > 0 ? lv.index(i - 1, j, 0) : row;
        xp = i + 1 < nx ? lv.index(i + 1, j, 0) : row;
        ym = j > 0 ? lv.index(i, j - 1, 0) : row;
        yp = j + 1 < ny ? lv.index(i, j + 1, 0) : row;
        cxm = i > 0 ? X.link[std::size_t(i - 1)] * sy : 0.0;
        cxp = X.link[std::size_t(i)] * sy;  // 0 on the last cell
        cym = j > 0 ? Y.link[std::size_t(j - 1)] * sx : 0.0;
        cyp = Y.link[std::size_t(j)] * sx;
        cz = sx * sy;
    }
};

// The 7-point operator of one level: (A x)_p = Σ_neighbors c (x_p − x_q).
void apply_level(const Hierarchy& H, int l, const double* x, double* y) {
    const Level& lv = H.levels[std::size_t(l)];
    const int nx = lv.axis[0].n, ny = lv.axis[1].n, nz = lv.axis[2].n;
    const double* sz = lv.axis[2].size.data();
    const double* lz = lv.axis[2].link.data();
#pragma omp parallel for collapse(2) schedule(static)
    for (int i = 0; i < nx; ++i)
        for (int j = 0; j < ny; ++j) {
            const RowStencil st(lv, i, j);
            const double *xr = x + st.row, *xm = x + st.xm, *xp = x + st.xp, *ym = x + st.ym, *yp = x + st.yp;
            double* yr = y + st.row;
            for (int k = 0; k < nz; ++k) {
                const double v = xr[k];
                double s = sz[k] * (st.cxm * (v - xm[k]) + st.cxp * (v - xp[k]) + st.cym * (v - ym[k]) + st.cyp * (v - yp[k]));
                if (k > 0) s += st.cz * lz[k - 1] * (v - xr[k - 1]);
                if (k + 1 < nz) s += st.cz * lz[k] * (v - xr[k + 1]);
                yr[k] = s;
            }
        }
}

double diagonal(const Hierarchy& H, int l, int i, int j, int k) {
    const Level& lv = H.levels[std::size_t(l)];
    double d = 0;
    if (i > 0) d += H.coupling(l, 0, i - 1, j, k);
    if (i + 1 < lv.axis[0].n) d += H.coupling(l, 0, i, j, k);
    if (j > 0) d += H.coupling(l, 1, i, j - 1, k);
    if (j + 1 < lv.axis[1].n) d += H.coupling(l, 1, i, j, k);
    if (k > 0) d += H.coupling(l, 2, i, j, k - 1);
    if (k + 1 < lv.axis[2].n) d += H.coupling(l, 2, i, j, k);
    return d;
}

}  // namespace

// ---- CPU multigrid ---------------------------------------------------------------------------

class CpuMultigrid {
public:
    explicit CpuMultigrid(const Hierarchy& h) : H(h) {
        for (const Level& lv : H.levels) {
            r_.emplace_back(lv.count());
            e_.emplace_back(lv.count());
            t_.emplace_back(lv.count());
        }
    }

    /// One cycle on the finest level: e ≈ A⁺ r.
    std::vector<double> cycle(const std::vector<double>& r, bool f_cycle) {
        r_[0] = r;
        run(0, f_cycle);
        return e_[0];
    }

private:
    // Red-black Gauss–Seidel sweep of one color.
    void smooth(int l, int color) {
        const Level& lv = H.levels[std::size_t(l)];
        const int nx = lv.axis[0].n, ny = lv.axis[1].n, nz = lv.axis[2].n;
        const double* sz = lv.axis[2].size.data();
        const double* lz = lv.axis[2].link.data();
        const double* r = r_[std::size_t(l)].data();
        double* e = e_[std::size_t(l)].data();
#pragma omp parallel for collapse(2) schedule(static)
        for (int i = 0; i < nx; ++i)
            for (int j = 0; j < ny; ++j) {
                const RowStencil st(lv, i, j);
                const double *rr = r + st.row, *xm = e + st.xm, *xp = e + st.xp, *ym = e + st.ym, *yp = e + st.yp;
                double* er = e + st.row;
                const double side = st.cxm + st.cxp + st.cym + st.cyp;
                for (int k = (i + j + color) & 1; k < nz; k += 2) {
                    double s = rr[k] + sz[k] * (st.cxm * xm[k] + st.cxp * xp[k] + st.cym * ym[k] + st.cyp * yp[k]);
                    double d = sz[k] * side;
                    if (k > 0) {
                        const double c = st.cz * lz[k - 1];
                        s += c * er[k - 1];
                        d += c;
                    }
                    if (k + 1 < nz) {
                        const double c = st.cz * lz[k];
                        s += c * er[k + 1];
                        d += c;
                    }
                    if (d > 0) er[k] = s / d;
                }
            }
    }

    // coarse r_{l+1} = Pᵀ (r_l − A e_l)
    void restrict_residual(int l) {
        apply_level(H, l, e_[std::size_t(l)].data(), t_[std::size_t(l)].data());
        std::vector<double>& res = t_[std::size_t(l)];
        for (std::size_t p = 0; p < res.size(); ++p) res[p] = r_[std::size_t(l)][p] - res[p];
        const Level& c = H.levels[std::size_t(l) + 1];
        double* rc = r_[std::size_t(l) + 1].data();
#pragma omp parallel for collapse(2) schedule(static)
        for (int I = 0; I < c.axis[0].n; ++I)
            for (int J = 0; J < c.axis[1].n; ++J)
                for (int K = 0; K < c.axis[2].n; ++K) {
                    double s = 0;
                    const auto& ax = c.axis[0];
                    const auto& ay = c.axis[1];
                    const auto& az = c.axis[2];
                    for (int a = ax.offsets[std::size_t(I)]; a < ax.offsets[std::size_t(I) + 1]; ++a)
                        for (int b = ay.offsets[std::size_t(J)]; b < ay.offsets[std::size_t(J) + 1]; ++b)
                            for (int g = az.offsets[std::size_t(K)]; g < az.offsets[std::size_t(K) + 1]; ++g)
                                s += ax.gather_weight[std::size_t(a)] * ay.gather_weight[std::size_t(b)] * az.gather_weight[std::size_t(g)] *
                                     res[H.levels[std::size_t(l)].index(ax.gather_index[std::size_t(a)], ay.gather_index[std::size_t(b)],
                                                                         az.gather_index[std::size_t(g)])];
                    rc[c.index(I, J, K)] = s;
                }
    }

    // e_l += P e_{l+1}
    void prolong_add(int l) {
        const Level& f = H.levels[std::size_t(l)];
        const Level& c = H.levels[std::size_t(l) + 1];
        const double* ec = e_[std::size_t(l) + 1].data();
        double* e = e_[std::size_t(l)].data();
#pragma omp parallel for collapse(2) schedule(static)
        for (int i = 0; i < f.axis[0].n; ++i)
            for (int j = 0; j < f.axis[1].n; ++j)
                for (int k = 0; k < f.axis[2].n; ++k) {
                    const auto& ax = f.axis[0];
                    const auto& ay = f.axis[1];
                    const auto& az = f.axis[2];
                    const int ci[2] = {ax.c0[std::size_t(i)], ax.c1[std::size_t(i)]}, cj[2] = {ay.c0[std::size_t(j)], ay.c1[std::size_t(j)]},
                              ck[2] = {az.c0[std::size_t(k)], az.c1[std::size_t(k)]};
                    const double wi[2] = {ax.w0[std::size_t(i)], ax.w1[std::size_t(i)]}, wj[2] = {ay.w0[std::size_t(j)], ay.w1[std::size_t(j)]},
                                 wk[2] = {az.w0[std::size_t(k)], az.w1[std::size_t(k)]};
                    double s = 0;
                    for (int a = 0; a < 2; ++a)
                        for (int b = 0; b < 2; ++b)
                            for (int g = 0; g < 2; ++g) s += wi[a] * wj[b] * wk[g] * ec[c.index(ci[a], cj[b], ck[g])];
                    e[f.index(i, j, k)] += s;
                }
    }

    void solve_coarsest() {
        const std::size_t l = H.levels.size() - 1;
        const std::size_t m = H.levels[l].count();
        for (std::size_t p = 0; p < m; ++p) {
            double s = 0;
            for (std::size_t q = 0; q < m; ++q) s += H.coarse_pinv[p * m + q] * r_[l][q];
            e_[l][p] = s;
        }
    }

    void run(int l, bool f_cycle) {
        if (std::size_t(l) + 1 == H.levels.size()) { solve_coarsest(); return; }
        std::fill(e_[std::size_t(l)].begin(), e_[std::size_t(l)].end(), 0.0);
        for (int s = 0; s < 2; ++s) { smooth(l, 0); smooth(l, 1); }
        restrict_residual(l);
        run(l + 1, f_cycle);
        if (f_cycle && std::size_t(l) + 2 < H.levels.size()) {
            // F-cycle: one more V-cycle on the coarse level against its remaining residual.
            std::vector<double> ec = e_[std::size_t(l) + 1];
            std::vector<double>& rc = r_[std::size_t(l) + 1];
            apply_level(H, l + 1, ec.data(), t_[std::size_t(l) + 1].data());
            for (std::size_t p = 0; p < rc.size(); ++p) rc[p] -= t_[std::size_t(l) + 1][p];
            run(l + 1, false);
            for (std::size_t p = 0; p < ec.size(); ++p) e_[std::size_t(l) + 1][p] += ec[p];
        }
        prolong_add(l);
        for (int s = 0; s < 2; ++s) { smooth(l, 1); smooth(l, 0); }
    }

    const Hierarchy& H;
    std::vector<std::vector<double>> r_, e_, t_;
};

// ---- the public solver ---------------------------------------------------------------------

struct GridPoissonSolver::Impl {
    GridSpec grid;
    PoissonSolver kind;
    Device device_choice;
    Hierarchy H;
    mutable std::unique_ptr<shm::GpuMultigrid> gpu;
    mutable bool gpu_tried = false;
    mutable std::string device_name = "cpu";

    Impl(GridSpec g, PoissonSolver k, Device d) : grid(g), kind(k), device_choice(std::move(d)), H(g) {}

    // The GPU multigrid if the device choice gives one (once), else null. An attempt that throws
    // is not latched: the next call (solve() after a prepare() that met it) tries again and
    // throws to its caller.
    shm::GpuMultigrid* gpu_multigrid() const {
        if (!gpu_tried) {
            const gpu::DeviceRun run = gpu::on_device(device_choice, [&](const auto& ctx, std::string& why_not) {
                gpu = shm::make_gpu_multigrid(ctx, H, why_not);
                return gpu != nullptr;
            });
            if (run) device_name = run.device;
            gpu_tried = true;
        }
        return gpu.get();
    }

    // `storage`: a vector whose memory the device's φ may be returned in (GpuMultigrid::solve).
    std::vector<double> multigrid(const std::vector<double>& b, double tol, int max_it, std::vector<double>* history,
                                  bool f_cycle, const ProgressFn& progress, std::vector<double>* storage) const {
        if (shm::GpuMultigrid* g = gpu_multigrid()) return g->solve(b, tol, max_it, history, f_cycle, progress, storage);
        CpuMultigrid mg(H);
        const std::size_t n = b.size();
        std::vector<double> x(n, 0.0), r = b, Ax(n);
        const double bnorm = std::sqrt(dot(b, b));
        for (int it = 0; it < max_it; ++it) {
            const double rel = bnorm > 0 ? std::sqrt(dot(r, r)) / bnorm : 0.0;
            if (history && it > 0) history->push_back(rel);
            if (rel <= tol) break;
            const std::vector<double> e = mg.cycle(r, f_cycle);
            for (std::size_t p = 0; p < n; ++p) x[p] += e[p];
            apply_level(H, 0, x.data(), Ax.data());
            for (std::size_t p = 0; p < n; ++p) r[p] = b[p] - Ax[p];
            if (progress) progress("solve", std::min(1.0, std::log(std::max(rel, 1e-300)) / std::log(tol)));
        }
        if (history && (history->empty() || history->back() > 0)) {
            const double rel = bnorm > 0 ? std::sqrt(dot(r, r)) / bnorm : 0.0;
            if (history->empty() || history->back() != rel) history->push_back(rel);
        }
        remove_mean(x);
        return x;
    }

    std::vector<double> conjugate_gradient(const std::vector<double>& b, double tol, int max_it,
                                           std::vector<double>* history, const ProgressFn& progress) const {
        const Level& lv = H.levels[0];
        const std::size_t n = b.size();
        std::vector<double> inv_diag(n);
        for (int i = 0; i < lv.axis[0].n; ++i)
            for (int j = 0; j < lv.axis[1].n; ++j)
                for (int k = 0; k < lv.axis[2].n; ++k) inv_diag[lv.index(i, j, k)] = 1 / diagonal(H, 0, i, j, k);
        std::vector<double> x(n, 0.0), r = b, z(n), p(n), Ap(n);
        remove_mean(r);
        const double bnorm = std::sqrt(dot(r, r));
        for (std::size_t i = 0; i < n; ++i) z[i] = inv_diag[i] * r[i];
        remove_mean(z);
        p = z;
        double rz = dot(r, z);
        for (int it = 0; it < max_it; ++it) {
            const double rel = bnorm > 0 ? std::sqrt(dot(r, r)) / bnorm : 0.0;
            if (history && it > 0) history->push_back(rel);
            if (rel <= tol) break;
            apply_level(H, 0, p.data(), Ap.data());
            const double alpha = rz / dot(p, Ap);
            for (std::size_t i = 0; i < n; ++i) { x[i] += alpha * p[i]; r[i] -= alpha * Ap[i]; }
            for (std::size_t i = 0; i < n; ++i) z[i] = inv_diag[i] * r[i];
            remove_mean(z);
            const double rz_new = dot(r, z);
            const double beta = rz_new / rz;
            rz = rz_new;
            for (std::size_t i = 0; i < n; ++i) p[i] = z[i] + beta * p[i];
            if (progress && it % 10 == 0) progress("solve", std::min(1.0, std::log(std::max(rel, 1e-300)) / std::log(tol)));
        }
        remove_mean(x);
        return x;
    }

    std::vector<double> direct(const std::vector<double>& b) const {
        // Pin node 0 (the constant nullspace), factor the rest with CHOLMOD, then re-center.
        const auto n = Eigen::Index(b.size());
        if (n > 64 * 64 * 64 * 2)
            throw Error("ShmOptions::solver", "the direct solver is for small grids (≤ 2·64³ nodes); use mg or cg");
        std::vector<Eigen::Triplet<double>> t;
        t.reserve(std::size_t(n) * 7);
        auto add = [&](Eigen::Index p, Eigen::Index q, double v) {
            if (p > 0 && q > 0) t.emplace_back(p - 1, q - 1, v);
        };
        H.for_each_edge(0, [&](std::size_t p, std::size_t q, double w) {
            add(Eigen::Index(p), Eigen::Index(p), w);
            add(Eigen::Index(q), Eigen::Index(q), w);
            add(Eigen::Index(p), Eigen::Index(q), -w);
            add(Eigen::Index(q), Eigen::Index(p), -w);
        });
        Eigen::SparseMatrix<double> A(n - 1, n - 1);
        A.setFromTriplets(t.begin(), t.end());
        Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> chol(A);
        if (chol.info() != Eigen::Success) throw Error("ShmOptions::solver", "CHOLMOD could not factor the Poisson matrix");
        Eigen::VectorXd rhs = Eigen::Map<const Eigen::VectorXd>(b.data() + 1, n - 1);
        const Eigen::VectorXd sol = chol.solve(rhs);
        std::vector<double> x(std::size_t(n), 0.0);
        for (Eigen::Index i = 0; i < n - 1; ++i) x[std::size_t(i) + 1] = sol[i];
        remove_mean(x);
        return x;
    }
};

GridPoissonSolver::GridPoissonSolver(GridSpec grid, PoissonSolver solver, Device device) {
    grid.validate();
    impl_ = std::make_unique<Impl>(grid, solver, std::move(device));
}
GridPoissonSolver::~GridPoissonSolver() = default;
GridPoissonSolver::GridPoissonSolver(GridPoissonSolver&&) noexcept = default;
GridPoissonSolver& GridPoissonSolver::operator=(GridPoissonSolver&&) noexcept = default;

std::vector<double> GridPoissonSolver::divergence(std::span<const float> Y) const {
    const GridSpec& g = impl_->grid;
    if (Y.size() != 3 * g.node_count()) throw Error("divergence: the field needs 3 values per node");
    const double h[3] = {g.box.extent().x() / (g.nx - 1), g.box.extent().y() / (g.ny - 1), g.box.extent().z() / (g.nz - 1)};
    const int n[3] = {g.nx, g.ny, g.nz};
    const Level& lv = impl_->H.levels[0];
    std::vector<double> b;
    detail::resize_in_huge_pages(b, g.node_count());
    // Edge (p, p+e_a) carries Ȳ_a = (Y_a(p) + Y_a(p+e_a))/2: it adds −Ȳ_a/Δ_a to b_p and +Ȳ_a/Δ_a to
    // b_{p+e_a} (normal equations of Σ_edges ((φ_q − φ_p)/Δ_a − Ȳ_a)²). Each node gathers its six
    // edges, in parallel: first the edges from its lower neighbours, then its own, along x, y, z —
    // the order in which a serial sweep over the edges in storage order would add them.
    const std::size_t stride[3] = {std::size_t(n[1]) * std::size_t(n[2]), std::size_t(n[2]), 1};
    auto ybar = [&](std::size_t p, int a) {  // the edge (p, p + e_a)
        return 0.5 * (double(Y[3 * p + std::size_t(a)]) + double(Y[3 * (p + stride[a]) + std::size_t(a)]));
    };
#pragma omp parallel for collapse(2) schedule(static)
    for (int i = 0; i < n[0]; ++i)
        for (int j = 0; j < n[1]; ++j)
            for (int k = 0; k < n[2]; ++k) {
                const int ijk[3] = {i, j, k};
                const std::size_t p = lv.index(i, j, k);
                double v = 0.0;
                for (int a = 0; a < 3; ++a)
                    if (ijk[a] > 0) v += ybar(p - stride[a], a) / h[a];
                for (int a = 0; a < 3; ++a)
                    if (ijk[a] + 1 < n[a]) v -= ybar(p, a) / h[a];
                b[p] = v;
            }
    return b;
}

std::vector<double> GridPoissonSolver::solve(const std::vector<double>& b, const PoissonSolveOptions& o,
                                             std::vector<double>* history, const ProgressFn& progress) const {
    return solve_using(b, o, history, progress, nullptr);
}

std::vector<double> GridPoissonSolver::solve(std::vector<double>&& b, const PoissonSolveOptions& o,
                                             std::vector<double>* history, const ProgressFn& progress) const {
    return solve_using(b, o, history, progress, &b);
}

std::vector<double> GridPoissonSolver::solve_using(const std::vector<double>& b, const PoissonSolveOptions& o,
                                                   std::vector<double>* history, const ProgressFn& progress,
                                                   std::vector<double>* storage) const {
    if (b.size() != impl_->grid.node_count()) throw Error("Poisson right-hand side has the wrong size");
    if (o.max_iterations < 0) throw Error("max_iterations", "must be ≥ 0 (0: the solver's default)");
    switch (impl_->kind) {
        case PoissonSolver::Multigrid:
            return impl_->multigrid(b, o.tolerance, o.max_iterations ? o.max_iterations : 50, history, o.f_cycle, progress,
                                    storage);
        case PoissonSolver::CG:
            return impl_->conjugate_gradient(b, o.tolerance, o.max_iterations ? o.max_iterations : 5000, history, progress);
        case PoissonSolver::Direct: {
            std::vector<double> x = impl_->direct(b);
            if (history) {  // one entry: the residual the factorization achieved
                const std::vector<double> Ax = apply(x);
                double r = 0, n = 0;
                for (std::size_t i = 0; i < b.size(); ++i) { r += (b[i] - Ax[i]) * (b[i] - Ax[i]); n += b[i] * b[i]; }
                history->push_back(n > 0 ? std::sqrt(r / n) : 0.0);
            }
            return x;
        }
    }
    return {};
}

void GridPoissonSolver::prepare(bool f_cycle) const {
    if (impl_->kind != PoissonSolver::Multigrid) return;
    try {
        if (shm::GpuMultigrid* g = impl_->gpu_multigrid()) g->prepare(f_cycle);
    } catch (const std::exception&) {
        // solve() meets the same and says so.
    }
}

std::vector<double> GridPoissonSolver::apply(const std::vector<double>& x) const {
    std::vector<double> y(x.size());
    apply_level(impl_->H, 0, x.data(), y.data());
    return y;
}

std::string GridPoissonSolver::device() const {
    if (impl_->kind != PoissonSolver::Multigrid) return "cpu";
    impl_->gpu_multigrid();
    return impl_->device_name;
}

}  // namespace gsd
