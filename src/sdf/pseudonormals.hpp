// pseudonormals.hpp — the sign of the distance from angle-weighted pseudonormals (Bærentzen and
// Aanæs 2005): at the nearest point p of a query x, the normal of the feature p lies on — the
// face, an edge (the sum of its faces' normals) or a vertex (its faces' normals weighted by
// their angles there) — has (x − p)·n > 0 exactly when x is outside, on a closed, consistently
// oriented manifold without self-intersections. Private to src/sdf.
#pragma once

#include "sdf/triangles.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <unordered_map>
#include <vector>

namespace gsd::sdf {

/// The nearest point p of triangle abc to x, and the feature it lies on: corner k (0–2), side
/// k → k+1 (3 + k), or inside (6).
int nearest_feature(const Eigen::Vector3d& x, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                    const Eigen::Vector3d& c, Eigen::Vector3d& p);

class Pseudonormals {
public:
    explicit Pseudonormals(const Triangles& t);
    /// True if x, whose nearest triangle is t.triangles[f], is inside (behind the pseudonormal).
    bool inside(const Eigen::Vector3d& x, std::uint32_t f) const;

private:
    const Triangles& t_;
    std::vector<Eigen::Vector3d> face_, vertex_;
    std::unordered_map<std::uint64_t, Eigen::Vector3d> edge_;  // key: lo << 32 | hi
};

}  // namespace gsd::sdf
