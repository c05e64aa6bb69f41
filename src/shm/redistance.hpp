// Redistancing, shared by the uniform and the adaptive SHM: keep φ's sign and zero set, make
// |φ| the exact distance to that zero set.
#pragma once

#include <gsd/core.hpp>

#include <functional>
#include <memory>
#include <vector>

namespace gsd::sums {
class SumTree;
}

namespace gsd::shm {

/// The zero set's pieces in a tree for distance queries (SumTree::nearest_distance); null when
/// it has no triangle of area.
std::shared_ptr<const sums::SumTree> zero_set_tree(const PolygonMesh& zero_set);

/// |φ_i| → the distance from node i to the pieces of `zero_set` (as below, from its tree).
void redistance(const sums::SumTree& zero_set, std::vector<double>& phi, const std::function<Eigen::Vector3d(std::size_t)>& position);

/// |φ_i| → the distance from node i (at `position(i)`) to `zero_set` (φ's zero level set as
/// triangles, a soup will do), the sign kept; nodes where φ = 0 stay 0. Consecutive nodes
/// should be near each other (each search starts from the last node's nearest triangle).
/// Returns the zero set's triangle count; 0 (φ untouched) when it has no triangle of area.
std::size_t redistance(const PolygonMesh& zero_set, std::vector<double>& phi,
                       const std::function<Eigen::Vector3d(std::size_t)>& position);

}  // namespace gsd::shm
