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
using VecF = Eigen::VectorXf;

/// Levels with at most this many nodes are factored (CHOLMOD) instead of cycled through.
constexpr std::size_t kDirectNodes = 30000;
/// Gauss–Seidel sweeps before (forward) and after (backward) the coarse correction: the
/// V-cycle is then a symmetric operator, as CG's preconditioner must be.
constexpr int kSweeps = 2;
/// With no penalty (μ = 0) the Laplacian alone would leave the constant free: each diagonal is
/// raised by this fraction instead, which pins it (the caller shifts φ after) and perturbs the
/// rest by about as little, while the operator stays as sparse as the Laplacian.
constexpr double kPin = 1e-9;
/// How many axes a Prolongation off-byte (three bits) names: std::popcount is a libgcc call
/// on CPUs the build does not assume POPCNT on, and the transfers ask it of every node.
constexpr int kAxesOff[8] = {0, 1, 1, 2, 1, 2, 2, 3};

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

// Gauss–Seidel's order on a level, such that both threads can sweep it. The level's nodes go
// by the cells of a coarser level (Morton-contiguous runs of nodes), the cells coloured like a
// checkerboard by the parity of i + j + k. A segment no longer than such a cell joins nodes of
// one cell or of two face-adjacent ones, which have opposite colours: so the runs of one colour
// are independent and are swept in parallel, then the other colour's. Nodes with a longer
// segment (corners of leaves coarser than the cells: the far field's few) are swept last, in
// turn. That is Gauss–Seidel in one fixed order whatever the threads, and the backward sweep is
// its exact reverse, so the V-cycle stays a symmetric preconditioner.
struct SweepOrder {
    /// Cells of the level this many levels coarser: up to 16³ nodes a run.
    static constexpr int kCoarser = 4;
    std::vector<std::uint32_t> runs[2];     // per colour: begin, end of each run, in turn
    std::vector<std::uint32_t> lone;        // nodes with a segment longer than a cell, ascending
    std::vector<std::uint64_t> lone_bits;   // a bit a node: in `lone`

    bool is_lone(std::size_t i) const { return lone_bits[i >> 6] >> (i & 63) & 1; }

    SweepOrder() = default;
    SweepOrder(const NodeGraph& g, int depth) {
        const int cell_shift = depth - std::max(0, g.level - kCoarser);  // lattice bits below a cell
        const std::uint32_t cell = std::uint32_t(1) << cell_shift;
        const std::size_t n = g.size();
        lone_bits.assign((n + 63) / 64, 0);
        // Each word of bits by one thread: node i is lone if one of its own segments is long.
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t w = 0; w < std::ptrdiff_t(lone_bits.size()); ++w) {
            std::uint64_t bits = 0;
            for (std::size_t i = std::size_t(w) * 64; i < std::min(n, std::size_t(w + 1) * 64); ++i) {
                bool long_segment = false;
                for (int a = 0; a < 3 && !long_segment; ++a) {
                    const std::uint32_t at = morton_coordinate(g.keys[i], a);
                    const std::int32_t up = g.next(i, a), down = g.prev(i, a);
                    long_segment = (up >= 0 && morton_coordinate(g.keys[std::size_t(up)], a) - at > cell) ||
                                   (down >= 0 && at - morton_coordinate(g.keys[std::size_t(down)], a) > cell);
                }
                if (long_segment) bits |= std::uint64_t(1) << (i & 63);
            }
            lone_bits[std::size_t(w)] = bits;
        }
        for (std::size_t i = 0; i < n; ++i)
            if (is_lone(i)) lone.push_back(std::uint32_t(i));
        for (std::size_t i = 0; i < n;) {
            const std::uint64_t code = g.keys[i] >> (3 * cell_shift);
            std::size_t j = i + 1;
            while (j < n && g.keys[j] >> (3 * cell_shift) == code) ++j;
            const auto c = unmorton3(code);
            auto& r = runs[(c[0] + c[1] + c[2]) & 1];
            r.push_back(std::uint32_t(i));
            r.push_back(std::uint32_t(j));
            i = j;
        }
    }

    // relax(i) for every node in the order (forward) or its reverse.
    template <class Relax>
    void sweep(bool forward, Relax&& relax) const {
        const auto colour = [&](int c) {
            const std::vector<std::uint32_t>& r = runs[c];
            const auto count = std::ptrdiff_t(r.size() / 2);
#pragma omp parallel for schedule(dynamic, 64)
            for (std::ptrdiff_t k = 0; k < count; ++k) {
                const std::size_t begin = r[2 * std::size_t(k)], end = r[2 * std::size_t(k) + 1];
                if (forward) {
                    for (std::size_t i = begin; i < end; ++i)
                        if (!is_lone(i)) relax(i);
                } else {
                    for (std::size_t i = end; i-- > begin;)
                        if (!is_lone(i)) relax(i);
                }
            }
        };
        if (forward) {
            colour(0);
            colour(1);
            for (const std::uint32_t i : lone) relax(i);
        } else {
            for (auto i = lone.rbegin(); i != lone.rend(); ++i) relax(*i);
            colour(1);
            colour(0);
        }
    }
};

}  // namespace

