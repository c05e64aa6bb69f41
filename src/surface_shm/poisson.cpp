// Step 3 of the surface SHM on one triangulation (poisson.hpp). Constraints never refactor the
// plain Poisson factor: they go into a second factor of K + w CᵀC, whose pattern is K's (every
// constraint row lives in one face), so it is refactored numerically without a new analysis;
// hard constraints are then met exactly by iterative refinement of the KKT system [K Cᵀ; C 0]
// with that penalized factor as the preconditioner. Duplicate or nearly equal constraint rows
// (closed loops, reversed pieces, pieces meeting at a point) cannot make this singular, unlike
// a direct factorization of the saddle-point matrix.
#include "surface_shm/poisson.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace gsd::surface_shm {

using mesh::FacePoint;

namespace {

std::vector<std::pair<std::uint32_t, double>> interpolation_row(const mesh::Triangulation& T, const FacePoint& p, double sign) {
    std::vector<std::pair<std::uint32_t, double>> row;
    for (int k = 0; k < 3; ++k)
        if (p.bary[std::size_t(k)] != 0.0) row.push_back({T.faces[p.face][std::size_t(k)], sign * p.bary[std::size_t(k)]});
    return row;
}

double norm_inf(const std::vector<double>& v) {
    double m = 0;
    for (double x : v) m = std::max(m, std::abs(x));
    return m;
}

}  // namespace

void ConstraintRows::add(std::vector<std::pair<std::uint32_t, double>> row) {
    // Merge repeated vertices (a face may repeat a vertex in an intrinsic triangulation).
    std::sort(row.begin(), row.end());
    std::vector<std::pair<std::uint32_t, double>> merged;
    for (const auto& [v, c] : row) {
        if (!merged.empty() && merged.back().first == v) merged.back().second += c;
        else merged.push_back({v, c});
    }
    std::erase_if(merged, [](const auto& x) { return x.second == 0.0; });
    if (!merged.empty()) rows.push_back(std::move(merged));
}

std::vector<double> ConstraintRows::apply(const std::vector<double>& phi) const {
    std::vector<double> out(rows.size(), 0.0);
    for (std::size_t r = 0; r < rows.size(); ++r)
        for (const auto& [v, c] : rows[r]) out[r] += c * phi[v];
    return out;
}

void ConstraintRows::add_transpose(const std::vector<double>& y, double scale, std::vector<double>& out) const {
    for (std::size_t r = 0; r < rows.size(); ++r)
        for (const auto& [v, c] : rows[r]) out[v] += scale * c * y[r];
}

ConstrainedPoisson::ConstrainedPoisson(const mesh::Triangulation& T, const std::vector<double>& areas)
    : T_(&T), areas_(&areas), stiffness_(cotan_laplacian(T, areas)), components_(stiffness_components(T, areas)) {
    pin_weight_.assign(stiffness_.n, 0.0);
    for (std::size_t k = 0; k < stiffness_.entries(); ++k)
        if (stiffness_.rows[k] == stiffness_.cols[k]) pin_weight_[std::size_t(stiffness_.rows[k])] += stiffness_.values[k];
}

/// A factor of A (whose pattern is K's): the ordering and symbolic analysis are computed once
/// and shared by the plain and the constrained factors.
Cholesky<double> ConstrainedPoisson::factor_like_K(const SparseLower<double>& A) const {
    if (poisson_) return Cholesky<double>(*poisson_, A);
    if (constrained_) return Cholesky<double>(*constrained_, A);
    return Cholesky<double>(A);
}

const Cholesky<double>& ConstrainedPoisson::plain_poisson() {
    if (!poisson_) poisson_.emplace(factor_like_K(with_pins(stiffness_, components_.pins)));
    return *poisson_;
}

/// K plus a diagonal term at one vertex of each chosen component: it fixes the constant that K
/// leaves free there, as well conditioned as K itself (weight: K's own diagonal).
SparseLower<double> ConstrainedPoisson::with_pins(SparseLower<double> A, const std::vector<std::uint32_t>& pins) const {
    for (std::uint32_t v : pins) A.add(v, v, pin_weight_[v]);
    return A;
}

