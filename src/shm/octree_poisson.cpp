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

using Entries = std::vector<std::pair<std::int32_t, double>>;

// A row-major sparse matrix from a function that appends row i's entries (any order, repeats
// added): rows computed in parallel blocks, repeats merged through a per-thread slot per
// column (a row of the operator gathers hundreds of sample products onto a few dozen columns),
// then laid out in order. No triplet list: the matrix's own arrays are the only copy.
template <class RowFn>
SpMat rows_to_matrix(std::size_t rows, std::size_t cols, RowFn&& row) {
    constexpr std::size_t kBlock = 4096;
    const std::size_t blocks = (rows + kBlock - 1) / kBlock;
    std::vector<std::vector<std::int32_t>> count(blocks), index(blocks);
    std::vector<std::vector<double>> value(blocks);
#pragma omp parallel
    {
        Entries e, merged;
        std::vector<std::int32_t> slot(cols, -1);
#pragma omp for schedule(dynamic, 1)
        for (std::size_t b = 0; b < blocks; ++b) {
            for (std::size_t i = b * kBlock; i < std::min(rows, (b + 1) * kBlock); ++i) {
                e.clear();
                merged.clear();
                row(i, e);
                for (const auto& [col, v] : e) {
                    std::int32_t& at = slot[std::size_t(col)];
                    if (at < 0) {
                        at = std::int32_t(merged.size());
                        merged.emplace_back(col, v);
                    } else {
                        merged[std::size_t(at)].second += v;
                    }
                }
                for (const auto& m : merged) slot[std::size_t(m.first)] = -1;
                std::sort(merged.begin(), merged.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
                for (const auto& [col, v] : merged) {
                    index[b].push_back(col);
                    value[b].push_back(v);
                }
                count[b].push_back(std::int32_t(merged.size()));
            }
        }
    }
    SpMat M{Eigen::Index(rows), Eigen::Index(cols)};
    std::size_t nnz = 0;
    for (const auto& v : index) nnz += v.size();
    M.resizeNonZeros(Eigen::Index(nnz));
    std::size_t at = 0, r = 0;
    for (std::size_t b = 0; b < blocks; ++b) {
        std::copy(index[b].begin(), index[b].end(), M.innerIndexPtr() + at);
        std::copy(value[b].begin(), value[b].end(), M.valuePtr() + at);
        for (const std::int32_t n : count[b]) {
            M.outerIndexPtr()[r++] = int(at);
            at += std::size_t(n);
        }
    }
    M.outerIndexPtr()[rows] = int(at);
    return M;
}

// The samples' interpolation weights on a level: S (samples × nodes).
SpMat sample_matrix(const Octree& tree, const NodeGraph& g, const std::vector<ZeroSample>& samples) {
    return rows_to_matrix(samples.size(), g.size(), [&](std::size_t j, Entries& e) {
        std::int32_t node[27];
        double w[27];
        const int n = interpolation_weights(tree, g, tree.to_lattice(samples[j].position), node, w);
        for (int c = 0; c < n; ++c)
            if (w[c] != 0) e.emplace_back(node[c], w[c]);
    });
}

// Prolongation from `coarse` to `fine` (fine nodes × coarse nodes): a node both levels share
// keeps its value; a new one takes the coarse level's interpolated value there.
SpMat prolongation(const Octree& tree, const NodeGraph& fine, const NodeGraph& coarse) {
    return rows_to_matrix(fine.size(), coarse.size(), [&](std::size_t i, Entries& e) {
        const std::ptrdiff_t same = coarse.find(fine.keys[i]);
        if (same >= 0) {
            e.emplace_back(std::int32_t(same), 1.0);
            return;
        }
        const auto p = unmorton3(fine.keys[i]);
        std::int32_t node[27];
        double w[27];
        const int n = interpolation_weights(tree, coarse, Eigen::Vector3d(double(p[0]), double(p[1]), double(p[2])), node, w);
        for (int c = 0; c < n; ++c)
            if (w[c] != 0) e.emplace_back(node[c], w[c]);
    });
}

}  // namespace

