// Step 3 of the adaptive SHM: the least-squares Poisson problem on the octree's node graph with
// the zero set fitted softly, (L + μ SᵀAS) φ = b, solved by conjugate gradients preconditioned
// with a multigrid V-cycle over the octree's levels (the tree cut at D, D − 1, …: nested node
// sets, trilinear transfers, each level's operator assembled the same way, its zero-set samples
// merged per cell of that level), and CHOLMOD on the coarsest level.
#pragma once

#include "shm/octree.hpp"

#include <gsd/core.hpp>

#include <memory>
#include <span>
#include <vector>

namespace gsd::shm {

/// A point of the source where φ should vanish, with the area it stands for.
struct ZeroSample {
    Eigen::Vector3d position;
    double area = 0;
};

/// The samples merged per cell of `level`: a cell's samples become one at their area-weighted
/// centroid with their total area (samples of no area keep the first one's position). Order:
/// by the cells' Morton codes. `merged_into`, if given, receives each sample's merged index.
std::vector<ZeroSample> merge_by_cell(const Octree& tree, const std::vector<ZeroSample>& samples, int level,
                                      std::vector<std::uint32_t>* merged_into = nullptr);

/// Prolongation P from the tree cut at level l − 1 (coarse) to the tree cut at l (fine): a node
/// both share keeps its value; a new one is a corner of a cell of level l, so it lies at an edge
/// midpoint, face center or center of that cell's parent, a leaf of the coarse cut, and takes
/// the mean of that edge's, face's or cell's 2, 4 or 8 corners (the coarse field's trilinear
/// value there). Applied through the fine graph, no sources stored per node: a new node is off the
/// coarse lattice along 1, 2 or 3 axes, and its neighbours along those axes, half a coarse cell
/// away, are nodes off it along one axis fewer; the mean of those 2, 4 or 6 neighbours (each
/// the mean of its own) is the mean of the corners. The shared nodes come in the same order on
/// both levels (sorted keys), so a block's first shared node's coarse index is all it keeps
/// besides a byte a node (the axes it is off the coarse lattice along).
class Prolongation {
public:
    Prolongation() = default;
    /// Checks that the levels nest (throws if not).
    Prolongation(const Octree& tree, const NodeGraph& fine, const NodeGraph& coarse);
    /// out = P coarse (`fine`: the graph it was made with); in double or in float (the V-cycle).
    void prolong(const NodeGraph& fine, std::span<const double> coarse, std::span<double> out) const;
    void prolong(const NodeGraph& fine, std::span<const float> coarse, std::span<float> out) const;
    /// coarse = Pᵀ f; f (fine-sized) is overwritten.
    void restrict_in_place(const NodeGraph& fine, std::span<double> f, std::span<double> coarse) const;
    void restrict_in_place(const NodeGraph& fine, std::span<float> f, std::span<float> coarse) const;
    /// fine += P coarse; coarse = Pᵀ fine (each with a fine-sized copy: tests).
    void add_to(const NodeGraph& fine_graph, std::span<const double> coarse, std::span<double> fine) const;
    void restrict_to(const NodeGraph& fine_graph, std::span<const double> fine, std::span<double> coarse) const;
    std::size_t fine_size() const { return fine_size_; }

private:
    template <class T>
    void prolong_as(const NodeGraph& fine, std::span<const T> coarse, std::span<T> out) const;
    template <class T>
    void restrict_in_place_as(const NodeGraph& fine, std::span<T> f, std::span<T> coarse) const;
    /// The axes along which node i is off the coarse lattice (bit a for axis a).
    unsigned off_axes(const NodeGraph& fine, std::size_t i) const;

    std::uint32_t half_ = 0;  // a fine cell's side where new nodes are: half a coarse one, in lattice steps
    std::size_t fine_size_ = 0;
    std::vector<std::uint32_t> block_first_;  // per block of kBlock fine nodes: its first shared node's coarse index
    std::vector<std::uint8_t> off_;           // off_axes of each fine node (1 byte a node, read in every pass)
};

struct OctreePoissonStats {
    std::vector<std::size_t> level_nodes;  ///< nodes per multigrid level, finest first
    std::vector<double> residual_history;  ///< relative residual after each CG iteration
    double seconds_setup = 0, seconds_solve = 0;
};

class OctreePoisson {
public:
    /// `penalty`: μ, the weight of Σ_j A_j φ(y_j)² against the volume-weighted energy (> 0: it
    /// also pins the constant, which the Laplacian alone leaves free; 0: no penalty, the
    /// constant pinned by raising the diagonal by 1e-9 of itself, the operator as sparse as the
    /// Laplacian: the solve of φ₀ before fit_on_level).
    OctreePoisson(const Octree& tree, std::vector<ZeroSample> samples, double penalty);
    /// The same with the finest level's graph (build_node_graph(tree, tree.depth())) made by
    /// the caller, who needed its nodes first (step 1 runs at them before the operators exist).
    OctreePoisson(const Octree& tree, NodeGraph finest, std::vector<ZeroSample> samples, double penalty);
    ~OctreePoisson();

    const NodeGraph& nodes() const;
    /// The finest level's keys, moved out (not copied) for the field that outlives the solver;
    /// nothing else may be asked of the solver after.
    std::vector<std::uint64_t> take_finest_keys();
    /// b of the normal equations from Y (3 floats per finest node).
    std::vector<double> divergence(const std::vector<float>& Y) const;
    /// Solves to ‖b − Aφ‖ ≤ tolerance·‖b‖ or max_iterations (b is taken: its memory holds the
    /// residual while the solve iterates). Without a penalty the constant is free (the pin only
    /// nudges it): b and the residuals are taken free of their means, the tolerance is on those
    /// (and so is `residual_history`), and φ's constant is CG's; the caller sets it.
    /// Not const: the levels' keys are held packed while it iterates (NodeGraph::pack_keys).
    std::vector<double> solve(std::vector<double> b, double tolerance, int max_iterations, OctreePoissonStats& stats,
                              const ProgressFn& progress = {});
    /// Changes μ (the constructor's `penalty`): every level's penalty rows, smoother and the
    /// coarsest factor (refactored numerically when the pattern is the same: μ stays > 0 or
    /// stays 0; analysed and factored again when μ goes between 0 and > 0). The samples' rows of
    /// interpolation weights (S) are made the first time μ > 0: φ₀'s solve (μ = 0) runs without
    /// them, so they never share memory with its CG vectors.
    void set_penalty(double penalty);
    /// The zero set fitted as a smooth correction (as SignedHeatGrid's fit): ψ on the tree cut
    /// at `level` (clamped to the multigrid's levels) minimizing that level's energy plus
    /// μ Σ_j A_j (φ(y_j) + ψ(y_j))² over its merged samples (φ(y_j): φ's area-weighted mean over
    /// the finest samples merged into sample j), prolonged to the finest level and added to φ.
    /// `history`: the relative residual after each CG iteration. Returns the level it fitted on.
    int fit_on_level(std::vector<double>& phi, int level, double tolerance, int max_iterations,
                     std::vector<double>& history, const ProgressFn& progress = {}) const;
    /// The octree level of the multigrid's coarsest (factored) level.
    int coarsest_level() const;
    /// y = A x on the finest level (tests).
    std::vector<double> apply(const std::vector<double>& x) const;
    /// Area-weighted mean of φ over the samples.
    double mean_on_samples(const std::vector<double>& phi) const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace gsd::shm
