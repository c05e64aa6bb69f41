// SignedHeatGrid: the three steps of the grid Signed Heat Method, the zero-set shift and fit,
// and the outside veto.
#include "gpu/on_device.hpp"
#include <gsd/shm.hpp>
#include <gsd/viz.hpp>

#include "shm/diffuse.hpp"
#include "shm/redistance.hpp"
#include "shm/veto.hpp"
#include "sums/sum_tree.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <future>
#include <numeric>

namespace gsd {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Trilinear interpolation weights of a point inside the grid: 8 (node, weight) pairs; false if
// the point lies outside the box.
bool trilinear(const GridSpec& g, const Eigen::Vector3d& x, std::size_t (&node)[8], double (&w)[8]) {
    const int n[3] = {g.nx, g.ny, g.nz};
    int base[3];
    double t[3];
    for (int a = 0; a < 3; ++a) {
        const double u = (x[a] - g.box.lo[a]) / g.box.extent()[a] * (n[a] - 1);
        if (!(u >= 0 && u <= n[a] - 1)) return false;
        base[a] = std::min(int(u), n[a] - 2);
        t[a] = u - base[a];
    }
    for (int c = 0; c < 8; ++c) {
        const int o[3] = {c & 1, (c >> 1) & 1, (c >> 2) & 1};
        node[c] = (std::size_t(base[0] + o[0]) * std::size_t(g.ny) + std::size_t(base[1] + o[1])) * std::size_t(g.nz) + std::size_t(base[2] + o[2]);
        w[c] = (o[0] ? t[0] : 1 - t[0]) * (o[1] ? t[1] : 1 - t[1]) * (o[2] ? t[2] : 1 - t[2]);
    }
    return true;
}

}  // namespace

struct SignedHeatGrid::Impl {
    ShmSource source;
    GridSpec grid;
    ShmOptions opt;

    shm::KernelParams kernel() const {
        return shm::kernel_params(source, opt.t_coef, opt.cutoff, opt.sum_tolerance);
    }

    detail::UninitializedVector<float> directions(shm::DiffuseStats& stats, std::string& device, const ProgressFn& progress,
                                  double* seconds_setup = nullptr) const {
        const auto t0 = std::chrono::steady_clock::now();
        std::unique_ptr<shm::DirectionEvaluator> eval;
        gpu::on_device(opt.device, [&](const auto& ctx, std::string& why_not) {
            eval = shm::make_gpu_evaluator(ctx, source, kernel(), opt.chunk_size, why_not);
            return eval != nullptr;
        });
        if (!eval) eval = shm::make_cpu_evaluator(source, kernel());
        device = eval->device();
        if (seconds_setup) *seconds_setup = seconds_since(t0);
        return shm::diffuse(grid, *eval, opt.interpolation_cells, stats, progress);
    }

    // Area samples of the source inside the box (triangles split to the grid spacing): their
    // trilinear nodes and weights on the grid, their area and position.
    template <class Emit>
    void samples(Emit&& emit) const {
        const double cell = grid.box.extent().maxCoeff() / double(std::max({grid.nx, grid.ny, grid.nz}) - 1);
        shm::for_each_sample(source, cell, grid.box, [&](const Eigen::Vector3d& p, double area) {
            std::size_t node[8];
            double w[8];
            if (trilinear(grid, p, node, w)) emit(node, w, area, p);
        });
    }

    // Area-weighted mean of φ over the source inside the box.
    double mean_on_source(const std::vector<double>& phi) const {
        double sum = 0, weight = 0;
        samples([&](const std::size_t (&node)[8], const double (&w)[8], double a, const Eigen::Vector3d&) {
            double v = 0;
            for (int c = 0; c < 8; ++c) v += w[c] * phi[node[c]];
            sum += a * v;
            weight += a;
        });
        if (!(weight > 0)) throw Error("the source lies outside the grid's bounds");
        return sum / weight;
    }

    struct Sample {
        std::size_t node[8];
        double w[8];
        double area, value;  // value: φ₀ there
    };

