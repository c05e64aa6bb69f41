// Step 3 of the adaptive SHM on the octree (shm/octree_poisson.hpp).
#include "shm/octree_poisson.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/Sparse>

#include <algorithm>
#include <chrono>
#include <cmath>

namespace gsd::shm {

namespace {

using SpMat = Eigen::SparseMatrix<double, Eigen::RowMajor>;
using Vec = Eigen::VectorXd;

/// Levels with at most this many nodes are factored (CHOLMOD) instead of cycled through.
constexpr std::size_t kDirectNodes = 30000;
/// Gauss–Seidel sweeps before (forward) and after (backward) the coarse correction: the
/// V-cycle is then a symmetric operator, as CG's preconditioner must be.
constexpr int kSweeps = 2;

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The samples' trilinear weights on a level: S (samples × nodes).
SpMat sample_matrix(const Octree& tree, const NodeGraph& g, const std::vector<ZeroSample>& samples) {
    std::vector<Eigen::Triplet<double>> t;
    t.reserve(8 * samples.size());
    for (std::size_t j = 0; j < samples.size(); ++j) {
        std::int32_t node[27];
        double w[27];
        const int n = interpolation_weights(tree, g, tree.to_lattice(samples[j].position), node, w);
        for (int c = 0; c < n; ++c)
            if (w[c] != 0) t.emplace_back(Eigen::Index(j), node[c], w[c]);
    }
    SpMat S(Eigen::Index(samples.size()), Eigen::Index(g.size()));
    S.setFromTriplets(t.begin(), t.end());
    return S;
}

// L (Σ_segments V/ℓ² (e_i − e_j)(e_i − e_j)ᵀ) + μ SᵀAS.
SpMat level_operator(const NodeGraph& g, double h, const SpMat& S, const Vec& area, double mu) {
    std::vector<Eigen::Triplet<double>> t;
    t.reserve(12 * g.size());
    for (std::size_t i = 0; i < g.size(); ++i) {
        const auto p = unmorton3(g.keys[i]);
        for (int a = 0; a < 3; ++a) {
            const std::int32_t j = g.next[i][std::size_t(a)];
            if (j < 0) continue;
            const auto q = unmorton3(g.keys[std::size_t(j)]);
            const double len = double(q[std::size_t(a)] - p[std::size_t(a)]) * h;
            const double w = g.volume[i][std::size_t(a)] / (len * len);
            const auto ii = Eigen::Index(i), jj = Eigen::Index(j);
            t.emplace_back(ii, ii, w);
            t.emplace_back(jj, jj, w);
            t.emplace_back(ii, jj, -w);
            t.emplace_back(jj, ii, -w);
        }
    }
    SpMat L(Eigen::Index(g.size()), Eigen::Index(g.size()));
    L.setFromTriplets(t.begin(), t.end());
    const SpMat penalty = SpMat(S.transpose() * (mu * area).asDiagonal() * S);
    return SpMat(L + penalty);
}

// Prolongation from `coarse` to `fine` (fine nodes × coarse nodes): a node both levels share
// keeps its value; a new one takes the trilinear value of the coarse leaf that holds it.
SpMat prolongation(const Octree& tree, const NodeGraph& fine, const NodeGraph& coarse) {
    std::vector<Eigen::Triplet<double>> t;
    t.reserve(2 * fine.size());
    for (std::size_t i = 0; i < fine.size(); ++i) {
        const std::ptrdiff_t same = coarse.find(fine.keys[i]);
        if (same >= 0) {
            t.emplace_back(Eigen::Index(i), Eigen::Index(same), 1.0);
            continue;
        }
        const auto p = unmorton3(fine.keys[i]);
        std::int32_t node[27];
        double w[27];
        const int n = interpolation_weights(tree, coarse, Eigen::Vector3d(double(p[0]), double(p[1]), double(p[2])), node, w);
        for (int c = 0; c < n; ++c)
            if (w[c] != 0) t.emplace_back(Eigen::Index(i), node[c], w[c]);
    }
    SpMat P(Eigen::Index(fine.size()), Eigen::Index(coarse.size()));
    P.setFromTriplets(t.begin(), t.end());
    return P;
}

}  // namespace

struct OctreePoisson::Impl {
    struct Level {
        NodeGraph graph;
        SpMat A;
        Vec diagonal;
        SpMat P;  // to the next (coarser) level; empty on the coarsest
    };
    const Octree& tree;
    std::vector<ZeroSample> samples;
    Vec area;
    SpMat S;  // the samples on the finest level
    std::vector<Level> levels;
    Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> coarsest;

    void gauss_seidel(const Level& lv, const Vec& b, Vec& x, bool forward) const {
        const Eigen::Index n = lv.A.rows();
        for (Eigen::Index s = 0; s < n; ++s) {
            const Eigen::Index i = forward ? s : n - 1 - s;
            double sum = b[i];
            for (SpMat::InnerIterator it(lv.A, i); it; ++it)
                if (it.col() != i) sum -= it.value() * x[it.col()];
            x[i] = sum / lv.diagonal[i];
        }
    }

