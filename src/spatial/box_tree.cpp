#include "spatial/box_tree.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace gsd::spatial {

BoxTree::BoxTree(const Points& p, std::uint32_t leaf_size) {
    const auto n = std::uint32_t(p.rows());
    if (n == 0) throw Error("cannot build a spatial index over an empty point set");
    // The smallest depth with ≤ leaf_size points per leaf: every leaf then holds > leaf_size/2.
    int depth = 0;
    while ((std::uint64_t(n) >> depth) > std::max<std::uint32_t>(leaf_size, 1)) ++depth;
    order_.resize(n);
    std::iota(order_.begin(), order_.end(), 0u);
    nodes_.resize((std::size_t(1) << (depth + 1)) - 1);
    first_leaf_ = std::uint32_t((std::size_t(1) << depth) - 1);

    // Each node: its box, then a median split along its longest side. The two halves are
    // independent, so large ones are built as OpenMP tasks (the same tree as in serial).
    auto build = [&](auto&& self, std::uint32_t index, std::uint32_t begin, std::uint32_t end, int level) -> void {
        Node& node = nodes_[index];
        node.begin = begin;
        node.end = end;
        for (int a = 0; a < 3; ++a) { node.lo[a] = INFINITY; node.hi[a] = -INFINITY; }
        for (std::uint32_t j = begin; j < end; ++j)
            for (int a = 0; a < 3; ++a) {
                node.lo[a] = std::min(node.lo[a], p(order_[j], a));
                node.hi[a] = std::max(node.hi[a], p(order_[j], a));
            }
        if (level == depth) return;
        int axis = 0;
        for (int a = 1; a < 3; ++a)
            if (node.hi[a] - node.lo[a] > node.hi[axis] - node.lo[axis]) axis = a;
        const std::uint32_t mid = begin + (end - begin) / 2;
        std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                         [&](std::uint32_t a, std::uint32_t b) { return p(a, axis) < p(b, axis); });
        if (end - begin > 16384) {
#pragma omp task default(shared) firstprivate(index, begin, mid, level)
            self(self, 2 * index + 1, begin, mid, level + 1);
            self(self, 2 * index + 2, mid, end, level + 1);
#pragma omp taskwait
        } else {
            self(self, 2 * index + 1, begin, mid, level + 1);
            self(self, 2 * index + 2, mid, end, level + 1);
        }
    };
#pragma omp parallel if (n > 16384)
#pragma omp single
    build(build, 0, 0, n, 0);
    xyz_.resize(3 * std::size_t(n));
    for (std::uint32_t j = 0; j < n; ++j)
        for (int a = 0; a < 3; ++a) xyz_[3 * j + std::uint32_t(a)] = p(order_[j], a);
}

double BoxTree::box_distance2(const double* x, std::uint32_t i) const {
    double s = 0;
    for (int a = 0; a < 3; ++a) {
        const double e = std::max({nodes_[i].lo[a] - x[a], x[a] - nodes_[i].hi[a], 0.0});
        s += e * e;
    }
    return s;
}

void BoxTree::knn(const Eigen::Vector3d& q, std::size_t k, std::vector<Neighbor>& out) const {
    k = std::min(k, size());
    const double x[3] = {q.x(), q.y(), q.z()};
    // Sorted squared distances and tree positions of the best k so far.
    thread_local std::vector<double> kd;
    thread_local std::vector<std::uint32_t> ki;
    kd.assign(k, INFINITY);
    ki.assign(k, 0);
    std::uint32_t stack[64];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const std::uint32_t i = stack[--top];
        if (box_distance2(x, i) >= kd[k - 1]) continue;
        if (i >= first_leaf_) {
            for (std::uint32_t j = nodes_[i].begin; j < nodes_[i].end; ++j) {
                const double* p = &xyz_[3 * std::size_t(j)];
                const double d = (x[0] - p[0]) * (x[0] - p[0]) + (x[1] - p[1]) * (x[1] - p[1]) + (x[2] - p[2]) * (x[2] - p[2]);
                if (d >= kd[k - 1]) continue;
                std::size_t m = k - 1;
                while (m > 0 && kd[m - 1] > d) { kd[m] = kd[m - 1]; ki[m] = ki[m - 1]; --m; }
                kd[m] = d;
                ki[m] = j;
            }
        } else {
            const std::uint32_t l = 2 * i + 1, r = 2 * i + 2;
            const bool left_first = box_distance2(x, l) <= box_distance2(x, r);
            stack[top++] = left_first ? r : l;  // the nearer child is visited first
            stack[top++] = left_first ? l : r;
        }
    }
    out.resize(k);
    for (std::size_t m = 0; m < k; ++m) out[m] = {order_[ki[m]], std::sqrt(kd[m])};
}

void BoxTree::radius(const Eigen::Vector3d& q, double r, std::vector<Neighbor>& out) const {
    out.clear();
    const double x[3] = {q.x(), q.y(), q.z()};
    const double r2 = r * r;
    std::uint32_t stack[64];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const std::uint32_t i = stack[--top];
        if (box_distance2(x, i) > r2) continue;
        if (i >= first_leaf_) {
            for (std::uint32_t j = nodes_[i].begin; j < nodes_[i].end; ++j) {
                const double* p = &xyz_[3 * std::size_t(j)];
                const double d = (x[0] - p[0]) * (x[0] - p[0]) + (x[1] - p[1]) * (x[1] - p[1]) + (x[2] - p[2]) * (x[2] - p[2]);
                if (d <= r2) out.push_back({order_[j], std::sqrt(d)});
            }
        } else {
            stack[top++] = 2 * i + 1;
            stack[top++] = 2 * i + 2;
        }
    }
}

}  // namespace gsd::spatial
