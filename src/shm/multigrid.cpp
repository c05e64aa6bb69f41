#include "shm/multigrid.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>

namespace gsd::shm {

namespace {

// The next coarser axis: pairs of cells merge; an odd last cell stays alone.
AxisLevel coarsen(const AxisLevel& f) {
    AxisLevel c;
    c.n = (f.n + 1) / 2;
    c.size.resize(std::size_t(c.n));
    c.center.resize(std::size_t(c.n));
    double start = 0;
    for (int I = 0; I < c.n; ++I) {
        const int a = 2 * I, b = 2 * I + 1;
        c.size[std::size_t(I)] = f.size[std::size_t(a)] + (b < f.n ? f.size[std::size_t(b)] : 0.0);
        c.center[std::size_t(I)] = start + 0.5 * c.size[std::size_t(I)];
        start += c.size[std::size_t(I)];
    }
    return c;
}

// Linear interpolation along one axis from coarse cell centers to fine cell centers (constant
// beyond the outermost centers), stored on the fine axis; and its transpose as gather lists
// on the coarse axis.
void link(AxisLevel& fine, AxisLevel& coarse) {
    const auto n = std::size_t(fine.n);
    fine.c0.resize(n);
    fine.c1.resize(n);
    fine.w0.resize(n);
    fine.w1.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        const double x = fine.center[i];
        const int parent = int(i / 2);
        int lo = parent, hi = parent;
        if (x < coarse.center[std::size_t(parent)] && parent > 0) lo = parent - 1;
        if (x > coarse.center[std::size_t(parent)] && parent + 1 < coarse.n) hi = parent + 1;
        double w_hi = 0;
        if (lo != hi) w_hi = (x - coarse.center[std::size_t(lo)]) / (coarse.center[std::size_t(hi)] - coarse.center[std::size_t(lo)]);
        fine.c0[i] = lo;
        fine.c1[i] = hi;
        fine.w0[i] = 1 - w_hi;
        fine.w1[i] = w_hi;
    }
    std::vector<std::vector<std::pair<int, double>>> lists(std::size_t(coarse.n));
    for (std::size_t i = 0; i < n; ++i) {
        if (fine.w0[i] != 0) lists[std::size_t(fine.c0[i])].push_back({int(i), fine.w0[i]});
        if (fine.w1[i] != 0 && fine.c1[i] != fine.c0[i]) lists[std::size_t(fine.c1[i])].push_back({int(i), fine.w1[i]});
        if (fine.c1[i] == fine.c0[i] && fine.w1[i] != 0) lists[std::size_t(fine.c0[i])].back().second += fine.w1[i];
    }
    coarse.offsets.assign(1, 0);
    for (const auto& l : lists) {
        for (const auto& [idx, w] : l) {
            coarse.gather_index.push_back(idx);
            coarse.gather_weight.push_back(w);
        }
        coarse.offsets.push_back(int(coarse.gather_index.size()));
    }
}

}  // namespace

Hierarchy::Hierarchy(const GridSpec& g) {
    const int dims[3] = {g.nx, g.ny, g.nz};
    Level top;
    for (int a = 0; a < 3; ++a) {
        AxisLevel& ax = top.axis[std::size_t(a)];
        ax.n = dims[a];
        ax.size.assign(std::size_t(ax.n), 1.0);
        ax.center.resize(std::size_t(ax.n));
        for (int i = 0; i < ax.n; ++i) ax.center[std::size_t(i)] = i + 0.5;
        const double h = g.box.extent()[a] / (dims[a] - 1);
        inv_h2[std::size_t(a)] = 1 / (h * h);
    }
    levels.push_back(std::move(top));
    // Coarsen until every axis has at most 4 cells (≤ 64 unknowns for the dense solve).
    while (levels.back().axis[0].n > 4 || levels.back().axis[1].n > 4 || levels.back().axis[2].n > 4) {
        Level next;
        for (std::size_t a = 0; a < 3; ++a) {
            AxisLevel& f = levels.back().axis[a];
            next.axis[a] = coarsen(f);
            link(f, next.axis[a]);
        }
        levels.push_back(std::move(next));
    }
    for (Level& lv : levels)
        for (std::size_t a = 0; a < 3; ++a) {
            AxisLevel& ax = lv.axis[a];
            ax.link.assign(std::size_t(ax.n), 0.0);
            for (std::size_t i = 0; i + 1 < std::size_t(ax.n); ++i) ax.link[i] = inv_h2[a] / (0.5 * (ax.size[i] + ax.size[i + 1]));
        }

    // Dense operator of the coarsest level and its pseudo-inverse (the nullspace is the constants).
    const int l = int(levels.size()) - 1;
    const auto m = Eigen::Index(levels.back().count());
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(m, m);
    for_each_edge(l, [&](std::size_t p, std::size_t q, double w) {
        A(Eigen::Index(p), Eigen::Index(p)) += w;
        A(Eigen::Index(q), Eigen::Index(q)) += w;
        A(Eigen::Index(p), Eigen::Index(q)) -= w;
        A(Eigen::Index(q), Eigen::Index(p)) -= w;
    });
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(A);
    const double largest = eig.eigenvalues().cwiseAbs().maxCoeff();
    Eigen::VectorXd inv = eig.eigenvalues();
    for (Eigen::Index i = 0; i < inv.size(); ++i) inv[i] = std::abs(inv[i]) > 1e-10 * largest ? 1 / inv[i] : 0.0;
    const Eigen::MatrixXd pinv = eig.eigenvectors() * inv.asDiagonal() * eig.eigenvectors().transpose();
    coarse_pinv.resize(std::size_t(m * m));
    for (Eigen::Index r = 0; r < m; ++r)
        for (Eigen::Index q = 0; q < m; ++q) coarse_pinv[std::size_t(r * m + q)] = pinv(r, q);
}


}  // namespace gsd::shm
