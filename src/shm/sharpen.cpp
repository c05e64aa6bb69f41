// Distance sharpening on a grid: the program (sharpen.hpp), its CPU loop, and the public
// sharpen_distance that runs it on the chosen device.
#include "shm/sharpen.hpp"

#include "gpu/on_device.hpp"
#include "shm/diffuse.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <array>
#include <limits>
#include <unordered_map>

namespace gsd {

namespace shm {

namespace {

// The objective's weight against the constraints (PDLP's primal weight: only the ratio of the
// primal and dual steps matters, and this sets it). Measured on closed and broken meshes at
// 32³–64³: with 1, φ runs several cells past the distance before the dual has grown the flow that
// holds it; with 0.01 it crawls toward it; 0.3 halves the error of an SHM φ₀ within 24n
// iterations.
constexpr float kObjectiveWeight = 0.3f;
// Iterations between restarts, per node along the grid's longest axis: the dual has to carry
// the objective across the grid, and a restart before it has done so averages too little.
constexpr int kRestartPerNode = 6;

// Node strides of storage order (GridSpec: index = (i·ny + j)·nz + k).
std::array<std::size_t, 3> strides(const SharpenProblem& P) {
    return {std::size_t(P.n[1]) * std::size_t(P.n[2]), std::size_t(P.n[2]), 1};
}

// A cell's corners c = x + 2y + 4z (bit a: +1 along axis a) as offsets from its corner (0, 0, 0).
std::array<std::size_t, 8> corners(const SharpenProblem& P) {
    const auto st = strides(P);
    std::array<std::size_t, 8> c{};
    for (std::size_t k = 0; k < 8; ++k) c[k] = (k & 1 ? st[0] : 0) + (k & 2 ? st[1] : 0) + (k & 4 ? st[2] : 0);
    return c;
}

// The zero set's rows: the source sampled at the grid's spacing, each sample's trilinear weights
// added (area-weighted) to the row of the cell it falls in; rows normalized to sum 1.
void build_rows(SharpenProblem& P, const GridSpec& grid, const ShmSource& source) {
    const double cell = grid.box.extent().maxCoeff() / double(std::max({grid.nx, grid.ny, grid.nz}) - 1);
    const auto st = strides(P);
    std::unordered_map<std::uint64_t, std::uint32_t> row_of;
    std::vector<double> acc;  // 8 per row
    for_each_sample(source, 0.5 * cell, grid.box, [&](const Eigen::Vector3d& x, double area) {
        if (!(area > 0)) return;
        std::size_t base = 0;
        double t[3];
        for (int a = 0; a < 3; ++a) {
            const double u = (x[a] - grid.box.lo[a]) / grid.box.extent()[a] * (P.n[a] - 1);
            const int b = std::clamp(int(u), 0, P.n[a] - 2);
            t[a] = std::clamp(u - b, 0.0, 1.0);
            base += std::size_t(b) * st[std::size_t(a)];
        }
        const auto [it, added] = row_of.try_emplace(base, std::uint32_t(P.row_cell.size()));
        if (added) {
            P.row_cell.push_back(std::uint32_t(base));
            acc.resize(acc.size() + 8, 0.0);
        }
        double* w = &acc[8 * std::size_t(it->second)];
        for (int c = 0; c < 8; ++c)
            w[c] += area * ((c & 1) ? t[0] : 1 - t[0]) * ((c & 2) ? t[1] : 1 - t[1]) * ((c & 4) ? t[2] : 1 - t[2]);
    });
    if (P.row_cell.empty()) throw Error("sharpen", "the source lies outside the grid's bounds");
    P.row_weight.resize(acc.size());
    for (std::size_t r = 0; r < P.row_cell.size(); ++r) {
        double sum = 0;
        for (int c = 0; c < 8; ++c) sum += acc[8 * r + std::size_t(c)];
        for (int c = 0; c < 8; ++c) P.row_weight[8 * r + std::size_t(c)] = float(acc[8 * r + std::size_t(c)] / sum);
    }
}

// Pᵀ as lists per node (the primal step gathers instead of scattering).
void build_columns(SharpenProblem& P) {
    const auto corner = corners(P);
    std::vector<std::uint32_t> count(P.nodes() + 1, 0);
    for (std::size_t r = 0; r < P.row_cell.size(); ++r)
        for (int c = 0; c < 8; ++c) count[P.row_cell[r] + corner[c] + 1]++;
    for (std::size_t i = 0; i < P.nodes(); ++i) count[i + 1] += count[i];
    P.node_first = count;
    P.entry_row.resize(count.back());
    P.entry_weight.resize(count.back());
    std::vector<std::uint32_t> fill(count.begin(), count.end() - 1);
    for (std::size_t r = 0; r < P.row_cell.size(); ++r)
        for (int c = 0; c < 8; ++c) {
            const std::uint32_t e = fill[P.row_cell[r] + corner[c]]++;
            P.entry_row[e] = std::uint32_t(r);
            P.entry_weight[e] = P.row_weight[8 * r + std::size_t(c)];
        }
}

}  // namespace

SharpenProblem build_sharpen_problem(const GridSpec& grid, std::span<const float> phi0, const ShmSource& source,
                                     const SharpenOptions& options) {
    SharpenProblem P;
    P.n[0] = grid.nx, P.n[1] = grid.ny, P.n[2] = grid.nz;
    double h_min = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
        const double h = grid.box.extent()[a] / double(P.n[a] - 1);
        P.inv_h[a] = float(1 / h);
        h_min = std::min(h_min, h);
    }
    // Diagonal preconditioning (Pock & Chambolle 2011, α = 1): a block's dual step is 1 over its
    // rows' largest absolute sum, a node's primal step 1 over its column's. D's rows hold ±1/h_a;
    // P's rows are scaled by β = 1/h_min so that both kinds of row speak in slopes.
    P.sigma_d = float(h_min / 2);
    P.row_scale = float(1 / h_min);
    const double sigma_q = h_min;  // 1 / (β · row sum 1)
    P.damping = options.zero_set_weight > 0 ? float(1 / (1 + sigma_q / options.zero_set_weight)) : 1.0f;
    P.sign_floor = options.keep_sign ? float(1e-4 * h_min) : 0.0f;
    P.restart = kRestartPerNode * std::max({grid.nx, grid.ny, grid.nz});
    build_rows(P, grid, source);
    build_columns(P);
    const std::size_t nodes = P.nodes();
    P.tau.resize(nodes);
    P.sign.resize(nodes);
    const auto st = strides(P);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t ii = 0; ii < std::ptrdiff_t(nodes); ++ii) {
        const auto i = std::size_t(ii);
        double column = 0;
        for (int a = 0; a < 3; ++a) {
            const int c = int(i / st[std::size_t(a)] % std::size_t(P.n[a]));
            column += (double(c > 0) + double(c + 1 < P.n[a])) * P.inv_h[a];
        }
        for (std::uint32_t e = P.node_first[i]; e < P.node_first[i + 1]; ++e) column += P.row_scale * P.entry_weight[e];
        P.tau[i] = float(1 / column);
        const float v = phi0[i];
        P.sign[i] = v > 0 ? kObjectiveWeight : v < 0 ? -kObjectiveWeight : 0.0f;
    }
    return P;
}

