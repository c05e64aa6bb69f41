// Step 1–2 of the grid SHM: diffused, normalized source normals Y at grid nodes.
//
// The free-space solution of (id − tΔ)X = Σ_j A_j N_j δ_{y_j} is X(x) = Σ_j A_j N_j G(x, y_j)
// with the screened kernel G = exp(−λr)/(4π t r), λ = 1/√t. Only Y = X/|X| is needed, so the
// kernel is evaluated with exp(−λ r_min) factored out (r_min: the nearest source), which keeps
// far-field directions defined in any precision, and sources with r > r_min + cutoff/λ —
// weight below e^(−cutoff) of the nearest — are dropped. Far from the source Y varies on the
// scale of the distance, so it is evaluated exactly only near the source on each level of a
// coarse-to-fine hierarchy of grids and interpolated elsewhere (docs/shm.md).
#pragma once

#include <gsd/shm.hpp>

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/uninitialized.hpp"
#include "sums/sum_tree.hpp"

namespace gsd::gpu { class Context; }

namespace gsd::shm {

struct KernelParams {
    double lambda = 0;  ///< 1/√t
    double cutoff = 12; ///< drop sources with weight < e^(−cutoff) of the nearest
    double r_floor = 0; ///< distances below this count as r_floor (1/r is singular at a source)
    double sum_tolerance = 0.3; ///< expansion accuracy (ShmOptions::sum_tolerance)
};

/// Exact Y and r_min at a batch of points.
class DirectionEvaluator {
public:
    virtual ~DirectionEvaluator() = default;
    /// y: 3 floats per point (unit, or 0 where X vanishes); r_min: distance to the nearest source.
    /// Returns the number of source terms summed.
    virtual std::size_t evaluate(const Points& x, std::vector<float>& y, std::vector<double>& r_min,
                                 const ProgressFn& progress) = 0;
    virtual std::string device() const = 0;
};

/// Step 1's parameters for a source: λ = 1/√t with t = t_coef·h², the singularity floored at
/// 1e-3 h (the uniform and the adaptive grid alike).
KernelParams kernel_params(const ShmSource& source, double t_coef, double cutoff, double sum_tolerance);

std::unique_ptr<DirectionEvaluator> make_cpu_evaluator(const ShmSource& src, const KernelParams& k);
/// The same parameters as the tree's screened sum takes them (sums/sum_tree.hpp).
sums::SumTree::Screened screened_params(const KernelParams& k);
/// Null (and a reason) when the device cannot take the source.
std::unique_ptr<DirectionEvaluator> make_gpu_evaluator(const std::shared_ptr<gpu::Context>& ctx, const ShmSource& src,
                                                       const KernelParams& k, std::size_t chunk_size, std::string& why_not);

/// Area samples of the source for the zero-set shift: points as they are, triangles split
/// until no longer than max_element near `focus` (coarser away from it). emit(position, area).
void for_each_sample(const ShmSource& source, double max_element, const Box& focus,
                     const std::function<void(const Eigen::Vector3d&, double)>& emit);

struct DiffuseStats {
    std::size_t exact_nodes = 0, kernel_terms = 0;
    double seconds_sums = 0;  ///< in DirectionEvaluator::evaluate
};

/// Y at every node of `grid` (3 floats per node, GridSpec order): exact within
/// interpolation_cells cells of the source on each level, interpolated beyond.
detail::UninitializedVector<float> diffuse(const GridSpec& grid, DirectionEvaluator& eval, double interpolation_cells,
                                           DiffuseStats& stats, const ProgressFn& progress);

}  // namespace gsd::shm
