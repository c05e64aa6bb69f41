// The Signed Heat Method on surfaces: the mesh topology it reads (edge numbering of curve files),
// its operators (checked on functions and fields with known answers), accuracy against exact
// distances (planar polygons, circles of latitude on a sphere) including broken curves, the
// level-set constraints, nonmanifold and nonorientable meshes, the intrinsic Delaunay option,
// bad input, and every curve file of the shared data.
#include <doctest/doctest.h>

#include <gsd/io.hpp>
#include <gsd/shapes.hpp>
#include <gsd/surface.hpp>

#include "support.hpp"
#include "surface_shm/cholesky.hpp"
#include "surface_shm/operators.hpp"
#include "mesh/topology.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>

using namespace gsd;
using test::polygon_sdf;

namespace {

constexpr double kPi = std::numbers::pi;

/// The triangle of a planar mesh holding p, as a surface point.
SurfacePoint locate_in_plane(const SurfaceMesh& mesh, const Eigen::Vector2d& p) {
    const Points& x = mesh.polygons().vertices;
    for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
        const auto c = mesh.triangle(t);
        const Eigen::Vector2d a(x(c[0], 0), x(c[0], 1)), b(x(c[1], 0), x(c[1], 1)), d(x(c[2], 0), x(c[2], 1));
        auto cross = [](const Eigen::Vector2d& u, const Eigen::Vector2d& v) { return u.x() * v.y() - u.y() * v.x(); };
        const double area = cross(b - a, d - a);
        const double u = cross(p - a, d - a) / area, v = cross(b - a, p - a) / area;
        if (u >= 0 && v >= 0 && u + v <= 1) return SurfacePoint::in_triangle(std::uint32_t(t), u, v);
    }
    FAIL("point outside the mesh");
    return {};
}

/// A closed polygon drawn on a planar mesh: its corners are points inside triangles, so every
/// side crosses many triangles (the resolver follows the straight line between corners).
SurfaceCurve polygon_curve(const SurfaceMesh& mesh, const std::vector<Eigen::Vector2d>& P) {
    SurfaceCurve c;
    for (const auto& p : P) c.nodes.push_back(locate_in_plane(mesh, p));
    return c;
}

std::vector<Eigen::Vector2d> regular_polygon(int k, double r, double phase) {
    std::vector<Eigen::Vector2d> P;
    for (int i = 0; i <= k; ++i) P.push_back(r * Eigen::Vector2d(std::cos(2 * kPi * i / k + phase), std::sin(2 * kPi * i / k + phase)));
    return P;
}

/// Error of φ over the vertices with |φ_true| ≤ band: root mean square, area-weighted.
double band_error(const SurfaceMesh& mesh, const std::vector<double>& phi, const std::vector<double>& truth, double band) {
    const std::vector<double> A = vertex_areas(mesh);
    double s = 0, a = 0;
    for (std::size_t i = 0; i < A.size(); ++i)
        if (std::abs(truth[i]) <= band) {
            s += A[i] * (phi[i] - truth[i]) * (phi[i] - truth[i]);
            a += A[i];
        }
    return std::sqrt(s / a);
}

/// A circle of latitude z = z0 on a unit icosphere through exact points of its edges (not the
/// zero set of any piecewise-linear function), with its exact geodesic signed distance: the
/// cap above is on the curve's left (it runs counter-clockwise seen from +z), so φ < 0 there.
struct Latitude {
    SurfaceMesh mesh;
    SurfaceSources sources;
    std::vector<double> truth;
};

Latitude latitude_circle(int level, double z0) {
    const PolygonMesh m = shapes::icosphere(level);
    SurfaceMesh mesh(m);
    std::vector<double> f(mesh.vertex_count());
    for (std::size_t i = 0; i < f.size(); ++i) f[i] = z0 - m.vertices(Eigen::Index(i), 2);  // < 0 above
    SurfaceSources s;
    s.curves = level_set_curves(mesh, f, 0);
    // Move each node to where the chord meets the circle (the sphere point with z = z0).
    for (SurfaceCurve& c : s.curves)
        for (SurfacePoint& p : c.nodes) {
            const auto e = mesh.edge(p.index);
            const Eigen::Vector3d a = m.vertices.row(e[0]).transpose(), b = m.vertices.row(e[1]).transpose();
            double lo = 0, hi = 1;
            const bool a_below = a.z() < z0;
            for (int it = 0; it < 60; ++it) {
                const double mid = 0.5 * (lo + hi);
                ((a + mid * (b - a)).normalized().z() < z0) == a_below ? lo = mid : hi = mid;
            }
            p.u = 0.5 * (lo + hi);
        }
    std::vector<double> truth(mesh.vertex_count());
    for (std::size_t i = 0; i < truth.size(); ++i)
        truth[i] = std::acos(z0) - std::acos(std::clamp(m.vertices.row(Eigen::Index(i)).normalized().z(), -1.0, 1.0));
    for (double& d : truth) d = -d;  // above the circle (smaller polar angle) is inside: negative
    return {std::move(mesh), std::move(s), std::move(truth)};
}

std::size_t piece_count(const SurfaceSources& s) {
    std::size_t n = 0;
    for (const SurfaceCurve& c : s.curves) n += c.nodes.size() - 1;
    return n;
}

bool all_finite(const std::vector<double>& v) {
    for (double x : v)
        if (!std::isfinite(x)) return false;
    return true;
}

}  // namespace

// ---- topology -------------------------------------------------------------------------------

