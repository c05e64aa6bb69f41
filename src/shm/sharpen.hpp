// Distance sharpening on a grid (thesis §4.4, eq. 4.13) as a linear program solved by the
// diagonally preconditioned primal–dual hybrid gradient (Pock & Chambolle 2011):
//
//   max Σ_i s_i φ_i   s.t.  |D φ|_i ≤ 1 at every node,   P φ = 0 (softly, weight w),
//                           s_i φ_i ≥ 0 (keep_sign)
//
// s_i = sign(φ₀_i), times the objective's weight against the constraints (PDLP's "primal
// weight"); D: forward differences per node (a node's own three, one per axis, where the
// next node exists); P: one row per grid cell that the zero set crosses, the area-weighted mean
// of the trilinear weights of the zero set's samples in that cell (one row per cell, not per
// sample: many samples of a curved surface in one cell would ask a trilinear φ to vanish on a
// surface it cannot represent, and the only φ that does is 0 on the whole cell). Private.
//
// PDHG converges slowly on a linear program, and the dual starts far from its optimum (a flow
// that carries every node's weight to the zero set) while φ₀ starts near φ's: so every
// `restart` iterations φ, p and q are replaced by their averages over those iterations (restarts
// to the average, as PDLP: Applegate et al. 2021, 2023), which turns the slow ergodic
// convergence into a fast one on these problems.
//
// Both the CPU loop (sharpen.cpp) and the compute shaders (sharpen_gpu.cpp) run this, in float32
// and in the same order per node, so the device equals the CPU to rounding.
#pragma once

#include <gsd/shm.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace gsd::gpu { class Context; }

namespace gsd::shm {

struct SharpenProblem {
    int n[3] = {0, 0, 0};          ///< nodes per axis
    float inv_h[3] = {0, 0, 0};    ///< 1 / spacing per axis
    float sigma_d = 0;             ///< dual step of the gradient blocks: min_a h_a / 2
    float row_scale = 0;           ///< β: P's rows are scaled by 1/h_min, like D's
    float damping = 0;             ///< soft zero set: q ← (q + σ_q β P φ̄) · damping, 1/(1 + σ_q/w)
    float sign_floor = 0;          ///< keep_sign: s·φ ≥ sign_floor (a strict side)
    int restart = 0;               ///< iterations between restarts to the average
    std::vector<float> tau;        ///< primal step per node: 1 / (column sum of |K|)
    std::vector<float> sign;       ///< s_i ∈ {−1, 0, 1}
    std::vector<std::uint32_t> row_cell;  ///< per zero-set row: the node index of its cell's corner (0, 0, 0)
    std::vector<float> row_weight;        ///< per row: 8 trilinear weights (corner c = x + 2y + 4z), summing to 1
    std::vector<std::uint32_t> node_first;  ///< CSR over nodes: entries node_first[i] … node_first[i + 1]
    std::vector<std::uint32_t> entry_row;   ///< the row of each entry
    std::vector<float> entry_weight;        ///< its weight (P's entry, before β)
    std::size_t nodes() const { return std::size_t(n[0]) * std::size_t(n[1]) * std::size_t(n[2]); }
};

/// Builds the program for a grid, the warm start φ₀ and the zero set's samples.
SharpenProblem build_sharpen_problem(const GridSpec& grid, std::span<const float> phi0, const ShmSource& zero_set,
                                     const SharpenOptions& options);

/// The iteration state: φ, its extrapolation φ̄ = 2φ_new − φ_old, the dual variables.
struct SharpenState {
    std::vector<float> phi, phi_bar;
    std::vector<float> p;  ///< 3 per node
    std::vector<float> q;  ///< 1 per zero-set row
    /// Sums of φ, p and q over the iterations since the last restart, and their count.
    std::vector<float> phi_sum, p_sum, q_sum;
    int summed = 0;
    SharpenState(std::span<const float> phi0, std::size_t rows);
};

/// Runs `iterations` PDHG steps on the CPU (OpenMP), from `state`, restarting every
/// problem.restart iterations counted from the state's last restart.
void sharpen_cpu(const SharpenProblem& problem, bool keep_sign, SharpenState& state, int iterations,
                 const ProgressFn& progress);

/// The same on a device; false (with why_not) when it cannot hold the problem. Only `state.phi`
/// comes back.
bool sharpen_gpu(const std::shared_ptr<gpu::Context>& ctx, const SharpenProblem& problem, bool keep_sign,
                 SharpenState& state, int iterations, const ProgressFn& progress, std::string& why_not);

}  // namespace gsd::shm
