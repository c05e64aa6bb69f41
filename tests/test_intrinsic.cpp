// Intrinsic Delaunay triangulations: flips, refinement, and tracing input curves through them.
// Planar meshes (z = 0) have a known embedding of every intrinsic vertex, so traced pieces can be
// checked against the plane exactly; curved ones are checked through intrinsic invariants.
#include <doctest/doctest.h>

#include "mesh/geometry.hpp"
#include "mesh/intrinsic.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

using namespace gsd::mesh;
using Eigen::Vector2d;
using Eigen::Vector3d;
using Bary = std::array<double, 3>;

namespace {

constexpr double kPi = std::numbers::pi;

struct Mesh {
    std::vector<Vector3d> positions;
    std::vector<std::array<std::uint32_t, 3>> faces;
};

/// The triangulation of a mesh: one edge per vertex pair (so three faces on a pair share one
/// edge), lengths from the positions.
Triangulation triangulate(const Mesh& m) {
    Triangulation t;
    t.vertex_count = std::uint32_t(m.positions.size());
    t.faces = m.faces;
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> edge_of;
    for (const auto& f : m.faces) {
        std::array<std::uint32_t, 3> fe{};
        std::array<std::uint8_t, 3> al{};
        for (std::size_t k = 0; k < 3; ++k) {
            const std::uint32_t a = f[k], b = f[(k + 1) % 3];
            const auto key = std::minmax(a, b);
            auto [it, added] = edge_of.try_emplace({key.first, key.second}, std::uint32_t(t.edges.size()));
            if (added) {
                t.edges.push_back({a, b});
                t.edge_lengths.push_back((m.positions[a] - m.positions[b]).norm());
            }
            fe[k] = it->second;
            al[k] = t.edges[it->second][0] == a;
        }
        t.face_edges.push_back(fe);
        t.aligned.push_back(al);
    }
    return t;
}

/// An nx × ny grid of points in z = 0 with spacing 1, jittered (but never so far that a face
/// folds over), each cell split by a random diagonal (or the one `diagonal` says); faces
/// counter-clockwise seen from +z.
Mesh planar_grid(int nx, int ny, double jitter, unsigned seed, int diagonal = -1, double shear = 0) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-jitter, jitter);
    std::bernoulli_distribution coin(0.5);
    Mesh m;
    std::vector<Vector3d> lattice;
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
            const bool rim = i == 0 || j == 0 || i == nx - 1 || j == ny - 1;
            lattice.emplace_back(i + shear * j, j, 0);
            m.positions.push_back(lattice.back() + (rim ? Vector3d::Zero() : Vector3d(u(rng), u(rng), 0)));
        }
    const auto id = [&](int i, int j) { return std::uint32_t(j * nx + i); };
    for (int j = 0; j + 1 < ny; ++j)
        for (int i = 0; i + 1 < nx; ++i) {
            const std::uint32_t a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
            const bool main = diagonal < 0 ? coin(rng) : diagonal == 0;
            if (main) {  // a—c
                m.faces.push_back({a, b, c});
                m.faces.push_back({a, c, d});
            } else {  // b—d
                m.faces.push_back({a, b, d});
                m.faces.push_back({b, c, d});
            }
        }
    // Faces folded over (or nearly) by the jitter get their corners put back on the lattice.
    for (bool folded = true; folded;) {
        folded = false;
        for (const auto& f : m.faces) {
            const Vector3d e1 = m.positions[f[1]] - m.positions[f[0]], e2 = m.positions[f[2]] - m.positions[f[0]];
            if (e1.x() * e2.y() - e1.y() * e2.x() > 0.02) continue;
            for (std::uint32_t v : f) m.positions[v] = lattice[v];
            folded = true;
        }
    }
    return m;
}

/// Splits some faces at a point very near one corner: slivers that flips cannot remove.
void add_slivers(Mesh& m, std::size_t every) {
    const std::size_t n = m.faces.size();
    for (std::size_t f = 0; f < n; f += every) {
        const auto [a, b, c] = m.faces[f];
        const auto x = std::uint32_t(m.positions.size());
        m.positions.push_back(0.96 * m.positions[a] + 0.03 * m.positions[b] + 0.01 * m.positions[c]);
        m.faces[f] = {a, b, x};
        m.faces.push_back({b, c, x});
        m.faces.push_back({c, a, x});
    }
}

/// A height field over a jittered grid: curved, so intrinsic flips are not planar ones.
Mesh bumpy_grid(int n, unsigned seed) {
    Mesh m = planar_grid(n, n, 0.3, seed);
    for (Vector3d& p : m.positions) p.z() = 0.8 * std::sin(0.9 * p.x()) * std::cos(0.7 * p.y());
    return m;
}