TEST_CASE("edges are numbered as curve files expect: faces in order, sides in order, first sighting") {
    PolygonMesh m;
    m.vertices.resize(5, 3);
    m.vertices << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 2, 0.5, 0;
    m.add_face({0, 1, 2});     // sides 0→1, 1→2, 2→0
    m.add_face({0, 2, 3});     // 0→2 (seen: edge 2), 2→3, 3→0
    m.add_face({1, 4, 2, 2});  // a quad with a repeated vertex: sides 1→4, 4→2, 2→2, 2→1
    const SurfaceMesh s(m);
    REQUIRE(s.file_edge_count() == 8);
    const std::array<std::array<std::uint32_t, 2>, 8> expected{
        {{0, 1}, {1, 2}, {2, 0}, {2, 3}, {3, 0}, {1, 4}, {4, 2}, {2, 2}}};
    for (std::size_t e = 0; e < expected.size(); ++e) CHECK(s.edge(e) == expected[e]);
    // The quad fans into (1,4,2) and (1,2,2); its diagonal 1–2 is an existing edge, no new one.
    CHECK(s.triangle_count() == 4);
    CHECK(s.triangle_face(3) == 2);
    CHECK(s.edge_count() == 8);
    const SurfaceMesh::Summary sum = s.summary();
    CHECK(sum.degenerate_triangles == 1);  // (1, 2, 2)
}

TEST_CASE("mesh summary: boundary, nonmanifold and misoriented edges, components, Euler characteristic") {
    const SurfaceMesh sphere(shapes::icosphere(2));
    const SurfaceMesh::Summary s = sphere.summary();
    CHECK(s.boundary_edges == 0);
    CHECK(s.nonmanifold_edges == 0);
    CHECK(s.misoriented_edges == 0);
    CHECK(s.components == 1);
    CHECK(s.euler_characteristic == 2);

    PolygonMesh fan;  // three sheets on the edge 0–1, one of them flipped
    fan.vertices.resize(5, 3);
    fan.vertices << 0, 0, 0, 1, 0, 0, 0.5, 1, 0, 0.5, -1, 0, 0.5, 0, 1;
    fan.add_face({0, 1, 2});
    fan.add_face({1, 0, 3});
    fan.add_face({0, 1, 4});
    const SurfaceMesh::Summary f = SurfaceMesh(fan).summary();
    CHECK(f.nonmanifold_edges == 1);
    CHECK(f.boundary_edges == 6);
    CHECK(f.components == 1);
}

// ---- operators --------------------------------------------------------------------------------

TEST_CASE("operators on a flat mesh: the cotan Laplacian kills linear functions, a parallel field has no energy") {
    const PolygonMesh m = shapes::grid_mesh(6, 0.3, true, 3);
    const SurfaceMesh s(m);
    const mesh::Topology& t = s.topology();
    const mesh::Triangulation& T = t.mesh;

    // K (x + 2y) vanishes at interior vertices; K·1 vanishes everywhere.
    const surface_shm::SparseLower<double> K = surface_shm::cotan_laplacian(T, t.face_areas);
    std::vector<double> Kf(T.vertex_count, 0.0), K1(T.vertex_count, 0.0);
    for (std::size_t k = 0; k < K.entries(); ++k) {
        const auto r = std::size_t(K.rows[k]), c = std::size_t(K.cols[k]);
        const double fr = m.vertices(Eigen::Index(r), 0) + 2 * m.vertices(Eigen::Index(r), 1);
        const double fc = m.vertices(Eigen::Index(c), 0) + 2 * m.vertices(Eigen::Index(c), 1);
        Kf[r] += K.values[k] * fc;
        K1[r] += K.values[k];
        if (r != c) {
            Kf[c] += K.values[k] * fr;
            K1[c] += K.values[k];
        }
    }
    for (std::size_t v = 0; v < T.vertex_count; ++v) {
        CHECK(std::abs(K1[v]) < 1e-12);
        const double x = m.vertices(Eigen::Index(v), 0), y = m.vertices(Eigen::Index(v), 1);
        if (std::abs(x) < 0.99 && std::abs(y) < 0.99) CHECK(std::abs(Kf[v]) < 1e-12);
    }

    // The connection Laplacian: the field (1, 0.5) expressed in every edge's frame has zero energy,
    // a rotating field has positive energy. (M + tL) must factor (Hermitian positive definite).
    const surface_shm::SparseLower<surface_shm::Complex> A = surface_shm::vector_heat_operator(T, t.face_areas, 0.0);
    const surface_shm::SparseLower<surface_shm::Complex> L = surface_shm::vector_heat_operator(T, t.face_areas, 1.0);
    auto energy = [&](const std::vector<surface_shm::Complex>& X) {
        double e = 0;
        for (std::size_t k = 0; k < L.entries(); ++k) {
            const auto r = std::size_t(L.rows[k]), c = std::size_t(L.cols[k]);
            const surface_shm::Complex v = L.values[k] - (r == c ? A.values[k] : surface_shm::Complex(0, 0));
            e += (std::conj(X[r]) * v * X[c]).real();
            if (r != c) e += (std::conj(X[c]) * std::conj(v) * X[r]).real();
        }
        return e;
    };
    // Mass on the diagonal of A (t = 0) comes first among each diagonal's triplets: both
    // operators list the same entries in the same order, so subtracting them leaves L alone.
    REQUIRE(A.entries() == L.entries());
    std::vector<surface_shm::Complex> parallel(T.edge_count()), rotating(T.edge_count());
    for (std::size_t e = 0; e < T.edge_count(); ++e) {
        const Eigen::Vector3d d = (m.vertices.row(T.edges[e][1]) - m.vertices.row(T.edges[e][0])).transpose().normalized();
        const surface_shm::Complex frame(d.x(), d.y());  // the edge's direction; faces are counter-clockwise
        parallel[e] = std::conj(frame) * surface_shm::Complex(1.0, 0.5);
        const Eigen::Vector3d mid = 0.5 * (m.vertices.row(T.edges[e][1]) + m.vertices.row(T.edges[e][0])).transpose();
        rotating[e] = std::conj(frame) * surface_shm::Complex(-mid.y(), mid.x());
    }
    CHECK(std::abs(energy(parallel)) < 1e-10);
    CHECK(energy(rotating) > 0.1);
    CHECK_NOTHROW(surface_shm::Cholesky<surface_shm::Complex>{L});
}

