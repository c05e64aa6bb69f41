// Point clouds as surface domains (thesis fig. 4.5, left): the surface of a cloud built from its
// points' local Delaunay fans, normals oriented consistently, and the surface Signed Heat
// Method on it held to the exact geodesic distance and to gsd's own mesh path on a mesh with
// the same vertices (a sphere and a plane, with and without noise).
#include <doctest/doctest.h>

#include <gsd/shapes.hpp>
#include <gsd/surface.hpp>
#include <gsd/swn.hpp>
#include <gsd/viz.hpp>

#include "support.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <random>

using namespace gsd;
using test::polygon_sdf;

namespace {

/// A unit icosphere whose vertices are moved along the sphere by up to `jitter` × the edge
/// length (faces kept: a mesh with uneven vertices), then off it along the normal by Gaussian
/// noise of deviation `noise` × the radius.
PolygonMesh uneven_sphere(int level, double jitter, double noise, std::uint64_t seed) {
    PolygonMesh m = shapes::icosphere(level);
    const double edge = (m.vertices.row(m.indices[0]) - m.vertices.row(m.indices[1])).norm();
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    std::normal_distribution<double> g(0, 1);
    for (Eigen::Index i = 0; i < m.vertices.rows(); ++i) {
        Eigen::Vector3d x = m.vertices.row(i).transpose();
        x = (x + jitter * edge * Eigen::Vector3d(u(rng), u(rng), u(rng))).normalized();
        m.vertices.row(i) = (x * (1 + noise * g(rng))).transpose();
    }
    return m;
}

/// Exact signed geodesic distance on the unit sphere to a closed loop of great-circle arcs
/// through the given points (negative on the loop's left), at each point's radial projection.
std::vector<double> sphere_loop_sdf(const Points& x, const std::vector<Eigen::Vector3d>& loop) {
    std::vector<double> d(std::size_t(x.rows()));
    const std::size_t m = loop.size() - 1;
    std::vector<Eigen::Vector3d> n(m);
    for (std::size_t k = 0; k < m; ++k) n[k] = loop[k].cross(loop[k + 1]).normalized();
    for (Eigen::Index i = 0; i < x.rows(); ++i) {
        const Eigen::Vector3d p = x.row(i).transpose().normalized();
        double best = INFINITY, side = 0;
        for (std::size_t k = 0; k < m; ++k) {
            const Eigen::Vector3d& a = loop[k];
            const Eigen::Vector3d& b = loop[k + 1];
            const Eigen::Vector3d q = p - p.dot(n[k]) * n[k];
            double dist, s;
            if (q.norm() > 1e-12 && a.cross(q).dot(n[k]) >= 0 && q.cross(b).dot(n[k]) >= 0) {
                dist = std::asin(std::min(1.0, std::abs(p.dot(n[k]))));
                s = p.dot(n[k]);
            } else {
                const double da = std::acos(std::clamp(p.dot(a), -1.0, 1.0)), db = std::acos(std::clamp(p.dot(b), -1.0, 1.0));
                // At a loop point the side is that of the two arcs' summed normal there.
                const std::size_t at = da < db ? k : k + 1;
                const Eigen::Vector3d pseudo = n[(at + m - 1) % m] + n[at % m];
                dist = std::min(da, db);
                s = p.dot(pseudo);
            }
            if (dist < best) best = dist, side = s;
        }
        d[std::size_t(i)] = side > 0 ? -best : best;
    }
    return d;
}

/// A flat, uneven mesh of [−1, 1]² (jittered grid, random diagonals) lifted off its plane by
/// Gaussian noise of deviation `noise`.
PolygonMesh uneven_square(int n, double noise, std::uint64_t seed) {
    PolygonMesh m = shapes::grid_mesh(n, 0.3, true, seed);
    std::mt19937_64 rng(seed + 1);
    std::normal_distribution<double> g(0, 1);
    for (Eigen::Index i = 0; i < m.vertices.rows(); ++i) m.vertices(i, 2) = noise * g(rng);
    return m;
}

/// A closed loop through mesh vertices near the zero set of f (its crossings snapped to the
/// nearer end of their edge), with f < 0 on its left.
SurfaceCurve vertex_loop(const SurfaceMesh& mesh, const std::vector<double>& f) {
    const std::vector<SurfaceCurve> level = level_set_curves(mesh, f, 0);
    REQUIRE(level.size() == 1);
    SurfaceCurve loop;
    for (const SurfacePoint& p : level[0].nodes) {
        const auto e = mesh.edge(p.index);
        const std::uint32_t v = p.u < 0.5 ? e[0] : e[1];
        if (loop.nodes.empty() || loop.nodes.back().index != v) loop.nodes.push_back(SurfacePoint::at_vertex(v));
    }
    if (loop.nodes.front().index != loop.nodes.back().index) loop.nodes.push_back(loop.nodes.front());
    return loop;
}

struct Comparison {
    double mesh_error, mesh_delaunay_error, cloud_error;
};

/// The surface SHM's ε to the loop's exact distance: on the mesh (as it is, and on its
/// intrinsic Delaunay triangulation) and on the cloud of its vertices (no normals), all
/// measured with the mesh's vertex areas (the cloud's own fans overlap).
Comparison compare(const SurfaceMesh& mesh, const SurfaceSources& src, const std::vector<double>& truth) {
    SignedHeatSurface on_mesh(mesh);
    SurfaceShmSetup delaunay;
    delaunay.intrinsic_delaunay = true;
    SignedHeatSurface on_delaunay(mesh, delaunay);
    const CloudSurface cloud = cloud_surface(mesh.polygons().vertices);
    SignedHeatSurface on_cloud(cloud.mesh);
    return {surface_distance_error(mesh, on_mesh.solve(src).phi, truth),
            surface_distance_error(mesh, on_delaunay.solve(src).phi, truth),
            surface_distance_error(mesh, on_cloud.solve(src).phi, truth)};
}

Comparison sphere_comparison(int level, double noise, std::uint64_t seed) {
    const SurfaceMesh mesh(uneven_sphere(level, 0.25, noise, seed));
    const Points& x = mesh.polygons().vertices;
    std::vector<double> f(mesh.vertex_count());
    for (std::size_t i = 0; i < f.size(); ++i) f[i] = 0.3 - x(Eigen::Index(i), 2) / x.row(Eigen::Index(i)).norm();
    SurfaceSources src;
    src.curves.push_back(vertex_loop(mesh, f));  // the cap above z = 0.3 on its left
    std::vector<Eigen::Vector3d> loop;
    for (const SurfacePoint& p : src.curves[0].nodes) loop.push_back(x.row(p.index).normalized());
    return compare(mesh, src, sphere_loop_sdf(x, loop));
}

Comparison square_comparison(int n, double noise, std::uint64_t seed) {
    const SurfaceMesh mesh(uneven_square(n, noise, seed));
    const Points& x = mesh.polygons().vertices;
    std::vector<double> f(mesh.vertex_count());
    for (std::size_t i = 0; i < f.size(); ++i) f[i] = std::hypot(x(Eigen::Index(i), 0) - 0.1, x(Eigen::Index(i), 1)) - 0.5;
    SurfaceSources src;
    src.curves.push_back(vertex_loop(mesh, f));  // the disk on its left
    std::vector<Eigen::Vector2d> loop;
    for (const SurfacePoint& p : src.curves[0].nodes) loop.emplace_back(x(p.index, 0), x(p.index, 1));
    return compare(mesh, src, polygon_sdf(x, loop));
}

}  // namespace