    // Minimizes ½xᵀLx + ½μ Σ_j A_j (v_j + (Sx)_j)², i.e. (L + μ SᵀDS) x = −μ SᵀD v, on `g` (L: its
    // Poisson operator; S: trilinear weights of the samples; v: their values), by CG
    // preconditioned with a multigrid cycle of L plus the constant mode (which L cannot see but
    // the penalty pins).
    std::vector<double> penalized_solve(const GridSpec& g, const std::vector<Sample>& samples, double mu,
                                        std::vector<double>& history) const {
        const GridPoissonSolver mg(g, PoissonSolver::Multigrid, "cpu");
        double total_area = 0;
        std::vector<double> b(g.node_count(), 0.0);
        for (const Sample& s : samples) {
            total_area += s.area;
            for (int c = 0; c < 8; ++c) b[s.node[c]] -= mu * s.area * s.w[c] * s.value;
        }
        auto apply = [&](const std::vector<double>& x) {
            std::vector<double> y = mg.apply(x);
            for (const Sample& s : samples) {
                double v = 0;
                for (int c = 0; c < 8; ++c) v += s.w[c] * x[s.node[c]];
                for (int c = 0; c < 8; ++c) y[s.node[c]] += mu * s.area * s.w[c] * v;
            }
            return y;
        };
        // z = P0 M P0 r + (1ᵀr / 1ᵀA1)·1 with M one multigrid cycle and P0 the projection onto
        // zero mean: symmetric positive definite, as CG needs.
        auto precondition = [&](const std::vector<double>& r) {
            std::vector<double> r0 = r;
            const double mean = std::accumulate(r.begin(), r.end(), 0.0) / double(r.size());
            for (double& v : r0) v -= mean;
            std::vector<double> z = mg.solve(r0, {0.0, 1});  // one cycle, mean removed
            // The constant mode: 1ᵀA1 = μ Σ A_j (trilinear weights sum to one).
            const double mode = std::accumulate(r.begin(), r.end(), 0.0) / (mu * total_area);
            for (double& v : z) v += mode;
            return z;
        };
        std::vector<double> x(b.size(), 0.0), r = b, z = precondition(r), p = z;
        auto dot = [](const std::vector<double>& a, const std::vector<double>& c) {
            return std::inner_product(a.begin(), a.end(), c.begin(), 0.0);
        };
        const double bnorm = std::sqrt(dot(b, b));
        if (!(bnorm > 0)) return x;
        double rz = dot(r, z);
        for (int it = 0; it < 5000; ++it) {  // a small grid: converges in tens
            const double rel = std::sqrt(dot(r, r)) / bnorm;
            history.push_back(rel);
            if (rel <= opt.tolerance) break;
            const std::vector<double> Ap = apply(p);
            const double alpha = rz / dot(p, Ap);
            for (std::size_t i = 0; i < x.size(); ++i) { x[i] += alpha * p[i]; r[i] -= alpha * Ap[i]; }
            z = precondition(r);
            const double rz_new = dot(r, z);
            for (std::size_t i = 0; i < x.size(); ++i) p[i] = z[i] + rz_new / rz * p[i];
            rz = rz_new;
        }
        return x;
    }

    // μ = w/(h V) of the fine grid: the penalty (w/h) Σ A_j φ(y_j)² against Σ_edges (Δφ/h)² V.
    double penalty_weight(const GridSpec& on) const {
        const Eigen::Vector3d step = grid.box.extent().cwiseQuotient(Eigen::Vector3d(grid.nx - 1, grid.ny - 1, grid.nz - 1));
        const Eigen::Vector3d coarse = on.box.extent().cwiseQuotient(Eigen::Vector3d(on.nx - 1, on.ny - 1, on.nz - 1));
        return opt.fit_zero_set / (step.maxCoeff() * coarse.prod());
    }

