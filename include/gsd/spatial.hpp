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

/// reorient_normals' options; the widths are in the cloud's mean spacings h.
struct ReorientOptions {
    int neighbors = 64;          ///< the k nearest points that vote
    double width = 3.0;          ///< Gaussian width of a vote's weight in distance
    double tangent_width = 0.5;  ///< … and in the offset from the point's tangent plane
    double behind_width = 0.1;   ///< … for a neighbour behind the point whose normal opposes it
    int passes = 8;              ///< at most this many passes (each votes with the last's normals)
};

/// Turns back the normals that their neighbours contradict (scattered flips, as a scanner's or a
/// normal estimator's orientation errors make): a point's normal is reversed when the weighted sum
/// of its neighbours' normals points against it, the weights falling off with the distance and
/// with the offset from the point's tangent plane (so the far side of a thin part has no say; a
/// neighbour behind the point whose normal opposes it, as a thin solid's far side lies, is weighed
/// with the narrower `behind_width`).
/// Repeated while anything changes, up to `passes` (the neighbours and their weights are found once:
/// 12 bytes a neighbour while it runs). A patch of flips wider than the neighbourhood
/// votes for itself and stays. Returns how many normals ended reversed (their length kept).
/// Throws gsd::Error on a cloud that validate() rejects or options out of range.
GSD_EXPORT std::size_t reorient_normals(PointCloud& cloud, const ReorientOptions& options = {});

}  // namespace gsd