/// A UV sphere with its rings' vertices jittered around: closed, with fans of thin triangles at
/// the poles and quads that are no longer cyclic.
Mesh uv_sphere(int stacks, int slices) {
    std::mt19937 rng(unsigned(stacks * 1000 + slices));
    std::uniform_real_distribution<double> jitter(-0.3, 0.3);
    Mesh m;
    m.positions.emplace_back(0, 0, 1);
    for (int i = 1; i < stacks; ++i)
        for (int j = 0; j < slices; ++j) {
            const double th = kPi * (i + 0.5 * jitter(rng)) / stacks, ph = 2 * kPi * (j + jitter(rng)) / slices;
            m.positions.emplace_back(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th));
        }
    m.positions.emplace_back(0, 0, -1);
    const auto ring = [&](int i, int j) { return std::uint32_t(1 + (i - 1) * slices + (j % slices)); };
    const std::uint32_t south = std::uint32_t(m.positions.size() - 1);
    for (int j = 0; j < slices; ++j) {
        m.faces.push_back({0, ring(1, j), ring(1, j + 1)});
        for (int i = 1; i + 1 < stacks; ++i) {
            m.faces.push_back({ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
            m.faces.push_back({ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
        }
        m.faces.push_back({ring(stacks - 1, j), south, ring(stacks - 1, j + 1)});
    }
    return m;
}

double face_area(const Triangulation& t, std::size_t f) {
    const auto l = face_lengths(t, f);
    return triangle_area(l[0], l[1], l[2]);
}

double total_area(const Triangulation& t) {
    double a = 0;
    for (std::size_t f = 0; f < t.face_count(); ++f) a += face_area(t, f);
    return a;
}

std::vector<double> angle_sums(const Triangulation& t) {
    std::vector<double> s(t.vertex_count, 0.0);
    for (std::size_t f = 0; f < t.face_count(); ++f)
        for (int k = 0; k < 3; ++k) s[t.faces[f][std::size_t(k)]] += corner_angle(face_lengths(t, f), k);
    return s;
}

double min_angle(const Triangulation& t) {
    double m = kPi;
    for (std::size_t f = 0; f < t.face_count(); ++f)
        for (int k = 0; k < 3; ++k) m = std::min(m, corner_angle(face_lengths(t, f), k));
    return m;
}

/// Every face side runs along its edge as `aligned` says, and every edge is used.
bool consistent(const Triangulation& t) {
    std::vector<int> uses(t.edge_count(), 0);
    for (std::size_t f = 0; f < t.face_count(); ++f)
        for (std::size_t k = 0; k < 3; ++k) {
            const std::uint32_t a = t.faces[f][k], b = t.faces[f][(k + 1) % 3], e = t.face_edges[f][k];
            const auto& ends = t.edges[e];
            if (t.aligned[f][k] ? (ends[0] != a || ends[1] != b) : (ends[0] != b || ends[1] != a)) return false;
            ++uses[e];
        }
    return std::all_of(uses.begin(), uses.end(), [](int u) { return u > 0; });
}

/// The smallest cot α + cot β over edges with two consistently oriented faces whose vertices are
/// all in `flippable_vertex` (all vertices if empty).
double worst_cot_sum(const Triangulation& t, const std::vector<bool>& flippable_vertex = {}) {
    std::vector<std::vector<std::pair<std::size_t, int>>> sides(t.edge_count());
    for (std::size_t f = 0; f < t.face_count(); ++f)
        for (int k = 0; k < 3; ++k) sides[t.face_edges[f][std::size_t(k)]].push_back({f, k});
    double worst = std::numeric_limits<double>::infinity();
    for (std::size_t e = 0; e < t.edge_count(); ++e) {
        if (sides[e].size() != 2) continue;
        const auto [f0, k0] = sides[e][0];
        const auto [f1, k1] = sides[e][1];
        if (t.aligned[f0][std::size_t(k0)] == t.aligned[f1][std::size_t(k1)]) continue;
        bool skip = false;
        for (auto [f, k] : {sides[e][0], sides[e][1]})
            for (std::uint32_t v : t.faces[f]) skip = skip || (!flippable_vertex.empty() && !flippable_vertex[v]);
        if (skip) continue;
        const auto l0 = face_lengths(t, f0), l1 = face_lengths(t, f1);
        const double cot = corner_cot(l0, (k0 + 2) % 3, face_area(t, f0)) + corner_cot(l1, (k1 + 2) % 3, face_area(t, f1));
        worst = std::min(worst, cot);
    }
    return worst;
}

/// Positions of the current triangulation's vertices for a planar input (inserted ones placed
/// from the faces around them), in the plane.
std::vector<Vector2d> embed(const Triangulation& t, const Mesh& input) {
    std::vector<Vector2d> p(t.vertex_count, Vector2d::Constant(NAN));
    for (std::size_t v = 0; v < input.positions.size(); ++v) p[v] = input.positions[v].head<2>();
    for (bool progress = true; progress;) {
        progress = false;
        for (std::size_t f = 0; f < t.face_count(); ++f)
            for (int k = 0; k < 3; ++k) {
                const std::uint32_t a = t.faces[f][std::size_t(k)], b = t.faces[f][std::size_t((k + 1) % 3)];
                const std::uint32_t c = t.faces[f][std::size_t((k + 2) % 3)];
                if (std::isnan(p[a].x()) || std::isnan(p[b].x()) || !std::isnan(p[c].x())) continue;
                const auto q = layout({t.length(f, k), t.length(f, (k + 1) % 3), t.length(f, (k + 2) % 3)});
                const Vector2d x = (p[b] - p[a]).normalized(), y(-x.y(), x.x());
                p[c] = p[a] + q[2].x() * x + q[2].y() * y;
                progress = true;
            }
    }
    return p;
}

/// The worst disagreement between the stored lengths and the embedding, and the smallest
/// signed area (all faces counter-clockwise means a proper planar triangulation).
std::pair<double, double> planar_fit(const Triangulation& t, const std::vector<Vector2d>& p) {
    double worst = 0, smallest = std::numeric_limits<double>::infinity();
    for (std::size_t f = 0; f < t.face_count(); ++f) {
        const auto& v = t.faces[f];
        for (int k = 0; k < 3; ++k)
            worst = std::max(worst, std::abs((p[v[std::size_t(k)]] - p[v[std::size_t((k + 1) % 3)]]).norm() - t.length(f, k)));
        const Vector2d e1 = p[v[1]] - p[v[0]], e2 = p[v[2]] - p[v[0]];
        smallest = std::min(smallest, 0.5 * (e1.x() * e2.y() - e1.y() * e2.x()));
    }
    return {worst, smallest};
}

Vector2d point_of(const Triangulation& t, const std::vector<Vector2d>& p, std::uint32_t f, const Bary& b) {
    const auto& v = t.faces[f];
    return b[0] * p[v[0]] + b[1] * p[v[1]] + b[2] * p[v[2]];
}

/// Length of a piece measured in its own face (from lengths only).
double piece_length(const Triangulation& t, const FaceSegment& s) {
    const auto q = layout(face_lengths(t, s.face));
    Vector2d d = Vector2d::Zero();
    for (std::size_t k = 0; k < 3; ++k) d += (s.b[k] - s.a[k]) * q[k];
    return d.norm();
}

double input_length(const Triangulation& t, const FaceSegment& s) { return piece_length(t, s); }

Bary random_bary(std::mt19937& rng) {
    std::uniform_real_distribution<double> u(0, 1);
    double x = u(rng), y = u(rng);
    if (x + y > 1) x = 1 - x, y = 1 - y;
    return {x, y, 1 - x - y};
}

/// Random segments of every kind: inside, from corners, between points on sides, along sides.
std::vector<FaceSegment> random_segments(std::size_t face_count, std::size_t n, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<std::uint32_t> pick_face(0, std::uint32_t(face_count - 1));
    std::uniform_int_distribution<int> pick_corner(0, 2);
    std::uniform_real_distribution<double> u(0, 1);
    const auto on_side = [&](int k) {
        Bary b{0, 0, 0};
        const double s = u(rng);
        b[std::size_t(k)] = 1 - s;
        b[std::size_t((k + 1) % 3)] = s;
        return b;
    };
    std::vector<FaceSegment> out;
    for (std::size_t i = 0; i < n; ++i) {
        FaceSegment s;
        s.face = pick_face(rng);
        const int k = pick_corner(rng);
        switch (i % 6) {
            case 0: s.a = random_bary(rng), s.b = random_bary(rng); break;
            case 1: s.a = Bary{0, 0, 0}, s.a[std::size_t(k)] = 1, s.b = random_bary(rng); break;
            case 2: s.a = on_side(k), s.b = on_side((k + 1) % 3); break;
            case 3: s.a = on_side(k), s.b = on_side(k); break;  // along a side
            case 4: s.a = Bary{0, 0, 0}, s.a[std::size_t(k)] = 1, s.b = s.a, s.b[std::size_t(k)] = 0,
                    s.b[std::size_t((k + 1) % 3)] = 1; break;  // a whole side, corner to corner
            default: s.a = random_bary(rng), s.b = on_side(k); break;
        }
        out.push_back(s);
    }
    return out;
}

/// Segments of a planar input that pass exactly through the vertices refinement inserted (one per
/// vertex: from a corner of the input face holding it to the opposite side, and a piece of that
/// line around the vertex, backwards).
std::vector<FaceSegment> segments_through_inserted(const Triangulation& t, const Mesh& m, const Triangulation& input) {
    const std::vector<Vector2d> p = embed(t, m);
    const auto cross2 = [](const Vector2d& a, const Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); };
    std::vector<FaceSegment> out;
    for (std::uint32_t v = input.vertex_count; v < t.vertex_count; ++v)
        for (std::uint32_t f = 0; f < input.face_count(); ++f) {
            const auto& c = input.faces[f];
            const Vector2d A = m.positions[c[0]].head<2>(), B = m.positions[c[1]].head<2>(), C = m.positions[c[2]].head<2>();
            const double area = cross2(B - A, C - A);
            const Bary b{cross2(B - p[v], C - p[v]) / area, cross2(C - p[v], A - p[v]) / area, cross2(A - p[v], B - p[v]) / area};
            if (std::min({b[0], b[1], b[2]}) < -1e-12) continue;
            const auto k = std::size_t(v % 3);
            if (b[k] > 1 - 1e-9) break;
            Bary corner{0, 0, 0}, side{};
            corner[k] = 1;
            for (std::size_t q = 0; q < 3; ++q) side[q] = q == k ? 0.0 : b[q] / (1 - b[k]);
            out.push_back({f, corner, side});
            Bary before{}, after{};
            for (std::size_t q = 0; q < 3; ++q) before[q] = 0.5 * (corner[q] + b[q]), after[q] = 0.5 * (b[q] + side[q]);
            out.push_back({f, after, before});
            break;
        }
    return out;
}

/// What went wrong, at worst, over traced segments of a planar mesh.
struct TraceErrors {
    double length = 0;       ///< |Σ piece lengths − segment length| / segment length
    double off_line = 0;     ///< distance of a piece end from the segment
    double chain = 0;        ///< gap between a piece's end and the next piece's start
    double ends = 0;         ///< first start vs a, last end vs b
    double backwards = 0;    ///< how far a piece end goes back along the segment
    double bary = 0;         ///< how far a barycentric weight is below 0 or sums off 1
    std::size_t empty = 0;   ///< traces with no piece
};

void check_barys(const Bary& b, TraceErrors& e) {
    e.bary = std::max({e.bary, -b[0], -b[1], -b[2], std::abs(b[0] + b[1] + b[2] - 1)});
}

TraceErrors trace_errors(const IntrinsicTriangulation& idt, const Mesh& m, const Triangulation& input,
                         const std::vector<FaceSegment>& segments) {
    const Triangulation& t = idt.triangulation();
    const std::vector<Vector2d> p = embed(t, m);
    std::vector<Vector2d> p_in(m.positions.size());
    for (std::size_t v = 0; v < p_in.size(); ++v) p_in[v] = m.positions[v].head<2>();
    TraceErrors e;
    for (const FaceSegment& s : segments) {
        const std::vector<FaceSegment> pieces = idt.trace(s);
        if (pieces.empty()) {
            ++e.empty;
            continue;
        }
        const Vector2d a = point_of(input, p_in, s.face, s.a), b = point_of(input, p_in, s.face, s.b);
        const double length = (b - a).norm();
        double sum = 0, along = 0;
        for (std::size_t i = 0; i < pieces.size(); ++i) {
            const FaceSegment& q = pieces[i];
            check_barys(q.a, e), check_barys(q.b, e);
            sum += piece_length(t, q);
            for (const Bary& end : {q.a, q.b}) {
                const Vector2d x = point_of(t, p, q.face, end);
                const Vector2d d = length > 0 ? Vector2d((b - a) / length) : Vector2d(1, 0);
                e.off_line = std::max(e.off_line, std::abs(d.x() * (x - a).y() - d.y() * (x - a).x()));
                const double at = d.dot(x - a);
                e.backwards = std::max(e.backwards, along - at);
                along = std::max(along, at);
            }
            if (i + 1 < pieces.size())
                e.chain = std::max(e.chain, (point_of(t, p, q.face, q.b) - point_of(t, p, pieces[i + 1].face, pieces[i + 1].a)).norm());
        }
        e.ends = std::max({e.ends, (point_of(t, p, pieces.front().face, pieces.front().a) - a).norm(),
                           (point_of(t, p, pieces.back().face, pieces.back().b) - b).norm()});
        e.length = std::max(e.length, std::abs(sum - length) / std::max(length, 1e-300) * (length > 0));
    }
    return e;
}

void require_small(const TraceErrors& e, double tol) {
    CHECK(e.empty == 0);
    CHECK(e.length < 1e-9);
    CHECK(e.off_line < tol);
    CHECK(e.chain < tol);
    CHECK(e.ends < tol);
    CHECK(e.backwards < tol);
    CHECK(e.bary < 1e-12);
}

}  // namespace

TEST_CASE("a sheared grid with every long diagonal flips each cell to its short one") {
    const Mesh m = planar_grid(12, 9, 0.0, 1, /*diagonal=*/0, /*shear=*/0.6);
    const Triangulation input = triangulate(m);
    REQUIRE(worst_cot_sum(input) < -0.1);
    IntrinsicTriangulation idt(input);
    const std::size_t flips = idt.flip_to_delaunay();
    CHECK(flips == 11 * 8);
    const Triangulation& t = idt.triangulation();
    CHECK(consistent(t));
    // Lattice sides are 1 and 1.166, the short diagonal 1.077, the long one 1.887.
    CHECK(*std::max_element(t.edge_lengths.begin(), t.edge_lengths.end()) < 1.2);
    CHECK(worst_cot_sum(t) >= -1e-9);
    const auto [misfit, smallest] = planar_fit(t, embed(t, m));
    CHECK(misfit < 1e-12);
    CHECK(smallest > 0);
    // A second pass finds nothing to do.
    CHECK(idt.flip_to_delaunay() == 0);
}

TEST_CASE("a perfect square grid is already Delaunay: nothing flips (cocircular ties)") {
    IntrinsicTriangulation idt(triangulate(planar_grid(10, 10, 0.0, 2)));
    CHECK(idt.flip_to_delaunay() == 0);
}

TEST_CASE("flips on a jittered planar grid give its Delaunay triangulation, area and angles kept") {
    const Mesh m = planar_grid(20, 15, 0.35, 3);
    const Triangulation input = triangulate(m);
    REQUIRE(worst_cot_sum(input) < -0.1);
    IntrinsicTriangulation idt(input);
    CHECK(idt.flip_to_delaunay() > 20);
    const Triangulation& t = idt.triangulation();
    CHECK(consistent(t));
    CHECK(t.face_count() == input.face_count());
    CHECK(t.edge_count() == input.edge_count());
    CHECK(worst_cot_sum(t) >= -1e-9);
    CHECK(total_area(t) == doctest::Approx(total_area(input)).epsilon(1e-12));
    const auto before = angle_sums(input), after = angle_sums(t);
    double worst = 0;
    for (std::size_t v = 0; v < before.size(); ++v) worst = std::max(worst, std::abs(before[v] - after[v]));
    CHECK(worst < 1e-9);
    const auto [misfit, smallest] = planar_fit(t, embed(t, m));
    CHECK(misfit < 1e-12);
    CHECK(smallest > 0);
    CHECK(min_angle(t) > min_angle(input));
}

TEST_CASE("flips on curved meshes keep area and every vertex's angle sum") {
    for (const Mesh& m : {bumpy_grid(18, 4), uv_sphere(12, 30)}) {
        const Triangulation input = triangulate(m);
        REQUIRE(worst_cot_sum(input) < -0.05);
        IntrinsicTriangulation idt(input);
        CHECK(idt.flip_to_delaunay() > 10);
        const Triangulation& t = idt.triangulation();
        CHECK(consistent(t));
        CHECK(worst_cot_sum(t) >= -1e-9);
        CHECK(total_area(t) == doctest::Approx(total_area(input)).epsilon(1e-12));
        const auto before = angle_sums(input), after = angle_sums(t);
        double worst = 0;
        for (std::size_t v = 0; v < before.size(); ++v) worst = std::max(worst, std::abs(before[v] - after[v]));
        CHECK(worst < 1e-9);
    }
}

TEST_CASE("a fan of slivers over a flat ellipse is flipped to fat triangles") {
    Mesh m;
    const int n = 24;
    for (int i = 0; i < n; ++i) {
        const double th = 2 * kPi * i / n;
        m.positions.emplace_back(std::cos(th), 0.08 * std::sin(th), 0);
    }
    for (std::uint32_t i = 1; i + 1 < n; ++i) m.faces.push_back({0, i, i + 1});
    const Triangulation input = triangulate(m);
    IntrinsicTriangulation idt(input);
    CHECK(idt.flip_to_delaunay() > 5);
    const Triangulation& t = idt.triangulation();
    CHECK(worst_cot_sum(t) >= -1e-9);
    CHECK(min_angle(t) > 2 * min_angle(input));
    // Vertex 0 no longer sees every other vertex.
    int degree0 = 0;
    for (const auto& e : t.edges) degree0 += (e[0] == 0 || e[1] == 0);
    CHECK(degree0 < n - 1);
    CHECK(total_area(t) == doctest::Approx(total_area(input)).epsilon(1e-12));
    const auto [misfit, smallest] = planar_fit(t, embed(t, m));
    CHECK(misfit < 1e-12);
    CHECK(smallest > 0);
    require_small(trace_errors(idt, m, input, random_segments(input.face_count(), 600, 5)), 1e-11);
}

TEST_CASE("traced segments follow the input segment exactly through flipped planar triangulations") {
    for (unsigned seed : {11u, 12u, 13u}) {
        CAPTURE(seed);
        const Mesh m = planar_grid(16, 13, 0.4, seed);
        const Triangulation input = triangulate(m);
        IntrinsicTriangulation idt(input);
        REQUIRE(idt.flip_to_delaunay() > 0);
        require_small(trace_errors(idt, m, input, random_segments(input.face_count(), 3000, seed)), 1e-11);
    }
}

TEST_CASE("a segment along an edge of the current triangulation comes out on that edge") {
    // Quad a, b, c, d with the bad diagonal a—b; after the flip c—d crosses input face (a,b,c).
    const Mesh m{{{0, 0, 0}, {1, 0, 0}, {0.5, 0.2, 0}, {0.5, -0.2, 0}}, {{0, 1, 2}, {1, 0, 3}}};
    const Triangulation input = triangulate(m);
    IntrinsicTriangulation idt(input);
    REQUIRE(idt.flip_to_delaunay() == 1);
    const Triangulation& t = idt.triangulation();
    const std::vector<Vector2d> p = embed(t, m);
    const auto zero_both_ends = [](const FaceSegment& s) {
        for (std::size_t k = 0; k < 3; ++k)
            if (s.a[k] == 0 && s.b[k] == 0) return true;
        return false;
    };
    // c to the middle of a—b: along the new edge c—d.
    std::vector<FaceSegment> pieces = idt.trace({0, {0, 0, 1}, {0.5, 0.5, 0}});
    REQUIRE(pieces.size() == 1);
    CHECK(zero_both_ends(pieces[0]));
    CHECK((point_of(t, p, pieces[0].face, pieces[0].b) - Vector2d(0.5, 0)).norm() < 1e-14);
    CHECK(piece_length(t, pieces[0]) == doctest::Approx(0.2).epsilon(1e-12));
    // a to c along an input edge that survived; and part of it.
    pieces = idt.trace({0, {1, 0, 0}, {0, 0, 1}});
    REQUIRE(pieces.size() == 1);
    CHECK(zero_both_ends(pieces[0]));
    pieces = idt.trace({0, {0.7, 0, 0.3}, {0.2, 0, 0.8}});
    REQUIRE(pieces.size() == 1);
    CHECK(zero_both_ends(pieces[0]));
    // Across the whole quad along the old diagonal: two pieces meeting on c—d.
    pieces = idt.trace({0, {1, 0, 0}, {0, 1, 0}});
    REQUIRE(pieces.size() == 2);
    CHECK((point_of(t, p, pieces[0].face, pieces[0].b) - Vector2d(0.5, 0)).norm() < 1e-14);
    CHECK(piece_length(t, pieces[0]) + piece_length(t, pieces[1]) == doctest::Approx(1.0).epsilon(1e-14));
}

TEST_CASE("locate puts random points of input faces where they are in the plane") {
    const Mesh m = planar_grid(25, 20, 0.4, 21);
    const Triangulation input = triangulate(m);
    IntrinsicTriangulation idt(input);
    REQUIRE(idt.flip_to_delaunay() > 0);
    const Triangulation& t = idt.triangulation();
    const std::vector<Vector2d> p = embed(t, m);
    std::vector<Vector2d> p_in(m.positions.size());
    for (std::size_t v = 0; v < p_in.size(); ++v) p_in[v] = m.positions[v].head<2>();
    std::mt19937 rng(5);
    double worst = 0, worst_bary = 0;
    for (int i = 0; i < 5000; ++i) {
        FacePoint q{std::uint32_t(rng() % input.face_count()), random_bary(rng)};
        if (i % 7 == 0) q.bary = {0, 0, 0}, q.bary[std::size_t(i % 3)] = 1;  // corners
        const FacePoint r = idt.locate(q);
        worst = std::max(worst, (point_of(t, p, r.face, r.bary) - point_of(input, p_in, q.face, q.bary)).norm());
        worst_bary = std::max({worst_bary, -r.bary[0], -r.bary[1], -r.bary[2], std::abs(r.bary[0] + r.bary[1] + r.bary[2] - 1)});
    }
    CHECK(worst < 1e-11);
    CHECK(worst_bary < 1e-12);
}

TEST_CASE("traces on curved meshes keep their length and end where locate says") {
    for (const Mesh& m : {bumpy_grid(14, 8), uv_sphere(10, 24)}) {
        const Triangulation input = triangulate(m);
        IntrinsicTriangulation idt(input);
        REQUIRE(idt.flip_to_delaunay() > 0);
        const Triangulation& t = idt.triangulation();
        double worst_length = 0, worst_end = 0;
        for (const FaceSegment& s : random_segments(input.face_count(), 2000, 17)) {
            const auto pieces = idt.trace(s);
            REQUIRE(!pieces.empty());
            double sum = 0;
            for (const auto& q : pieces) sum += piece_length(t, q);
            const double length = input_length(input, s);
            worst_length = std::max(worst_length, std::abs(sum - length) / std::max(length, 1e-300) * (length > 0));
            // Where b was located and where the trace ended: the same point of the same face
            // (b is generic often enough to be inside a face).
            const FacePoint end = idt.locate({s.face, s.b});
            if (end.face == pieces.back().face)
                for (std::size_t k = 0; k < 3; ++k) worst_end = std::max(worst_end, std::abs(end.bary[k] - pieces.back().b[k]));
        }
        CHECK(worst_length < 1e-9);
        CHECK(worst_end < 1e-8);
    }
}

TEST_CASE("three faces on one edge and a bowtie vertex are left alone, the rest still flips") {
    Mesh m;
    // Edge 0—1 with three nearly flat faces (each pair of apex angles sums past π).
    m.positions = {{0, 0, 0}, {1, 0, 0}, {0.5, 0.1, 0}, {0.5, -0.1, 0}, {0.5, 0, 0.1}};
    m.faces = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
    // A bowtie: two quads sharing vertex 5 only, each with a bad diagonal at 5.
    const auto add = [&](Vector3d p) { m.positions.push_back(p); return std::uint32_t(m.positions.size() - 1); };
    const std::uint32_t v = add({3, 0, 0});
    const std::uint32_t p1 = add({3.5, 0.1, 0}), q1 = add({4, 0, 0}), r1 = add({3.5, -0.1, 0});
    const std::uint32_t p2 = add({2.5, 0.1, 1}), q2 = add({2, 0, 1}), r2 = add({2.5, -0.1, 1});
    m.faces.push_back({v, r1, q1}), m.faces.push_back({v, q1, p1});
    m.faces.push_back({v, p2, q2}), m.faces.push_back({v, q2, r2});
    // A separate, healthy component with a bad diagonal that must flip.
    const std::uint32_t a = add({10, 0, 0}), b = add({11, 0, 0}), c = add({10.5, 0.2, 0}), d = add({10.5, -0.2, 0});
    m.faces.push_back({a, b, c}), m.faces.push_back({b, a, d});
    const Triangulation input = triangulate(m);
    IntrinsicTriangulation idt(input);
    CHECK(idt.flip_to_delaunay() == 1);
    const Triangulation& t = idt.triangulation();
    CHECK(consistent(t));
    for (std::size_t f = 0; f < 7; ++f) {
        CHECK(t.faces[f] == input.faces[f]);
        CHECK(t.face_edges[f] == input.face_edges[f]);
    }
    CHECK(t.edges[input.face_edges[0][0]] == input.edges[input.face_edges[0][0]]);  // 0—1 kept
    CHECK(worst_cot_sum(t) < -0.5);  // the bad ones are still there
    // Curves on the untouched faces come back as they were; on the flipped quad they are traced.
    const FaceSegment s{0, {0.2, 0.3, 0.5}, {0.6, 0.1, 0.3}};
    const auto same = idt.trace(s);
    REQUIRE(same.size() == 1);
    CHECK(same[0].face == 0);
    CHECK(same[0].a[1] == doctest::Approx(0.3));
    const auto across = idt.trace({7, {1, 0, 0}, {0, 1, 0}});
    CHECK(across.size() == 2);
    CHECK(idt.refine(25, 50) < 50);
}

TEST_CASE("a Möbius strip: the seam's faces are not flipped, the rest is, traces keep length") {
    // A twisted band of sheared quads, each split along its long diagonal.
    Mesh m;
    const int n = 40;
    const double radius = 3, half_width = 0.5;
    for (int i = 0; i < n; ++i) {
        const double th = 2 * kPi * i / n;
        const Vector3d center(radius * std::cos(th), radius * std::sin(th), 0);
        const Vector3d out(std::cos(th), std::sin(th), 0), up(0, 0, 1);
        const Vector3d across = std::cos(th / 2) * out + std::sin(th / 2) * up;
        const Vector3d tangent(-std::sin(th), std::cos(th), 0);
        m.positions.push_back(center + half_width * across + 0.35 * tangent);
        m.positions.push_back(center - half_width * across);
    }
    for (int i = 0; i < n; ++i) {
        const std::uint32_t t0 = std::uint32_t(2 * i), b0 = t0 + 1;
        std::uint32_t t1 = std::uint32_t(2 * ((i + 1) % n)), b1 = t1 + 1;
        if (i == n - 1) std::swap(t1, b1);  // the half twist
        m.faces.push_back({b0, b1, t1});
        m.faces.push_back({b0, t1, t0});
    }
    const Triangulation input = triangulate(m);
    REQUIRE(worst_cot_sum(input) < -0.05);
    IntrinsicTriangulation idt(input);
    CHECK(idt.flip_to_delaunay() > 10);
    const Triangulation& t = idt.triangulation();
    CHECK(consistent(t));
    // The faces at the seam (the last quad and the first) are the input's.
    for (std::size_t f : {std::size_t(0), std::size_t(1), std::size_t(2 * n - 2), std::size_t(2 * n - 1)})
        CHECK(t.faces[f] == input.faces[f]);
    CHECK(total_area(t) == doctest::Approx(total_area(input)).epsilon(1e-12));
    double worst = 0;
    for (const FaceSegment& s : random_segments(input.face_count(), 1000, 3)) {
        double sum = 0;
        for (const auto& q : idt.trace(s)) sum += piece_length(t, q);
        worst = std::max(worst, std::abs(sum - input_length(input, s)));
    }
    CHECK(worst < 1e-9);
}

TEST_CASE("degenerate faces (flat, or lengths no triangle has) are kept and do not break anything") {
    Mesh m = planar_grid(6, 6, 0.3, 31);
    // A flat triangle hung on a boundary edge: its corners sit on one line.
    m.positions.emplace_back(2.5, 0, 0);
    m.faces.push_back({std::uint32_t(1), std::uint32_t(m.positions.size() - 1), std::uint32_t(2)});
    Triangulation input = triangulate(m);
    // One more face whose sides violate the triangle inequality, on its own vertices.
    const std::uint32_t base = input.vertex_count;
    input.vertex_count += 3;
    const std::uint32_t e0 = std::uint32_t(input.edge_count());
    input.edges.insert(input.edges.end(), {{base, base + 1}, {base + 1, base + 2}, {base + 2, base}});
    input.edge_lengths.insert(input.edge_lengths.end(), {1.0, 1.0, 5.0});
    input.faces.push_back({base, base + 1, base + 2});
    input.face_edges.push_back({e0, e0 + 1, e0 + 2});
    input.aligned.push_back({1, 1, 1});
    IntrinsicTriangulation idt(input);
    idt.flip_to_delaunay();
    idt.refine(30, 20);
    const Triangulation& t = idt.triangulation();
    CHECK(consistent(t));
    const std::size_t flat = m.faces.size() - 1, broken = input.face_count() - 1;
    CHECK(t.faces[flat] == input.faces[flat]);
    CHECK(t.faces[broken] == input.faces[broken]);
    for (std::size_t f = 0; f < input.face_count(); ++f) CHECK(!idt.trace({std::uint32_t(f), {1, 0, 0}, {0, 0.5, 0.5}}).empty());
}

TEST_CASE("refinement lifts the smallest angle of a planar sliver mesh above the target") {
    // A rectangle of 8 × 5 with interior points jittered almost onto each other: slivers remain
    // after flips.
    Mesh m = planar_grid(9, 6, 0.3, 41);
    add_slivers(m, 7);
    const Triangulation input = triangulate(m);
    REQUIRE(std::abs(total_area(input) - 40.0) < 1e-10);
    IntrinsicTriangulation idt(input);
    idt.flip_to_delaunay();
    REQUIRE(min_angle(idt.triangulation()) < 10 * kPi / 180);
    const std::size_t added = idt.refine(25, 3000);
    const Triangulation& t = idt.triangulation();
    CHECK(added > 0);
    CHECK(t.vertex_count == input.vertex_count + added);
    CHECK(consistent(t));
    CHECK(min_angle(t) >= 25 * kPi / 180 - 1e-9);
    CHECK(worst_cot_sum(t) >= -1e-9);
    CHECK(total_area(t) == doctest::Approx(40.0).epsilon(1e-11));
    const auto [misfit, smallest] = planar_fit(t, embed(t, m));
    CHECK(misfit < 1e-9);
    CHECK(smallest > 0);
    // Input vertices keep their angle sums; inserted ones are flat (2π inside, π on the rim).
    const auto before = angle_sums(input), after = angle_sums(t);
    for (std::size_t v = 0; v < before.size(); ++v) CHECK(after[v] == doctest::Approx(before[v]).epsilon(1e-9));
    for (std::size_t v = before.size(); v < after.size(); ++v)
        CHECK((std::abs(after[v] - 2 * kPi) < 1e-9 || std::abs(after[v] - kPi) < 1e-9));
    require_small(trace_errors(idt, m, input, random_segments(input.face_count(), 3000, 77)), 1e-9);
    const std::vector<FaceSegment> through = segments_through_inserted(t, m, input);
    CHECK(through.size() > added);
    require_small(trace_errors(idt, m, input, through), 1e-9);
    // The budget is respected.
    IntrinsicTriangulation capped(input);
    CHECK(capped.refine(25, 7) == 7);
    CHECK(capped.triangulation().vertex_count == input.vertex_count + 7);
}

TEST_CASE("refinement of a curved mesh keeps area and input angle sums") {
    const Mesh m = bumpy_grid(10, 6);
    const Triangulation input = triangulate(m);
    IntrinsicTriangulation idt(input);
    const std::size_t added = idt.refine(28, 0);
    CHECK(added > 0);
    CHECK(added <= input.vertex_count);
    const Triangulation& t = idt.triangulation();
    CHECK(consistent(t));
    CHECK(total_area(t) == doctest::Approx(total_area(input)).epsilon(1e-10));
    const auto before = angle_sums(input), after = angle_sums(t);
    for (std::size_t v = 0; v < before.size(); ++v) CHECK(after[v] == doctest::Approx(before[v]).epsilon(1e-9));
    double worst = 0;
    for (const FaceSegment& s : random_segments(input.face_count(), 1000, 8)) {
        double sum = 0;
        for (const auto& q : idt.trace(s)) sum += piece_length(t, q);
        worst = std::max(worst, std::abs(sum - input_length(input, s)));
    }
    CHECK(worst < 1e-9);
}

TEST_CASE("refinement at 20°, 25°, 30° on many planar meshes: valid, and traces stay exact") {
    for (unsigned seed = 100; seed < 112; ++seed) {
        Mesh m = planar_grid(6 + seed % 7, 5 + seed % 5, 0.05 + 0.1 * (seed % 4), seed);
        if (seed % 2) add_slivers(m, 3 + seed % 5);
        const Triangulation input = triangulate(m);
        for (double target : {20.0, 25.0, 30.0}) {
            CAPTURE(seed);
            CAPTURE(target);
            IntrinsicTriangulation idt(input);
            idt.refine(target, 5000);
            const Triangulation& t = idt.triangulation();
            CHECK(consistent(t));
            if (target <= 25) CHECK(min_angle(t) >= target * kPi / 180 - 1e-9);
            const auto [misfit, smallest] = planar_fit(t, embed(t, m));
            CHECK(misfit < 1e-9);
            CHECK(smallest > 0);
            std::vector<FaceSegment> segments = random_segments(input.face_count(), 500, seed);
            const std::vector<FaceSegment> through = segments_through_inserted(t, m, input);
            segments.insert(segments.end(), through.begin(), through.end());
            require_small(trace_errors(idt, m, input, segments), 1e-9);
        }
    }
}

TEST_CASE("small closed meshes: flips make loops and double edges, everything stays consistent") {
    std::size_t loops = 0, doubled = 0;
    for (unsigned seed = 0; seed < 30; ++seed) {
        CAPTURE(seed);
        std::mt19937 rng(seed);
        std::uniform_real_distribution<double> u(-1, 1);
        // A long, flat, irregular tetrahedron and a stretched, jittered octahedron.
        Mesh tet;
        for (int i = 0; i < 4; ++i) tet.positions.emplace_back(u(rng) * (i == 0 ? 4 : 1), u(rng), 0.2 * u(rng));
        tet.faces = {{0, 1, 2}, {0, 3, 1}, {1, 3, 2}, {2, 3, 0}};
        const Vector3d normal = (tet.positions[1] - tet.positions[0]).cross(tet.positions[2] - tet.positions[0]);
        if (normal.dot(tet.positions[3] - tet.positions[0]) > 0)
            for (auto& f : tet.faces) std::swap(f[1], f[2]);
        Mesh oct;
        oct.positions = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
        for (Vector3d& x : oct.positions) x += 0.45 * Vector3d(u(rng), u(rng), u(rng)), x.x() *= 1 + 2 * (seed % 3);
        oct.faces = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
        for (const Mesh& m : {tet, oct}) {
            const Triangulation input = triangulate(m);
            IntrinsicTriangulation idt(input);
            idt.flip_to_delaunay();
            idt.refine(25, 40);
            const Triangulation& t = idt.triangulation();
            CHECK(consistent(t));
            CHECK(worst_cot_sum(t) >= -1e-9);
            CHECK(total_area(t) == doctest::Approx(total_area(input)).epsilon(1e-11));
            const auto before = angle_sums(input), after = angle_sums(t);
            for (std::size_t v = 0; v < before.size(); ++v) CHECK(after[v] == doctest::Approx(before[v]).epsilon(1e-9));
            std::map<std::pair<std::uint32_t, std::uint32_t>, int> pairs;
            for (const auto& e : t.edges) {
                loops += e[0] == e[1];
                doubled += ++pairs[std::minmax(e[0], e[1])] == 2;
            }
            // Curves keep their length, here and after feeding the result back in as an input.
            IntrinsicTriangulation again(t);
            again.flip_to_delaunay();
            double worst = 0;
            for (const FaceSegment& s : random_segments(input.face_count(), 200, seed)) {
                double sum = 0;
                for (const auto& q : idt.trace(s)) sum += piece_length(t, q);
                worst = std::max(worst, std::abs(sum - input_length(input, s)));
            }
            for (const FaceSegment& s : random_segments(t.face_count(), 200, seed)) {
                double sum = 0;
                for (const auto& q : again.trace(s)) sum += piece_length(again.triangulation(), q);
                worst = std::max(worst, std::abs(sum - input_length(t, s)));
            }
            CHECK(worst < 1e-9);
        }
    }
    CHECK(loops > 0);
    CHECK(doubled > 0);
}
