// Cutting a mesh along curve pieces (src/mesh/split): every input triangle is exactly tiled
// by same-oriented new triangles, the new mesh is conforming (no T-junctions, also across
// nonmanifold edges), and every piece becomes a path of new edges lying on it. Cases: pieces
// across triangles, along edges, through vertices, of zero length, overlapping, crossing (also
// many at random in one triangle), points near vertices and edges, closed level-set curves,
// nonmanifold and degenerate triangles, polygons, bad input.
#include <doctest/doctest.h>

#include <gsd/shapes.hpp>
#include <gsd/surface.hpp>

#include "surface_shm/curves.hpp"
#include "mesh/split.hpp"
#include "mesh/topology.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <random>
#include <set>

using namespace gsd;
using mesh::FaceSegment;
using mesh::SplitMesh;
using mesh::Topology;
using Bary = std::array<double, 3>;

namespace {

Eigen::Vector3d corner(const Topology& t, std::size_t f, int k) { return t.corner_position(f, k); }

Eigen::Vector3d at(const Topology& t, std::size_t f, const Bary& b) {
    return b[0] * corner(t, f, 0) + b[1] * corner(t, f, 1) + b[2] * corner(t, f, 2);
}

Eigen::Vector3d vertex(const PolygonMesh& m, std::uint32_t v) { return m.vertices.row(v).transpose(); }

double bbox_diagonal(const PolygonMesh& m) {
    return (m.vertices.colwise().maxCoeff() - m.vertices.colwise().minCoeff()).norm();
}

double segment_distance(const Eigen::Vector3d& x, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const Eigen::Vector3d d = b - a;
    const double s = d.squaredNorm() > 0 ? std::clamp((x - a).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
    return (x - a - s * d).norm();
}

/// Barycentric weights of the point at parameter t along edge e (its direction), in triangle f.
Bary on_edge(const Topology& t, std::uint32_t f, std::uint32_t e, double s) {
    const mesh::Triangulation& T = t.mesh;
    for (int k = 0; k < 3; ++k)
        if (T.face_edges[f][std::size_t(k)] == e) {
            Bary b{0, 0, 0};
            const bool al = T.aligned[f][std::size_t(k)];
            b[std::size_t(k)] = al ? 1 - s : s;
            b[std::size_t((k + 1) % 3)] = al ? s : 1 - s;
            return b;
        }
    FAIL("edge not on triangle");
    return {};
}

/// Every input triangle is tiled by its new triangles: signed areas (along the input normal)
/// positive and summing to its area, vertices inside it. Orientation is only checked where the
/// input triangle is not flat to rounding (there its normal, and every sign, is noise).
void check_tiling(const Topology& t, const SplitMesh& cut) {
    const PolygonMesh& m = cut.mesh;
    REQUIRE(m.face_count() == cut.triangle_of.size());
    REQUIRE(m.vertices.rows() >= t.polygons.vertices.rows());
    CHECK(m.vertices.topRows(t.polygons.vertices.rows()) == t.polygons.vertices);
    const std::size_t F = t.mesh.face_count();
    std::vector<double> area(F, 0.0);
    std::size_t not_positive = 0, outside = 0;
    for (std::size_t j = 0; j < m.face_count(); ++j) {
        REQUIRE(m.face_size(j) == 3);
        const std::uint32_t f = cut.triangle_of[j];
        REQUIRE(f < F);
        const Eigen::Vector3d a = corner(t, f, 0), b = corner(t, f, 1), c = corner(t, f, 2);
        const Eigen::Vector3d n = (b - a).cross(c - a);
        const double size = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
        const std::uint32_t* v = m.indices.data() + m.offsets[j];
        const Eigen::Vector3d p = vertex(m, v[0]), q = vertex(m, v[1]), r = vertex(m, v[2]);
        const bool flat = t.degenerate(f) || n.norm() <= 1e-9 * size * size;
        const double signed_area = t.degenerate(f) ? 0.0 : 0.5 * n.normalized().dot((q - p).cross(r - p));
        area[f] += signed_area;
        if (flat) continue;
        if (!(signed_area > 0)) ++not_positive;
        for (const Eigen::Vector3d& x : {p, q, r}) {
            // Inside the triangle: in its plane and on the inner side of each of its sides.
            const bool off_plane = std::abs(n.normalized().dot(x - a)) > 1e-12 * size;
            const bool beyond = n.dot((b - a).cross(x - a)) < -1e-12 * n.norm() * size ||
                                n.dot((c - b).cross(x - b)) < -1e-12 * n.norm() * size ||
                                n.dot((a - c).cross(x - c)) < -1e-12 * n.norm() * size;
            outside += off_plane || beyond;
        }
    }
    CHECK(not_positive == 0);
    CHECK(outside == 0);
    std::size_t wrong_sum = 0;
    for (std::size_t f = 0; f < F; ++f) {
        const Eigen::Vector3d a = corner(t, f, 0), b = corner(t, f, 1), c = corner(t, f, 2);
        const double exact = t.degenerate(f) ? 0.0 : 0.5 * (b - a).cross(c - a).norm();
        const double scale = (b - a).squaredNorm() + (c - a).squaredNorm();
        wrong_sum += std::abs(area[f] - exact) > 1e-12 * exact + 1e-15 * scale;
    }
    CHECK(wrong_sum == 0);
}

/// Total length of the edges with one triangle, with three or more, and with two that disagree
/// on orientation.
std::array<double, 3> special_edge_length(const SurfaceMesh& s) {
    const Topology& t = s.topology();
    std::array<double, 3> length{0, 0, 0};
    for (std::size_t e = 0; e < t.mesh.edge_count(); ++e) {
        const std::size_t n = t.edge_halfedges.count(e);
        const std::uint32_t* h = t.edge_halfedges.begin(e);
        auto aligned = [&](std::uint32_t c) {
            return t.mesh.aligned[mesh::corner_face(c)][std::size_t(mesh::corner_index(c))];
        };
        if (n == 1) length[0] += t.mesh.edge_lengths[e];
        if (n >= 3) length[1] += t.mesh.edge_lengths[e];
        if (n == 2 && aligned(h[0]) == aligned(h[1])) length[2] += t.mesh.edge_lengths[e];
    }
    return length;
}

/// The new mesh is conforming: a T-junction would leave edges with one triangle inside the
/// surface (more boundary length); edges with three triangles or two disagreeing ones are
/// split, not made; splitting keeps the Euler characteristic.
void check_conforming(const SurfaceMesh& in, const SurfaceMesh& out) {
    const SurfaceMesh::Summary a = in.summary(), b = out.summary();
    CHECK(b.euler_characteristic == a.euler_characteristic);
    CHECK(b.components == a.components);
    if (a.boundary_edges == 0) CHECK(b.boundary_edges == 0);
    if (a.nonmanifold_edges == 0) CHECK(b.nonmanifold_edges == 0);
    if (a.misoriented_edges == 0) CHECK(b.misoriented_edges == 0);
    const auto before = special_edge_length(in), after = special_edge_length(out);
    for (int k = 0; k < 3; ++k) CHECK(after[std::size_t(k)] == doctest::Approx(before[std::size_t(k)]).epsilon(1e-12));
}

/// Every piece's path: joined by edges of the new mesh, on the piece, from its start to its end,
/// as long as the piece.
void check_paths(const Topology& t, const std::vector<FaceSegment>& pieces, const SplitMesh& cut,
                 const SurfaceMesh& out) {
    REQUIRE(cut.piece_paths.size() == pieces.size());
    const double tol = 1e-9 * bbox_diagonal(t.polygons);
    std::size_t no_edge = 0, off_piece = 0, bad_ends = 0, bad_length = 0;
    for (std::size_t i = 0; i < pieces.size(); ++i) {
        const FaceSegment& s = pieces[i];
        const Eigen::Vector3d a = at(t, s.face, s.a), b = at(t, s.face, s.b);
        const std::vector<std::uint32_t>& path = cut.piece_paths[i];
        if (path.empty()) {
            CHECK((b - a).norm() <= tol);
            continue;
        }
        REQUIRE(path.size() >= 2);
        double length = 0;
        for (std::size_t k = 0; k < path.size(); ++k) {
            REQUIRE(path[k] < cut.mesh.vertices.rows());
            off_piece += segment_distance(vertex(cut.mesh, path[k]), a, b) > tol;
            if (k + 1 == path.size()) continue;
            no_edge += out.topology().find_edge(path[k], path[k + 1]) == UINT32_MAX;
            length += (vertex(cut.mesh, path[k + 1]) - vertex(cut.mesh, path[k])).norm();
        }
        bad_ends += (vertex(cut.mesh, path.front()) - a).norm() > tol || (vertex(cut.mesh, path.back()) - b).norm() > tol;
        bad_length += std::abs(length - (b - a).norm()) > tol;
    }
    CHECK(no_edge == 0);
    CHECK(off_piece == 0);
    CHECK(bad_ends == 0);
    CHECK(bad_length == 0);
}

/// Splits and checks everything; returns the split and its mesh.
std::pair<SplitMesh, SurfaceMesh> split_checked(const SurfaceMesh& in, const std::vector<FaceSegment>& pieces) {
    SplitMesh cut = mesh::split_along(in.topology(), pieces);
    check_tiling(in.topology(), cut);
    SurfaceMesh out(cut.mesh, "split");
    check_conforming(in, out);
    check_paths(in.topology(), pieces, cut, out);
    return {std::move(cut), std::move(out)};
}

std::vector<FaceSegment> segments_of(const surface_shm::ResolvedSources& r) {
    std::vector<FaceSegment> s;
    for (const surface_shm::CurvePiece& p : r.pieces) s.push_back(p.segment);
    return s;
}

/// A triangle of a planar grid mesh whose three edges are all interior.
std::uint32_t interior_triangle(const Topology& t) {
    for (std::uint32_t f = 0; f < t.mesh.face_count(); ++f) {
        bool inner = true;
        for (std::uint32_t e : t.mesh.face_edges[f]) inner = inner && t.edge_halfedges.count(e) == 2;
        if (inner) return f;
    }
    FAIL("no interior triangle");
    return 0;
}

bool contains(const std::vector<std::uint32_t>& path, std::uint32_t v) {
    return std::find(path.begin(), path.end(), v) != path.end();
}

}  // namespace

TEST_CASE("split: a piece across a triangle cuts it and both neighbours at shared edge points") {
    const SurfaceMesh mesh(shapes::grid_mesh(4, 0.2, true, 5));
    const Topology& t = mesh.topology();
    const std::uint32_t f = interior_triangle(t);
    const std::vector<FaceSegment> pieces{{f, {0.5, 0.5, 0}, {0, 0.3, 0.7}}};
    const auto [cut, out] = split_checked(mesh, pieces);
    const std::uint32_t V = std::uint32_t(mesh.vertex_count());
    CHECK(out.vertex_count() == V + 2);
    CHECK(out.triangle_count() == mesh.triangle_count() + 4);  // 3 for the triangle, 2 per neighbour
    REQUIRE(cut.piece_paths[0].size() == 2);
    CHECK(cut.piece_paths[0][0] >= V);
    CHECK(cut.piece_paths[0][1] >= V);
}

TEST_CASE("split: pieces along edges map onto the (split) edges, pieces through vertices use them") {
    const SurfaceMesh mesh(shapes::grid_mesh(4, 0.2, true, 5));
    const Topology& t = mesh.topology();
    const std::uint32_t f = interior_triangle(t);
    const auto& c = t.mesh.faces[f];
    const std::uint32_t V = std::uint32_t(mesh.vertex_count());

    SUBCASE("vertex to vertex: already an edge, nothing changes") {
        const auto [cut, out] = split_checked(mesh, {{f, {1, 0, 0}, {0, 1, 0}}, {f, {0, 0, 1}, {0, 1, 0}}});
        CHECK(cut.mesh.indices == mesh.triangles().indices);
        CHECK(cut.piece_paths[0] == std::vector<std::uint32_t>{c[0], c[1]});
        CHECK(cut.piece_paths[1] == std::vector<std::uint32_t>{c[2], c[1]});
    }
    SUBCASE("an edge holding a point of another piece: the side piece runs through it, no sliver") {
        // Piece 0 ends on side 0 (corners 0–1) at 0.4; piece 1 runs along all of side 0 from the
        // neighbour across that edge; piece 2 along part of side 0 in f itself.
        const std::uint32_t e = t.mesh.face_edges[f][0];
        const std::uint32_t* h = t.edge_halfedges.begin(e);
        const std::uint32_t g = mesh::corner_face(h[0]) == f ? mesh::corner_face(h[1]) : mesh::corner_face(h[0]);
        const std::vector<FaceSegment> pieces{{f, {0.6, 0.4, 0}, {0.2, 0.2, 0.6}},
                                              {g, on_edge(t, g, e, 0), on_edge(t, g, e, 1)},
                                              {f, {0.9, 0.1, 0}, {0, 1, 0}}};
        const auto [cut, out] = split_checked(mesh, pieces);
        const std::uint32_t p = cut.piece_paths[0].front();
        CHECK(p >= V);
        REQUIRE(cut.piece_paths[1].size() == 4);  // both ends and the points at 0.1 and 0.4
        CHECK(contains(cut.piece_paths[1], p));
        REQUIRE(cut.piece_paths[2].size() == 3);
        CHECK(cut.piece_paths[2][1] == p);
        CHECK(cut.piece_paths[2][2] == c[1]);
        CHECK(out.vertex_count() == V + 3);  // the points at 0.1 and 0.4, piece 0's inside end
    }
    SUBCASE("through vertices: corner to the opposite side, corner to an inside point") {
        const auto [cut, out] = split_checked(mesh, {{f, {1, 0, 0}, {0, 0.5, 0.5}}, {f, {0, 1, 0}, {0.3, 0.5, 0.2}}});
        CHECK(cut.piece_paths[0].front() == c[0]);
        CHECK(cut.piece_paths[1].front() == c[1]);
        CHECK(out.vertex_count() == V + 2);
    }
}

TEST_CASE("split: zero-length pieces have empty paths and change nothing") {
    const SurfaceMesh mesh(shapes::grid_mesh(3));
    const Topology& t = mesh.topology();
    const std::uint32_t f = interior_triangle(t);
    const std::vector<FaceSegment> pieces{{f, {0.2, 0.3, 0.5}, {0.2, 0.3, 0.5}},
                                          {f, {0.5, 0.5, 0}, {0.5 + 1e-14, 0.5 - 1e-14, 0}},
                                          {f, {1, 0, 0}, {1, 0, 0}}};
    const auto [cut, out] = split_checked(mesh, pieces);
    for (const auto& path : cut.piece_paths) CHECK(path.empty());
    CHECK(cut.mesh.indices == mesh.triangles().indices);
    CHECK(out.vertex_count() == mesh.vertex_count());
}

TEST_CASE("split: crossing pieces share their crossing; three through one point share one vertex") {
    const SurfaceMesh mesh(shapes::grid_mesh(4, 0.2, true, 5));
    const Topology& t = mesh.topology();
    const std::uint32_t f = interior_triangle(t);
    const Bary centroid{1.0 / 3, 1.0 / 3, 1.0 / 3};
    // Lines through the centroid from each corner to the middle of the opposite side, and one
    // more (weight 0.2 at corner 0) crossing all three elsewhere.
    const std::vector<FaceSegment> pieces{{f, {1, 0, 0}, {0, 0.5, 0.5}},
                                          {f, {0, 1, 0}, {0.5, 0, 0.5}},
                                          {f, {0, 0, 1}, {0.5, 0.5, 0}},
                                          {f, {0.2, 0.8, 0}, {0.2, 0, 0.8}}};
    const auto [cut, out] = split_checked(mesh, pieces);
    // The median from corner 0 meets the centroid; find that vertex and check all three have it.
    std::uint32_t middle = UINT32_MAX;
    for (std::uint32_t v : cut.piece_paths[0])
        if ((vertex(cut.mesh, v) - at(t, f, centroid)).norm() < 1e-12) middle = v;
    REQUIRE(middle != UINT32_MAX);
    CHECK(contains(cut.piece_paths[1], middle));
    CHECK(contains(cut.piece_paths[2], middle));
    // Piece 3 crosses each median once, away from the centroid.
    for (int m = 0; m < 3; ++m) {
        std::size_t shared = 0;
        for (std::uint32_t v : cut.piece_paths[3]) shared += contains(cut.piece_paths[std::size_t(m)], v);
        CHECK(shared == 1);
    }
    CHECK(out.vertex_count() == mesh.vertex_count() + 3 + 1 + 2 + 3);  // 3 midpoints, centroid, 2 ends, 3 crossings
}

TEST_CASE("split: collinear overlapping pieces share the edges of their overlap") {
    const SurfaceMesh mesh(shapes::grid_mesh(4, 0.2, true, 5));
    const Topology& t = mesh.topology();
    const std::uint32_t f = interior_triangle(t);
    const Bary p{0.7, 0.3, 0}, q{0, 0.4, 0.6};  // on sides 0 and 1
    auto along = [&](double s) {
        return Bary{(1 - s) * p[0] + s * q[0], (1 - s) * p[1] + s * q[1], (1 - s) * p[2] + s * q[2]};
    };
    const std::vector<FaceSegment> pieces{{f, along(0), along(0.6)},
                                          {f, along(0.3), along(1)},
                                          {f, along(0.5), along(0.2)},
                                          {f, along(0.3), along(1)}};
    const auto [cut, out] = split_checked(mesh, pieces);
    const auto &A = cut.piece_paths[0], &B = cut.piece_paths[1], &C = cut.piece_paths[2];
    CHECK(contains(A, B.front()));
    CHECK(contains(B, A.back()));
    CHECK(contains(A, C.front()));
    CHECK(contains(B, C.front()));
    CHECK(cut.piece_paths[3] == B);
    CHECK(A.size() == 5);  // 0, 0.2, 0.3, 0.5, 0.6
    CHECK(B.size() == 4);  // 0.3, 0.5, 0.6, 1
    CHECK(C.size() == 3);  // 0.5, 0.3, 0.2
    CHECK(out.vertex_count() == mesh.vertex_count() + 2 + 4);
}

TEST_CASE("split: many random crossing segments in one triangle (stress)") {
    const SurfaceMesh mesh(shapes::grid_mesh(3, 0.25, true, 11));
    const Topology& t = mesh.topology();
    const std::uint32_t f = interior_triangle(t);
    std::mt19937_64 rng(20240601);
    std::uniform_real_distribution<double> U(0, 1);
    auto random_point = [&]() -> Bary {
        const double kind = U(rng);
        if (kind < 0.1) {  // a corner
            Bary b{0, 0, 0};
            b[std::size_t(rng() % 3)] = 1;
            return b;
        }
        if (kind < 0.4) {  // on a side
            const double s = U(rng);
            Bary b{0, 0, 0};
            const int k = int(rng() % 3);
            b[std::size_t(k)] = s;
            b[std::size_t((k + 1) % 3)] = 1 - s;
            return b;
        }
        const double u = U(rng), v = U(rng);  // inside, uniformly
        return u + v <= 1 ? Bary{1 - u - v, u, v} : Bary{u + v - 1, 1 - u, 1 - v};
    };
    std::vector<FaceSegment> pieces;
    for (int i = 0; i < 60; ++i) {
        FaceSegment s{f, random_point(), random_point()};
        if (i > 0 && rng() % 5 == 0) s.a = pieces[rng() % pieces.size()].b;  // shared ends
        pieces.push_back(s);
    }
    const auto [cut, out] = split_checked(mesh, pieces);
    // Every pair that crosses clearly (the grid lies in z = 0) shares a vertex at the crossing.
    std::size_t crossings = 0, missed = 0;
    const double tol = 1e-9 * bbox_diagonal(mesh.polygons());
    for (std::size_t i = 0; i < pieces.size(); ++i)
        for (std::size_t j = i + 1; j < pieces.size(); ++j) {
            const Eigen::Vector3d a = at(t, f, pieces[i].a), b = at(t, f, pieces[i].b);
            const Eigen::Vector3d c = at(t, f, pieces[j].a), d = at(t, f, pieces[j].b);
            const Eigen::Vector2d r = (b - a).head<2>(), s = (d - c).head<2>(), w = (c - a).head<2>();
            const double den = r.x() * s.y() - r.y() * s.x();
            if (!(std::abs(den) > 1e-6 * r.norm() * s.norm())) continue;  // near-parallel, or a piece of no length
            const double lambda = (w.x() * s.y() - w.y() * s.x()) / den, mu = (w.x() * r.y() - w.y() * r.x()) / den;
            if (lambda < 1e-6 || lambda > 1 - 1e-6 || mu < 1e-6 || mu > 1 - 1e-6) continue;
            ++crossings;
            const Eigen::Vector3d x = a + lambda * (b - a);
            bool found = false;
            for (std::uint32_t v : cut.piece_paths[i])
                found = found || (contains(cut.piece_paths[j], v) && (vertex(cut.mesh, v) - x).norm() < tol);
            missed += !found;
        }
    CHECK(crossings > 300);
    CHECK(missed == 0);
}

TEST_CASE("split: pieces leaving one side at nearby points cross next to it, inside the triangle") {
    const SurfaceMesh mesh(shapes::grid_mesh(4, 0.2, true, 5));
    const Topology& t = mesh.topology();
    const std::uint32_t f = interior_triangle(t);
    // Piece i leaves side 0 at 0.4 + i·δ and ends inside with a smaller weight at corner 1, so
    // every pair crosses at about δ from the side: far from it, nearer than the tolerance, or
    // merged into one point on the side.
    for (double delta : {1e-3, 1e-7, 5e-9, 1.5e-9, 1e-10}) {
        CAPTURE(delta);
        std::vector<FaceSegment> pieces;
        for (int i = 0; i < 3; ++i) {
            const double s = 0.4 + i * delta;
            pieces.push_back({f, {1 - s, s, 0}, {0.2 + 0.3 * i, 0.6 - 0.3 * i, 0.2}});
        }
        const auto [cut, out] = split_checked(mesh, pieces);
        for (int i = 0; i < 3; ++i)
            for (int j = i + 1; j < 3; ++j) {
                std::size_t shared = 0;
                for (std::uint32_t v : cut.piece_paths[std::size_t(i)])
                    shared += contains(cut.piece_paths[std::size_t(j)], v);
                CHECK(shared >= 1);
            }
    }
}

TEST_CASE("split: slivers and triangles flat to rounding stay conforming") {
    PolygonMesh m;
    m.vertices.resize(5, 3);
    const Eigen::RowVector3d a(0, 0, 0), b(1, 0.3, 0.1);
    m.vertices << a, b, 0.5, 0.15 + 1e-6, 0.05, 0.5, -1, 0, 0.3 * a + 0.7 * b;  // 2: a sliver's apex; 4: on a–b
    m.add_face({0, 1, 2});  // a sliver, 1e-6 high
    m.add_face({1, 0, 3});
    m.add_face({0, 4, 1});  // flat to rounding: its computed area is noise, not zero
    const SurfaceMesh mesh(m);
    std::vector<FaceSegment> pieces{{0, {0.5, 0.2, 0.3}, {0.1, 0.5, 0.4}},  // inside the sliver
                                    {1, {0.3, 0.3, 0.4}, {0.4, 0.6, 0}},    // onto edge 0–1 from below
                                    {2, {0.2, 0.3, 0.5}, {0.6, 0, 0.4}},    // inside the flat one
                                    {0, {0.3, 0.7, 0}, {0.3, 0.3, 0.4}}};
    split_checked(mesh, pieces);
}

TEST_CASE("split: points near vertices and edges snap to them") {
    const SurfaceMesh mesh(shapes::grid_mesh(4, 0.2, true, 5));
    const Topology& t = mesh.topology();
    const std::uint32_t f = interior_triangle(t);
    const auto& c = t.mesh.faces[f];
    const std::uint32_t V = std::uint32_t(mesh.vertex_count());
    const std::uint32_t e = t.mesh.face_edges[f][0];
    const std::uint32_t* h = t.edge_halfedges.begin(e);
    const std::uint32_t g = mesh::corner_face(h[0]) == f ? mesh::corner_face(h[1]) : mesh::corner_face(h[0]);

    SUBCASE("a point 1e-13 from a corner is the corner") {
        const auto [cut, out] = split_checked(mesh, {{f, {1 - 1e-13, 5e-14, 5e-14}, {0.2, 0.3, 0.5}}});
        CHECK(cut.piece_paths[0].front() == c[0]);
        CHECK(out.vertex_count() == V + 1);
    }
    SUBCASE("a point 1e-13 from a side is on the edge, and splits the neighbour there") {
        const auto [cut, out] = split_checked(mesh, {{f, {0.6, 0.4 - 1e-13, 1e-13}, {0.2, 0.3, 0.5}}});
        const std::uint32_t p = cut.piece_paths[0].front();
        CHECK(p >= V);
        CHECK(segment_distance(vertex(cut.mesh, p), corner(t, f, 0), corner(t, f, 1)) < 1e-15);
        CHECK(out.triangle_count() == mesh.triangle_count() + 4);  // f into 4, g into 2
    }
    SUBCASE("one edge point given from both sides, 1e-13 apart, is one vertex") {
        const Bary in_g = on_edge(t, g, e, 0.35 + 1e-13);
        const Bary in_f = on_edge(t, f, e, 0.35);
        Bary inside_g{0.2, 0.2, 0.2};
        for (int k = 0; k < 3; ++k) inside_g[std::size_t(k)] += in_g[std::size_t(k)] * 0.4 / 1.0;
        const auto [cut, out] = split_checked(mesh, {{f, in_f, {0.2, 0.3, 0.5}}, {g, inside_g, in_g}});
        CHECK(cut.piece_paths[0].front() == cut.piece_paths[1].back());
        CHECK(out.vertex_count() == V + 3);
    }
    SUBCASE("an edge point at t = 1e-12 is the edge's end vertex") {
        const auto [cut, out] = split_checked(mesh, {{f, on_edge(t, f, e, 1e-12), {0.2, 0.3, 0.5}}});
        CHECK(cut.piece_paths[0].front() == t.mesh.edges[e][0]);
        CHECK(out.vertex_count() == V + 1);
    }
}

TEST_CASE("split: a closed level-set curve on a sphere becomes a closed edge loop") {
    const SurfaceMesh mesh(shapes::icosphere(3));
    const PolygonMesh& m = mesh.polygons();
    std::vector<double> f(mesh.vertex_count());
    for (std::size_t i = 0; i < f.size(); ++i)
        f[i] = m.vertices(Eigen::Index(i), 2) + 0.3 * m.vertices(Eigen::Index(i), 0) - 0.1;
    SurfaceSources src;
    src.curves = level_set_curves(mesh, f, 0);
    REQUIRE(src.curves.size() == 1);
    const surface_shm::ResolvedSources r = surface_shm::resolve_sources(mesh.topology(), src);
    const std::vector<FaceSegment> pieces = segments_of(r);
    const auto [cut, out] = split_checked(mesh, pieces);
    CHECK(out.summary().boundary_edges == 0);
    // Consecutive paths join; the last returns to the first: a closed loop of edges.
    std::size_t joined = 0;
    for (std::size_t i = 0; i < pieces.size(); ++i) {
        const auto &p = cut.piece_paths[i], &q = cut.piece_paths[(i + 1) % pieces.size()];
        REQUIRE(p.size() >= 2);
        joined += p.back() == q.front();
    }
    CHECK(joined == pieces.size());
    // Each edge-point node is one vertex: new vertices = distinct nodes (a loop: as many as pieces).
    CHECK(out.vertex_count() == mesh.vertex_count() + pieces.size());
}

TEST_CASE("split: two crossing level-set loops share exactly their two crossings") {
    const SurfaceMesh mesh(shapes::icosphere(3));
    const PolygonMesh& m = mesh.polygons();
    std::vector<double> f(mesh.vertex_count()), g(mesh.vertex_count());
    for (std::size_t i = 0; i < f.size(); ++i) {
        const Eigen::Vector3d x = m.vertices.row(Eigen::Index(i)).transpose();
        f[i] = x.z() + 0.21 * x.y() - 0.13;
        g[i] = x.x() - 0.17 * x.y() + 0.07;
    }
    SurfaceSources src;
    src.curves = level_set_curves(mesh, f, 0);
    const std::size_t first_curves = src.curves.size();
    for (SurfaceCurve& c : level_set_curves(mesh, g, 0)) src.curves.push_back(std::move(c));
    REQUIRE(first_curves == 1);
    REQUIRE(src.curves.size() == 2);
    const surface_shm::ResolvedSources r = surface_shm::resolve_sources(mesh.topology(), src);
    std::size_t n_first = src.curves[0].nodes.size() - 1;
    const auto [cut, out] = split_checked(mesh, segments_of(r));
    std::set<std::uint32_t> on_f, on_g;
    for (std::size_t i = 0; i < r.pieces.size(); ++i)
        for (std::uint32_t v : cut.piece_paths[i]) (i < n_first ? on_f : on_g).insert(v);
    std::vector<std::uint32_t> both;
    std::set_intersection(on_f.begin(), on_f.end(), on_g.begin(), on_g.end(), std::back_inserter(both));
    CHECK(both.size() == 2);
    // Every vertex of the union of paths has even degree: the curves are closed 1-chains.
    std::map<std::uint32_t, int> degree;
    for (const auto& p : cut.piece_paths)
        for (std::size_t k = 0; k + 1 < p.size(); ++k) {
            ++degree[p[k]];
            ++degree[p[k + 1]];
        }
    std::size_t odd = 0;
    for (const auto& [v, d] : degree) odd += d % 2;
    CHECK(odd == 0);
}

TEST_CASE("split: a point on a nonmanifold edge splits all three triangles there") {
    PolygonMesh fan;
    fan.vertices.resize(5, 3);
    fan.vertices << 0, 0, 0, 1, 0, 0, 0.5, 1, 0, 0.5, -1, 0, 0.5, 0, 1;
    fan.add_face({0, 1, 2});
    fan.add_face({1, 0, 3});
    fan.add_face({0, 1, 4});
    const SurfaceMesh mesh(fan);
    const std::vector<FaceSegment> pieces{{0, {0.6, 0.4, 0}, {0.2, 0.3, 0.5}}, {2, {0.2, 0.2, 0.6}, {0.6, 0.4, 0}}};
    const auto [cut, out] = split_checked(mesh, pieces);
    CHECK(cut.piece_paths[0].front() == cut.piece_paths[1].back());
    CHECK(out.vertex_count() == 5 + 3);
    CHECK(out.triangle_count() == 4 + 2 + 4);
    CHECK(out.summary().nonmanifold_edges == 2);
}

TEST_CASE("split: a flat triangle on a split edge is split consistently; pieces in it follow its sides") {
    // Triangle 0 is regular; triangle 1 is flat (vertex 2 between 0 and 1) and shares edge 0–1.
    PolygonMesh m;
    m.vertices.resize(5, 3);
    m.vertices << 0, 0, 0, 2, 0, 0, 1, 0, 0, 1, 1, 0, 1, -1, 0;
    m.add_face({0, 1, 3});
    m.add_face({1, 0, 2});
    m.add_face({0, 4, 2});
    const SurfaceMesh mesh(m);
    REQUIRE(mesh.summary().degenerate_triangles == 1);
    const Topology& t = mesh.topology();
    const std::vector<FaceSegment> pieces{{0, {0.75, 0.25, 0}, {0, 0, 1}},
                                          {1, {0.5, 0, 0.5}, {0.1, 0.9, 0}},   // inside the flat triangle
                                          {1, {0.2, 0.3, 0.5}, {0, 0.5, 0.5}}};  // an "inside" point of it
    const auto [cut, out] = split_checked(mesh, pieces);
    // The flat triangle runs x = 2 → 0 along y = z = 0 with corner 2 at x = 1. Piece 1 goes from
    // x = 1.5 (on side 2–1) to x = 0.2 (on side 1–0) in order along the segment: through corner
    // 2, x = 0.9 (piece 2's start, moved onto the long side), the point x = 0.5 that piece 0
    // put on edge 0–1 and the one at x = 0.5 that piece 2 put on edge 0–2.
    CHECK(t.degenerate(1));
    const auto& path = cut.piece_paths[1];
    REQUIRE(path.size() == 6);
    CHECK(path[1] == 2);
    CHECK(contains(path, cut.piece_paths[0].front()));
    CHECK(contains(path, cut.piece_paths[2].back()));
    // Piece 2 puts a point on edge 0–2, which the regular triangle 2 shares: split there too.
    std::size_t flat = 0, third = 0;
    for (std::uint32_t f : cut.triangle_of) {
        flat += f == 1;
        third += f == 2;
    }
    CHECK(flat == 8 - 2);  // 3 corners and 5 points on its sides
    CHECK(third == 2);
}

TEST_CASE("split: a triangle naming a vertex twice is kept; a piece in it runs along its edge") {
    PolygonMesh m;
    m.vertices.resize(3, 3);
    m.vertices << 0, 0, 0, 1, 0, 0, 0.5, 1, 0;
    m.add_face({0, 1, 2});
    m.add_face({1, 0, 0});  // the segment 0–1: its sides 1→0 and 0→1 are both edge 0–1
    const SurfaceMesh mesh(m);
    const std::vector<FaceSegment> pieces{{1, {0.7, 0.3, 0}, {0.2, 0, 0.8}}};  // from 0.3 to 0.8 of 1→0
    const SplitMesh cut = mesh::split_along(mesh.topology(), pieces);
    check_tiling(mesh.topology(), cut);
    const SurfaceMesh out(cut.mesh, "split");
    check_paths(mesh.topology(), pieces, cut, out);
    CHECK(cut.piece_paths[0].size() == 2);
    CHECK(out.triangle_count() == 1 + 3);  // the triangle beside it is split at both points
}

TEST_CASE("split: polygon faces (fan diagonals get points too) and bad input") {
    PolygonMesh m;
    m.vertices.resize(4, 3);
    m.vertices << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0;
    m.add_face({0, 1, 2, 3});  // triangles (0,1,2), (0,2,3), diagonal 0–2
    const SurfaceMesh mesh(m);
    // A piece across the diagonal, as two pieces meeting on it.
    const Topology& t = mesh.topology();
    const std::uint32_t diagonal = t.find_edge(0, 2);
    const std::vector<FaceSegment> pieces{{0, {0.5, 0.5, 0}, on_edge(t, 0, diagonal, 0.6)},
                                          {1, on_edge(t, 1, diagonal, 0.6), {0.5, 0, 0.5}}};
    const auto [cut, out] = split_checked(mesh, pieces);
    CHECK(cut.piece_paths[0].back() == cut.piece_paths[1].front());

    CHECK_THROWS_AS(mesh::split_along(t, {{7, {1, 0, 0}, {0, 1, 0}}}), Error);
    CHECK_THROWS_AS(mesh::split_along(t, {{0, {NAN, 0, 0}, {0, 1, 0}}}), Error);
}

TEST_CASE("split: timing on many level-set pieces") {
    const SurfaceMesh mesh(shapes::grid_mesh(150, 0.2, true, 1));
    const PolygonMesh& m = mesh.polygons();
    SurfaceSources src;
    for (double k : {11.0, 13.0}) {
        std::vector<double> f(mesh.vertex_count());
        for (std::size_t i = 0; i < f.size(); ++i)
            f[i] = std::sin(k * m.vertices(Eigen::Index(i), 0)) * std::sin(k * 1.1 * m.vertices(Eigen::Index(i), 1)) - 0.1;
        for (SurfaceCurve& c : level_set_curves(mesh, f, 0)) src.curves.push_back(std::move(c));
    }
    const surface_shm::ResolvedSources r = surface_shm::resolve_sources(mesh.topology(), src);
    const auto start = std::chrono::steady_clock::now();
    const SplitMesh cut = mesh::split_along(mesh.topology(), segments_of(r));
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    MESSAGE(r.pieces.size() << " pieces on " << mesh.triangle_count() << " triangles: " << seconds << " s");
    const SurfaceMesh out(cut.mesh, "split");
    check_conforming(mesh, out);
    check_paths(mesh.topology(), segments_of(r), cut, out);
}