TEST_CASE("divergence of the gradient of a piecewise-linear function is its cotan Laplacian") {
    const PolygonMesh m = shapes::icosphere(2);
    const SurfaceMesh s(m);
    const mesh::Topology& t = s.topology();
    const mesh::Triangulation& T = t.mesh;
    std::mt19937_64 rng(4);
    std::normal_distribution<double> n(0, 1);
    std::vector<double> phi(T.vertex_count);
    for (double& x : phi) x = n(rng);
    // ∇φ in each face's plane: Σ_i φ_i ∇λ_i, ∇λ_i = J(p_k − p_j)/(2A).
    std::vector<Eigen::Vector2d> Y(T.face_count());
    for (std::size_t f = 0; f < T.face_count(); ++f) {
        const surface_shm::FaceFrame F = surface_shm::face_frame(T, f, t.face_areas[f]);
        Eigen::Vector2d g = Eigen::Vector2d::Zero();
        for (int i = 0; i < 3; ++i) {
            const Eigen::Vector2d d = F.p[std::size_t((i + 2) % 3)] - F.p[std::size_t((i + 1) % 3)];
            g += phi[T.faces[f][std::size_t(i)]] * Eigen::Vector2d(-d.y(), d.x()) / (2 * F.area);
        }
        Y[f] = g;
    }
    const std::vector<double> div = surface_shm::face_field_divergence(T, t.face_areas, Y);
    const surface_shm::SparseLower<double> K = surface_shm::cotan_laplacian(T, t.face_areas);
    std::vector<double> Kphi(T.vertex_count, 0.0);
    for (std::size_t k = 0; k < K.entries(); ++k) {
        const auto r = std::size_t(K.rows[k]), c = std::size_t(K.cols[k]);
        Kphi[r] += K.values[k] * phi[c];
        if (r != c) Kphi[c] += K.values[k] * phi[r];
    }
    for (std::size_t v = 0; v < T.vertex_count; ++v) CHECK(div[v] == doctest::Approx(Kphi[v]).epsilon(1e-9).scale(1));
}

TEST_CASE("level-set curves are oriented with the region below the level on their left") {
    const PolygonMesh m = shapes::grid_mesh(20, 0.2, true, 9);
    const SurfaceMesh s(m);
    std::vector<double> f(s.vertex_count());
    for (std::size_t i = 0; i < f.size(); ++i) f[i] = m.vertices.row(Eigen::Index(i)).head<2>().norm() - 0.5;
    const std::vector<SurfaceCurve> curves = level_set_curves(s, f, 0);
    REQUIRE(curves.size() == 1);
    double twice_area = 0;  // shoelace: positive for counter-clockwise
    const auto& n = curves[0].nodes;
    for (std::size_t i = 0; i + 1 < n.size(); ++i) {
        const Eigen::Vector3d a = position(s, n[i]), b = position(s, n[i + 1]);
        twice_area += a.x() * b.y() - a.y() * b.x();
        CHECK(std::abs(a.head<2>().norm() - 0.5) < 0.02);
    }
    CHECK(position(s, n.front()).isApprox(position(s, n.back())));  // closed
    CHECK(twice_area / 2 == doctest::Approx(kPi * 0.25).epsilon(0.02));
}

// ---- accuracy -----------------------------------------------------------------------------------

TEST_CASE("planar polygon: sign right everywhere, error near the curve falls at least linearly with h") {
    // A square whose corners sit inside triangles: its sides cross triangles, and the corner
    // triangles hold two sides each (the case that breaks exact zero-set constraints).
    const std::vector<Eigen::Vector2d> square = regular_polygon(4, 0.85, 0.1);
    std::vector<double> errors;
    for (int n : {12, 24, 48}) {
        const PolygonMesh m = shapes::grid_mesh(n, 0.2, true, 7);
        const SurfaceMesh mesh(m);
        SurfaceSources src;
        src.curves.push_back(polygon_curve(mesh, square));
        const std::vector<double> truth = polygon_sdf(m.vertices, square);
        SignedHeatSurface shm(mesh);
        const SurfaceShmResult r = shm.solve(src);
        REQUIRE(all_finite(r.phi));
        errors.push_back(band_error(mesh, r.phi, truth, 0.25));
        const double eps = surface_distance_error(mesh, r.phi, truth);
        MESSAGE("n = " << n << ": ε = " << eps << ", error within 0.25 of the curve " << errors.back()
                       << ", sign right on " << surface_sign_agreement(mesh, r.phi, truth) << " of the area");
        CHECK(eps < 0.06);
        if (n == 48) CHECK(surface_sign_agreement(mesh, r.phi, truth) > 0.995);
    }
    // At least linear over the three resolutions (h → h/4: error ÷ 4 or more), falling at each step.
    CHECK(errors[0] / errors[2] >= 4.0);
    CHECK(errors[0] / errors[1] >= 1.5);
    CHECK(errors[1] / errors[2] >= 1.5);
}

TEST_CASE("circle of latitude on a sphere: exact geodesic distance, error falls at least linearly") {
    std::vector<double> eps;
    for (int level : {2, 3, 4}) {
        const Latitude L = latitude_circle(level, 0.3);
        SignedHeatSurface shm(L.mesh);
        const SurfaceShmResult r = shm.solve(L.sources);
        eps.push_back(surface_distance_error(L.mesh, r.phi, L.truth));
        MESSAGE("level " << level << ": ε = " << eps.back());
        CHECK(surface_sign_agreement(L.mesh, r.phi, L.truth) > 0.999);
    }
    CHECK(eps[0] / eps[1] >= 2.0);
    CHECK(eps[1] / eps[2] >= 2.0);
    CHECK(eps[2] < 5e-4);
}

