// Redistancing (shm/redistance.hpp).
#include "shm/redistance.hpp"

#include <gsd/sums.hpp>

#include "sums/sum_tree.hpp"

namespace gsd::shm {

std::shared_ptr<const sums::SumTree> zero_set_tree(const PolygonMesh& zero_set) {
    OrientedElements pieces;
    try {
        pieces = OrientedElements::from_mesh(zero_set);
    } catch (const Error&) {
        return nullptr;  // no zero crossing (or only degenerate pieces): nothing to measure from
    }
    return std::make_shared<const sums::SumTree>(pieces);
}

void redistance(const sums::SumTree& tree, std::vector<double>& phi, const std::function<Eigen::Vector3d(std::size_t)>& position) {
#pragma omp parallel
    {
        std::uint32_t hint = std::uint32_t(-1);  // the last node's nearest triangle
#pragma omp for schedule(dynamic, 4096)
        for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(phi.size()); ++i) {
            double& v = phi[std::size_t(i)];
            if (v == 0) continue;
            const double d = tree.nearest_distance(position(std::size_t(i)), INFINITY, &hint);
            v = v < 0 ? -d : d;
        }
    }
}

std::size_t redistance(const PolygonMesh& zero_set, std::vector<double>& phi,
                       const std::function<Eigen::Vector3d(std::size_t)>& position) {
    const auto tree = zero_set_tree(zero_set);
    if (!tree) return 0;
    redistance(*tree, phi, position);
    return tree->size();
}

}  // namespace gsd::shm