std::vector<ZeroSample> merge_by_cell(const Octree& tree, const std::vector<ZeroSample>& samples, int level,
                                      std::vector<std::uint32_t>* merged_into) {
    const int shift = tree.depth() - level;
    const double top = double(std::uint64_t(1) << tree.depth()) - 1;
    std::vector<std::pair<std::uint64_t, std::uint32_t>> order(samples.size());
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t j = 0; j < std::ptrdiff_t(samples.size()); ++j) {
        const Eigen::Vector3d u = tree.to_lattice(samples[std::size_t(j)].position);
        const auto cell = [&](int a) { return std::uint32_t(std::clamp(std::floor(u[a]), 0.0, top)) >> shift; };
        order[std::size_t(j)] = {morton3(cell(0), cell(1), cell(2)), std::uint32_t(j)};
    }
    std::sort(order.begin(), order.end());
    std::vector<ZeroSample> out;
    if (merged_into) merged_into->resize(samples.size());
    for (std::size_t i = 0; i < order.size();) {
        Eigen::Vector3d moment = Eigen::Vector3d::Zero();
        double area = 0;
        std::size_t j = i;
        for (; j < order.size() && order[j].first == order[i].first; ++j) {
            const ZeroSample& s = samples[order[j].second];
            moment += s.area * s.position;
            area += s.area;
            if (merged_into) (*merged_into)[order[j].second] = std::uint32_t(out.size());
        }
        out.push_back({area > 0 ? Eigen::Vector3d(moment / area) : samples[order[i].second].position, area});
        i = j;
    }
    return out;
}

namespace {
/// Fine nodes per block of the prolongation's shared-node count.
constexpr std::size_t kBlock = 4096;
}  // namespace

unsigned Prolongation::off_axes(const NodeGraph& fine, std::size_t i) const {
    const auto p = unmorton3(fine.keys[i]);
    const std::uint32_t mask = 2 * half_ - 1;  // the coarse lattice's step is 2·half_, a power of two
    return unsigned((p[0] & mask) != 0) | unsigned((p[1] & mask) != 0) << 1 | unsigned((p[2] & mask) != 0) << 2;
}

Prolongation::Prolongation(const Octree& tree, const NodeGraph& fine, const NodeGraph& coarse) : fine_size_(fine.size()) {
    if (coarse.level + 1 != fine.level || coarse.level < 0 || fine.level > tree.depth())
        throw Error("Prolongation: the levels must be consecutive levels of the tree");
    half_ = std::uint32_t(1) << (tree.depth() - fine.level);
    if (fine.up.size() != fine.size() || fine.down.size() != fine.size()) throw Error("Prolongation: the fine graph has no segments");
    const std::size_t n = fine.size(), blocks = (n + kBlock - 1) / kBlock;
    // Shared nodes per block, then their running count; every new node's neighbours along its
    // off axes must be nodes half a coarse cell away (the levels nest).
    off_.resize(n);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(n); ++i) off_[std::size_t(i)] = std::uint8_t(off_axes(fine, std::size_t(i)));
    std::vector<std::uint32_t> shared(blocks, 0);
    bool nested = true;
#pragma omp parallel for schedule(static) reduction(&& : nested)
    for (std::ptrdiff_t b = 0; b < std::ptrdiff_t(blocks); ++b)
        for (std::size_t i = std::size_t(b) * kBlock; i < std::min(n, std::size_t(b + 1) * kBlock); ++i) {
            const unsigned off = off_[i];
            shared[std::size_t(b)] += off == 0;
            const auto p = unmorton3(fine.keys[i]);
            for (int a = 0; a < 3; ++a) {
                if (!(off >> a & 1)) continue;
                const std::int32_t up = fine.next(i, a), down = fine.prev(i, a);
                nested = nested && up >= 0 && down >= 0 && morton_coordinate(fine.keys[std::size_t(up)], a) == p[std::size_t(a)] + half_ &&
                         morton_coordinate(fine.keys[std::size_t(down)], a) + half_ == p[std::size_t(a)];
            }
        }
    block_first_.resize(blocks);
    std::size_t total = 0;
    for (std::size_t b = 0; b < blocks; ++b) {
        block_first_[b] = std::uint32_t(total);
        total += shared[b];
    }
    if (!nested || total != coarse.size()) throw Error("Prolongation: a coarse corner is missing (the levels are not nested)");
    // The shared nodes are the coarse ones, in the same order.