TEST_CASE("broken curves (30–50 % deleted, a piece reversed): the sign is still right on ≥ 99 % of the area") {
    SUBCASE("plane") {
        const PolygonMesh m = shapes::grid_mesh(48, 0.2, true, 5);
        const SurfaceMesh mesh(m);
        const std::vector<Eigen::Vector2d> P = regular_polygon(40, 0.6, 0.0);
        SurfaceSources whole;
        std::vector<double> f(mesh.vertex_count());
        for (std::size_t i = 0; i < f.size(); ++i) f[i] = m.vertices.row(Eigen::Index(i)).head<2>().norm() - 0.6;
        whole.curves = level_set_curves(mesh, f, 0);
        const std::vector<double> truth = polygon_sdf(m.vertices, P);
        SignedHeatSurface shm(mesh);
        for (double cut : {0.3, 0.5}) {
            const SurfaceSources b = damage(whole, {cut, 8, 1}, 11);
            const double kept = double(piece_count(b)) / double(piece_count(whole));
            const SurfaceShmResult r = shm.solve(b);
            const double sign = surface_sign_agreement(mesh, r.phi, truth);
            MESSAGE("plane, " << kept * 100 << " % of the pieces kept: sign right on " << sign * 100 << " %");
            CHECK(sign >= 0.99);
        }
    }
    SUBCASE("sphere") {
        const Latitude L = latitude_circle(4, 0.2);
        SignedHeatSurface shm(L.mesh);
        for (double cut : {0.3, 0.5}) {
            const SurfaceSources b = damage(L.sources, {cut, 8, 1}, 3);
            const SurfaceShmResult r = shm.solve(b);
            const double sign = surface_sign_agreement(L.mesh, r.phi, L.truth);
            MESSAGE("sphere, " << cut * 100 << " % cut in 8 gaps, a piece reversed: sign right on " << sign * 100 << " %");
            CHECK(sign >= 0.99);
        }
    }
}

TEST_CASE("unsigned distance to a point on a plane") {
    const PolygonMesh m = shapes::grid_mesh(40, 0.2, true, 2);
    const SurfaceMesh mesh(m);
    SignedHeatSurface shm(mesh);
    for (const Eigen::Vector2d& p : {Eigen::Vector2d(0.05, -0.1), Eigen::Vector2d(0.3, 0.2)}) {
        SurfaceSources s;
        s.points.push_back(locate_in_plane(mesh, p));
        std::vector<double> truth(mesh.vertex_count());
        for (std::size_t i = 0; i < truth.size(); ++i) truth[i] = (m.vertices.row(Eigen::Index(i)).head<2>().transpose() - p).norm();
        const SurfaceShmResult r = shm.solve(s);
        const double eps = surface_distance_error(mesh, r.phi, truth);
        MESSAGE("point source at (" << p.x() << ", " << p.y() << "): ε = " << eps);
        CHECK(eps < 0.03);
        double lowest = INFINITY;
        for (double x : r.phi) lowest = std::min(lowest, x);
        CHECK(lowest > -0.05);  // unsigned: no side is negative
    }
}

TEST_CASE("signed and unsigned sources mix in one solve (thesis fig. 4.10)") {
    const PolygonMesh m = shapes::grid_mesh(32, 0.1, false, 0);
    const SurfaceMesh mesh(m);
    std::vector<double> f(mesh.vertex_count());
    for (std::size_t i = 0; i < f.size(); ++i) f[i] = (m.vertices.row(Eigen::Index(i)).head<2>() - Eigen::RowVector2d(-0.4, 0)).norm() - 0.3;
    SurfaceSources s;
    s.curves = level_set_curves(mesh, f, 0);          // a signed circle on the left
    SurfaceCurve open;                                 // an unsigned open curve on the right
    for (double y : {-0.5, -0.2, 0.1, 0.4}) open.nodes.push_back(locate_in_plane(mesh, {0.5, y}));
    open.is_signed = false;
    s.curves.push_back(open);
    s.points.push_back(locate_in_plane(mesh, {0.0, 0.8}));
    SignedHeatSurface shm(mesh);
    const SurfaceShmResult r = shm.solve(s);
    REQUIRE(all_finite(r.phi));
    // Inside the signed circle φ < 0; next to the unsigned curve φ is small and positive on both sides.
    auto phi_at = [&](double x, double y) {
        std::size_t best = 0;
        for (std::size_t i = 0; i < mesh.vertex_count(); ++i)
            if ((m.vertices.row(Eigen::Index(i)).head<2>() - Eigen::RowVector2d(x, y)).norm() <
                (m.vertices.row(Eigen::Index(best)).head<2>() - Eigen::RowVector2d(x, y)).norm())
                best = i;
        return r.phi[best];
    };
    CHECK(phi_at(-0.4, 0.0) < -0.2);
    CHECK(phi_at(0.44, 0.0) > 0.0);
    CHECK(phi_at(0.56, 0.0) > 0.0);
    CHECK(phi_at(0.44, 0.0) < 0.15);
    CHECK(phi_at(0.56, 0.0) < 0.15);
}

// ---- constraints, robustness -------------------------------------------------------------------

