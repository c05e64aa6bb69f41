// The Signed Heat Method on surfaces (thesis §4.3, eq. 4.8–4.11):
//  1. (M + t L∇) X = X₀ on Crouzeix–Raviart edge midpoints, X₀ the curve normals and point disks;
//  2. Y = X averaged to faces, normalized;
//  3. K φ = g, g_i = Σ_f A_f ⟨Y_f, ∇λ_i⟩ (least squares ∇φ ≈ Y), with the level-set constraints.
// Both matrices are factored once per mesh (and per t) and cached; step 3 with its constraints
// is poisson.cpp. With L1 integration (§6.4.1), step 3 first finds where φ must jump
// (jumps.cpp) and solves on the triangulation cut there.
#include <gsd/surface.hpp>

#include "surface_shm/cholesky.hpp"
#include "surface_shm/curves.hpp"
#include "surface_shm/jumps.hpp"
#include "surface_shm/poisson.hpp"
#include "mesh/intrinsic.hpp"
#include "surface_shm/operators.hpp"
#include "surface_shm/sources.hpp"
#include "mesh/topology.hpp"
#include "mesh/geometry.hpp"

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

/// Puts the curves at level 0 where no constraint did (shift by their mean), and makes exact
/// rows at vertices exactly 0 (not ±1e-16).
void settle_levels(const Triangulation& tri, const surface_shm::ConstrainedPoisson& poisson, const ResolvedSources& S,
                   const SurfaceShmOptions& o, std::vector<double>& phi) {
    const double shift = poisson.source_mean(phi, S);
    for (double& x : phi) x -= shift;
    if (o.level_set == LevelSetConstraint::ZeroSet)
        for (const FacePoint& p : S.nodes)
            for (int k = 0; k < 3; ++k)
                if (p.bary[std::size_t(k)] == 1.0) phi[tri.faces[p.face][std::size_t(k)]] = 0.0;
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
    std::optional<surface_shm::ConstrainedPoisson> poisson;  // step 3 on the triangulation solved on

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
        if (!poisson) poisson.emplace(T(), solve_mesh->areas);
    }

    ResolvedSources resolve(const SurfaceSources& sources) const;
    std::vector<double> unsigned_distance(const ResolvedSources& S);
    std::vector<double> integrate_l1(const std::vector<Eigen::Vector2d>& Y, const ResolvedSources& S,
                                     const SurfaceShmOptions& o, SurfaceShmResult& r);
    std::vector<Complex> diffuse(const ResolvedSources& S, const SurfaceShmOptions& o);
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

std::vector<double> SignedHeatSurface::Impl::unsigned_distance(const ResolvedSources& S) {
    // The heat method's distance to the curves as unsigned ones (curves that bound nothing have
    // one): where φ is farthest from them, its sign is least determined.
    ResolvedSources U = S;
    for (surface_shm::CurvePiece& c : U.pieces) c.is_signed = false;
    const std::vector<Complex> X = vector_heat->solve(surface_shm::vector_sources(*solve_mesh, U));
    std::vector<Eigen::Vector2d> Y;
    surface_shm::normalized_face_field(T(), solve_mesh->areas, X, Y);
    SurfaceShmOptions o;
    SurfaceShmResult unused;
    std::vector<double> d = poisson->solve(surface_shm::face_field_divergence(T(), solve_mesh->areas, Y), U, o, unused);
    settle_levels(T(), *poisson, U, o, d);
    return d;
}

std::vector<double> SignedHeatSurface::Impl::integrate_l1(const std::vector<Eigen::Vector2d>& Y,
                                                          const ResolvedSources& S, const SurfaceShmOptions& o,
                                                          SurfaceShmResult& r) {
    const Triangulation& tri = T();
    const std::vector<double>& areas = solve_mesh->areas;
    const surface_shm::JumpSet J = surface_shm::l1_jumps(tri, areas, Y, unsigned_distance(S), S, mean_edge);
    r.jump_cost = J.objective;
    r.corner_phi.resize(tri.face_count());
    if (!J.cut_edges) {  // Y integrable: the L² result, from the cached factors
        std::vector<double> phi = poisson->solve(surface_shm::face_field_divergence(tri, areas, Y), S, o, r);
        settle_levels(tri, *poisson, S, o, phi);
        for (std::size_t f = 0; f < tri.face_count(); ++f)
            for (std::size_t k = 0; k < 3; ++k) r.corner_phi[f][k] = phi[tri.faces[f][k]];
        return phi;
    }
    // The cut triangulation has the same faces and lengths: the same areas, Y and sources.
    const surface_shm::CutTriangulation cut = surface_shm::cut_triangulation(tri, J.cut);
    surface_shm::ConstrainedPoisson poisson_cut(cut.T, areas);
    const std::vector<double> g = surface_shm::face_field_divergence(cut.T, areas, Y);
    std::vector<double> phi_cut = poisson_cut.solve(g, S, o, r);
    settle_levels(cut.T, poisson_cut, S, o, phi_cut);

    std::vector<double> phi(tri.vertex_count, 0.0), angle(tri.vertex_count, -1.0);
    std::vector<double> class_angle(cut.T.vertex_count, 0.0);
    for (std::size_t f = 0; f < tri.face_count(); ++f) {
        const auto l = mesh::face_lengths(tri, f);
        for (int k = 0; k < 3; ++k) {
            r.corner_phi[f][std::size_t(k)] = phi_cut[cut.T.faces[f][std::size_t(k)]];
            class_angle[cut.T.faces[f][std::size_t(k)]] += areas[f] > 0 ? mesh::corner_angle(l, k) : 0.0;
        }
    }
    for (std::size_t c = 0; c < cut.T.vertex_count; ++c) {
        const std::uint32_t v = cut.vertex_of[c];
        if (class_angle[c] > angle[v]) {
            angle[v] = class_angle[c];
            phi[v] = phi_cut[c];
        }
    }
    std::vector<double> on_cut(J.cut.begin(), J.cut.end());
    r.jumps = mesh::chain_polylines(mesh.topology(), on_cut);
    return phi;
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
    if (options.integration == SurfaceIntegration::L1 && m.setup.intrinsic_delaunay)
        throw Error("SurfaceShmOptions::integration",
                    "L1 integration runs on the input triangulation: turn intrinsic_delaunay off for it");
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
    std::vector<double> phi;
    if (options.integration == SurfaceIntegration::L1) {
        phi = m.integrate_l1(Y, S, options, r);
    } else {
        const std::vector<double> g = surface_shm::face_field_divergence(tri, m.solve_mesh->areas, Y);
        phi = m.poisson->solve(g, S, options, r);
        settle_levels(tri, *m.poisson, S, options, phi);
    }
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

SurfaceIntegration surface_integration_from_name(const std::string& name) {
    if (name == "l2") return SurfaceIntegration::L2;
    if (name == "l1") return SurfaceIntegration::L1;
    throw Error("integration", "unknown integration '" + name + "' (l2, l1)");
}

LevelSetConstraint level_set_from_name(const std::string& name) {
    if (name == "none") return LevelSetConstraint::None;
    if (name == "zero") return LevelSetConstraint::ZeroSet;
    if (name == "components") return LevelSetConstraint::Components;
    throw Error("level set", "unknown level-set constraint '" + name + "' (none, zero, components)");
}

}  // namespace gsd