TEST_CASE("cloud surface: fans of a sphere's points form a closed surface with outward normals") {
    const PolygonMesh m = uneven_sphere(3, 0.25, 0, 1);
    const CloudSurface s = cloud_surface(m.vertices);
    CHECK(s.mesh.vertex_count() == std::size_t(m.vertices.rows()));
    const SurfaceMesh::Summary sum = s.mesh.summary();
    CHECK(sum.unreferenced_vertices == 0);
    CHECK(sum.components == 1);
    CHECK(sum.boundary_edges == 0);  // every fan is closed on a sphere: no point is on a hull
    // Every fitted normal points outward, and every triangle turns counter-clockwise around it.
    int inward = 0, clockwise = 0;
    for (Eigen::Index i = 0; i < m.vertices.rows(); ++i) inward += s.normals.row(i).dot(m.vertices.row(i)) < 0.9;
    for (std::size_t t = 0; t < s.mesh.triangle_count(); ++t) {
        const auto c = s.mesh.triangle(t);
        const Eigen::Vector3d a = m.vertices.row(c[0]).transpose(), b = m.vertices.row(c[1]).transpose(),
                              d = m.vertices.row(c[2]).transpose();
        clockwise += (b - a).cross(d - a).dot(a) <= 0;
    }
    CHECK(inward == 0);
    CHECK(clockwise == 0);
    // Mostly each triangle three times (once per corner's fan): about 6 per point, 2 of them unique.
    const double per_point = double(s.mesh.triangle_count()) / double(m.vertices.rows());
    CHECK(per_point > 5.5);
    CHECK(per_point < 7.0);
}

