#include "shm/diffuse.hpp"

#include "core/uninitialized.hpp"
#include "sums/sum_tree.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace gsd::shm {

namespace {

class CpuEvaluator final : public DirectionEvaluator {
public:
    CpuEvaluator(const ShmSource& src, const KernelParams& k) : k_(screened_params(k)), tree_(src.elements) {
        tree_.prepare_screened(k_.lambda);
    }

    std::size_t evaluate(const Points& x, std::vector<float>& y, std::vector<double>& r_min,
                         const ProgressFn& progress) override {
        const auto n = std::size_t(x.rows());
        y.assign(3 * n, 0.0f);
        r_min.assign(n, 0.0);
        std::size_t terms = 0;
        const std::size_t block = 32768;
        for (std::size_t first = 0; first < n; first += block) {
            const std::size_t last = std::min(n, first + block);
            // Runs of consecutive points (usually grid neighbors) per task: a known r_min plus
            // the step bounds a neighbor's, which prunes the nearest-element search.
            const std::size_t run = 64, runs = (last - first + run - 1) / run;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : terms)
            for (std::size_t r = 0; r < runs; ++r) {
                // Packets of consecutive points walk the tree together; each point's r_min is
                // bounded by the previous packet's last r_min plus the step to it.
                constexpr int P = sums::SumTree::kScreenedLanes;
                Eigen::Vector3d prev = Eigen::Vector3d::Zero();
                double prev_r = INFINITY;
                std::uint32_t nearest = std::uint32_t(-1);  // the previous packet's nearest element: usually these ones' too
                const std::size_t end = std::min(last, first + (r + 1) * run);
                for (std::size_t i = first + r * run; i < end; i += P) {
                    const int n = int(std::min<std::size_t>(P, end - i));
                    double p[3 * P], bound[P], X[3 * P];
                    for (int l = 0; l < n; ++l) {
                        for (int a = 0; a < 3; ++a) p[3 * l + a] = x(Eigen::Index(i) + l, a);
                        bound[l] = prev_r + (Eigen::Vector3d(p[3 * l], p[3 * l + 1], p[3 * l + 2]) - prev).norm();
                    }
                    tree_.screened(p, n, k_, &r_min[i], X, terms, bound, &nearest);
                    prev = Eigen::Vector3d(p[3 * (n - 1)], p[3 * (n - 1) + 1], p[3 * (n - 1) + 2]);
                    prev_r = r_min[i + std::size_t(n) - 1];
                    for (int l = 0; l < n; ++l) {
                        const double len = std::sqrt(X[3 * l] * X[3 * l] + X[3 * l + 1] * X[3 * l + 1] + X[3 * l + 2] * X[3 * l + 2]);
                        if (len > 0)
                            for (int a = 0; a < 3; ++a) y[3 * (i + std::size_t(l)) + std::size_t(a)] = float(X[3 * l + a] / len);
                    }
                }
            }
            if (progress) progress("diffuse", double(last) / double(n));
        }
        return terms;
    }
    std::string device() const override { return "cpu"; }

private:
    sums::SumTree::Screened k_;
    sums::SumTree tree_;
};

// The grids of the hierarchy: the same box, about half the nodes per axis each level.
std::vector<GridSpec> levels_for(const GridSpec& g, bool interpolate) {
    std::vector<GridSpec> out{g};
    if (!interpolate) return out;
    while (std::max({out.back().nx, out.back().ny, out.back().nz}) > 9) {
        GridSpec c = out.back();
        c.nx = std::max(2, (c.nx - 1 + 1) / 2 + 1);
        c.ny = std::max(2, (c.ny - 1 + 1) / 2 + 1);
        c.nz = std::max(2, (c.nz - 1 + 1) / 2 + 1);
        out.push_back(c);
    }
    return out;
}

struct LevelField {
    detail::UninitializedVector<float> y;       // 3 per node
    detail::UninitializedVector<double> r_low;  // a lower bound of the distance to the source (exact where evaluated)
};

// The nodes of `g` where exact[p] is set, in storage order, from parallel counts per block of
// rows (16.7 M nodes at 256³: a serial pass was a tenth of step 1 on a 16-core GPU host).
std::vector<std::size_t> exact_nodes(const detail::UninitializedVector<char>& exact) {
    const std::size_t n = exact.size(), block = 1 << 16, blocks = (n + block - 1) / block;
    std::vector<std::size_t> count(blocks + 1, 0);
#pragma omp parallel for schedule(static)
    for (std::size_t b = 0; b < blocks; ++b)
        for (std::size_t p = b * block; p < std::min(n, (b + 1) * block); ++p) count[b + 1] += exact[p] != 0;
    for (std::size_t b = 0; b < blocks; ++b) count[b + 1] += count[b];
    std::vector<std::size_t> out(count[blocks]);
#pragma omp parallel for schedule(static)
    for (std::size_t b = 0; b < blocks; ++b) {
        std::size_t m = count[b];
        for (std::size_t p = b * block; p < std::min(n, (b + 1) * block); ++p)
            if (exact[p]) out[m++] = p;
    }
    return out;
}

}  // namespace

sums::SumTree::Screened screened_params(const KernelParams& k) {
    sums::SumTree::Screened s;
    s.lambda = k.lambda;
    s.cutoff = k.cutoff;
    s.r_floor = k.r_floor;
    s.tolerance = k.sum_tolerance;
    return s;
}