SharpenState::SharpenState(std::span<const float> phi0, std::size_t rows)
    : phi(phi0.begin(), phi0.end()), phi_bar(phi), p(3 * phi.size(), 0.0f), q(rows, 0.0f), phi_sum(phi.size(), 0.0f),
      p_sum(p.size(), 0.0f), q_sum(rows, 0.0f) {}

namespace {

// One PDHG iteration; the device's kernels do the same per item, in the same float32 order.
void iterate(const SharpenProblem& P, bool keep_sign, SharpenState& S) {
    const auto st = strides(P);
    const auto corner = corners(P);
    const auto nodes = std::ptrdiff_t(P.nodes());
    const auto rows = std::ptrdiff_t(P.row_cell.size());
    // Dual (sharpen_dual.comp): the gradient blocks, p ← shrink(p + σ D φ̄), the projection's
    // complement; the zero-set rows, q ← (q + P φ̄)·damping.
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t ii = 0; ii < nodes; ++ii) {
        const auto i = std::size_t(ii);
        const float c = S.phi_bar[i];
        float v[3];
        for (std::size_t a = 0; a < 3; ++a) {
            const int k = int(i / st[a] % std::size_t(P.n[a]));
            const float g = k + 1 < P.n[a] ? (S.phi_bar[i + st[a]] - c) * P.inv_h[a] : 0.0f;
            v[a] = S.p[3 * i + a] + P.sigma_d * g;
        }
        const float len = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        const float keep = len > P.sigma_d ? 1.0f - P.sigma_d / len : 0.0f;
        for (std::size_t a = 0; a < 3; ++a) {
            const float w = v[a] * keep;
            S.p[3 * i + a] = w;
            S.p_sum[3 * i + a] += w;
        }
    }
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t rr = 0; rr < rows; ++rr) {
        const auto r = std::size_t(rr);
        float z = 0;
        for (std::size_t c = 0; c < 8; ++c) z += P.row_weight[8 * r + c] * S.phi_bar[P.row_cell[r] + corner[c]];
        const float w = (S.q[r] + z) * P.damping;
        S.q[r] = w;
        S.q_sum[r] += w;
    }
    // Primal (sharpen_primal.comp): φ − τ(Dᵀp + βPᵀq) + τs, bounded to φ₀'s side; φ̄ = 2φ_new − φ_old.
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t ii = 0; ii < nodes; ++ii) {
        const auto i = std::size_t(ii);
        float div = 0;
        for (std::size_t a = 0; a < 3; ++a) {
            const int k = int(i / st[a] % std::size_t(P.n[a]));
            const float prev = k > 0 ? S.p[3 * (i - st[a]) + a] : 0.0f;
            div += (prev - S.p[3 * i + a]) * P.inv_h[a];
        }
        float pq = 0;
        for (std::uint32_t e = P.node_first[i]; e < P.node_first[i + 1]; ++e) pq += P.entry_weight[e] * S.q[P.entry_row[e]];
        const float old = S.phi[i], s = P.sign[i], tau = P.tau[i];
        float v = old - tau * (div + P.row_scale * pq) + tau * s;
        if (keep_sign) v = s > 0 ? std::max(v, P.sign_floor) : s < 0 ? std::min(v, -P.sign_floor) : v;
        S.phi_bar[i] = 2 * v - old;
        S.phi[i] = v;
        S.phi_sum[i] += v;
    }
}