ConstrainedPoisson::Constraints ConstrainedPoisson::constraint_rows(const ResolvedSources& S, LevelSetConstraint mode,
                                                                   bool all_exact) const {
    // Rows whose points are all vertices (a node at a vertex; a piece along an edge between
    // vertices) are always consistent and are met exactly. Rows with points on edges or inside
    // faces are exact too where they leave φ free to be nonzero next to the curve; where they do
    // not (see SurfaceShmOptions::soft_weight), they are soft unless the caller asks for exact.
    Constraints C;
    const mesh::Triangulation& tri = *T_;
    auto at_vertex = [](const FacePoint& p) {
        int nonzero = 0;
        for (double b : p.bary) nonzero += b != 0.0;
        return nonzero == 1;
    };
    ConstraintRows candidates;
    std::vector<std::uint32_t> fixed_vertices;  // zero-set rows at vertices: φ = 0 there
    if (mode == LevelSetConstraint::ZeroSet) {
        for (const FacePoint& p : S.nodes) {
            const bool vertex = at_vertex(p);
            (all_exact || vertex ? C.exact : candidates).add(interpolation_row(tri, p, 1.0));
            if (vertex) fixed_vertices.push_back(C.exact.rows.back().front().first);
        }
    } else if (mode == LevelSetConstraint::Components) {
        // φ(a) = φ(b) along every piece: each connected component of the curves gets one level.
        for (const surface_shm::CurvePiece& c : S.pieces) {
            const FacePoint a{c.segment.face, c.segment.a}, b{c.segment.face, c.segment.b};
            auto row = interpolation_row(tri, a, 1.0);
            const auto rb = interpolation_row(tri, b, -1.0);
            row.insert(row.end(), rb.begin(), rb.end());
            (all_exact || (at_vertex(a) && at_vertex(b)) ? C.exact : candidates).add(std::move(row));
        }
    }
    split_by_consistency(candidates, fixed_vertices, mode == LevelSetConstraint::Components, C);
    return C;
}

void ConstrainedPoisson::split_by_consistency(const ConstraintRows& rows, const std::vector<std::uint32_t>& fixed,
                                                   bool differences, Constraints& C) const {
    // Rows that share vertices form groups. Generically a group of R rows on V vertices, Z of
    // them fixed to 0 by vertex rows, leaves φ a nonzero solution there only if R + Z < V
    // (difference rows always allow constants, so: only if R < V − 1). A group that fails the
    // count would be forced to 0 (or to one constant) on every vertex it touches: soft rows.
    std::unordered_map<std::uint32_t, std::uint32_t> parent;
    auto root = [&](std::uint32_t x) {
        auto it = parent.try_emplace(x, x).first;
        while (it->second != x) {
            x = it->second;
            it = parent.find(x);
        }
        return x;
    };
    for (const auto& row : rows.rows)
        for (const auto& [v, c] : row) parent[root(v)] = root(row.front().first);
    std::unordered_map<std::uint32_t, long long> balance;  // V − R − Z per group
    for (const auto& [v, p] : parent) ++balance[root(v)];
    for (const auto& row : rows.rows) --balance[root(row.front().first)];
    for (std::uint32_t v : fixed)
        if (parent.count(v)) --balance[root(v)];
    for (const auto& row : rows.rows) {
        const long long room = balance[root(row.front().first)];
        (room > (differences ? 1 : 0) ? C.exact : C.soft).rows.push_back(row);
    }
}

std::vector<double> ConstrainedPoisson::solve_constrained(const Constraints& C,
                                                               const std::vector<std::uint32_t>& pins,
                                                               const std::vector<double>& g, double w_soft,
                                                               SurfaceShmResult& r) {
    // F = K + pins + w_soft CsᵀCs + w_exact CeᵀCe. Every row's vertices share a face, so F has
    // K's pattern and is refactored without a new analysis. The exact rows' penalty, far above
    // the stiffness scale, only preconditions the conjugate gradients that meet them exactly.
    double diag = 0;
    for (std::size_t k = 0; k < stiffness_.entries(); ++k)
        if (stiffness_.rows[k] == stiffness_.cols[k]) diag = std::max(diag, std::abs(stiffness_.values[k]));
    const double w_exact = 1e6 * diag;
    SparseLower<double> A = with_pins(stiffness_, pins);
    auto add_penalty = [&A](const ConstraintRows& rows, double w) {
        for (const auto& row : rows.rows)
            for (std::size_t i = 0; i < row.size(); ++i)
                for (std::size_t j = 0; j <= i; ++j) {
                    const auto [vi, ci] = row[i];
                    const auto [vj, cj] = row[j];
                    A.add(std::max(vi, vj), std::min(vi, vj), w * ci * cj);
                }
    };
    add_penalty(C.soft, w_soft);
    add_penalty(C.exact, w_exact);
    if (!constrained_) constrained_.emplace(factor_like_K(A));
    else constrained_->refactor(A);
    if (C.exact.size() == 0) return constrained_->solve(g);
    return solve_exact(C.exact, g, r);
}

