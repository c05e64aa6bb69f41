#include <gsd/spatial.hpp>

#include "spatial/morton.hpp"

#include <nanoflann.hpp>

#include <algorithm>
#include <cmath>

namespace gsd {

namespace {
// Zero-copy nanoflann adaptor over a row-major N×3 matrix.
struct PointsAdaptor {
    const Points* p;
    std::size_t kdtree_get_point_count() const { return std::size_t(p->rows()); }
    double kdtree_get_pt(std::size_t i, std::size_t d) const { return (*p)(Eigen::Index(i), Eigen::Index(d)); }
    template <class BBox>
    bool kdtree_get_bbox(BBox&) const { return false; }
};
using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, PointsAdaptor>,
                                                 PointsAdaptor, 3, std::uint32_t>;
}  // namespace

struct KdTree::Impl {
    PointsAdaptor adaptor;
    Tree tree;
    explicit Impl(const Points& p)
        : adaptor{&p}, tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16)) {
        tree.buildIndex();
    }
};

KdTree::KdTree(const Points& points) : points_(&points) {
    if (points.rows() == 0) throw Error("cannot build a spatial index over an empty point set");
    impl_ = std::make_unique<Impl>(points);
}
KdTree::~KdTree() = default;
KdTree::KdTree(KdTree&&) noexcept = default;
KdTree& KdTree::operator=(KdTree&&) noexcept = default;

std::vector<Neighbor> KdTree::knn(const Eigen::Vector3d& q, std::size_t k) const {
    std::vector<Neighbor> out;
    knn(q, k, out);
    return out;
}

void KdTree::knn(const Eigen::Vector3d& q, std::size_t k, std::vector<Neighbor>& out) const {
    k = std::min<std::size_t>(k, std::size_t(points_->rows()));
    thread_local std::vector<std::uint32_t> idx;
    thread_local std::vector<double> d2;
    idx.resize(k);
    d2.resize(k);
    const std::size_t found = impl_->tree.knnSearch(q.data(), k, idx.data(), d2.data());
    out.resize(found);
    for (std::size_t i = 0; i < found; ++i) out[i] = {idx[i], std::sqrt(d2[i])};
}

void KdTree::radius(const Eigen::Vector3d& q, double r, std::vector<Neighbor>& out) const {
    thread_local std::vector<std::pair<std::uint32_t, double>> matches;
    matches.clear();
    nanoflann::SearchParams params;
    params.sorted = false;
    impl_->tree.radiusSearch(q.data(), r * r, matches, params);
    out.resize(matches.size());
    for (std::size_t i = 0; i < matches.size(); ++i)
        out[i] = {matches[i].first, std::sqrt(matches[i].second)};
}

double mean_spacing(const KdTree& tree) {
    const Points& p = tree.points();
    if (p.rows() < 2) throw Error("mean spacing needs at least two points");
    std::vector<double> gap(std::size_t(p.rows()));
    const std::vector<std::uint32_t> order = spatial::morton_order(p);  // searches near each other in turn
#pragma omp parallel
    {
        std::vector<Neighbor> nb;
#pragma omp for schedule(static)
        for (Eigen::Index o = 0; o < p.rows(); ++o) {
            const auto i = Eigen::Index(order[std::size_t(o)]);
            tree.knn(p.row(i).transpose(), 2, nb);
            // nb[0] is the point itself (or a duplicate at distance 0).
            gap[std::size_t(i)] = nb.size() > 1 ? nb[1].distance : 0.0;
        }
    }
    return robust_mean(std::move(gap));  // a stray point far away must not set the scale
}

double mean_spacing(const Points& p) {
    KdTree tree(p);
    return mean_spacing(tree);
}

std::vector<double> point_areas(const KdTree& tree, int k) {
    const Points& p = tree.points();
    const int kk = std::max(1, std::min<int>(k, int(p.rows()) - 1));
    std::vector<double> area(std::size_t(p.rows()));
    const double fallback = [&] {
        const double h = mean_spacing(tree);
        return M_PI * h * h;
    }();
    const std::vector<std::uint32_t> order = spatial::morton_order(p);  // searches near each other in turn
#pragma omp parallel
    {
        std::vector<Neighbor> nb;
#pragma omp for schedule(static)
        for (Eigen::Index o = 0; o < p.rows(); ++o) {
            const auto i = Eigen::Index(order[std::size_t(o)]);
            tree.knn(p.row(i).transpose(), std::size_t(kk) + 1, nb);
            const double dk = nb.back().distance;
            area[std::size_t(i)] = dk > 0 ? M_PI * dk * dk / kk : fallback;
        }
    }
    return area;
}

}  // namespace gsd