    // Soft zero set: minimize the Poisson energy of φ plus (w/h) Σ_j A_j φ(y_j)², with φ = φ₀ + Iψ:
    // φ₀ the solution shifted by its mean on the source, ψ a correction on a grid of a quarter of
    // the resolution (at least 9 nodes an axis; its own Poisson energy standing for that of Iψ),
    // I trilinear interpolation. The correction is smooth, so a coarse grid carries it: on ten
    // broken meshes the full grid, half and a quarter of it sign the same shares of nodes right
    // to within 0.3 points (docs/shm.md), and the quarter costs a small part of the full fit.
    void fit_zero_set(std::vector<double>& phi, std::vector<double>& history) const {
        const std::vector<double>& phi0 = phi;  // φ₀ until the correction is added, in place
        GridSpec coarse = grid;
        coarse.nx = std::min(grid.nx, std::max(9, grid.nx / 4 + 1));
        coarse.ny = std::min(grid.ny, std::max(9, grid.ny / 4 + 1));
        coarse.nz = std::min(grid.nz, std::max(9, grid.nz / 4 + 1));
        std::vector<Sample> samples;
        this->samples([&](const std::size_t (&node)[8], const double (&w)[8], double area, const Eigen::Vector3d& p) {
            Sample s;
            s.area = area;
            s.value = 0;
            for (int c = 0; c < 8; ++c) s.value += w[c] * phi0[node[c]];
            if (trilinear(coarse, p, s.node, s.w)) samples.push_back(s);
        });
        if (samples.empty()) throw Error("the source lies outside the grid's bounds");
        const std::vector<double> psi = penalized_solve(coarse, samples, penalty_weight(coarse), history);
        // Node coordinates as computed, not a grid.nodes() copy (400 MB at 256³, filled serially).
#pragma omp parallel for collapse(2) schedule(static)
        for (int i = 0; i < grid.nx; ++i)
            for (int j = 0; j < grid.ny; ++j)
                for (int k = 0; k < grid.nz; ++k) {
                    std::size_t node[8];
                    double w[8];
                    if (!trilinear(coarse, grid.node(i, j, k), node, w)) continue;
                    double v = 0;
                    for (int c = 0; c < 8; ++c) v += w[c] * psi[node[c]];
                    phi[(std::size_t(i) * std::size_t(grid.ny) + std::size_t(j)) * std::size_t(grid.nz) + std::size_t(k)] += v;
                }
    }

    // The outside veto (ShmOptions::veto_winding, shm/veto.hpp) at every node.
    std::size_t veto_outside(std::vector<double>& phi) const {
        const Eigen::Vector3d step = grid.box.extent().cwiseQuotient(Eigen::Vector3d(grid.nx - 1, grid.ny - 1, grid.nz - 1));
        return shm::veto_outside(source, {opt.veto_winding, opt.veto_slope, opt.veto_margin}, phi, [&](std::size_t i) {
            const std::size_t iz = i % std::size_t(grid.nz), iy = (i / std::size_t(grid.nz)) % std::size_t(grid.ny),
                              ix = i / (std::size_t(grid.nz) * std::size_t(grid.ny));
            return Eigen::Vector3d(grid.box.lo + step.cwiseProduct(Eigen::Vector3d(double(ix), double(iy), double(iz))));
        });
    }
};

SignedHeatGrid::SignedHeatGrid(ShmSource source, GridSpec grid, ShmOptions options) {
    grid.validate();
    if (source.size() == 0) throw Error("the signed heat method needs a non-empty source");
    // Finite and in range; NaN fails both (the Python module passes floats through as given).
    const auto positive = [](double x) { return x > 0 && std::isfinite(x); };
    const auto non_negative = [](double x) { return x >= 0 && std::isfinite(x); };
    if (!positive(source.spacing)) throw Error("the source has no spacing (all samples coincide?)");
    if (!positive(options.t_coef))
        throw Error("ShmOptions::t_coef", "the diffusion time coefficient must be finite and > 0");
    if (!positive(options.cutoff)) throw Error("ShmOptions::cutoff", "the kernel cutoff must be finite and > 0");
    if (!non_negative(options.interpolation_cells))
        throw Error("ShmOptions::interpolation_cells", "must be finite and ≥ 0");
    if (!non_negative(options.fit_zero_set))
        throw Error("ShmOptions::fit_zero_set", "the zero-set weight must be finite and ≥ 0");
    if (!(options.sum_tolerance > 0) || !(options.sum_tolerance <= 1))
        throw Error("ShmOptions::sum_tolerance", "the step 1 sum tolerance must be in (0, 1]");
    if (!(options.veto_winding >= 0) || !(options.veto_winding < 1))
        throw Error("ShmOptions::veto_winding", "the outside veto's winding number must be in [0, 1) (0: no veto)");
    if (!non_negative(options.veto_slope))
        throw Error("ShmOptions::veto_slope", "the outside veto's slope must be finite and ≥ 0");
    if (!positive(options.veto_margin))
        throw Error("ShmOptions::veto_margin", "the outside veto's margin must be finite and > 0");
    source.elements.validate();
    impl_ = std::make_unique<Impl>(Impl{std::move(source), grid, std::move(options)});
}

SignedHeatGrid::~SignedHeatGrid() = default;
SignedHeatGrid::SignedHeatGrid(SignedHeatGrid&&) noexcept = default;
SignedHeatGrid& SignedHeatGrid::operator=(SignedHeatGrid&&) noexcept = default;

const GridSpec& SignedHeatGrid::grid() const { return impl_->grid; }
const ShmSource& SignedHeatGrid::source() const { return impl_->source; }