std::vector<double> ConstrainedPoisson::solve_exact(const ConstraintRows& C, const std::vector<double>& g,
                                                         SurfaceShmResult& r) const {
    // Exact constraints from the penalized factor F = K + pins + w CᵀC: φ(λ) = F⁻¹(g − Cᵀλ)
    // satisfies K φ + Cᵀ(λ + w Cφ) = g for any λ, so only C φ(λ) = 0 is left, i.e. the SPD
    // system C F⁻¹ Cᵀ λ = C F⁻¹ g. Its eigenvalues σ/(1 + wσ) (σ those of C K⁻¹ Cᵀ) crowd
    // below 1/w, except for nearly dependent rows (nodes almost on top of each other), which
    // conjugate gradients absorb in a few extra steps. One F-solve per step.
    const std::vector<double> phi0 = constrained_->solve(g);
    const double scale = std::max(norm_inf(phi0), 1e-300);
    std::vector<double> lambda(C.size(), 0.0), res = C.apply(phi0), p = res;
    std::vector<double> correction(g.size(), 0.0);  // Σ F⁻¹Cᵀ(step) accumulated: φ = φ0 − correction
    double rr = 0;
    for (double x : res) rr += x * x;
    int it = 0;
    for (; it < 200 && norm_inf(res) > 1e-12 * scale; ++it) {
        std::vector<double> Ctp(g.size(), 0.0);
        C.add_transpose(p, 1.0, Ctp);
        const std::vector<double> z = constrained_->solve(Ctp);  // F⁻¹ Cᵀ p
        const std::vector<double> Sp = C.apply(z);
        double pSp = 0;
        for (std::size_t k = 0; k < p.size(); ++k) pSp += p[k] * Sp[k];
        if (!(pSp > 0)) break;  // converged to rounding
        const double a = rr / pSp;
        for (std::size_t k = 0; k < p.size(); ++k) {
            lambda[k] += a * p[k];
            res[k] -= a * Sp[k];
        }
        for (std::size_t i = 0; i < g.size(); ++i) correction[i] += a * z[i];
        double rr_next = 0;
        for (double x : res) rr_next += x * x;
        for (std::size_t k = 0; k < p.size(); ++k) p[k] = res[k] + (rr_next / rr) * p[k];
        rr = rr_next;
    }
    std::vector<double> phi(g.size());
    for (std::size_t i = 0; i < g.size(); ++i) phi[i] = phi0[i] - correction[i];
    r.constraint_residual = norm_inf(C.apply(phi));
    r.constraint_iterations = std::size_t(it);
    return phi;
}

std::vector<double> ConstrainedPoisson::solve(const std::vector<double>& g, const ResolvedSources& S,
                                              const SurfaceShmOptions& o, SurfaceShmResult& r) {
    const Constraints C = constraint_rows(S, o.level_set, o.soft_weight == 0);
    r.constraints = C.exact.size() + C.soft.size();
    if (r.constraints == 0) return plain_poisson().solve(g);
    const std::vector<std::uint32_t> pins = free_components(C, o.level_set == LevelSetConstraint::ZeroSet);
    return solve_constrained(C, pins, g, o.soft_weight, r);
}

std::vector<std::uint32_t> ConstrainedPoisson::free_components(const Constraints& C,
                                                                    bool rows_fix_levels) const {
    // Zero-set rows fix the level of the components they touch; difference rows fix nothing.
    std::vector<std::uint8_t> fixed(components_.pins.size(), 0);
    if (rows_fix_levels)
        for (const ConstraintRows* rows : {&C.exact, &C.soft})
            for (const auto& row : rows->rows)
                for (const auto& [v, c] : row)
                    if (components_.component[v] != UINT32_MAX) fixed[components_.component[v]] = 1;
    std::vector<std::uint32_t> pins;
    for (std::size_t k = 0; k < fixed.size(); ++k)
        if (!fixed[k]) pins.push_back(components_.pins[k]);
    return pins;
}

double ConstrainedPoisson::source_mean(const std::vector<double>& phi, const ResolvedSources& S) const {
    const mesh::Triangulation& tri = *T_;
    double sum = 0, weight = 0;
    for (const surface_shm::CurvePiece& c : S.pieces) {
        const std::size_t f = c.segment.face;
        const surface_shm::FaceFrame F = surface_shm::face_frame(tri, f, (*areas_)[f]);
        Eigen::Vector2d a = Eigen::Vector2d::Zero(), b = Eigen::Vector2d::Zero();
        double mid = 0;
        for (int k = 0; k < 3; ++k) {
            a += c.segment.a[std::size_t(k)] * F.p[std::size_t(k)];
            b += c.segment.b[std::size_t(k)] * F.p[std::size_t(k)];
            mid += 0.5 * (c.segment.a[std::size_t(k)] + c.segment.b[std::size_t(k)]) * phi[tri.faces[f][std::size_t(k)]];
        }
        const double length = (b - a).norm();
        sum += length * mid;  // midpoint rule: exact for φ linear on the face
        weight += length;
    }
    if (weight > 0) return sum / weight;
    for (const FacePoint& p : S.points)
        for (int k = 0; k < 3; ++k) sum += p.bary[std::size_t(k)] * phi[tri.faces[p.face][std::size_t(k)]];
    return S.points.empty() ? 0.0 : sum / double(S.points.size());
}

}  // namespace gsd::surface_shm