#pragma omp parallel for schedule(static) reduction(&& : nested)
    for (std::ptrdiff_t b = 0; b < std::ptrdiff_t(blocks); ++b) {
        std::size_t k = block_first_[std::size_t(b)];
        for (std::size_t i = std::size_t(b) * kBlock; i < std::min(n, std::size_t(b + 1) * kBlock); ++i)
            if (off_[i] == 0) nested = nested && fine.keys[i] == coarse.keys[k++];
    }
    if (!nested) throw Error("Prolongation: a coarse corner is missing (the levels are not nested)");
}

template <class T>
void Prolongation::prolong_as(const NodeGraph& fine, std::span<const T> coarse, std::span<T> out) const {
    const std::size_t n = fine_size_, blocks = block_first_.size();
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t b = 0; b < std::ptrdiff_t(blocks); ++b) {
        std::size_t k = block_first_[std::size_t(b)];
        for (std::size_t i = std::size_t(b) * kBlock; i < std::min(n, std::size_t(b + 1) * kBlock); ++i)
            if (off_[i] == 0) out[i] = coarse[k++];
    }
    // Edge midpoints from the shared nodes, face centers from edge midpoints, cell centers from
    // face centers: each pass reads only what the one before wrote.
    for (int count = 1; count <= 3; ++count) {
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(n); ++i) {
            const unsigned off = off_[std::size_t(i)];
            if (kAxesOff[off] != count) continue;
            double sum = 0;
            for (int a = 0; a < 3; ++a)
                if (off >> a & 1) sum += out[std::size_t(fine.next(std::size_t(i), a))] + out[std::size_t(fine.prev(std::size_t(i), a))];
            out[std::size_t(i)] = T(sum / double(2 * count));
        }
    }
}

template <class T>
void Prolongation::restrict_in_place_as(const NodeGraph& fine, std::span<T> f, std::span<T> coarse) const {
    const std::size_t n = fine_size_, blocks = block_first_.size();
    // The passes of prolong transposed, last first: a node off the lattice along `count` axes
    // gathers 1/(2(count + 1)) of each neighbour half a coarse cell away along its other axes
    // (those neighbours are off along one axis more, and it was one of their sources).
    for (int count = 2; count >= 0; --count) {
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(n); ++i) {
            const unsigned off = off_[std::size_t(i)];
            if (kAxesOff[off] != count) continue;
            double sum = 0;
            for (int a = 0; a < 3; ++a) {
                if (off >> a & 1) continue;
                // A neighbour off the lattice along a is the one half a coarse cell away (segments
                // are powers of two at least that long).
                const std::int32_t up = fine.next(std::size_t(i), a), down = fine.prev(std::size_t(i), a);
                if (up >= 0 && off_[std::size_t(up)] >> a & 1) sum += f[std::size_t(up)];
                if (down >= 0 && off_[std::size_t(down)] >> a & 1) sum += f[std::size_t(down)];
            }
            f[std::size_t(i)] += T(sum / double(2 * (count + 1)));
        }
    }
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t b = 0; b < std::ptrdiff_t(blocks); ++b) {
        std::size_t k = block_first_[std::size_t(b)];
        for (std::size_t i = std::size_t(b) * kBlock; i < std::min(n, std::size_t(b + 1) * kBlock); ++i)
            if (off_[i] == 0) coarse[k++] = f[i];
    }
}

void Prolongation::prolong(const NodeGraph& fine, std::span<const double> coarse, std::span<double> out) const {
    prolong_as(fine, coarse, out);
}
void Prolongation::prolong(const NodeGraph& fine, std::span<const float> coarse, std::span<float> out) const {
    prolong_as(fine, coarse, out);
}
void Prolongation::restrict_in_place(const NodeGraph& fine, std::span<double> f, std::span<double> coarse) const {
    restrict_in_place_as(fine, f, coarse);
}
void Prolongation::restrict_in_place(const NodeGraph& fine, std::span<float> f, std::span<float> coarse) const {
    restrict_in_place_as(fine, f, coarse);
}

void Prolongation::add_to(const NodeGraph& fine_graph, std::span<const double> coarse, std::span<double> fine) const {
    std::vector<double> p(fine_size_);
    prolong(fine_graph, coarse, p);
    for (std::size_t i = 0; i < fine_size_; ++i) fine[i] += p[i];
}

void Prolongation::restrict_to(const NodeGraph& fine_graph, std::span<const double> fine, std::span<double> coarse) const {
    std::vector<double> f(fine.begin(), fine.end());
    restrict_in_place(fine_graph, f, coarse);
}

