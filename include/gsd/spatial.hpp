// gsd/spatial.hpp — nearest-neighbor queries over a point set (CPU).
//
// `KdTree` wraps nanoflann over the caller's `Points` without copying them: the matrix must
// outlive the tree and must not be resized while the tree exists.
#pragma once

#include <gsd/export.hpp>

#include <gsd/core.hpp>

#include <memory>
#include <vector>

namespace gsd {

struct Neighbor {
    std::uint32_t index;
    double distance;  ///< Euclidean (not squared)
};

class GSD_EXPORT KdTree {
public:
    explicit KdTree(const Points& points);
    ~KdTree();
    KdTree(KdTree&&) noexcept;
    KdTree& operator=(KdTree&&) noexcept;

    /// The k nearest points to q, nearest first (fewer if the set is smaller).
    std::vector<Neighbor> knn(const Eigen::Vector3d& q, std::size_t k) const;
    /// Same, writing into `out` (reused across calls to avoid allocation).
    void knn(const Eigen::Vector3d& q, std::size_t k, std::vector<Neighbor>& out) const;
    /// All points within `radius` of q (inclusive), in no particular order.
    void radius(const Eigen::Vector3d& q, double radius, std::vector<Neighbor>& out) const;

    const Points& points() const { return *points_; }

private:
    struct Impl;
    const Points* points_;
    std::unique_ptr<Impl> impl_;
};

/// Mean distance from each point to its nearest other point (duplicates count as 0; each
/// capped at kRobustMeanCap × the median, see robust_mean): the spacing h that scales default
/// parameters. Throws if there are fewer than two points.
GSD_EXPORT double mean_spacing(const Points& p);
GSD_EXPORT double mean_spacing(const KdTree& tree);

/// Per-point area estimate A_i = π d_k² / k, with d_k the distance to the k-th nearest
/// other point: the area of the disk that holds the point's k neighbors, shared among them.
/// Used as the quadrature weight of a point sample.
GSD_EXPORT std::vector<double> point_areas(const KdTree& tree, int k = 8);

}  // namespace gsd
