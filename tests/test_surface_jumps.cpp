// The surface SHM's L1 integration (thesis §6.4.1, fig. 6.13): on a curve that bounds nothing,
// φ jumps along one loop at the antipode and is the distance elsewhere (checked against the
// exact distance along a torus' inner equator, where it is known in closed form); on curves
// that bound a region it is the L² result; and the cut triangulation it solves on.
#include <doctest/doctest.h>

#include <gsd/shapes.hpp>
#include <gsd/surface.hpp>

#include "support.hpp"
#include "surface_shm/jumps.hpp"
#include "mesh/topology.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <numbers>

using namespace gsd;

namespace {

constexpr double kPi = std::numbers::pi;

/// The loop of a torus_mesh(n_major, n_minor) around its tube at grid column i (along edges).
SurfaceCurve meridian(int n_minor, int i, bool reverse = false) {
    SurfaceCurve c;
    for (int j = 0; j <= n_minor; ++j) c.nodes.push_back(SurfacePoint::at_vertex(std::uint32_t(i * n_minor + j % n_minor)));
    if (reverse) std::reverse(c.nodes.begin(), c.nodes.end());
    return c;
}

/// Share of the area where |∇φ| is within 10 % of 1, φ linear on each triangle from its corners.
double unit_slope_share(const SurfaceMesh& mesh, const std::vector<std::array<double, 3>>& corner_phi) {
    const Points& x = mesh.polygons().vertices;
    double good = 0, total = 0;
    for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
        const auto c = mesh.triangle(t);
        std::array<Eigen::Vector3d, 3> p;
        for (std::size_t k = 0; k < 3; ++k) p[k] = x.row(c[k]).transpose();
        const Eigen::Vector3d n = (p[1] - p[0]).cross(p[2] - p[0]);
        const double twice_area = n.norm();
        const Eigen::Vector3d u = n / twice_area;
        const Eigen::Vector3d g = (corner_phi[t][0] * u.cross(p[2] - p[1]) + corner_phi[t][1] * u.cross(p[0] - p[2]) +
                                   corner_phi[t][2] * u.cross(p[1] - p[0])) / twice_area;
        total += twice_area;
        if (std::abs(g.norm() - 1) <= 0.1) good += twice_area;
    }
    return good / total;
}

std::vector<std::array<double, 3>> corners_of(const SurfaceMesh& mesh, const std::vector<double>& phi) {
    std::vector<std::array<double, 3>> out(mesh.triangle_count());
    for (std::size_t t = 0; t < out.size(); ++t)
        for (std::size_t k = 0; k < 3; ++k) out[t][k] = phi[mesh.triangle(t)[k]];
    return out;
}

}  // namespace

TEST_CASE("L1 integration: a meridian of a torus bounds nothing; φ is the distance, jumping at the antipode") {
    // On a torus of revolution every path from a point of the inner equator to the meridian
    // θ = 0 has length ≥ ∫(R − r)|dθ|, which the inner equator itself attains: the distance there
    // is (R − r)·min(θ, 2π − θ), and the sign of a distance to a curve with no inside must flip
    // once more, at the antipode θ = π.
    struct Case {
        double R, r;
        int n_minor;
    };
    for (const Case c : {Case{0.5, 0.2, 32}, Case{0.5, 0.1, 32}}) {
        CAPTURE(c.r);
        const int n_major = 3 * c.n_minor;
        const SurfaceMesh mesh(shapes::torus_mesh(n_major, c.n_minor, c.R, c.r), "torus");
        SignedHeatSurface shm(mesh);
        SurfaceSources src;
        src.curves.push_back(meridian(c.n_minor, 0));
        SurfaceShmOptions o;
        o.integration = SurfaceIntegration::L1;
        const SurfaceShmResult l1 = shm.solve(src, o);
        const SurfaceShmResult l2 = shm.solve(src);
        REQUIRE(l1.corner_phi.size() == mesh.triangle_count());
        CHECK(l2.corner_phi.empty());
        CHECK(l2.jumps.empty());

        // Along the inner equator, away from the curve's and the antipode's neighbourhoods.
        auto equator_error = [&](const std::vector<double>& phi) {
            double worst = 0;
            int side = 0;
            for (int i = 1; i < n_major; ++i) {
                const double theta = 2 * kPi * i / n_major;
                if (std::abs(theta - kPi) < 0.25) continue;
                const double d = (c.R - c.r) * std::min(theta, 2 * kPi - theta);
                const double v = phi[std::size_t(i * c.n_minor + c.n_minor / 2)];
                const int s = (v > 0) == (theta < kPi) ? 1 : -1;
                if (side == 0) side = s;
                worst = std::max(worst, s == side ? std::abs(std::abs(v) - d) : INFINITY);
            }
            return worst / ((c.R - c.r) * kPi);
        };
        const double e1 = equator_error(l1.phi), e2 = equator_error(l2.phi);
        CAPTURE(e1);
        CAPTURE(e2);
        CHECK(e1 < 0.03);
        CHECK(e2 > 0.15);  // L²: warped over the whole torus (one sign, or far from the distance)

        // One loop of jump edges around the tube, at the antipode.
        REQUIRE(l1.jumps.size() == 1);
        const Polyline& jump = l1.jumps[0];
        CHECK((jump.front() - jump.back()).norm() < 1e-12);
        for (const Eigen::Vector3d& p : jump) CHECK(std::abs(std::abs(std::atan2(p.y(), p.x())) - kPi) < 0.15);
        CHECK(l1.jump_cost > 0);

        // Evenly spaced isolines away from the jump: |∇φ| ≈ 1 on most of the area (L²: almost none).
        const double s1 = unit_slope_share(mesh, l1.corner_phi), s2 = unit_slope_share(mesh, corners_of(mesh, l2.phi));
        CAPTURE(s1);
        CAPTURE(s2);
        CHECK(s1 > 0.9);
        CHECK(s2 < 0.1);
    }
}