struct OctreePoisson::Impl {
    // A multigrid level, matrix-free: the operator is applied from its node graph (segments
    // along ±axis, each with its weight V/ℓ²) and the samples' interpolation rows, so a node
    // costs its graph and a share of the samples instead of a row of ~20 stored products. A
    // coarser level fits its own samples, the finest level's merged per cell of its level: as
    // many as the surface has cells there, not the finest level's count on every level.
    struct Level {
        NodeGraph graph;  // keys, segments and their weights V/ℓ²
        std::vector<ZeroSample> samples;  // this level's (merged per cell of it)
        SpMat S, St;      // samples × nodes and its transpose: made when a penalty first needs them
        Vec area;         // A_j per sample (μ: Impl::mu)
        Prolongation P;                          // from the next (coarser) level; empty on the coarsest
        std::vector<std::uint32_t> merged_from;  // the finer level's samples: their merged one here
        SweepOrder order;                        // Gauss–Seidel's, on both threads (μ = 0)
    };
    const Octree& tree;
    double mu = 0;
    std::vector<Level> levels;
    Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> coarsest;

    Level make_level(NodeGraph graph, std::vector<ZeroSample> samples) const {
        Level lv;
        lv.graph = std::move(graph);
        lv.order = SweepOrder(lv.graph, tree.depth());
        lv.samples = std::move(samples);
        lv.area.resize(Eigen::Index(lv.samples.size()));
        for (std::size_t j = 0; j < lv.samples.size(); ++j) lv.area[Eigen::Index(j)] = lv.samples[j].area;
        return lv;
    }

    // The samples' rows on every level, once. Without a penalty (φ₀'s solve) nothing reads them,
    // so they are made after it, when the CG's vectors are gone (~9 bytes a node at the peak).
    void make_sample_rows() {
        for (Level& lv : levels) {
            if (lv.S.rows() == Eigen::Index(lv.samples.size())) continue;
            lv.S = sample_matrix(tree, lv.graph, lv.samples);
            lv.St = lv.S.transpose();
        }
    }

    // `refactor`: the same pattern as before (a new μ), only the numbers change.
    void factor_coarsest(bool refactor = false) {
        if (refactor)
            coarsest.factorize(assemble(levels.back()));
        else
            coarsest.compute(assemble(levels.back()));
        if (coarsest.info() != Eigen::Success) throw Error("the adaptive grid's coarsest Poisson matrix could not be factored");
    }

    // A_ii: the segments' weights and the penalty's (μ = 0: the pin's).
    double diagonal(const Level& lv, std::size_t i) const {
        double d = 0;
        for (int a = 0; a < 3; ++a) {
            d += lv.graph.weight(i, a);
            if (const std::int32_t j = lv.graph.prev(i, a); j >= 0) d += lv.graph.weight(std::size_t(j), a);
        }
        if (mu == 0) return d * (1 + kPin);
        for (SpMat::InnerIterator s(lv.St, Eigen::Index(i)); s; ++s) d += mu * lv.area[s.col()] * s.value() * s.value();
        return d;
    }

    // The level's operator assembled (the coarsest, for CHOLMOD): L + μSᵀAS (μ = 0: L pinned,
    // as sparse as L: no sample products).
    Eigen::SparseMatrix<double> assemble(const Level& lv) const {
        const std::size_t n = lv.graph.size();
        return Eigen::SparseMatrix<double>(rows_to_matrix(n, n, [&](std::size_t i, Entries& e) {
            for (int a = 0; a < 3; ++a) {
                if (const std::int32_t j = lv.graph.next(i, a); j >= 0) e.emplace_back(j, -lv.graph.weight(i, a));
                if (const std::int32_t j = lv.graph.prev(i, a); j >= 0) e.emplace_back(j, -lv.graph.weight(std::size_t(j), a));
            }
            if (mu > 0)
                for (SpMat::InnerIterator s(lv.St, Eigen::Index(i)); s; ++s) {
                    const double f = mu * lv.area[s.col()] * s.value();
                    for (SpMat::InnerIterator k(lv.S, s.col()); k; ++k)
                        if (k.col() != Eigen::Index(i)) e.emplace_back(std::int32_t(k.col()), f * k.value());
                }
            e.emplace_back(std::int32_t(i), diagonal(lv, i));  // L's and the penalty's
        }));
    }

    // (A x)_i, given at = μA ∘ S x (the samples' weighted values; empty when μ = 0). x: double
    // or float (the V-cycle's and CG's search directions), summed in double.
    template <class X>
    double row(const Level& lv, const X& x, const Vec& at, std::size_t i) const {
        const double xi = double(x[Eigen::Index(i)]);
        double v = 0, d = 0;
        for (int a = 0; a < 3; ++a) {
            if (const std::int32_t j = lv.graph.next(i, a); j >= 0) {
                v += lv.graph.weight(i, a) * (xi - double(x[j]));
                d += lv.graph.weight(i, a);
            }
            if (const std::int32_t j = lv.graph.prev(i, a); j >= 0) {
                v += lv.graph.weight(std::size_t(j), a) * (xi - double(x[j]));
                d += lv.graph.weight(std::size_t(j), a);
            }
        }
        if (mu == 0) return v + kPin * d * xi;
        for (SpMat::InnerIterator k(lv.St, Eigen::Index(i)); k; ++k) v += k.value() * at[k.col()];
        return v;
    }

