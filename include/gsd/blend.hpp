// gsd/blend.hpp — the options of every blended field: PAT (gsd/pat.hpp) and the SSPD and
// signed Hopf–Cole baselines (gsd/baselines.hpp) sum per-point terms the same way (thesis
// eq. 5.6–5.7), so they share them.
#pragma once

#include <gsd/gpu.hpp>

namespace gsd {

/// Options shared by every blended field (PAT and the SSPD / signed Hopf–Cole baselines); where
/// it runs and the queries per GPU chunk: Execution (gsd/gpu.hpp).
struct BlendOptions : Execution {
    /// Sum over all points (eq. 5.6 with σ_x from all of them) instead of the accelerated sum.
    bool exact = false;
    /// Accelerated mode: the points within ρ = max(r_eval, d_k) are summed, d_k being the
    /// distance to the k = `fallback_k`-th nearest point, with σ = ρ/2, λ = C/σ (eq. 5.7 for
    /// that set). Near the surface that is the ball of radius r_eval with a constant λ; farther
    /// than r_eval from the cloud, the k nearest with λ_x of eq. 5.7 (the thesis' fallback).
    /// Weights are tapered by (1 − (d/ρ)²)³ so φ is continuous where the set changes
    /// (docs/pat.md). r_eval = 0: r_eval_spacings × the cloud's mean spacing.
    double r_eval = 0;
    double r_eval_spacings = 8.0;
    int fallback_k = 32;
    /// exp(−C) is the smallest relative weight kept (thesis: C = 64 stays above float32 underflow).
    double C = 64.0;
};

}  // namespace gsd