TEST_CASE("cloud surface: given normals choose the sign, even when many are flipped") {
    const PolygonMesh m = uneven_sphere(3, 0.25, 0, 2);
    Points inward = -m.vertices;  // unit normals pointing in
    std::mt19937_64 rng(3);
    for (Eigen::Index i = 0; i < inward.rows(); ++i)
        if (rng() % 10 < 3) inward.row(i) *= -1;  // 30 % flipped
    const CloudSurface s = cloud_surface(m.vertices, inward);
    int outward = 0;
    for (Eigen::Index i = 0; i < m.vertices.rows(); ++i) outward += s.normals.row(i).dot(m.vertices.row(i)) > 0;
    CHECK(outward == 0);
}

TEST_CASE("cloud surface: SHM on a cloud is as accurate as on a mesh of the same points") {
    auto report = [](const std::string& what, const Comparison& c) {
        MESSAGE(what << ": ε mesh " << c.mesh_error << ", its intrinsic Delaunay " << c.mesh_delaunay_error << ", cloud "
                     << c.cloud_error << " (" << c.cloud_error / c.mesh_error << "× the mesh's)");
        CHECK(c.cloud_error < 1.5 * std::min(c.mesh_error, c.mesh_delaunay_error));
    };
    for (double noise : {0.0, 0.01}) {
        report(noise ? "sphere, 2562 points, noise 0.01" : "sphere, 2562 points", sphere_comparison(4, noise, 7));
        report(noise ? "square, 3721 points, noise 0.01" : "square, 3721 points", square_comparison(60, noise, 8));
    }
}

TEST_CASE("cloud surface: bad input") {
    Points two(2, 3);
    two << 0, 0, 0, 1, 0, 0;
    CHECK_THROWS_WITH_AS(cloud_surface(two), doctest::Contains("at least 3 points"), Error);
    Points line(10, 3);
    for (int i = 0; i < 10; ++i) line.row(i) << i, 0, 0;
    CHECK_THROWS_WITH_AS(cloud_surface(line), doctest::Contains("span no surface"), Error);
    const PolygonMesh m = shapes::icosphere(1);
    CHECK_THROWS_WITH_AS(cloud_surface(m.vertices, Points(3, 3)), doctest::Contains("normals for"), Error);
    CloudSurfaceOptions o;
    o.neighbors = 2;
    CHECK_THROWS_WITH_AS(cloud_surface(m.vertices, {}, o), doctest::Contains("neighbors"), Error);
    Points bad = m.vertices;
    bad(3, 1) = NAN;
    CHECK_THROWS_AS(cloud_surface(bad), Error);
    Points same(20, 3);
    same.setOnes();
    CHECK_THROWS_WITH_AS(cloud_surface(same), doctest::Contains("span no surface"), Error);
    // Sources on a cloud name points.
    SurfaceSources on_edge;
    on_edge.curves.push_back({{SurfacePoint::at_vertex(0), SurfacePoint::on_edge(1, 0.5)}, true});
    CHECK_THROWS_WITH_AS(require_cloud_points(on_edge, "c.txt"), doctest::Contains("name cloud points"), Error);
    // Splats: 7 vertices and 6 triangles a point, facing the normal; counts must agree.
    const PolygonMesh splats = splat_mesh(m.vertices, m.vertices, std::vector<double>(std::size_t(m.vertices.rows()), 0.1));
    CHECK(splats.vertices.rows() == Eigen::Index(kSplatVertices) * m.vertices.rows());
    CHECK(splats.face_count() == (kSplatVertices - 1) * std::size_t(m.vertices.rows()));
    const Eigen::Vector3d a = splats.vertices.row(splats.indices[0]).transpose(), b = splats.vertices.row(splats.indices[1]).transpose(),
                          c = splats.vertices.row(splats.indices[2]).transpose();
    CHECK((b - a).cross(c - a).dot(m.vertices.row(0).transpose()) > 0);
    CHECK_THROWS_AS(splat_mesh(m.vertices, Points(2, 3), {}), Error);
    CHECK_THROWS_AS(vertex_labels(SurfaceMesh(m), {1, 2}), Error);
}