KernelParams kernel_params(const ShmSource& source, double t_coef, double cutoff, double sum_tolerance) {
    KernelParams k;
    k.lambda = 1 / std::sqrt(t_coef * source.spacing * source.spacing);
    k.cutoff = cutoff;
    k.r_floor = 1e-3 * source.spacing;
    k.sum_tolerance = sum_tolerance;
    return k;
}

std::unique_ptr<DirectionEvaluator> make_cpu_evaluator(const ShmSource& src, const KernelParams& k) {
    return std::make_unique<CpuEvaluator>(src, k);
}

detail::UninitializedVector<float> diffuse(const GridSpec& grid, DirectionEvaluator& eval, double interpolation_cells,
                                           DiffuseStats& stats, const ProgressFn& progress) {
    const std::vector<GridSpec> levels = levels_for(grid, interpolation_cells > 0);
    LevelField coarse;
    for (int l = int(levels.size()) - 1; l >= 0; --l) {
        const GridSpec& g = levels[std::size_t(l)];
        const std::size_t n = g.node_count();
        const bool bound = l > 0;  // the finest level's bounds have no use
        // Every entry is written below, by the parallel loops (their first touch of the pages):
        // interpolated nodes here, the others from the sums.
        LevelField cur;
        cur.y.resize(3 * n);
        if (bound) cur.r_low.resize(n);
        detail::UninitializedVector<char> exact(n);
        if (std::size_t(l) + 1 < levels.size()) {
            // Interpolate where every corner of the enclosing coarse cell is far from the source.
            const GridSpec& c = levels[std::size_t(l) + 1];
            const Eigen::Vector3d step = c.box.extent().cwiseQuotient(Eigen::Vector3d(c.nx - 1, c.ny - 1, c.nz - 1));
            const double far = interpolation_cells * step.maxCoeff();
            const int cn[3] = {c.nx, c.ny, c.nz};
#pragma omp parallel for schedule(static)
            for (std::size_t p = 0; p < n; ++p) {
                const int i = int(p / (std::size_t(g.ny) * std::size_t(g.nz))), j = int((p / std::size_t(g.nz)) % std::size_t(g.ny)),
                          k = int(p % std::size_t(g.nz));
                const Eigen::Vector3d x = g.node(i, j, k);
                int base[3];
                double t[3];
                for (int a = 0; a < 3; ++a) {
                    const double u = (x[a] - c.box.lo[a]) / step[a];
                    base[a] = std::clamp(int(std::floor(u)), 0, cn[a] - 2);
                    t[a] = std::clamp(u - base[a], 0.0, 1.0);
                }
                Eigen::Vector3d sum = Eigen::Vector3d::Zero();
                double low = INFINITY;
                bool all_far = true;
                for (int corner = 0; corner < 8 && all_far; ++corner) {
                    const int o[3] = {corner & 1, (corner >> 1) & 1, (corner >> 2) & 1};
                    const std::size_t q = c.nz * (std::size_t(base[0] + o[0]) * std::size_t(c.ny) + std::size_t(base[1] + o[1])) +
                                          std::size_t(base[2] + o[2]);
                    if (coarse.r_low[q] < far) all_far = false;
                    const double w = (o[0] ? t[0] : 1 - t[0]) * (o[1] ? t[1] : 1 - t[1]) * (o[2] ? t[2] : 1 - t[2]);
                    for (int a = 0; a < 3; ++a) sum[a] += w * coarse.y[3 * q + std::size_t(a)];
                    // r_min is 1-Lipschitz: a bound at the corner bounds it here too.
                    if (bound)
                        low = std::min(low, coarse.r_low[q] - (x - c.node(base[0] + o[0], base[1] + o[1], base[2] + o[2])).norm());
                }
                exact[p] = !all_far;
                if (!all_far) continue;
                const double len = sum.norm();
                for (int a = 0; a < 3; ++a) cur.y[3 * p + std::size_t(a)] = len > 1e-6 ? float(sum[a] / len) : 0.0f;
                if (bound) cur.r_low[p] = std::max(low, 0.0);
            }
        } else {
#pragma omp parallel for schedule(static)
            for (std::size_t p = 0; p < n; ++p) exact[p] = 1;
        }
        const std::vector<std::size_t> to_sum = exact_nodes(exact);
        Points x(Eigen::Index(to_sum.size()), 3);
#pragma omp parallel for schedule(static)
        for (std::size_t m = 0; m < to_sum.size(); ++m) {
            const std::size_t p = to_sum[m];
            x.row(Eigen::Index(m)) = g.node(int(p / (std::size_t(g.ny) * std::size_t(g.nz))), int((p / std::size_t(g.nz)) % std::size_t(g.ny)),
                                            int(p % std::size_t(g.nz)))
                                         .transpose();
        }
        std::vector<float> y;
        std::vector<double> rmin;
        const ProgressFn level_progress = progress && l == 0 ? progress : ProgressFn{};
        const auto t0 = std::chrono::steady_clock::now();
        stats.kernel_terms += eval.evaluate(x, y, rmin, level_progress);
        stats.seconds_sums += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        stats.exact_nodes += to_sum.size();
#pragma omp parallel for schedule(static)
        for (std::size_t m = 0; m < to_sum.size(); ++m) {
            const std::size_t p = to_sum[m];
            for (int a = 0; a < 3; ++a) cur.y[3 * p + std::size_t(a)] = y[3 * m + std::size_t(a)];
            if (bound) cur.r_low[p] = rmin[m];
        }
        coarse = std::move(cur);
    }
    return std::move(coarse.y);
}

}  // namespace gsd::shm