std::vector<float> SignedHeatGrid::diffused_directions(const ProgressFn& progress) const {
    shm::DiffuseStats stats;
    std::string device;
    const detail::UninitializedVector<float> y = impl_->directions(stats, device, progress);
    return std::vector<float>(y.begin(), y.end());
}

SharpenResult SignedHeatGrid::sharpen(std::span<const float> phi, const SharpenOptions& options,
                                      const ProgressFn& progress) const {
    return sharpen_distance(impl_->grid, phi, impl_->source, options, progress);
}

ShmResult SignedHeatGrid::solve(const ProgressFn& progress) const {
    const Impl& m = *impl_;
    ShmResult out;
    auto t0 = std::chrono::steady_clock::now();
    // Step 3's solver on a device is made ready while step 1 runs (its pipelines, its host
    // grids' page faults: ~45 ms of a 0.55 s solve at 128³ on lavapipe), on a thread of its own:
    // on a GPU the host is idle then, and on a software device step 1's own thread waits on it.
    const GridPoissonSolver poisson(m.grid, m.opt.solver, m.opt.device);
    // Declared after `poisson`: a std::async future waits for its thread when destroyed, so the
    // thread ends before `poisson` does, whatever step 1 throws.
    std::future<void> prepared;
    if (m.opt.solver == PoissonSolver::Multigrid && m.opt.device.describe() != "cpu") {
        try {
            prepared = std::async(std::launch::async, [&] { poisson.prepare(m.opt.f_cycle); });
        } catch (const std::exception&) {  // no thread: solve() makes it all
        }
    }
    shm::DiffuseStats stats;
    std::string diffuse_device;
    const detail::UninitializedVector<float> Y = m.directions(stats, diffuse_device, progress, &out.seconds_setup);
    out.seconds_sums = stats.seconds_sums;
    out.exact_nodes = stats.exact_nodes;
    out.kernel_terms = stats.kernel_terms;
    out.seconds_diffuse = seconds_since(t0);

    t0 = std::chrono::steady_clock::now();
    if (prepared.valid()) prepared.get();  // prepare() throws nothing
    std::vector<double> b = poisson.divergence(std::span<const float>(Y.data(), Y.size()));
    std::vector<double> phi =
        poisson.solve(std::move(b), {m.opt.tolerance, std::max(0, m.opt.max_iterations), m.opt.f_cycle}, &out.residual_history, progress);
    const double shift = m.mean_on_source(phi);
    const auto nodes = std::ptrdiff_t(phi.size());
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < nodes; ++i) phi[std::size_t(i)] -= shift;
    out.seconds_poisson = seconds_since(t0);
    auto t1 = std::chrono::steady_clock::now();
    if (m.opt.fit_zero_set > 0) m.fit_zero_set(phi, out.fit_history);  // on the CPU: a small grid
    out.seconds_fit = seconds_since(t1);
    t1 = std::chrono::steady_clock::now();
    if (m.opt.veto_winding > 0) out.vetoed_nodes = m.veto_outside(phi);      // on the CPU: a few nodes' sums
    out.seconds_veto = seconds_since(t1);
    if (m.opt.redistance) {
        t1 = std::chrono::steady_clock::now();
        if (progress) progress("redistance", 0.0);
        std::vector<float> values(phi.begin(), phi.end());
        const Eigen::Vector3d step = m.grid.box.extent().cwiseQuotient(Eigen::Vector3d(m.grid.nx - 1, m.grid.ny - 1, m.grid.nz - 1));
        shm::redistance(contour(m.grid, values, 0.0), phi, [&](std::size_t i) {
            const std::size_t iz = i % std::size_t(m.grid.nz), iy = (i / std::size_t(m.grid.nz)) % std::size_t(m.grid.ny),
                              ix = i / (std::size_t(m.grid.nz) * std::size_t(m.grid.ny));
            return Eigen::Vector3d(m.grid.box.lo + step.cwiseProduct(Eigen::Vector3d(double(ix), double(iy), double(iz))));
        });
        out.seconds_redistance = seconds_since(t1);
    }
    out.seconds_solve = seconds_since(t0);
    const std::string solve_device = poisson.device();
    out.device = diffuse_device == solve_device ? diffuse_device : diffuse_device + " (step 1), " + solve_device + " (step 3)";
    out.phi.resize(phi.size());
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < nodes; ++i) out.phi[std::size_t(i)] = float(phi[std::size_t(i)]);
    return out;
}

}  // namespace gsd