// A restart to the average (sharpen_restart.comp).
void restart(SharpenState& S) {
    const float inv = 1.0f / float(S.summed);
    const auto nodes = std::ptrdiff_t(S.phi.size());
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t ii = 0; ii < nodes; ++ii) {
        const auto i = std::size_t(ii);
        S.phi[i] = S.phi_bar[i] = S.phi_sum[i] * inv;
        S.phi_sum[i] = 0;
        for (std::size_t a = 0; a < 3; ++a) S.p[3 * i + a] = S.p_sum[3 * i + a] * inv, S.p_sum[3 * i + a] = 0;
    }
    for (std::size_t r = 0; r < S.q.size(); ++r) S.q[r] = S.q_sum[r] * inv, S.q_sum[r] = 0;
    S.summed = 0;
}

}  // namespace

void sharpen_cpu(const SharpenProblem& P, bool keep_sign, SharpenState& S, int iterations, const ProgressFn& progress) {
    for (int it = 0; it < iterations; ++it) {
        iterate(P, keep_sign, S);
        if (++S.summed == P.restart) restart(S);
        if (progress && (it % 16 == 15 || it + 1 == iterations)) progress("sharpen", double(it + 1) / iterations);
    }
}

}  // namespace shm

namespace {

void slope_stats(const GridSpec& g, const std::vector<float>& phi, SharpenResult& out) {
    const std::size_t st[3] = {std::size_t(g.ny) * std::size_t(g.nz), std::size_t(g.nz), 1};
    const int n[3] = {g.nx, g.ny, g.nz};
    double inv_h[3];
    for (int a = 0; a < 3; ++a) inv_h[a] = (n[a] - 1) / g.box.extent()[a];
    double max_slope = 0, excess = 0;
    const auto nodes = std::ptrdiff_t(phi.size());
#pragma omp parallel for schedule(static) reduction(max : max_slope) reduction(+ : excess)
    for (std::ptrdiff_t ii = 0; ii < nodes; ++ii) {
        const auto i = std::size_t(ii);
        double s2 = 0;
        for (int a = 0; a < 3; ++a) {
            const int k = int(i / st[a] % std::size_t(n[a]));
            if (k + 1 < n[a]) {
                const double d = (double(phi[i + st[a]]) - phi[i]) * inv_h[a];
                s2 += d * d;
            }
        }
        const double s = std::sqrt(s2);
        max_slope = std::max(max_slope, s);
        excess += std::max(s - 1, 0.0);
    }
    out.max_slope = max_slope;
    out.mean_excess_slope = excess / double(phi.size());
}

}  // namespace