    // S x, for x of either precision (no double copy of a float x).
    template <class X>
    Vec samples_of(const Level& lv, const X& x) const {
        Vec t(lv.S.rows());
#pragma omp parallel for schedule(static)
        for (Eigen::Index j = 0; j < lv.S.rows(); ++j) {
            double v = 0;
            for (SpMat::InnerIterator k(lv.S, j); k; ++k) v += k.value() * double(x[k.col()]);
            t[j] = v;
        }
        return t;
    }

    // μA ∘ S x (empty when μ = 0).
    Vec penalty_values(const Level& lv, const Vec& Sx) const { return mu > 0 ? Vec(mu * lv.area.cwiseProduct(Sx)) : Vec(); }
    template <class X>
    Vec penalty_of(const Level& lv, const X& x) const { return mu > 0 ? penalty_values(lv, samples_of(lv, x)) : Vec(); }

    void apply(const Level& lv, const Vec& x, Vec& y) const {
        const auto n = std::ptrdiff_t(lv.graph.size());
        const Vec at = penalty_of(lv, x);
        y.resize(n);
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t i = 0; i < n; ++i) y[i] = row(lv, x, at, std::size_t(i));
    }

    // One Gauss–Seidel sweep on x (the V-cycle's correction, float; summed in double), b of
    // either precision. t = S x on entry and on return: the samples' values follow each node's
    // update, so a node's penalty row costs its samples, not their products. With a penalty a
    // sample's nodes can lie in two cells of one colour (diagonal neighbours), so that sweep
    // stays on one thread (it is the zero-set fit's, on a coarse level); without one the level's
    // SweepOrder runs it on all of them.
    template <class B, class X>
    void gauss_seidel(const Level& lv, const B& b, X& x, Vec& t, bool forward) const {
        const auto relax = [&](std::size_t i) {
            const double xi = x[Eigen::Index(i)];
            // The diagonal is made on the way (the weights are read anyway), not stored.
            double sum = double(b[Eigen::Index(i)]), d = 0;
            for (int a = 0; a < 3; ++a) {
                if (const std::int32_t j = lv.graph.next(i, a); j >= 0) {
                    const double w = lv.graph.weight(i, a);
                    sum += w * x[j];
                    d += w;
                }
                if (const std::int32_t j = lv.graph.prev(i, a); j >= 0) {
                    const double w = lv.graph.weight(std::size_t(j), a);
                    sum += w * x[j];
                    d += w;
                }
            }
            if (mu > 0) {
                for (SpMat::InnerIterator k(lv.St, Eigen::Index(i)); k; ++k) {
                    const double f = mu * lv.area[k.col()] * k.value();
                    sum -= f * (t[k.col()] - k.value() * xi);
                    d += f * k.value();
                }
            } else {
                d *= 1 + kPin;
            }
            const auto updated = typename X::Scalar(sum / d);
            const double delta = double(updated) - xi;
            x[Eigen::Index(i)] = updated;
            if (mu > 0)
                for (SpMat::InnerIterator k(lv.St, Eigen::Index(i)); k; ++k) t[k.col()] += k.value() * delta;
        };
        if (mu == 0) {
            lv.order.sweep(forward, relax);
            return;
        }
        const std::size_t n = lv.graph.size();
        for (std::size_t s = 0; s < n; ++s) relax(forward ? s : n - 1 - s);
    }

    // Solves level k's system A x = r by CG preconditioned with V-cycles from level k (the
    // coarsest: factored, exact). r is the residual throughout; x starts at 0. A p is not
    // stored: p·Ap and r −= αAp each apply A on the way, so r stays b − A x (μ = 0: its part free
    // of the constant) to double rounding and CG keeps four vectors, not five. z is float: its rounding only perturbs the
    // preconditioner, as x and r move along the same p (the residuals did not change, measured
    // at depths 9, 11 and 12). p stays double: its smooth part is up to (2^D/π)² times its rough
    // part, and its rounding would carry over the iterations. Without a penalty the constant is
    // free (the pin only nudges it) and the V-cycle's coarsest solve is the pseudo-inverse: r and
    // z are kept free of their means, or the constant that rounding lets in grows until the
    // residual climbs back (a 2·10⁶-point scan at depth 11: 10 iterations instead of 5).
    void conjugate_gradients(std::size_t k, Eigen::Ref<Vec> r, Eigen::Ref<Vec> x, double tolerance, int max_iterations,
                             std::vector<double>& history, const ProgressFn& progress) const {
        const Level& lv = levels[k];
        if (mu == 0) remove_mean(r);
        const double bn = r.norm();
        const auto n = std::ptrdiff_t(lv.graph.size());
        if (k + 1 == levels.size()) {  // small enough to factor: exact
            x = coarsest.solve(r);
            Vec z;
            apply(lv, x, z);
            history.push_back(bn > 0 ? (r - z).norm() / bn : 0.0);
            return;
        }
        VecF z;
        vcycle(k, r, z);
        if (mu == 0) remove_mean(z);
        Vec p = z.cast<double>();
        double rz = dot(r, z);
        for (int it = 0; it < max_iterations && bn > 0; ++it) {
            const Vec at = penalty_of(lv, p);
            const double pap = blocked_sum(n, [&](std::ptrdiff_t i) { return double(p[i]) * row(lv, p, at, std::size_t(i)); });
            const double alpha = rz / pap;
            double rr = blocked_sum(n, [&](std::ptrdiff_t i) {
                x[i] += alpha * double(p[i]);
                r[i] -= alpha * row(lv, p, at, std::size_t(i));
                return r[i] * r[i];
            });
            if (mu == 0) rr = remove_mean(r);
            const double rel = std::sqrt(rr) / bn;
            history.push_back(rel);
            if (progress) progress("solve", std::clamp(std::log(std::max(rel, 1e-300)) / std::log(tolerance), 0.0, 1.0));
            if (rel <= tolerance) break;
            vcycle(k, r, z);
            if (mu == 0) remove_mean(z);
            const double rz_new = dot(r, z);
            const double beta = rz_new / rz;
#pragma omp parallel for schedule(static)
            for (std::ptrdiff_t i = 0; i < n; ++i) p[i] = double(z[i]) + beta * p[i];
            rz = rz_new;
        }
    }

    // Σ f(i) over i < n in parallel, in the same order whatever the threads (blocks' partial
    // sums, added in turn): the solve is reproducible.
    template <class F>
    static double blocked_sum(std::ptrdiff_t n, F&& f) {
        constexpr std::ptrdiff_t kBlock = 4096;
        const std::ptrdiff_t blocks = (n + kBlock - 1) / kBlock;
        std::vector<double> part(std::size_t(blocks), 0.0);
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t b = 0; b < blocks; ++b) {
            double v = 0;
            for (std::ptrdiff_t i = b * kBlock; i < std::min(n, (b + 1) * kBlock); ++i) v += f(i);
            part[std::size_t(b)] = v;
        }
        double sum = 0;
        for (const double v : part) sum += v;
        return sum;
    }

    // v −= mean(v); returns the new v·v.
    template <class V>
    static double remove_mean(V& v) {
        const auto n = std::ptrdiff_t(v.size());
        const double mean = blocked_sum(n, [&](std::ptrdiff_t i) { return double(v[i]); }) / double(n);
        return blocked_sum(n, [&](std::ptrdiff_t i) {
            v[i] -= mean;
            return double(v[i]) * double(v[i]);
        });
    }

    // r·v without a copy of either (r is a Ref: a Vec parameter would copy it).
    template <class R, class V>
    static double dot(const R& r, const V& v) {
        return blocked_sum(r.size(), [&](std::ptrdiff_t i) { return r[i] * double(v[i]); });
    }

    // x ≈ A⁻¹ b on level k by one V-cycle, x in float on every level (CG's z on the first), as
    // the coarser levels' residuals b and the transfers are; sums in double.
    template <class B, class X>
    void vcycle(std::size_t k, const B& b, X& x) const {
        const Level& lv = levels[k];
        if (k + 1 == levels.size()) {
            // Without a penalty the operator is the Laplacian pinned by 1e-9 of its diagonal:
            // its inverse scales a constant by ~1e9, and the constant that rounding leaves in
            // a float residual would come back as a correction whose constant swamps, in
            // float, the rest of it (CG stalled). So the constant is taken out before and
            // after: the Laplacian's pseudo-inverse, still symmetric as CG's preconditioner
            // must be (φ's constant is the caller's to set).
            Vec rhs = b.template cast<double>();
            if (mu == 0) rhs.array() -= rhs.mean();
            Vec e = coarsest.solve(rhs);
            if (mu == 0) e.array() -= e.mean();
            x = e.cast<typename X::Scalar>();
            return;
        }
        x.setZero(b.size());
        Vec t = mu > 0 ? Vec(Vec::Zero(lv.S.rows())) : Vec();  // S x (no use without a penalty)
        for (int s = 0; s < kSweeps; ++s) gauss_seidel(lv, b, x, t, true);
        // The coarse residual Pᵀ(b − A x); the fine residual's vector then holds P e.
        VecF fine(b.size()), rc(levels[k + 1].graph.size());
        const Vec at = penalty_values(lv, t);
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t i = 0; i < b.size(); ++i) fine[i] = float(double(b[i]) - row(lv, x, at, std::size_t(i)));
        lv.P.restrict_in_place(lv.graph, std::span<float>(fine.data(), std::size_t(fine.size())), std::span<float>(rc.data(), std::size_t(rc.size())));
        // The fine vector is let go while the coarser levels cycle, and rc once they have: the
        // finest level's copy would otherwise sit beside all of theirs (~0.3 GB at depth 11).
        VecF().swap(fine);
        VecF ec;
        vcycle(k + 1, rc, ec);
        VecF().swap(rc);
        fine.resize(b.size());
        lv.P.prolong(lv.graph, std::span<const float>(ec.data(), std::size_t(ec.size())), std::span<float>(fine.data(), std::size_t(fine.size())));
        x += fine.cast<typename X::Scalar>();
        if (mu > 0) t = samples_of(lv, x);
        for (int s = 0; s < kSweeps; ++s) gauss_seidel(lv, b, x, t, false);
    }
};