TEST_CASE("L1 integration: on curves that bound a region it is the L² result") {
    struct Case {
        const char* name;
        PolygonMesh mesh;
        std::function<SurfaceSources(const SurfaceMesh&)> curves;
    };
    const std::vector<Case> cases = {
        {"two opposite meridians of a torus", shapes::torus_mesh(96, 32),
         [](const SurfaceMesh&) {
             SurfaceSources s;
             s.curves = {meridian(32, 5), meridian(32, 53, true)};
             return s;
         }},
        {"a small loop on a torus, off the edges", shapes::torus_mesh(96, 32),
         [](const SurfaceMesh& mesh) {
             std::vector<double> f(mesh.vertex_count());
             for (std::size_t v = 0; v < f.size(); ++v)
                 f[v] = (mesh.polygons().vertices.row(Eigen::Index(v)).transpose() - Eigen::Vector3d(0.7, 0, 0)).norm() - 0.15;
             SurfaceSources s;
             s.curves = level_set_curves(mesh, f);
             return s;
         }},
        {"a pair of loops around a double torus' tube (they bound the tube between them)", shapes::double_torus_mesh(48),
         [](const SurfaceMesh& mesh) {
             std::vector<double> f(mesh.vertex_count());
             for (std::size_t v = 0; v < f.size(); ++v)
                 f[v] = (mesh.polygons().vertices.row(Eigen::Index(v)).transpose() - Eigen::Vector3d(-0.9, 0.3, 0)).norm() - 0.3;
             SurfaceSources s;
             s.curves = level_set_curves(mesh, f);
             return s;
         }},
        {"a wavy loop on a sphere", shapes::icosphere(4),
         [](const SurfaceMesh& mesh) {
             std::vector<double> f(mesh.vertex_count());
             for (std::size_t v = 0; v < f.size(); ++v) {
                 const Eigen::Vector3d x = mesh.polygons().vertices.row(Eigen::Index(v)).transpose();
                 f[v] = x.z() + 0.2 * x.x() * x.x() - 0.3;
             }
             SurfaceSources s;
             s.curves = level_set_curves(mesh, f);
             return s;
         }},
    };
    for (const Case& c : cases) {
        CAPTURE(c.name);
        const SurfaceMesh mesh(c.mesh, c.name);
        SignedHeatSurface shm(mesh);
        const SurfaceSources src = c.curves(mesh);
        REQUIRE(!src.curves.empty());
        SurfaceShmOptions o;
        o.integration = SurfaceIntegration::L1;
        const SurfaceShmResult l1 = shm.solve(src, o), l2 = shm.solve(src);
        CHECK(l1.jumps.empty());
        CHECK(surface_distance_error(mesh, l1.phi, l2.phi) < 1e-9);
        for (std::size_t t = 0; t < mesh.triangle_count(); ++t)
            for (std::size_t k = 0; k < 3; ++k) CHECK(l1.corner_phi[t][k] == l1.phi[mesh.triangle(t)[k]]);
    }
}