    void vcycle(std::size_t k, const Vec& b, Vec& x) const {
        const Level& lv = levels[k];
        if (k + 1 == levels.size()) {
            x = coarsest.solve(b);
            return;
        }
        x.setZero(b.size());
        for (int s = 0; s < kSweeps; ++s) gauss_seidel(lv, b, x, true);
        const Vec r = b - lv.A * x;
        const Vec rc = lv.P.transpose() * r;
        Vec ec;
        vcycle(k + 1, rc, ec);
        x += lv.P * ec;
        for (int s = 0; s < kSweeps; ++s) gauss_seidel(lv, b, x, false);
    }
};

OctreePoisson::OctreePoisson(const Octree& tree, std::vector<ZeroSample> samples, double penalty)
    : impl_(new Impl{tree, std::move(samples), {}, {}, {}, {}}) {
    Impl& m = *impl_;
    if (m.samples.empty()) throw Error("the source lies outside the adaptive grid's bounds");
    if (!(penalty > 0)) throw Error("OctreePoisson: the penalty must be > 0");
    m.area.resize(Eigen::Index(m.samples.size()));
    for (std::size_t j = 0; j < m.samples.size(); ++j) m.area[Eigen::Index(j)] = m.samples[j].area;
    const double h = tree.lattice_step();
    for (int level = tree.depth();; --level) {
        Impl::Level lv;
        lv.graph = build_node_graph(tree, level);
        const SpMat S = sample_matrix(tree, lv.graph, m.samples);
        lv.A = level_operator(lv.graph, h, S, m.area, penalty);
        lv.diagonal = lv.A.diagonal();
        if (m.levels.empty()) m.S = S;
        if (!m.levels.empty()) m.levels.back().P = prolongation(tree, m.levels.back().graph, lv.graph);
        const bool last = lv.graph.size() <= kDirectNodes || level == 0;
        m.levels.push_back(std::move(lv));
        if (last) break;
    }
    const Eigen::SparseMatrix<double> Ac = m.levels.back().A;  // column-major for CHOLMOD
    m.coarsest.compute(Ac);
    if (m.coarsest.info() != Eigen::Success) throw Error("the adaptive grid's coarsest Poisson matrix could not be factored");
}

OctreePoisson::~OctreePoisson() = default;

const NodeGraph& OctreePoisson::nodes() const { return impl_->levels.front().graph; }

std::vector<double> OctreePoisson::divergence(const std::vector<float>& Y) const {
    const NodeGraph& g = nodes();
    if (Y.size() != 3 * g.size()) throw Error("divergence: the field needs 3 values per node");
    const double h = impl_->tree.lattice_step();
    std::vector<double> b(g.size(), 0.0);
    // Segment (i, j) along axis a carries Ȳ_a, the mean of its ends: −VȲ_a/ℓ to b_i, +VȲ_a/ℓ to
    // b_j (the normal equations of Σ V((φ_j − φ_i)/ℓ − Ȳ_a)²).
    for (std::size_t i = 0; i < g.size(); ++i) {
        const auto p = unmorton3(g.keys[i]);
        for (int a = 0; a < 3; ++a) {
            const std::int32_t j = g.next[i][std::size_t(a)];
            if (j < 0) continue;
            const auto q = unmorton3(g.keys[std::size_t(j)]);
            const double len = double(q[std::size_t(a)] - p[std::size_t(a)]) * h;
            const double ybar = 0.5 * (double(Y[3 * i + std::size_t(a)]) + double(Y[3 * std::size_t(j) + std::size_t(a)]));
            const double flux = g.volume[i][std::size_t(a)] * ybar / len;
            b[i] -= flux;
            b[std::size_t(j)] += flux;
        }
    }
    return b;
}

std::vector<double> OctreePoisson::apply(const std::vector<double>& x) const {
    const Vec y = impl_->levels.front().A * Eigen::Map<const Vec>(x.data(), Eigen::Index(x.size()));
    return std::vector<double>(y.data(), y.data() + y.size());
}

double OctreePoisson::mean_on_samples(const std::vector<double>& phi) const {
    const Vec v = impl_->S * Eigen::Map<const Vec>(phi.data(), Eigen::Index(phi.size()));
    return v.dot(impl_->area) / impl_->area.sum();
}

std::vector<double> OctreePoisson::solve(const std::vector<double>& b_in, double tolerance, int max_iterations,
                                         OctreePoissonStats& stats, const ProgressFn& progress) const {
    const Impl& m = *impl_;
    for (const auto& lv : m.levels) stats.level_nodes.push_back(lv.graph.size());
    const auto t0 = std::chrono::steady_clock::now();
    const Eigen::Map<const Vec> b(b_in.data(), Eigen::Index(b_in.size()));
    const SpMat& A = m.levels.front().A;
    Vec x = Vec::Zero(b.size());
    if (m.levels.size() == 1) {  // small enough to factor: exact
        x = m.coarsest.solve(b);
        const double bn = b.norm();
        stats.residual_history.push_back(bn > 0 ? (b - A * x).norm() / bn : 0.0);
    } else {
        Vec r = b, z, p, Ap;
        const double bn = b.norm();
        m.vcycle(0, r, z);
        p = z;
        double rz = r.dot(z);
        for (int it = 0; it < max_iterations && bn > 0; ++it) {
            Ap = A * p;
            const double alpha = rz / p.dot(Ap);
            x += alpha * p;
            r -= alpha * Ap;
            const double rel = r.norm() / bn;
            stats.residual_history.push_back(rel);
            if (progress) progress("solve", std::clamp(std::log(std::max(rel, 1e-300)) / std::log(tolerance), 0.0, 1.0));
            if (rel <= tolerance) break;
            m.vcycle(0, r, z);
            const double rz_new = r.dot(z);
            p = z + (rz_new / rz) * p;
            rz = rz_new;
        }
    }
    stats.seconds_solve = seconds_since(t0);
    return std::vector<double>(x.data(), x.data() + x.size());
}

}  // namespace gsd::shm