SharpenResult sharpen_distance(const GridSpec& grid, std::span<const float> phi0, const ShmSource& source,
                               const SharpenOptions& options, const ProgressFn& progress) {
    const auto t0 = std::chrono::steady_clock::now();
    grid.validate();
    if (phi0.size() != grid.node_count())
        throw Error("sharpen", "φ₀ has " + std::to_string(phi0.size()) + " values for a grid of " +
                                   std::to_string(grid.node_count()) + " nodes");
    for (std::size_t i = 0; i < phi0.size(); ++i)
        if (!std::isfinite(phi0[i])) throw Error("sharpen", "φ₀ is not finite at node " + std::to_string(i));
    if (options.iterations < 0) throw Error("SharpenOptions::iterations", "iterations must be ≥ 0 (0: automatic)");
    if (!(options.zero_set_weight >= 0) || !std::isfinite(options.zero_set_weight))
        throw Error("SharpenOptions::zero_set_weight", "the zero-set weight must be finite and ≥ 0 (0: exact)");
    if (source.size() == 0) throw Error("sharpen", "the source is empty");
    source.elements.validate();
    check_memory(double(grid.node_count()) * 40.0, "sharpen", "sharpening a " + std::to_string(grid.node_count()) + "-node grid");

    const shm::SharpenProblem problem = shm::build_sharpen_problem(grid, phi0, source, options);
    const int iterations = options.iterations > 0 ? options.iterations : 4 * problem.restart;
    shm::SharpenState state(phi0, problem.row_cell.size());

    SharpenResult out;
    const gpu::DeviceRun run = gpu::on_device(options.device, [&](const auto& ctx, std::string& why_not) {
        return shm::sharpen_gpu(ctx, problem, options.keep_sign, state, iterations, progress, why_not);
    }, "; sharpening on the CPU");
    if (!run) shm::sharpen_cpu(problem, options.keep_sign, state, iterations, progress);
    out.device = run ? run.device : "cpu";
    out.iterations = iterations;
    out.zero_set_rows = problem.row_cell.size();
    for (std::size_t i = 0; i < phi0.size(); ++i) out.sign_changes += (phi0[i] < 0) != (state.phi[i] < 0);
    slope_stats(grid, state.phi, out);
    out.phi = std::move(state.phi);
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return out;
}

}  // namespace gsd