TEST_CASE("cloud surface: random samples — SHM on the fans is as accurate as on the cloud's own triangulation") {
    // Random points on the unit sphere: no mesh comes with them, so the mesh path runs on the
    // cloud's triangulation (the sphere's Delaunay triangulation when it is right).
    constexpr int N = 5000;
    std::mt19937_64 rng(5000);
    std::normal_distribution<double> g(0, 1);
    Points x(N, 3);
    for (int i = 0; i < N; ++i) x.row(i) = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized().transpose();
    const CloudSurface cloud = cloud_surface(x);
    const SurfaceMesh tri(cloud.triangulation);
    const SurfaceMesh::Summary s = tri.summary();
    CHECK(s.boundary_edges == 0);
    CHECK(s.nonmanifold_edges == 0);
    CHECK(s.misoriented_edges == 0);
    CHECK(s.euler_characteristic == 2);
    CHECK(tri.triangle_count() == std::size_t(2 * N - 4));

    std::vector<double> f(N);
    for (int i = 0; i < N; ++i) f[std::size_t(i)] = 0.3 - x(i, 2);
    SurfaceSources src;
    src.curves.push_back(vertex_loop(tri, f));
    std::vector<Eigen::Vector3d> loop;
    for (const SurfacePoint& p : src.curves[0].nodes) loop.push_back(x.row(p.index).transpose());
    const std::vector<double> truth = sphere_loop_sdf(x, loop);
    SignedHeatSurface on_mesh(tri), on_fans(cloud.mesh);
    const double mesh_error = surface_distance_error(tri, on_mesh.solve(src).phi, truth);
    const double cloud_error = surface_distance_error(tri, on_fans.solve(src).phi, truth);
    MESSAGE("random sphere, 5000 points: ε on its triangulation " << mesh_error << ", on the fans " << cloud_error);
    CHECK(cloud_error < 0.01);
    CHECK(cloud_error < 1.5 * mesh_error);
}