TEST_CASE("hard zero set: φ = 0 at every curve node, duplicate nodes included") {
    const Latitude L = latitude_circle(3, 0.1);
    SurfaceSources s = L.sources;
    // Duplicates: the loop repeats its first node, a reversed copy of a stretch, and two pieces
    // meeting at a point.
    const SurfaceCurve c = s.curves.front();
    SurfaceCurve reversed(c);
    reversed.nodes.resize(6);
    std::reverse(reversed.nodes.begin(), reversed.nodes.end());
    s.curves.push_back(reversed);
    s.curves.push_back({{c.nodes[3], c.nodes[3], c.nodes[4]}, true});
    SurfaceShmOptions o;
    o.soft_weight = 0;
    SignedHeatSurface shm(L.mesh);
    const SurfaceShmResult r = shm.solve(s, o);
    REQUIRE(all_finite(r.phi));
    CHECK(r.constraint_residual < 1e-10);
    const auto& x = L.mesh.polygons().vertices;
    double range = 0;
    for (double v : r.phi) range = std::max(range, std::abs(v));
    for (const SurfaceCurve& curve : s.curves)
        for (const SurfacePoint& p : curve.nodes) {
            const auto e = L.mesh.edge(p.index);
            const double value = (1 - p.u) * r.phi[e[0]] + p.u * r.phi[e[1]];
            CHECK(std::abs(value) < 1e-9 * range);
            (void)x;
        }
}

TEST_CASE("level-set modes: components get one level each; soft and none stay near zero on the curve") {
    const PolygonMesh m = shapes::grid_mesh(32, 0.2, true, 8);
    const SurfaceMesh mesh(m);
    SurfaceSources s;
    for (double cx : {-0.45, 0.45}) {
        std::vector<double> f(mesh.vertex_count());
        for (std::size_t i = 0; i < f.size(); ++i)
            f[i] = (m.vertices.row(Eigen::Index(i)).head<2>() - Eigen::RowVector2d(cx, 0)).norm() - (cx < 0 ? 0.3 : 0.15);
        for (const SurfaceCurve& c : level_set_curves(mesh, f, 0)) s.curves.push_back(c);
    }
    REQUIRE(s.curves.size() == 2);
    SignedHeatSurface shm(mesh);
    auto values_on = [&](const std::vector<double>& phi, const SurfaceCurve& c) {
        std::vector<double> v;
        for (const SurfacePoint& p : c.nodes) {
            const auto e = mesh.edge(p.index);
            v.push_back((1 - p.u) * phi[e[0]] + p.u * phi[e[1]]);
        }
        return v;
    };
    SurfaceShmOptions o;
    o.level_set = LevelSetConstraint::Components;
    o.soft_weight = 0;
    const SurfaceShmResult r = shm.solve(s, o);
    for (const SurfaceCurve& c : s.curves) {
        const std::vector<double> v = values_on(r.phi, c);
        const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
        CHECK(*hi - *lo < 1e-9);  // one level per component (the two levels may differ)
    }
    for (LevelSetConstraint mode : {LevelSetConstraint::None, LevelSetConstraint::ZeroSet}) {
        o.level_set = mode;
        o.soft_weight = 100;
        const SurfaceShmResult q = shm.solve(s, o);
        for (const SurfaceCurve& c : s.curves)
            for (double v : values_on(q.phi, c)) CHECK(std::abs(v) < 0.02);
    }
}

TEST_CASE("a repeated solve gives what a fresh solver gives (cached factors are reused correctly)") {
    const Latitude A = latitude_circle(3, 0.3);
    const Latitude B = latitude_circle(3, -0.4);
    SignedHeatSurface cached(A.mesh);
    const SurfaceShmResult a1 = cached.solve(A.sources);
    const SurfaceShmResult b = cached.solve(B.sources);
    const SurfaceShmResult a2 = cached.solve(A.sources);
    SignedHeatSurface fresh(B.mesh);
    const SurfaceShmResult b_fresh = fresh.solve(B.sources);
    for (std::size_t i = 0; i < a1.phi.size(); ++i) {
        CHECK(a2.phi[i] == doctest::Approx(a1.phi[i]).epsilon(1e-9).scale(1));
        CHECK(b.phi[i] == doctest::Approx(b_fresh.phi[i]).epsilon(1e-9).scale(1));
    }
}