struct OctreePoisson::Impl {
    // A multigrid level, matrix-free: the operator is applied from its node graph (segments
    // along ±axis, each with its weight V/ℓ²) and the samples' interpolation rows, so a node
    // costs its graph and a share of the samples instead of a row of ~20 stored products.
    struct Level {
        NodeGraph graph;  // keys and next (the volumes are folded into `weight`)
        std::vector<std::array<std::int32_t, 3>> prev;  // the node whose next this one is, per axis
        std::vector<std::array<double, 3>> weight;      // V/ℓ² of the segment (i, next[i][a])
        SpMat S, St;                                    // samples × nodes and its transpose
        Vec diagonal;
        SpMat P;  // to the next (coarser) level; empty on the coarsest
    };
    const Octree& tree;
    std::vector<ZeroSample> samples;
    Vec area;   // μ·A_j per sample
    double mu = 0;
    std::vector<Level> levels;
    Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> coarsest;

    Level make_level(int level) const {
        Level lv;
        lv.graph = build_node_graph(tree, level);
        const NodeGraph& g = lv.graph;
        const std::size_t n = g.size();
        const double h = tree.lattice_step();
        lv.prev.assign(n, {-1, -1, -1});
        lv.weight.assign(n, {0.0, 0.0, 0.0});
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(n); ++i) {
            const auto p = unmorton3(g.keys[std::size_t(i)]);
            for (int a = 0; a < 3; ++a) {
                const std::int32_t j = g.next[std::size_t(i)][std::size_t(a)];
                if (j < 0) continue;
                lv.prev[std::size_t(j)][std::size_t(a)] = std::int32_t(i);
                const double len = double(unmorton3(g.keys[std::size_t(j)])[std::size_t(a)] - p[std::size_t(a)]) * h;
                lv.weight[std::size_t(i)][std::size_t(a)] = g.volume[std::size_t(i)][std::size_t(a)] / (len * len);
            }
        }
        std::vector<std::array<double, 3>>().swap(lv.graph.volume);
        lv.S = sample_matrix(tree, g, samples);
        lv.St = lv.S.transpose();
        lv.diagonal.resize(Eigen::Index(n));
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(n); ++i) {
            double d = 0;
            for (int a = 0; a < 3; ++a) {
                d += lv.weight[std::size_t(i)][std::size_t(a)];
                if (const std::int32_t j = lv.prev[std::size_t(i)][std::size_t(a)]; j >= 0) d += lv.weight[std::size_t(j)][std::size_t(a)];
            }
            for (SpMat::InnerIterator s(lv.St, i); s; ++s) d += area[s.col()] * s.value() * s.value();
            lv.diagonal[i] = d;
        }
        return lv;
    }

    // The level's operator assembled (the coarsest, for CHOLMOD): L + SᵀAS.
    Eigen::SparseMatrix<double> assemble(const Level& lv) const {
        const std::size_t n = lv.graph.size();
        return Eigen::SparseMatrix<double>(rows_to_matrix(n, n, [&](std::size_t i, Entries& e) {
            for (int a = 0; a < 3; ++a) {
                if (const std::int32_t j = lv.graph.next[i][std::size_t(a)]; j >= 0) e.emplace_back(j, -lv.weight[i][std::size_t(a)]);
                if (const std::int32_t j = lv.prev[i][std::size_t(a)]; j >= 0) e.emplace_back(j, -lv.weight[std::size_t(j)][std::size_t(a)]);
            }
            for (SpMat::InnerIterator s(lv.St, Eigen::Index(i)); s; ++s) {
                const double f = area[s.col()] * s.value();
                for (SpMat::InnerIterator k(lv.S, s.col()); k; ++k)
                    if (k.col() != Eigen::Index(i)) e.emplace_back(std::int32_t(k.col()), f * k.value());
            }
            e.emplace_back(std::int32_t(i), lv.diagonal[Eigen::Index(i)]);  // L's and the penalty's
        }));
    }

    void apply(const Level& lv, const Vec& x, Vec& y) const {
        const auto n = std::ptrdiff_t(lv.graph.size());
        y.resize(n);
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t i = 0; i < n; ++i) {
            const double xi = x[i];
            double v = 0;
            for (int a = 0; a < 3; ++a) {
                if (const std::int32_t j = lv.graph.next[std::size_t(i)][std::size_t(a)]; j >= 0)
                    v += lv.weight[std::size_t(i)][std::size_t(a)] * (xi - x[j]);
                if (const std::int32_t j = lv.prev[std::size_t(i)][std::size_t(a)]; j >= 0)
                    v += lv.weight[std::size_t(j)][std::size_t(a)] * (xi - x[j]);
            }
            y[i] = v;
        }
        const Vec t = area.cwiseProduct(lv.S * x);
        y += lv.St * t;
    }

    // One Gauss–Seidel sweep. t = S x on entry and on return: the samples' values follow each
    // node's update, so a node's penalty row costs its samples, not their products.
    void gauss_seidel(const Level& lv, const Vec& b, Vec& x, Vec& t, bool forward) const {
        const auto n = std::ptrdiff_t(lv.graph.size());
        for (std::ptrdiff_t s = 0; s < n; ++s) {
            const std::ptrdiff_t i = forward ? s : n - 1 - s;
            const double xi = x[i];
            double sum = b[i];
            for (int a = 0; a < 3; ++a) {
                if (const std::int32_t j = lv.graph.next[std::size_t(i)][std::size_t(a)]; j >= 0)
                    sum += lv.weight[std::size_t(i)][std::size_t(a)] * x[j];
                if (const std::int32_t j = lv.prev[std::size_t(i)][std::size_t(a)]; j >= 0)
                    sum += lv.weight[std::size_t(j)][std::size_t(a)] * x[j];
            }
            for (SpMat::InnerIterator k(lv.St, i); k; ++k) sum -= area[k.col()] * k.value() * (t[k.col()] - k.value() * xi);
            const double updated = sum / lv.diagonal[i];
            const double delta = updated - xi;
            x[i] = updated;
            for (SpMat::InnerIterator k(lv.St, i); k; ++k) t[k.col()] += k.value() * delta;
        }
    }

    void vcycle(std::size_t k, const Vec& b, Vec& x) const {
        const Level& lv = levels[k];
        if (k + 1 == levels.size()) {
            x = coarsest.solve(b);
            return;
        }
        x.setZero(b.size());
        Vec t = Vec::Zero(lv.S.rows());
        for (int s = 0; s < kSweeps; ++s) gauss_seidel(lv, b, x, t, true);
        Vec Ax;
        apply(lv, x, Ax);
        const Vec rc = lv.P.transpose() * (b - Ax);
        Vec ec;
        vcycle(k + 1, rc, ec);
        x += lv.P * ec;
        t = lv.S * x;
        for (int s = 0; s < kSweeps; ++s) gauss_seidel(lv, b, x, t, false);
    }
};

