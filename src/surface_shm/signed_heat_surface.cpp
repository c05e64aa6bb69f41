// The Signed Heat Method on surfaces (thesis §4.3, eq. 4.8–4.11):
//  1. (M + t L∇) X = X₀ on Crouzeix–Raviart edge midpoints, X₀ the curve normals and point disks;
//  2. Y = X averaged to faces, normalized;
//  3. K φ = g, g_i = Σ_f A_f ⟨Y_f, ∇λ_i⟩ (least squares ∇φ ≈ Y), with the level-set constraints.
// Both matrices are factored once per mesh (and per t) and cached. Constraints never refactor
// the plain Poisson factor: they go into a second factor of K + w CᵀC, whose pattern is K's
// (every constraint row lives in one face), so it is refactored numerically without a new
// analysis; hard constraints are then met exactly by iterative refinement of the KKT system
// [K Cᵀ; C 0] with that penalized factor as the preconditioner. Duplicate or nearly equal
// constraint rows (closed loops, reversed pieces, pieces meeting at a point) cannot make this
// singular, unlike a direct factorization of the saddle-point matrix.
#include <gsd/surface.hpp>

#include "surface_shm/cholesky.hpp"
#include "surface_shm/curves.hpp"
#include "mesh/intrinsic.hpp"
#include "surface_shm/operators.hpp"
#include "surface_shm/sources.hpp"
#include "mesh/topology.hpp"

#include <Eigen/Dense>
#include <Eigen/Sparse>

#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <unordered_map>

namespace gsd {

using surface_shm::Cholesky;
using surface_shm::Complex;
using mesh::FacePoint;
using surface_shm::ResolvedSources;
using surface_shm::SolveMesh;
using surface_shm::SparseLower;
using mesh::Triangulation;

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// Sparse constraint rows over vertices: row r is Σ_k coef_k φ(vertex_k) (= 0).
struct ConstraintRows {
    std::vector<std::vector<std::pair<std::uint32_t, double>>> rows;