TEST_CASE("nonmanifold (three sheets on one edge) and nonorientable (Möbius) meshes give finite φ") {
    SUBCASE("three sheets") {
        PolygonMesh m;
        const int n = 6;
        std::vector<Eigen::Vector3d> v;
        // The shared edge along x, three rectangular sheets leaving it at 120° to each other.
        for (int i = 0; i <= n; ++i) v.push_back({double(i) / n, 0, 0});
        for (int s = 0; s < 3; ++s) {
            const double a = 2 * kPi * s / 3;
            for (int j = 1; j <= n; ++j)
                for (int i = 0; i <= n; ++i) v.push_back({double(i) / n, std::cos(a) * j / n, std::sin(a) * j / n});
        }
        m.vertices.resize(Eigen::Index(v.size()), 3);
        for (std::size_t i = 0; i < v.size(); ++i) m.vertices.row(Eigen::Index(i)) = v[i].transpose();
        auto id = [&](int s, int j, int i) { return std::uint32_t(j == 0 ? i : (n + 1) + s * n * (n + 1) + (j - 1) * (n + 1) + i); };
        for (int s = 0; s < 3; ++s)
            for (int j = 0; j < n; ++j)
                for (int i = 0; i < n; ++i) {
                    m.add_face({id(s, j, i), id(s, j, i + 1), id(s, j + 1, i + 1)});
                    m.add_face({id(s, j, i), id(s, j + 1, i + 1), id(s, j + 1, i)});
                }
        const SurfaceMesh mesh(m);
        REQUIRE(mesh.summary().nonmanifold_edges == std::size_t(n));
        SurfaceSources s;
        s.curves.push_back({{SurfacePoint::at_vertex(id(0, 3, 0)), SurfacePoint::at_vertex(id(0, 3, 3)),
                             SurfacePoint::at_vertex(id(0, 3, 6))},
                            true});
        s.points.push_back(SurfacePoint::at_vertex(id(1, 5, 5)));
        SignedHeatSurface shm(mesh);
        const SurfaceShmResult r = shm.solve(s);
        CHECK(all_finite(r.phi));
        CHECK(r.unreached_vertices == 0);
    }
    SUBCASE("Möbius strip") {
        PolygonMesh m;
        const int n = 40;
        m.vertices.resize(2 * n, 3);
        for (int i = 0; i < n; ++i) {
            const double u = 2 * kPi * i / n;
            for (int s = 0; s < 2; ++s) {
                const double w = s == 0 ? -0.3 : 0.3;
                m.vertices.row(2 * i + s) << (1 + w * std::cos(u / 2)) * std::cos(u), (1 + w * std::cos(u / 2)) * std::sin(u),
                    w * std::sin(u / 2);
            }
        }
        for (int i = 0; i < n; ++i) {
            const std::uint32_t a = std::uint32_t(2 * i), b = a + 1;
            // The last quad joins the strip with a half twist.
            const std::uint32_t c = i + 1 < n ? a + 2 : 1, d = i + 1 < n ? a + 3 : 0;
            m.add_face({a, c, d});
            m.add_face({a, d, b});
        }
        const SurfaceMesh mesh(m);
        CHECK(mesh.summary().misoriented_edges > 0);
        SurfaceSources s;
        s.curves.push_back({{SurfacePoint::at_vertex(10), SurfacePoint::at_vertex(12), SurfacePoint::at_vertex(14)}, true});
        for (bool idt : {false, true}) {
            SurfaceShmSetup setup;
            setup.intrinsic_delaunay = idt;
            SignedHeatSurface shm(mesh, setup);
            const SurfaceShmResult r = shm.solve(s);
            CHECK(all_finite(r.phi));
        }
    }
}

TEST_CASE("intrinsic Delaunay: same answer on a Delaunay mesh, better on a mesh of slivers, input vertices kept") {
    SUBCASE("a Delaunay mesh flips nothing and solves the same") {
        const Latitude L = latitude_circle(3, 0.2);
        SurfaceShmSetup setup;
        setup.intrinsic_delaunay = true;
        SignedHeatSurface idt(L.mesh, setup), plain(L.mesh);
        const SurfaceShmResult a = idt.solve(L.sources), b = plain.solve(L.sources);
        CHECK(a.flips == 0);
        for (std::size_t i = 0; i < a.phi.size(); ++i) CHECK(a.phi[i] == doctest::Approx(b.phi[i]).epsilon(1e-9).scale(1));
    }
    SUBCASE("slivers") {
        // A sheared grid cut along the long diagonal of every parallelogram: obtuse slivers,
        // negative cotan weights, the worst pattern for the cotan operators.
        PolygonMesh m;
        const int n = 24;
        m.vertices.resize((n + 1) * (n + 1), 3);
        for (int j = 0; j <= n; ++j)
            for (int i = 0; i <= n; ++i)
                m.vertices.row(j * (n + 1) + i) << -1.6 + 2.0 * i / n + 1.2 * j / n, -1 + 2.0 * j / n, 0;
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const std::uint32_t a = std::uint32_t(j * (n + 1) + i);
                const std::uint32_t b = a + 1, c = a + std::uint32_t(n + 1) + 1, d = a + std::uint32_t(n + 1);
                m.add_face({a, b, c});  // a–c is the long diagonal of the sheared cell
                m.add_face({a, c, d});
            }
        const SurfaceMesh mesh(m);
        const std::vector<Eigen::Vector2d> P = regular_polygon(6, 0.55, 0.3);
        SurfaceSources s;
        s.curves.push_back(polygon_curve(mesh, P));
        const std::vector<double> truth = polygon_sdf(m.vertices, P);
        SurfaceShmSetup setup;
        setup.intrinsic_delaunay = true;
        SignedHeatSurface idt(mesh, setup), plain(mesh);
        const SurfaceShmResult a = idt.solve(s), b = plain.solve(s);
        REQUIRE(a.phi.size() == mesh.vertex_count());
        const double ea = surface_distance_error(mesh, a.phi, truth), eb = surface_distance_error(mesh, b.phi, truth);
        MESSAGE("slivers: ε " << eb << " plain, " << ea << " intrinsic Delaunay (" << a.flips << " flips)");
        CHECK(a.flips > 0);
        CHECK(ea < eb);
    }
    SUBCASE("refinement adds vertices where flips cannot help, and reports the input vertices") {
        // Cells 8× wider than tall: every triangle has a 7° angle, Delaunay or not.
        PolygonMesh m;
        const int nx = 6, ny = 48;
        m.vertices.resize((nx + 1) * (ny + 1), 3);
        for (int j = 0; j <= ny; ++j)
            for (int i = 0; i <= nx; ++i) m.vertices.row(j * (nx + 1) + i) << -1 + 2.0 * i / nx, -1 + 2.0 * j / ny, 0;
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const std::uint32_t a = std::uint32_t(j * (nx + 1) + i);
                m.add_face({a, a + 1, a + std::uint32_t(nx + 2)});
                m.add_face({a, a + std::uint32_t(nx + 2), a + std::uint32_t(nx + 1)});
            }
        const SurfaceMesh mesh(m);
        const std::vector<Eigen::Vector2d> P = regular_polygon(5, 0.6, 0.2);
        SurfaceSources s;
        s.curves.push_back(polygon_curve(mesh, P));
        const std::vector<double> truth = polygon_sdf(m.vertices, P);
        SurfaceShmSetup setup;
        setup.intrinsic_delaunay = true;
        setup.refine = true;
        SignedHeatSurface refined(mesh, setup), plain(mesh);
        const SurfaceShmResult c = refined.solve(s), d = plain.solve(s);
        REQUIRE(c.phi.size() == mesh.vertex_count());
        CHECK(c.solve_vertices > mesh.vertex_count());
        CHECK(all_finite(c.phi));
        const double ec = surface_distance_error(mesh, c.phi, truth), ed = surface_distance_error(mesh, d.phi, truth);
        MESSAGE("thin cells: ε " << ed << " plain, " << ec << " refined (" << c.solve_vertices << " vertices)");
        CHECK(ec < ed);
    }
}