OctreePoisson::OctreePoisson(const Octree& tree, std::vector<ZeroSample> samples, double penalty)
    : impl_(new Impl{tree, std::move(samples), {}, penalty, {}, {}}) {
    Impl& m = *impl_;
    if (m.samples.empty()) throw Error("the source lies outside the adaptive grid's bounds");
    if (!(penalty > 0)) throw Error("OctreePoisson: the penalty must be > 0");
    m.area.resize(Eigen::Index(m.samples.size()));
    for (std::size_t j = 0; j < m.samples.size(); ++j) m.area[Eigen::Index(j)] = penalty * m.samples[j].area;
    for (int level = tree.depth();; --level) {
        Impl::Level lv = m.make_level(level);
        if (!m.levels.empty()) m.levels.back().P = prolongation(tree, m.levels.back().graph, lv.graph);
        const bool last = lv.graph.size() <= kDirectNodes || level == 0;
        m.levels.push_back(std::move(lv));
        if (last) break;
    }
    m.coarsest.compute(m.assemble(m.levels.back()));
    if (m.coarsest.info() != Eigen::Success) throw Error("the adaptive grid's coarsest Poisson matrix could not be factored");
}

OctreePoisson::~OctreePoisson() = default;

const NodeGraph& OctreePoisson::nodes() const { return impl_->levels.front().graph; }