OctreePoisson::OctreePoisson(const Octree& tree, std::vector<ZeroSample> samples, double penalty)
    : OctreePoisson(tree, build_node_graph(tree, tree.depth()), std::move(samples), penalty) {}

OctreePoisson::OctreePoisson(const Octree& tree, NodeGraph finest, std::vector<ZeroSample> samples, double penalty)
    : impl_(new Impl{tree, penalty, {}, {}}) {
    Impl& m = *impl_;
    if (samples.empty()) throw Error("the source lies outside the adaptive grid's bounds");
    if (!(penalty >= 0) || !std::isfinite(penalty)) throw Error("OctreePoisson: the penalty must be finite and ≥ 0");
    if (finest.level != tree.depth() || finest.keys_packed() || finest.down.size() != finest.size() ||
        finest.weight_code.size() != finest.size())
        throw Error("OctreePoisson: the finest graph must be build_node_graph(tree, tree.depth()), keys unpacked");
    // Reserved: a Level's copy constructor is what growth would use (Eigen's sparse matrices
    // have no noexcept move), copying the finest level's arrays.
    m.levels.reserve(std::size_t(tree.depth()) + 1);
    for (int level = tree.depth();; --level) {
        std::vector<std::uint32_t> merged_from;
        std::vector<ZeroSample> here =
            level == tree.depth() ? std::move(samples) : merge_by_cell(tree, m.levels.back().samples, level, &merged_from);
        Impl::Level lv = m.make_level(level == tree.depth() ? std::move(finest) : build_node_graph(tree, level), std::move(here));
        lv.merged_from = std::move(merged_from);
        if (!m.levels.empty()) m.levels.back().P = Prolongation(tree, m.levels.back().graph, lv.graph);
        const bool last = lv.graph.size() <= kDirectNodes || level == 0;
        m.levels.push_back(std::move(lv));
        if (last) break;
    }
    if (penalty > 0) m.make_sample_rows();
    m.factor_coarsest();
}