TEST_CASE("L1 integration: every level-set mode, and a clear error with an intrinsic triangulation") {
    const SurfaceMesh mesh(shapes::torus_mesh(72, 24), "torus");
    SurfaceSources src;
    src.curves.push_back(meridian(24, 0));
    for (LevelSetConstraint mode : {LevelSetConstraint::None, LevelSetConstraint::ZeroSet, LevelSetConstraint::Components}) {
        SignedHeatSurface shm(mesh);
        SurfaceShmOptions o;
        o.integration = SurfaceIntegration::L1;
        o.level_set = mode;
        const SurfaceShmResult r = shm.solve(src, o);
        CHECK(r.jumps.size() == 1);
        for (int j = 0; j < 24; ++j) CHECK(std::abs(r.phi[std::size_t(j)]) < 0.02);  // the curve stays at level 0
    }
    SurfaceShmSetup setup;
    setup.intrinsic_delaunay = true;
    SignedHeatSurface shm(mesh, setup);
    SurfaceShmOptions o;
    o.integration = SurfaceIntegration::L1;
    CHECK_THROWS_WITH_AS(shm.solve(src, o), doctest::Contains("intrinsic_delaunay"), Error);
    CHECK(surface_integration_from_name("l1") == SurfaceIntegration::L1);
    CHECK_THROWS_AS(surface_integration_from_name("l3"), Error);
}

TEST_CASE("cut_triangulation: corners across a cut edge part, a slit's ends stay whole") {
    const mesh::Topology t = mesh::build_topology(shapes::grid_mesh(6));
    const mesh::Triangulation& T = t.mesh;
    auto edge_between = [&](std::uint32_t a, std::uint32_t b) { return t.find_edge(a, b); };
    // Vertices of grid_mesh(6): 7 × 7, row-major. A slit of three edges along row 3, columns 1–4.
    std::vector<std::int8_t> cut(T.edge_count(), 0);
    for (std::uint32_t i = 1; i < 4; ++i) cut[edge_between(3 * 7 + i, 3 * 7 + i + 1)] = 1;
    const surface_shm::CutTriangulation C = surface_shm::cut_triangulation(T, cut);
    CHECK(C.T.vertex_count == T.vertex_count + 2);  // the slit's two inner vertices, twice each
    CHECK(C.T.edge_count() == T.edge_count() + 3);  // each cut edge once per side
    REQUIRE(C.T.face_count() == T.face_count());
    for (std::size_t f = 0; f < T.face_count(); ++f)
        for (std::size_t k = 0; k < 3; ++k) {
            CHECK(C.vertex_of[C.T.faces[f][k]] == T.faces[f][k]);
            const std::uint32_t e = C.T.face_edges[f][k];
            CHECK(C.T.edge_lengths[e] == T.edge_lengths[T.face_edges[f][k]]);
            // The cut triangulation's edges join its own vertices, in the stored direction.
            const std::uint32_t a = C.T.faces[f][k], b = C.T.faces[f][(k + 1) % 3];
            CHECK((C.T.aligned[f][k] ? C.T.edges[e] == std::array<std::uint32_t, 2>{a, b}
                                     : C.T.edges[e] == std::array<std::uint32_t, 2>{b, a}));
        }
    // A loop around a torus' tube parts every vertex on it.
    const mesh::Topology torus = mesh::build_topology(shapes::torus_mesh(12, 8));
    std::vector<std::int8_t> loop(torus.mesh.edge_count(), 0);
    for (std::uint32_t j = 0; j < 8; ++j) loop[torus.find_edge(j, (j + 1) % 8)] = -1;
    const surface_shm::CutTriangulation L = surface_shm::cut_triangulation(torus.mesh, loop);
    CHECK(L.T.vertex_count == torus.mesh.vertex_count + 8);
    // No cut: the same triangulation.
    const surface_shm::CutTriangulation N = surface_shm::cut_triangulation(T, std::vector<std::int8_t>(T.edge_count(), 0));
    CHECK(N.T.vertex_count == T.vertex_count);
    CHECK(N.T.edge_count() == T.edge_count());
}