TEST_CASE("vertices on no face get NaN; components no source reaches are counted, φ stays finite") {
    PolygonMesh m = shapes::icosphere(2);
    const PolygonMesh other = shapes::icosphere(2, 1.0, Eigen::Vector3d(4, 0, 0));
    const auto offset = std::uint32_t(m.vertices.rows());
    m.vertices.conservativeResize(m.vertices.rows() + other.vertices.rows() + 1, 3);
    m.vertices.block(offset, 0, other.vertices.rows(), 3) = other.vertices;
    m.vertices.bottomRows(1) << 9, 9, 9;  // on no face
    for (std::size_t f = 0; f < other.face_count(); ++f)
        m.add_face({other.indices[3 * f] + offset, other.indices[3 * f + 1] + offset, other.indices[3 * f + 2] + offset});
    const SurfaceMesh mesh(m);
    CHECK(mesh.summary().components == 2);
    CHECK(mesh.summary().unreferenced_vertices == 1);
    std::vector<double> z(mesh.vertex_count(), 1.0);
    for (std::uint32_t i = 0; i < offset; ++i) z[i] = m.vertices(i, 2) - 0.2;
    SurfaceSources s;
    s.curves = level_set_curves(mesh, z, 0);
    REQUIRE(s.curves.size() == 1);
    SignedHeatSurface shm(mesh);
    const SurfaceShmResult r = shm.solve(s);
    CHECK(std::isnan(r.phi.back()));
    for (std::size_t i = 0; i + 1 < r.phi.size(); ++i) CHECK(std::isfinite(r.phi[i]));
    CHECK(r.unreached_vertices == other.vertices.rows());
}

TEST_CASE("bad sources are refused with a clear error") {
    const SurfaceMesh mesh(shapes::icosphere(1));
    SignedHeatSurface shm(mesh);
    auto throws_with = [&](const SurfaceSources& s, const std::string& text) {
        try {
            shm.solve(s);
            FAIL("no error for: " << text);
        } catch (const Error& e) {
            CHECK_MESSAGE(std::string(e.what()).find(text) != std::string::npos, e.what());
        }
    };
    throws_with({}, "no curves and no points");
    throws_with({{{{SurfacePoint::at_vertex(0)}, true}}, {}}, "fewer than 2 nodes");
    throws_with({{{{SurfacePoint::at_vertex(0), SurfacePoint::at_vertex(999)}, true}}, {}}, "out of range");
    throws_with({{{{SurfacePoint::at_vertex(0), SurfacePoint::on_edge(0, 1.5)}, true}}, {}}, "not in [0, 1]");
    throws_with({{{{SurfacePoint::at_vertex(0), SurfacePoint::on_edge(0, NAN)}, true}}, {}}, "not in [0, 1]");
    throws_with({{{{SurfacePoint::at_vertex(0), SurfacePoint::in_triangle(0, 0.9, 0.9)}, true}}, {}}, "inside the triangle");
    throws_with({{{{SurfacePoint::at_vertex(0), SurfacePoint::at_vertex(0)}, true}}, {}}, "zero length");

    // Two separate spheres: a segment from one to the other has no path.
    PolygonMesh two = shapes::icosphere(1);
    const PolygonMesh other = shapes::icosphere(1, 1.0, Eigen::Vector3d(5, 0, 0));
    const auto offset = std::uint32_t(two.vertices.rows());
    two.vertices.conservativeResize(two.vertices.rows() + other.vertices.rows(), 3);
    two.vertices.bottomRows(other.vertices.rows()) = other.vertices;
    for (std::size_t f = 0; f < other.face_count(); ++f)
        two.add_face({other.indices[3 * f] + offset, other.indices[3 * f + 1] + offset, other.indices[3 * f + 2] + offset});
    const SurfaceMesh two_mesh(two);
    SignedHeatSurface split(two_mesh);
    try {
        split.solve({{{{SurfacePoint::at_vertex(0), SurfacePoint::at_vertex(offset)}, true}}, {}});
        FAIL("no error for a segment between two components");
    } catch (const Error& e) {
        CHECK(std::string(e.what()).find("no path") != std::string::npos);
    }
    // From a file, the error names the file and the line of the `l`.
    test::ScratchDir dir("surface-no-path");
    test::write_bytes(dir.file("c.txt"), "#offset 0\nv 0\nv 1\nv " + std::to_string(offset) + "\nl 0 1 2\n");
    try {
        read_surface_curves(dir.file("c.txt"), two_mesh);
        FAIL("no error for a curve file joining two components");
    } catch (const Error& e) {
        CHECK(e.where() == dir.file("c.txt"));
        CHECK(std::string(e.what()).find("line 5") != std::string::npos);
        CHECK(std::string(e.what()).find("no path") != std::string::npos);
    }
}