void OctreePoisson::set_penalty(double penalty) {
    Impl& m = *impl_;
    if (!(penalty >= 0) || !std::isfinite(penalty)) throw Error("OctreePoisson: the penalty must be finite and ≥ 0");
    const bool same_pattern = (m.mu > 0) == (penalty > 0);  // the samples' products in it or not
    if (penalty > 0) m.make_sample_rows();
    m.mu = penalty;
    m.factor_coarsest(same_pattern);
}

int OctreePoisson::coarsest_level() const { return impl_->levels.back().graph.level; }

int OctreePoisson::fit_on_level(std::vector<double>& phi, int level, double tolerance, int max_iterations,
                                std::vector<double>& history, const ProgressFn& progress) const {
    const Impl& m = *impl_;
    const Impl::Level& top = m.levels.front();
    if (phi.size() != top.graph.size()) throw Error("fit_on_level: φ needs a value per node");
    if (!(m.mu > 0)) throw Error("fit_on_level: the penalty must be > 0 (set_penalty)");
    const auto k = std::size_t(std::clamp(top.graph.level - level, 0, int(m.levels.size()) - 1));
    // φ at the finest samples, then averaged (by area) over the ones merged into each sample of
    // level k: the penalty of a merged sample stands for theirs.
    Vec v = top.S * Eigen::Map<const Vec>(phi.data(), Eigen::Index(phi.size()));
    Vec a = top.area;
    for (std::size_t l = 1; l <= k; ++l) {
        const Impl::Level& lv = m.levels[l];
        Vec sum = Vec::Zero(lv.area.size()), weight = Vec::Zero(lv.area.size());
        for (std::size_t j = 0; j < lv.merged_from.size(); ++j) {
            sum[lv.merged_from[j]] += a[Eigen::Index(j)] * v[Eigen::Index(j)];
            weight[lv.merged_from[j]] += a[Eigen::Index(j)];
        }
        v = (weight.array() > 0).select(sum.cwiseQuotient(weight), 0.0);
        a = std::move(weight);
    }
    // The normal equations of min E_k(ψ) + μ Σ A (v + Sψ)²: A_k ψ = −S_kᵀ(μA ∘ v).
    const Impl::Level& lk = m.levels[k];
    Vec r = -m.mu * (lk.St * lk.area.cwiseProduct(v));
    Vec psi = Vec::Zero(Eigen::Index(lk.graph.size()));
    m.conjugate_gradients(k, r, psi, tolerance, max_iterations, history, progress);
    // ψ prolonged level by level to the finest and added; in float (a smooth correction: its
    // rounding is 1e-7 of itself) on the way, so the finest level's copy costs 4 bytes a node
    // beside φ, not 8 (it was the whole run's peak at depth 11).
    VecF psi_f = psi.cast<float>();
    Vec().swap(psi);
    for (std::size_t l = k; l-- > 0;) {
        VecF fine(Eigen::Index(m.levels[l].graph.size()));
        m.levels[l].P.prolong(m.levels[l].graph, std::span<const float>(psi_f.data(), std::size_t(psi_f.size())),
                              std::span<float>(fine.data(), std::size_t(fine.size())));
        psi_f = std::move(fine);
    }
    for (std::size_t i = 0; i < phi.size(); ++i) phi[i] += double(psi_f[Eigen::Index(i)]);
    return lk.graph.level;
}

