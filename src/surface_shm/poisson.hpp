// poisson.hpp — step 3 of the surface Signed Heat Method on one triangulation: K φ = g (the
// cotan Laplacian, g the divergence of the unit field Y) with the level-set constraints of
// eq. 4.11, exact where they can be and soft where exact rows would pin φ to 0 next to the
// curve (SurfaceShmOptions::soft_weight). The solver of the input (or intrinsic) triangulation
// is built once per mesh and cached; the L1 integration builds a second one on the
// triangulation cut along its jumps. Private to src/surface_shm.
#pragma once

#include <gsd/surface.hpp>

#include "surface_shm/cholesky.hpp"
#include "surface_shm/curves.hpp"
#include "surface_shm/operators.hpp"
#include "mesh/triangulation.hpp"

#include <Eigen/Sparse>

#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

namespace gsd::surface_shm {

/// Sparse constraint rows over vertices: row r is Σ_k coef_k φ(vertex_k) (= 0).
struct ConstraintRows {
    std::vector<std::vector<std::pair<std::uint32_t, double>>> rows;

    void add(std::vector<std::pair<std::uint32_t, double>> row);  // repeated vertices merged
    std::size_t size() const { return rows.size(); }
    std::vector<double> apply(const std::vector<double>& phi) const;                                // C φ
    void add_transpose(const std::vector<double>& y, double scale, std::vector<double>& out) const;  // out += s Cᵀ y
};

class ConstrainedPoisson {
public:
    /// Assembles K on `T` (which must outlive this object); factors are made on first use.
    ConstrainedPoisson(const mesh::Triangulation& T, const std::vector<double>& areas);

    /// φ per vertex of T: min ∫|∇φ − Y|² (K φ = g) under the options' level-set rows. Fills
    /// r.constraints, r.constraint_residual, r.constraint_iterations.
    std::vector<double> solve(const std::vector<double>& g, const ResolvedSources& S, const SurfaceShmOptions& o,
                              SurfaceShmResult& r);

    /// The mean of φ along the curves (or over the points, without curves): the shift that
    /// puts the curves at level 0 when no constraint does.
    double source_mean(const std::vector<double>& phi, const ResolvedSources& S) const;

private:
    struct Constraints {
        ConstraintRows exact, soft;
    };
    Constraints constraint_rows(const ResolvedSources& S, LevelSetConstraint mode, bool all_exact) const;
    void split_by_consistency(const ConstraintRows& rows, const std::vector<std::uint32_t>& fixed, bool differences,
                              Constraints& C) const;
    std::vector<double> solve_constrained(const Constraints& C, const std::vector<std::uint32_t>& pins,
                                          const std::vector<double>& g, double w_soft, SurfaceShmResult& r);
    std::vector<std::uint32_t> free_components(const Constraints& C, bool rows_fix_levels) const;
    std::vector<double> solve_exact(const ConstraintRows& C, const std::vector<double>& g, SurfaceShmResult& r) const;
    Cholesky<double> factor_like_K(const SparseLower<double>& A) const;
    const Cholesky<double>& plain_poisson();
    SparseLower<double> with_pins(SparseLower<double> A, const std::vector<std::uint32_t>& pins) const;

    const mesh::Triangulation* T_;
    const std::vector<double>* areas_;
    SparseLower<double> stiffness_;         // K, lower triangle
    StiffnessComponents components_;        // where K's nullspace is constant
    std::vector<double> pin_weight_;        // diagonal of K
    std::optional<Cholesky<double>> poisson_;      // factor of K + a pin per component
    std::optional<Cholesky<double>> constrained_;  // factor of K + pins + w CᵀC (same pattern)
};

}  // namespace gsd::surface_shm
