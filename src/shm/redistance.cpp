// Redistancing (shm/redistance.hpp).
#include "shm/redistance.hpp"

#include <gsd/sums.hpp>

#include "sums/sum_tree.hpp"

namespace gsd::shm {

std::size_t redistance(const PolygonMesh& zero_set, std::vector<double>& phi,
                       const std::function<Eigen::Vector3d(std::size_t)>& position) {
    OrientedElements pieces;
    try {
        pieces = OrientedElements::from_mesh(zero_set);
    } catch (const Error&) {
        return 0;  // no zero crossing (or only degenerate pieces): nothing to measure from
    }
    const sums::SumTree tree(pieces);
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
    return pieces.size();
}

}  // namespace gsd::shm