std::vector<double> OctreePoisson::divergence(const std::vector<float>& Y) const {
    const Impl::Level& lv = impl_->levels.front();
    const NodeGraph& g = lv.graph;
    if (Y.size() != 3 * g.size()) throw Error("divergence: the field needs 3 values per node");
    const double h = impl_->tree.lattice_step();
    std::vector<double> b(g.size(), 0.0);
    // Segment (i, j) along axis a carries Ȳ_a, the mean of its ends: −VȲ_a/ℓ to b_i, +VȲ_a/ℓ to
    // b_j (the normal equations of Σ V((φ_j − φ_i)/ℓ − Ȳ_a)²; V/ℓ is the weight V/ℓ² times ℓ).
    // Each node gathers its two segments per axis, in parallel.
    auto flux = [&](std::size_t i, int a) {  // of the segment from i along +a
        const std::size_t j = std::size_t(g.next[i][std::size_t(a)]);
        const double len = double(unmorton3(g.keys[j])[std::size_t(a)] - unmorton3(g.keys[i])[std::size_t(a)]) * h;
        const double ybar = 0.5 * (double(Y[3 * i + std::size_t(a)]) + double(Y[3 * j + std::size_t(a)]));
        return lv.weight[i][std::size_t(a)] * len * ybar;
    };
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(g.size()); ++i) {
        double v = 0;
        for (int a = 0; a < 3; ++a) {
            if (const std::int32_t j = lv.prev[std::size_t(i)][std::size_t(a)]; j >= 0) v += flux(std::size_t(j), a);
            if (g.next[std::size_t(i)][std::size_t(a)] >= 0) v -= flux(std::size_t(i), a);
        }
        b[std::size_t(i)] = v;
    }
    return b;
}

std::vector<double> OctreePoisson::apply(const std::vector<double>& x) const {
    Vec y;
    impl_->apply(impl_->levels.front(), Eigen::Map<const Vec>(x.data(), Eigen::Index(x.size())), y);
    return std::vector<double>(y.data(), y.data() + y.size());
}

double OctreePoisson::mean_on_samples(const std::vector<double>& phi) const {
    const Impl& m = *impl_;
    const Vec v = m.levels.front().S * Eigen::Map<const Vec>(phi.data(), Eigen::Index(phi.size()));
    return v.dot(m.area) / m.area.sum();
}

std::vector<double> OctreePoisson::solve(const std::vector<double>& b_in, double tolerance, int max_iterations,
                                         OctreePoissonStats& stats, const ProgressFn& progress) const {
    const Impl& m = *impl_;
    for (const auto& lv : m.levels) stats.level_nodes.push_back(lv.graph.size());
    const auto t0 = std::chrono::steady_clock::now();
    const Eigen::Map<const Vec> b(b_in.data(), Eigen::Index(b_in.size()));
    const Impl::Level& top = m.levels.front();
    Vec x = Vec::Zero(b.size());
    const double bn = b.norm();
    if (m.levels.size() == 1) {  // small enough to factor: exact
        x = m.coarsest.solve(b);
        Vec Ax;
        m.apply(top, x, Ax);
        stats.residual_history.push_back(bn > 0 ? (b - Ax).norm() / bn : 0.0);
    } else {
        Vec r = b, z, p, Ap;
        m.vcycle(0, r, z);
        p = z;
        double rz = r.dot(z);
        for (int it = 0; it < max_iterations && bn > 0; ++it) {
            m.apply(top, p, Ap);
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