TEST_CASE("curve files: bad records name the file and line") {
    test::ScratchDir dir("surface-curves");
    const SurfaceMesh mesh(shapes::icosphere(1));
    auto error_of = [&](const std::string& text) {
        const std::string path = dir.file("c.txt");
        test::write_bytes(path, text);
        try {
            read_surface_curves(path, mesh);
        } catch (const Error& e) {
            CHECK(e.where() == path);
            return std::string(e.what());
        }
        return std::string("no error");
    };
    CHECK(error_of("#offset 0\nv 0\nv 500\nl 0 1\n").find("line 3") != std::string::npos);
    CHECK(error_of("v 1\ne 9999 0.5\nl 1 2\n").find("line 2") != std::string::npos);
    CHECK(error_of("v 1\ne 1 1.5\nl 1 2\n").find("line 2") != std::string::npos);
    CHECK(error_of("v 1\nv 2\n").find("no curves") != std::string::npos);
    // A good file reads: 1-based indices by default.
    test::write_bytes(dir.file("ok.txt"), "v 1\ne 2 0.25\nf 3 0.2 0.3\nl 1 2 3\n");
    const SurfaceSources s = read_surface_curves(dir.file("ok.txt"), mesh);
    REQUIRE(s.curves.size() == 1);
    REQUIRE(s.curves[0].nodes.size() == 3);
    CHECK(s.curves[0].nodes[0].index == 0);
    CHECK(s.curves[0].nodes[1].kind == SurfacePoint::Kind::Edge);
    CHECK(s.curves[0].nodes[1].index == 1);
    CHECK(s.curves[0].nodes[2].kind == SurfacePoint::Kind::Face);
    CHECK(s.curves[0].nodes[2].index == 2);
}

#if GSD_HAVE_SHARED_DATA
TEST_CASE("every curve in the shared data loads and solves to finite values" * doctest::test_suite("slow")) {
    const std::vector<std::pair<std::string, std::string>> pairs{
        {"S.obj", "S.txt"},
        {"annulus.obj", "annulus.txt"},
        {"asymmetric-torus.obj", "asymmetric-torus.txt"},
        {"bunny.obj", "bunny-heart.txt"},
        {"bunny.obj", "bunny-brokenheart.txt"},
        {"double-torus.obj", "double-torus.txt"},
        {"spots-on-spot.obj", "spots-on-spot.txt"},
        {"torus.obj", "torus-phi.txt"},
        {"twirl.obj", "twirl.txt"},
        {"DoubleTorusWithLoops.obj", "DoubleTorusWithLoops.obj"},
        {"DoubleTorusWithBrokenLoops.obj", "DoubleTorusWithBrokenLoops.obj"},
    };
    for (const auto& pair : pairs) {
        const auto& mesh_file = pair.first;  // (no structured binding: clang 14 cannot capture one)
        const auto& curve_file = pair.second;
        CAPTURE(curve_file);
        const std::string mp = test::shared_data("surface-curves/" + mesh_file);
        const SurfaceMesh mesh(io::read_mesh(mp), mp);
        const SurfaceSources s = read_surface_curves(test::shared_data("surface-curves/" + curve_file), mesh);
        SignedHeatSurface shm(mesh);
        const SurfaceShmResult r = shm.solve(s);
        CHECK(all_finite(r.phi));
        double lo = INFINITY, hi = -INFINITY;
        for (double x : r.phi) {
            lo = std::min(lo, x);
            hi = std::max(hi, x);
        }
        CHECK(lo < 0);  // every file has a signed curve with an inside
        CHECK(hi > 0);
    }
}
#endif

TEST_CASE("sharpening a blurred surface SHM distance (t = 100h²) halves its error, every label kept") {
    // A square and a non-convex seven-pointed curve across a jittered grid: the blur rounds
    // their corners and bends the distance between them; sharpening restores both.
    const std::vector<std::vector<Eigen::Vector2d>> curves = {
        regular_polygon(4, 0.85, 0.1),
        [] {
            std::vector<Eigen::Vector2d> P;
            for (int i = 0; i <= 7; ++i) {
                const double a = 2 * kPi * i / 7 + 0.1, r = 0.6 + 0.2 * std::cos(3 * a);
                P.push_back(r * Eigen::Vector2d(std::cos(a), std::sin(a)));
            }
            return P;
        }()};
    const PolygonMesh m = shapes::grid_mesh(40, 0.2, true, 11);
    const SurfaceMesh mesh(m);
    SurfaceShmSetup setup;
    setup.t_coef = 100;
    SignedHeatSurface shm(mesh, setup);
    for (const auto& P : curves) {
        SurfaceSources src;
        src.curves.push_back(polygon_curve(mesh, P));
        const std::vector<double> truth = polygon_sdf(m.vertices, P);
        const SurfaceShmResult r = shm.solve(src);
        const SurfaceSharpenResult s = shm.sharpen(r.phi, src);
        auto mean_error = [&](const std::vector<double>& phi) {
            double e = 0;
            for (std::size_t i = 0; i < phi.size(); ++i) e += std::abs(phi[i] - truth[i]);
            return e / double(phi.size());
        };
        std::size_t changed = 0;
        for (std::size_t i = 0; i < r.phi.size(); ++i) changed += (r.phi[i] < 0) != (s.phi[i] < 0);
        MESSAGE((P.size() - 1) << " corners: mean |φ − sdf| " << mean_error(r.phi) << " → " << mean_error(s.phi) << " in "
                              << s.iterations << " iterations, largest slope " << s.max_slope);
        CHECK(mean_error(s.phi) <= 0.5 * mean_error(r.phi));
        CHECK(changed == 0);
        CHECK(s.sign_changes == 0);
        CHECK(s.max_slope < 1.2);
    }
    SurfaceSharpenOptions bad;
    bad.iterations = -2;
    SurfaceSources src;
    src.curves.push_back(polygon_curve(mesh, curves[0]));
    CHECK_THROWS_WITH_AS(shm.sharpen(std::vector<double>(mesh.vertex_count(), 1.0), src, bad), doctest::Contains("iterations"), Error);
    CHECK_THROWS_WITH_AS(shm.sharpen(std::vector<double>(3, 1.0), src), doctest::Contains("values for a mesh of"), Error);
}
