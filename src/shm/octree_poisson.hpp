// Step 3 of the adaptive SHM: the least-squares Poisson problem on the octree's node graph with
// the zero set fitted softly, (L + μ SᵀAS) φ = b, solved by conjugate gradients preconditioned
// with a multigrid V-cycle over the octree's levels (the tree cut at D, D − 1, …: nested node
// sets, trilinear transfers, each level's operator assembled the same way), and CHOLMOD on the
// coarsest level.
#pragma once

#include "shm/octree.hpp"

#include <gsd/core.hpp>

#include <memory>
#include <vector>

namespace gsd::shm {

/// A point of the source where φ should vanish, with the area it stands for.
struct ZeroSample {
    Eigen::Vector3d position;
    double area = 0;
};

struct OctreePoissonStats {
    std::vector<std::size_t> level_nodes;  ///< nodes per multigrid level, finest first
    std::vector<double> residual_history;  ///< relative residual after each CG iteration
    double seconds_setup = 0, seconds_solve = 0;
};

class OctreePoisson {
public:
    /// `penalty`: μ, the weight of Σ_j A_j φ(y_j)² against the volume-weighted energy (> 0: it
    /// also pins the constant, which the Laplacian alone leaves free).
    OctreePoisson(const Octree& tree, std::vector<ZeroSample> samples, double penalty);
    ~OctreePoisson();

    const NodeGraph& nodes() const;
    /// b of the normal equations from Y (3 floats per finest node).
    std::vector<double> divergence(const std::vector<float>& Y) const;
    /// Solves to ‖b − Aφ‖ ≤ tolerance·‖b‖ or max_iterations.
    std::vector<double> solve(const std::vector<double>& b, double tolerance, int max_iterations, OctreePoissonStats& stats,
                              const ProgressFn& progress = {}) const;
    /// y = A x on the finest level (tests).
    std::vector<double> apply(const std::vector<double>& x) const;
    /// Area-weighted mean of φ over the samples.
    double mean_on_samples(const std::vector<double>& phi) const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace gsd::shm