TEST_CASE("cloud surface: the triangulation of a torus has its genus; SWN on the cloud labels as on the mesh") {
    // An exact parametric grid: each point's tangent plane bends its squares differently, so
    // fans disagree on every other one (no triangle has all three votes); the triangulation
    // still closes into a torus.
    const SurfaceMesh grid(cloud_surface(shapes::torus_mesh(72, 32).vertices).triangulation);
    CHECK(grid.summary().euler_characteristic == 0);
    CHECK(grid.summary().boundary_edges == 0);
    CHECK(grid.triangle_count() == 2 * 72 * 32);

    // The same torus with its vertices moved along the surface by up to a quarter of a spacing:
    // sampled unevenly, as a scan would be.
    PolygonMesh torus = shapes::torus_mesh(72, 32);
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> jitter(-0.25, 0.25);
    for (Eigen::Index i = 0; i < torus.vertices.rows(); ++i) {
        const Eigen::Vector3d p = torus.vertices.row(i).transpose();
        const double theta = std::atan2(p.y(), p.x()) + jitter(rng) * 2 * 3.14159265 / 72;
        const double phi = std::atan2(p.z(), std::hypot(p.x(), p.y()) - 0.5) + jitter(rng) * 2 * 3.14159265 / 32;
        torus.vertices.row(i) << (0.5 + 0.2 * std::cos(phi)) * std::cos(theta), (0.5 + 0.2 * std::cos(phi)) * std::sin(theta),
            0.2 * std::sin(phi);
    }
    const SurfaceMesh mesh(torus);
    const CloudSurface cloud = cloud_surface(torus.vertices);
    const SurfaceMesh tri(cloud.triangulation);
    CHECK(tri.summary().euler_characteristic == 0);
    CHECK(tri.summary().boundary_edges == 0);

    // A small loop (it bounds a disk) and a meridian (it bounds nothing), both broken and with
    // a piece reversed, through the torus's vertices — the same points on the cloud.
    const Points& x = torus.vertices;
    std::vector<double> disk(mesh.vertex_count()), meridian(mesh.vertex_count());
    for (std::size_t i = 0; i < disk.size(); ++i) {
        const Eigen::Vector3d p = x.row(Eigen::Index(i)).transpose();
        disk[i] = (p - Eigen::Vector3d(0.5, 0, 0.2)).norm() - 0.15;
        meridian[i] = p.x() > 0 ? p.y() : 1.0;  // the y = 0 loop around the tube at x > 0
    }
    SurfaceSources clean;
    clean.curves.push_back(vertex_loop(mesh, disk));
    const std::vector<SurfaceCurve> m = level_set_curves(mesh, meridian, 0);
    REQUIRE(!m.empty());
    SurfaceCurve mer;
    for (const SurfacePoint& p : m[0].nodes) {
        const auto e = mesh.edge(p.index);
        const std::uint32_t v = p.u < 0.5 ? e[0] : e[1];
        if (mer.nodes.empty() || mer.nodes.back().index != v) mer.nodes.push_back(SurfacePoint::at_vertex(v));
    }
    clean.curves.push_back(mer);
    CurveDamage d;
    d.cut = 0.25;
    d.gaps = 2;
    d.reversed = 1;
    const SurfaceSources broken = damage(clean, d, 3);

    SurfaceWindingNumbers on_mesh(mesh), on_cloud(tri);
    const std::vector<int> mesh_labels = vertex_labels(mesh, on_mesh.solve(broken).labels);
    const std::vector<int> cloud_labels = vertex_labels(tri, on_cloud.solve(broken).labels);
    std::size_t agree = 0, inside = 0;
    for (std::size_t i = 0; i < mesh_labels.size(); ++i) {
        agree += mesh_labels[i] == cloud_labels[i];
        inside += mesh_labels[i] != 0;
    }
    const double share = double(agree) / double(mesh_labels.size());
    MESSAGE("torus (2304 points), broken disk loop and meridian: labels agree on " << share * 100 << " % of the points");
    CHECK(inside > 0);
    CHECK(share >= 0.97);
}

TEST_CASE("cloud surface: a noisy random plane — noise above the spacing leaves the fans as good as a mesh" *
          doctest::test_suite("slow")) {
    // 20000 random points on [−1, 1]², lifted off the plane by σ = 0.02 (1.4 spacings). The mesh
    // path gets the clean points' triangulation (which a noisy cloud does not come with) with the
    // noisy positions. Single tangent-plane fits tilt so much at this noise that neighbouring
    // fans disagree (the cloud's ε was 1.9× the mesh's before the normals were smoothed).
    constexpr int N = 20000;
    std::mt19937_64 rng(20001);
    std::normal_distribution<double> g(0, 1);
    std::uniform_real_distribution<double> u(-1, 1);
    Points clean(N, 3), x(N, 3);
    for (int i = 0; i < N; ++i) {
        clean.row(i) << u(rng), u(rng), 0;
        x.row(i) << clean(i, 0), clean(i, 1), 0.02 * g(rng);
    }
    PolygonMesh m = cloud_surface(clean).triangulation;
    const SurfaceMesh flat(m);
    m.vertices = x;
    const SurfaceMesh mesh(m);
    std::vector<double> f(N);
    for (int i = 0; i < N; ++i) f[std::size_t(i)] = std::hypot(clean(i, 0) - 0.1, clean(i, 1)) - 0.5;
    SurfaceSources src;
    src.curves.push_back(vertex_loop(flat, f));
    std::vector<Eigen::Vector2d> loop;
    for (const SurfacePoint& p : src.curves[0].nodes) loop.emplace_back(clean(p.index, 0), clean(p.index, 1));
    const std::vector<double> truth = polygon_sdf(clean, loop);
    SignedHeatSurface on_mesh(mesh);
    const CloudSurface cloud = cloud_surface(x);
    SignedHeatSurface on_cloud(cloud.mesh);
    const double mesh_error = surface_distance_error(mesh, on_mesh.solve(src).phi, truth);
    const double cloud_error = surface_distance_error(mesh, on_cloud.solve(src).phi, truth);
    MESSAGE("noisy random plane, 20000 points: ε mesh " << mesh_error << ", cloud " << cloud_error);
    CHECK(cloud_error < 1.5 * mesh_error);
}