OctreePoisson::~OctreePoisson() = default;

const NodeGraph& OctreePoisson::nodes() const { return impl_->levels.front().graph; }

std::vector<std::uint64_t> OctreePoisson::take_finest_keys() { return std::move(impl_->levels.front().graph.keys); }

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
        const std::size_t j = std::size_t(g.next(i, a));
        const double len = double(morton_coordinate(g.keys[j], a) - morton_coordinate(g.keys[i], a)) * h;
        const double ybar = 0.5 * (double(Y[3 * i + std::size_t(a)]) + double(Y[3 * j + std::size_t(a)]));
        return lv.graph.weight(i, a) * len * ybar;
    };
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(g.size()); ++i) {
        double v = 0;
        for (int a = 0; a < 3; ++a) {
            if (const std::int32_t j = lv.graph.prev(std::size_t(i), a); j >= 0) v += flux(std::size_t(j), a);
            if (g.next(std::size_t(i), a) >= 0) v -= flux(std::size_t(i), a);
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
    const Impl::Level& top = m.levels.front();
    if (phi.size() != top.graph.size()) throw Error("mean_on_samples: φ needs a value per node");
    // From the samples' interpolation weights (their rows may not be made yet: φ₀ needs none).
    double sum = 0;
#pragma omp parallel for schedule(static) reduction(+ : sum)
    for (std::ptrdiff_t j = 0; j < std::ptrdiff_t(top.samples.size()); ++j) {
        std::int32_t node[27];
        double w[27];
        const ZeroSample& y = top.samples[std::size_t(j)];
        const int n = interpolation_weights(m.tree, top.graph, m.tree.to_lattice(y.position), node, w);
        double v = 0;
        for (int c = 0; c < n; ++c)
            if (w[c] != 0) v += w[c] * phi[std::size_t(node[c])];
        sum += y.area * v;
    }
    return sum / top.area.sum();
}

std::vector<double> OctreePoisson::solve(std::vector<double> b_in, double tolerance, int max_iterations, OctreePoissonStats& stats,
                                         const ProgressFn& progress) {
    Impl& m = *impl_;
    for (const auto& lv : m.levels) stats.level_nodes.push_back(lv.graph.size());
    const auto t0 = std::chrono::steady_clock::now();
    const auto n = Eigen::Index(b_in.size());
    std::vector<double> phi(b_in.size(), 0.0);
    Eigen::Map<Vec> x(phi.data(), n);
    // Through the iterations x (φ), r (in b's memory) and p in double, z and the V-cycle's
    // residual in float (conjugate_gradients): 32 bytes a node.
    Eigen::Map<Vec> r(b_in.data(), n);  // b's memory is r's
    // The iterations walk the steps alone: the keys wait packed (8 bytes a node → about 1).
    try {
        for (Impl::Level& lv : m.levels) lv.graph.pack_keys();
        m.conjugate_gradients(0, r, x, tolerance, max_iterations, stats.residual_history, progress);
    } catch (...) {
        for (Impl::Level& lv : m.levels) lv.graph.unpack_keys();
        throw;
    }
    for (Impl::Level& lv : m.levels) lv.graph.unpack_keys();
    stats.seconds_solve = seconds_since(t0);
    return phi;
}

}  // namespace gsd::shm