    void add(std::vector<std::pair<std::uint32_t, double>> row) {
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
    std::size_t size() const { return rows.size(); }

    std::vector<double> apply(const std::vector<double>& phi) const {  // C φ
        std::vector<double> out(rows.size(), 0.0);
        for (std::size_t r = 0; r < rows.size(); ++r)
            for (const auto& [v, c] : rows[r]) out[r] += c * phi[v];
        return out;
    }
    void add_transpose(const std::vector<double>& y, double scale, std::vector<double>& out) const {  // out += s Cᵀ y
        for (std::size_t r = 0; r < rows.size(); ++r)
            for (const auto& [v, c] : rows[r]) out[v] += scale * c * y[r];
    }
};

std::vector<std::pair<std::uint32_t, double>> interpolation_row(const Triangulation& T, const FacePoint& p, double sign) {
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

struct SignedHeatSurface::Impl {
    SurfaceMesh mesh;
    SurfaceShmSetup setup;

    // The triangulation solved on: the input's, or an intrinsic Delaunay one (built lazily).
    std::optional<mesh::IntrinsicTriangulation> intrinsic;
    std::optional<SolveMesh> solve_mesh;
    std::size_t flips = 0;
    double mean_edge = 0, time = 0;

    std::optional<Cholesky<Complex>> vector_heat;
    std::optional<SparseLower<double>> stiffness;       // K, lower triangle
    Eigen::SparseMatrix<double> stiffness_full;         // K, both triangles (residuals)
    surface_shm::StiffnessComponents components;            // where K's nullspace is constant
    std::vector<double> pin_weight;                     // diagonal of K
    std::optional<Cholesky<double>> poisson;            // factor of K + a pin per component
    std::optional<Cholesky<double>> constrained;        // factor of K + pins + w CᵀC (same pattern)

    Impl(SurfaceMesh m, SurfaceShmSetup s) : mesh(std::move(m)), setup(s) {
        if (!(setup.t_coef > 0) || !std::isfinite(setup.t_coef))
            throw Error("SurfaceShmSetup::t_coef", "must be a positive number (got " + std::to_string(setup.t_coef) + ")");
        if (setup.refine && !(setup.refine_min_angle > 0 && setup.refine_min_angle < 35))
            throw Error("SurfaceShmSetup::refine_min_angle", "must be in (0°, 35°) for refinement to terminate");
    }

    const Triangulation& T() const { return *solve_mesh->T; }

    void ensure_mesh(const ProgressFn& progress) {
        if (solve_mesh) return;
        const mesh::Topology& topo = mesh.topology();
        if (setup.intrinsic_delaunay) {
            if (progress) progress("intrinsic Delaunay", 0.0);
            intrinsic.emplace(topo.mesh);
            flips = intrinsic->flip_to_delaunay();
            if (setup.refine)
                intrinsic->refine(setup.refine_min_angle,
                                  setup.refine_max_vertices ? setup.refine_max_vertices : topo.mesh.vertex_count);
            solve_mesh.emplace(intrinsic->triangulation());
        } else {
            solve_mesh.emplace(topo.mesh);
        }
        // h: half the mean edge length (the spacing of the CR nodes, edge midpoints).
        mean_edge = mesh::mean_edge_length(T(), solve_mesh->areas);
        if (!(mean_edge > 0)) throw Error("mesh", "every triangle is degenerate");
        time = setup.t_coef * 0.25 * mean_edge * mean_edge;
    }

    void ensure_vector_heat() {
        if (vector_heat) return;
        vector_heat.emplace(surface_shm::vector_heat_operator(T(), solve_mesh->areas, time));
    }

    void ensure_poisson() {
        if (stiffness) return;
        stiffness = surface_shm::cotan_laplacian(T(), solve_mesh->areas);
        components = surface_shm::stiffness_components(T(), solve_mesh->areas);
        const SparseLower<double>& K = *stiffness;
        std::vector<Eigen::Triplet<double>> trip;
        trip.reserve(2 * K.entries());
        pin_weight.assign(K.n, 0.0);
        for (std::size_t k = 0; k < K.entries(); ++k) {
            trip.emplace_back(Eigen::Index(K.rows[k]), Eigen::Index(K.cols[k]), K.values[k]);
            if (K.rows[k] != K.cols[k]) trip.emplace_back(Eigen::Index(K.cols[k]), Eigen::Index(K.rows[k]), K.values[k]);
            else pin_weight[std::size_t(K.rows[k])] += K.values[k];
        }
        stiffness_full.resize(Eigen::Index(K.n), Eigen::Index(K.n));
        stiffness_full.setFromTriplets(trip.begin(), trip.end());
    }

    /// A factor of A (whose pattern is K's): the ordering and symbolic analysis are computed
    /// once per mesh and shared by the plain and the constrained factors.
    Cholesky<double> factor_like_K(const SparseLower<double>& A) const {
        if (poisson) return Cholesky<double>(*poisson, A);
        if (constrained) return Cholesky<double>(*constrained, A);
        return Cholesky<double>(A);
    }

    const Cholesky<double>& plain_poisson() {
        if (!poisson) poisson.emplace(factor_like_K(with_pins(*stiffness, components.pins)));
        return *poisson;
    }

    /// K plus a diagonal term at one vertex of each chosen component: it fixes the constant
    /// that K leaves free there, as well conditioned as K itself (weight: K's own diagonal).
    SparseLower<double> with_pins(SparseLower<double> A, const std::vector<std::uint32_t>& pins) const {
        for (std::uint32_t v : pins) A.add(v, v, pin_weight[v]);
        return A;
    }

    ResolvedSources resolve(const SurfaceSources& sources) const;
    std::vector<Complex> diffuse(const ResolvedSources& S, const SurfaceShmOptions& o);
    std::vector<double> integrate(const std::vector<double>& g, const ResolvedSources& S, const SurfaceShmOptions& o,
                                  SurfaceShmResult& r);
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
    double source_mean(const std::vector<double>& phi, const ResolvedSources& S) const;
};

ResolvedSources SignedHeatSurface::Impl::resolve(const SurfaceSources& sources) const {
    ResolvedSources S = surface_shm::resolve_sources(mesh.topology(), sources, "sources");
    if (!intrinsic) return S;
    // Carry everything drawn on the input mesh into the intrinsic triangulation.
    ResolvedSources out;
    out.component_count = S.component_count;
    for (const surface_shm::CurvePiece& c : S.pieces) {
        const std::vector<mesh::FaceSegment> traced = intrinsic->trace(c.segment);
        for (std::size_t i = 0; i < traced.size(); ++i) {
            surface_shm::CurvePiece p = c;
            p.segment = traced[i];
            p.open_a = c.open_a && i == 0;
            p.open_b = c.open_b && i + 1 == traced.size();
            out.pieces.push_back(p);
        }
    }
    for (const FacePoint& p : S.points) out.points.push_back(intrinsic->locate(p));
    for (const FacePoint& p : S.nodes) out.nodes.push_back(intrinsic->locate(p));
    out.node_components = S.node_components;
    return out;
}

std::vector<Complex> SignedHeatSurface::Impl::diffuse(const ResolvedSources& S, const SurfaceShmOptions& o) {
    const std::vector<Complex> X0 = surface_shm::vector_sources(*solve_mesh, S);
    std::vector<Complex> X = vector_heat->solve(X0);
    if (!o.preserve_normals) return X;
    const surface_shm::NormalConstraints N = surface_shm::normal_constraints(*solve_mesh, S);
    const std::size_t m = N.rows.size();
    if (m == 0) return X;
    // Minimize the heat energy subject to Re(c_m^H X) = 0: X = A⁻¹(X₀ − Σ μ_m c_m) with
    // S μ = Re(C^H A⁻¹ X₀), S = Re(C^H A⁻¹ C) (m × m, formed in blocks of columns).
    const std::size_t E = T().edge_count();
    auto dot = [&](std::size_t row, const Complex* z) {
        double s = 0;
        for (const auto& [e, c] : N.rows[row]) s += (std::conj(c) * z[e]).real();
        return s;
    };
    const auto mm = static_cast<Eigen::Index>(m);
    Eigen::MatrixXd Smat(mm, mm);
    constexpr std::size_t kBlock = 64;
    std::vector<Complex> Z;
    for (std::size_t b0 = 0; b0 < m; b0 += kBlock) {
        const std::size_t nb = std::min(kBlock, m - b0);
        Z.assign(E * nb, Complex(0, 0));
        for (std::size_t j = 0; j < nb; ++j)
            for (const auto& [e, c] : N.rows[b0 + j]) Z[j * E + e] += c;
        vector_heat->solve(Z.data(), nb);
        for (std::size_t j = 0; j < nb; ++j)
            for (std::size_t i = 0; i < m; ++i) Smat(Eigen::Index(i), Eigen::Index(b0 + j)) = dot(i, Z.data() + j * E);
    }
    Eigen::VectorXd rhs(mm);
    for (std::size_t i = 0; i < m; ++i) rhs[Eigen::Index(i)] = dot(i, X.data());
    // Duplicate rows make S singular: a tiny ridge keeps the solve defined (the minimum-norm μ
    // up to it), the constraints stay satisfied.
    Smat = 0.5 * (Smat + Smat.transpose());
    Smat.diagonal().array() += 1e-12 * std::max(Smat.diagonal().maxCoeff(), 1e-300);
    const Eigen::VectorXd mu = Smat.ldlt().solve(rhs);
    std::vector<Complex> rhs2 = X0;
    for (std::size_t i = 0; i < m; ++i)
        for (const auto& [e, c] : N.rows[i]) rhs2[e] -= mu[Eigen::Index(i)] * c;
    return vector_heat->solve(rhs2);
}

SignedHeatSurface::Impl::Constraints SignedHeatSurface::Impl::constraint_rows(const ResolvedSources& S,
                                                                               LevelSetConstraint mode,
                                                                               bool all_exact) const {
    // Rows whose points are all vertices (a node at a vertex; a piece along an edge between
    // vertices) are always consistent and are met exactly. Rows with points on edges or inside
    // faces are exact too where they leave φ free to be nonzero next to the curve; where they do
    // not (see SurfaceShmOptions::soft_weight), they are soft unless the caller asks for exact.
    Constraints C;
    const Triangulation& tri = T();
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

void SignedHeatSurface::Impl::split_by_consistency(const ConstraintRows& rows, const std::vector<std::uint32_t>& fixed,
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

std::vector<double> SignedHeatSurface::Impl::solve_constrained(const Constraints& C,
                                                               const std::vector<std::uint32_t>& pins,
                                                               const std::vector<double>& g, double w_soft,
                                                               SurfaceShmResult& r) {
    // F = K + pins + w_soft CsᵀCs + w_exact CeᵀCe. Every row's vertices share a face, so F has
    // K's pattern and is refactored without a new analysis. The exact rows' penalty, far above
    // the stiffness scale, only preconditions the conjugate gradients that meet them exactly.
    double diag = 0;
    for (std::size_t k = 0; k < stiffness->entries(); ++k)
        if (stiffness->rows[k] == stiffness->cols[k]) diag = std::max(diag, std::abs(stiffness->values[k]));
    const double w_exact = 1e6 * diag;
    SparseLower<double> A = with_pins(*stiffness, pins);
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
    if (!constrained) constrained.emplace(factor_like_K(A));
    else constrained->refactor(A);
    if (C.exact.size() == 0) return constrained->solve(g);
    return solve_exact(C.exact, g, r);
}

std::vector<double> SignedHeatSurface::Impl::solve_exact(const ConstraintRows& C, const std::vector<double>& g,
                                                         SurfaceShmResult& r) const {
    // Exact constraints from the penalized factor F = K + pins + w CᵀC: φ(λ) = F⁻¹(g − Cᵀλ)
    // satisfies K φ + Cᵀ(λ + w Cφ) = g for any λ, so only C φ(λ) = 0 is left, i.e. the SPD
    // system C F⁻¹ Cᵀ λ = C F⁻¹ g. Its eigenvalues σ/(1 + wσ) (σ those of C K⁻¹ Cᵀ) crowd
    // below 1/w, except for nearly dependent rows (nodes almost on top of each other), which
    // conjugate gradients absorb in a few extra steps. One F-solve per step.
    const std::vector<double> phi0 = constrained->solve(g);
    const double scale = std::max(norm_inf(phi0), 1e-300);
    std::vector<double> lambda(C.size(), 0.0), res = C.apply(phi0), p = res;
    std::vector<double> correction(g.size(), 0.0);  // Σ F⁻¹Cᵀ(step) accumulated: φ = φ0 − correction
    double rr = 0;
    for (double x : res) rr += x * x;
    int it = 0;
    for (; it < 200 && norm_inf(res) > 1e-12 * scale; ++it) {
        std::vector<double> Ctp(g.size(), 0.0);
        C.add_transpose(p, 1.0, Ctp);
        const std::vector<double> z = constrained->solve(Ctp);  // F⁻¹ Cᵀ p
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

std::vector<double> SignedHeatSurface::Impl::integrate(const std::vector<double>& g, const ResolvedSources& S,
                                                       const SurfaceShmOptions& o, SurfaceShmResult& r) {
    const Constraints C = constraint_rows(S, o.level_set, o.soft_weight == 0);
    r.constraints = C.exact.size() + C.soft.size();
    if (r.constraints == 0) return plain_poisson().solve(g);
    const std::vector<std::uint32_t> pins = free_components(C, o.level_set == LevelSetConstraint::ZeroSet);
    return solve_constrained(C, pins, g, o.soft_weight, r);
}

std::vector<std::uint32_t> SignedHeatSurface::Impl::free_components(const Constraints& C,
                                                                    bool rows_fix_levels) const {
    // Zero-set rows fix the level of the components they touch; difference rows fix nothing.
    std::vector<std::uint8_t> fixed(components.pins.size(), 0);
    if (rows_fix_levels)
        for (const ConstraintRows* rows : {&C.exact, &C.soft})
            for (const auto& row : rows->rows)
                for (const auto& [v, c] : row)
                    if (components.component[v] != UINT32_MAX) fixed[components.component[v]] = 1;
    std::vector<std::uint32_t> pins;
    for (std::size_t k = 0; k < fixed.size(); ++k)
        if (!fixed[k]) pins.push_back(components.pins[k]);
    return pins;
}

double SignedHeatSurface::Impl::source_mean(const std::vector<double>& phi, const ResolvedSources& S) const {
    const Triangulation& tri = T();
    double sum = 0, weight = 0;
    for (const surface_shm::CurvePiece& c : S.pieces) {
        const std::size_t f = c.segment.face;
        const surface_shm::FaceFrame F = surface_shm::face_frame(tri, f, solve_mesh->areas[f]);
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

SignedHeatSurface::SignedHeatSurface(SurfaceMesh mesh, SurfaceShmSetup setup) {
    // Measured: 4.2–4.3 KiB per vertex at 10⁶ (operators, their factorizations, the solves); docs/io.md.
    check_memory(5632.0 * double(mesh.vertex_count()), "mesh",
                 "the surface Signed Heat Method on " + std::to_string(mesh.vertex_count()) + " vertices");
    impl_ = std::make_unique<Impl>(std::move(mesh), setup);
}
SignedHeatSurface::~SignedHeatSurface() = default;
SignedHeatSurface::SignedHeatSurface(SignedHeatSurface&&) noexcept = default;
SignedHeatSurface& SignedHeatSurface::operator=(SignedHeatSurface&&) noexcept = default;

const SurfaceMesh& SignedHeatSurface::mesh() const { return impl_->mesh; }

double SignedHeatSurface::mean_edge_length() const {
    impl_->ensure_mesh({});
    return impl_->mean_edge;
}

double SignedHeatSurface::diffusion_time() const {
    impl_->ensure_mesh({});
    return impl_->time;
}

SurfaceShmResult SignedHeatSurface::solve(const SurfaceSources& sources, const SurfaceShmOptions& options,
                                          const ProgressFn& progress) {
    Impl& m = *impl_;
    if (!(options.soft_weight >= 0) || !std::isfinite(options.soft_weight))
        throw Error("SurfaceShmOptions::soft_weight", "must be ≥ 0 (0: hard constraint)");
    validate(sources, m.mesh, "sources");
    if (sources.empty()) throw Error("sources", "no curves and no points to measure distance to");
    SurfaceShmResult r;
    auto t0 = Clock::now();
    m.ensure_mesh(progress);
    if (progress) progress("factor vector heat operator", 0.05);
    m.ensure_vector_heat();
    if (progress) progress("factor Poisson operator", 0.5);
    m.ensure_poisson();
    r.seconds_factor = seconds_since(t0);

    t0 = Clock::now();
    if (progress) progress("diffuse", 0.8);
    const ResolvedSources S = m.resolve(sources);
    if (S.pieces.empty() && S.points.empty())
        throw Error("sources", "every curve has zero length and there are no points");
    const std::vector<Complex> X = m.diffuse(S, options);
    r.seconds_diffuse = seconds_since(t0);

    t0 = Clock::now();
    if (progress) progress("integrate", 0.9);
    const Triangulation& tri = m.T();
    std::vector<Eigen::Vector2d> Y;
    surface_shm::normalized_face_field(tri, m.solve_mesh->areas, X, Y);
    const std::vector<double> g = surface_shm::face_field_divergence(tri, m.solve_mesh->areas, Y);
    std::vector<double> phi = m.integrate(g, S, options, r);
    const double shift = m.source_mean(phi, S);
    for (double& x : phi) x -= shift;
    if (options.level_set == LevelSetConstraint::ZeroSet)  // exact rows at vertices: exactly 0, not ±1e-16
        for (const FacePoint& p : S.nodes)
            for (int k = 0; k < 3; ++k)
                if (p.bary[std::size_t(k)] == 1.0) phi[tri.faces[p.face][std::size_t(k)]] = 0.0;
    r.seconds_integrate = seconds_since(t0);

    // Report on the input vertices; count those cut off from every source.
    const mesh::Topology& topo = m.mesh.topology();
    const std::size_t V = topo.mesh.vertex_count;
    r.phi.assign(phi.begin(), phi.begin() + std::ptrdiff_t(V));
    std::vector<std::uint8_t> reached(tri.vertex_count, 0);
    for (std::size_t f = 0; f < tri.face_count(); ++f)
        if (Y[f].squaredNorm() > 0)
            for (std::uint32_t v : tri.faces[f]) reached[v] = 1;
    for (std::size_t v = 0; v < V; ++v) {
        if (topo.vertex_corners.count(v) == 0) r.phi[v] = std::numeric_limits<double>::quiet_NaN();
        else if (!reached[v]) ++r.unreached_vertices;
    }
    r.solve_vertices = tri.vertex_count;
    r.flips = m.flips;
    if (progress) progress("done", 1.0);
    return r;
}

LevelSetConstraint level_set_from_name(const std::string& name) {
    if (name == "none") return LevelSetConstraint::None;
    if (name == "zero") return LevelSetConstraint::ZeroSet;
    if (name == "components") return LevelSetConstraint::Components;
    throw Error("level set", "unknown level-set constraint '" + name + "' (none, zero, components)");
}

}  // namespace gsd
