// intrinsic.cpp — intrinsic Delaunay flips, Delaunay refinement and curve tracing (~1100 lines:
// all three move signposts through the same halfedge structure).
//
// The current triangulation is kept as a Triangulation plus halfedge twins (3·face + k) and one
// "signpost" per halfedge (Sharp, Soliman & Crane 2019): the direction of the halfedge at its
// tail vertex, as an angle in that vertex's tangent space. Angles are intrinsic (not rescaled):
// around an interior vertex they run modulo the vertex's total angle, around a boundary vertex
// from 0 (along the first boundary edge, counter-clockwise) to the total angle. The input's own
// signposts are kept, so a point of an input face is found by walking from one of that face's
// corners along its direction and distance in the face, unfolding the current triangles crossed.
//
// Only "navigable" vertices take part in changes: a single consistently oriented fan of
// non-degenerate faces around them (a disk or a half-disk). Faces that touch any other vertex
// (nonmanifold, nonorientable, degenerate neighbourhoods) are never rewritten, so their faces
// stay exactly the input's and curves inside them map as they are.
#include "mesh/intrinsic.hpp"

#include "mesh/geometry.hpp"
#include "mesh/topology.hpp"

#include <gsd/core.hpp>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <numbers>
#include <optional>
#include <queue>
#include <string>
#include <tuple>
#include <utility>

namespace gsd::mesh {

namespace {

using Eigen::Vector2d;
using Bary = std::array<double, 3>;

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
constexpr double kPi = std::numbers::pi;
/// An edge is flipped when cot α + cot β is below minus this: exactly cocircular pairs (a square
/// grid's diagonals) are left alone, so roundoff cannot make two flips undo each other forever.
constexpr double kDelaunayTolerance = 1e-10;
/// Directions closer than this (radians) to an edge are taken to run along it.
constexpr double kAngleSnap = 1e-9;
/// Barycentric distance below which a walk that reaches an edge is taken to hit its end vertex.
constexpr double kVertexSnap = 1e-10;
/// Relative length below which a walk counts as arrived and a piece as empty.
constexpr double kLengthSnap = 1e-13;
/// Quad corners at least this close to π make a flip fold the two triangles over.
constexpr double kConvexMargin = 1e-12;

int next(int k) { return k == 2 ? 0 : k + 1; }
int prev(int k) { return k == 0 ? 2 : k - 1; }
std::uint32_t halfedge(std::uint32_t f, int k) { return 3 * f + std::uint32_t(k); }
std::uint32_t face_of(std::uint32_t h) { return h / 3; }
int index_of(std::uint32_t h) { return int(h % 3); }

double cross(const Vector2d& a, const Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }
Vector2d perp(const Vector2d& v) { return {-v.y(), v.x()}; }
double signed_angle(const Vector2d& from, const Vector2d& to) {
    return std::atan2(cross(from, to), from.dot(to));
}
Vector2d rotate(const Vector2d& v, double angle) {
    const double c = std::cos(angle), s = std::sin(angle);
    return {c * v.x() - s * v.y(), s * v.x() + c * v.y()};
}
Bary corner_point(int k) {
    Bary b{0, 0, 0};
    b[std::size_t(k)] = 1;
    return b;
}

/// The angle at corner k from lengths; atan2 keeps tiny angles accurate where acos would not.
double angle_at(const std::array<double, 3>& l, int k) {
    const double a = l[std::size_t(next(k))], b = l[std::size_t(k)], c = l[std::size_t(prev(k))];
    return std::atan2(4 * triangle_area(a, b, c), b * b + c * c - a * a);
}

/// Whether a triangle carries no area (to rounding), or its lengths are not lengths at all.
bool degenerate(const std::array<double, 3>& l) {
    for (double x : l)
        if (!std::isfinite(x) || !(x > 0)) return true;
    const double longest = std::max({l[0], l[1], l[2]});
    return triangle_area(l[0], l[1], l[2]) <= kDegenerateRelativeArea * longest * longest;
}

double wrap(double x, double period) {
    x = std::fmod(x, period);
    if (x < 0) x += period;
    return x >= period ? 0.0 : x;
}

/// Circumcenter of a laid-out triangle (corner 0 at the origin).
Vector2d circumcenter(const std::array<Vector2d, 3>& p) {
    const Vector2d b = p[1] - p[0], c = p[2] - p[0];
    const double d = 2 * cross(b, c);
    const Vector2d o(c.y() * b.squaredNorm() - b.y() * c.squaredNorm(),
                     b.x() * c.squaredNorm() - c.x() * b.squaredNorm());
    return p[0] + o / d;
}

/// Barycentric weights cleaned for use: negatives clamped, normalized.
Bary normalized(const Bary& b, const char* what) {
    Bary r{std::max(b[0], 0.0), std::max(b[1], 0.0), std::max(b[2], 0.0)};
    const double sum = r[0] + r[1] + r[2];
    if (!(sum > 0) || !std::isfinite(sum))
        throw Error(std::string("intrinsic triangulation: invalid barycentric coordinates of ") + what);
    for (double& x : r) x /= sum;
    return r;
}

/// Where a straight walk is. At a vertex the heading is a signpost angle there; inside or on
/// the sides of a face it is a unit vector in the face's layout. Either way (face, bary) is the
/// point, so that a walk that stops at a vertex still names a face.
struct Cursor {
    std::uint32_t face = 0;
    Bary bary{1, 0, 0};
    Vector2d heading{1, 0};
    bool at_vertex = false;
    int corner = 0;      ///< at a vertex: the corner of `face` there
    double angle = 0;    ///< at a vertex: the direction to go on in
};

enum class WalkEnd { arrived, boundary, blocked };

struct WalkResult {
    WalkEnd end = WalkEnd::arrived;
    Cursor where;
    std::uint32_t halfedge = kNone;  ///< boundary: the boundary halfedge reached
};

/// How a signpost angle falls in a vertex's fan: inside a corner, or along one of its sides.
struct FanDirection {
    enum Kind { inside, along_first, along_second } kind = inside;
    std::uint32_t corner = kNone;  ///< corner id 3f + k
    double offset = 0;             ///< angle past the corner's first side
};

/// One side of a face being written: its edge, whether it runs the edge's way, its signpost.
struct Side {
    std::uint32_t edge;
    bool aligned;
    double signpost;
};

}  // namespace

struct IntrinsicTriangulation::Impl {
    const Triangulation* input;
    Triangulation mesh;
    std::uint32_t input_vertex_count;
    std::uint32_t input_face_count;

    std::vector<std::uint32_t> twin;           ///< per halfedge: its partner on a two-face,
                                               ///< consistently oriented edge, else kNone
    std::vector<std::uint32_t> edge_halfedge;  ///< per edge: one halfedge on it
    std::vector<std::uint32_t> vertex_corner;  ///< per vertex: one corner there (kNone: none)
    std::vector<double> signpost;              ///< per halfedge: direction at its tail
    std::vector<double> input_signpost;        ///< the input's halfedges' directions
    std::vector<double> cone_angle;            ///< per vertex: total angle around it
    std::vector<std::uint8_t> navigable;       ///< per vertex: disk or half-disk fan
    std::vector<std::uint8_t> on_boundary;     ///< per navigable vertex: half-disk
    std::vector<std::uint8_t> rewritten;       ///< per face slot: no longer the input's face
    std::vector<std::uint32_t> face_version;   ///< per face slot: bumped on every rewrite
    std::vector<std::uint8_t> queued;          ///< per edge: waiting in the flip queue

    explicit Impl(const Triangulation& in);

    // --- construction ---
    void validate_input() const;
    std::vector<std::uint32_t> link_twins();
    void classify_vertices(const std::vector<std::uint32_t>& faces_per_edge);

    // --- local geometry ---
    std::array<double, 3> lengths(std::uint32_t f) const { return face_lengths(mesh, f); }
    double angle(std::uint32_t f, int k) const { return angle_at(lengths(f), k); }
    double normalize_angle(std::uint32_t v, double a) const;
    double straight_on(std::uint32_t v, double back) const;
    double turn_at(std::uint32_t v, double heading, double turn) const;
    std::uint32_t counter_clockwise(std::uint32_t corner) const;
    std::uint32_t clockwise(std::uint32_t corner) const;
    template <class Visit>
    void for_each_corner_at(std::uint32_t v, Visit visit) const;
    FanDirection find_direction(std::uint32_t v, double heading) const;

    // --- edits ---
    std::uint32_t add_face();
    std::uint32_t add_edge(std::uint32_t a, std::uint32_t b, double length);
    std::uint32_t add_vertex(double cone, bool boundary);
    void write_face(std::uint32_t f, std::array<std::uint32_t, 3> v, std::array<Side, 3> s);
    Side side_of(std::uint32_t h) const {
        return {mesh.face_edges[face_of(h)][std::size_t(index_of(h))],
                mesh.aligned[face_of(h)][std::size_t(index_of(h))] != 0, signpost[h]};
    }
    void relink(const std::vector<std::pair<std::uint32_t, std::uint32_t>>& moved,
                const std::vector<std::uint32_t>& old_twins, std::uint32_t region_a, std::uint32_t region_b);
    void pair(std::uint32_t h0, std::uint32_t h1) { twin[h0] = h1, twin[h1] = h0; }

    // --- flips ---
    std::optional<double> flipped_length(std::uint32_t e) const;
    bool violates_delaunay(std::uint32_t e) const;
    void flip(std::uint32_t e, double new_length);
    std::size_t flip_queued(std::deque<std::uint32_t>& queue, std::vector<std::uint32_t>* touched);
    void queue_edges_of(std::uint32_t f, std::deque<std::uint32_t>& queue);

    // --- insertion ---
    bool face_navigable(std::uint32_t f) const;
    bool insert_in_face(std::uint32_t f, const Bary& b, std::vector<std::uint32_t>& touched);
    bool split_edge(std::uint32_t h, double t, std::vector<std::uint32_t>& touched);
    bool insert_circumcenter(std::uint32_t f, std::vector<std::uint32_t>& touched);
    std::uint32_t encroached_boundary(std::uint32_t f, const Vector2d& x) const;
    double smallest_angle(std::uint32_t f, int* corner) const;
    bool refinable(std::uint32_t f, double target) const;

    // --- walking ---
    WalkResult walk(Cursor c, double distance, std::vector<FaceSegment>* pieces, bool slide) const;
    std::optional<WalkResult> step_from_vertex(Cursor& c, double& left, double done,
                                               std::vector<FaceSegment>* pieces) const;
    std::optional<WalkResult> step_in_face(Cursor& c, double& left, double done,
                                           std::vector<FaceSegment>* pieces, bool slide) const;
    std::optional<WalkResult> cross_edge(Cursor& c, int opposite, const Bary& point,
                                         const std::array<Vector2d, 3>& p, bool slide) const;
    Cursor cursor_in_input(std::uint32_t face, const Bary& b, const Vector2d& toward) const;
};

// ------------------------------------------------------------------------------------------
// Construction

IntrinsicTriangulation::Impl::Impl(const Triangulation& in)
    : input(&in), mesh(in), input_vertex_count(in.vertex_count),
      input_face_count(std::uint32_t(in.face_count())) {
    validate_input();
    const std::vector<std::uint32_t> faces_per_edge = link_twins();
    classify_vertices(faces_per_edge);
    input_signpost = signpost;
    rewritten.assign(mesh.face_count(), 0);
    face_version.assign(mesh.face_count(), 0);
    queued.assign(mesh.edge_count(), 0);
}

void IntrinsicTriangulation::Impl::validate_input() const {
    const auto fail = [](const std::string& what) { throw Error("intrinsic triangulation: " + what); };
    const std::size_t F = mesh.face_count(), E = mesh.edge_count();
    if (mesh.face_edges.size() != F || mesh.aligned.size() != F) fail("per-face arrays differ in size");
    if (mesh.edge_lengths.size() != E) fail("edge lengths do not match the edges");
    if (F >= kNone / 3) fail("too many faces");
    for (std::size_t f = 0; f < F; ++f)
        for (int k = 0; k < 3; ++k) {
            const auto ks = std::size_t(k);
            const std::uint32_t a = mesh.faces[f][ks], b = mesh.faces[f][std::size_t(next(k))];
            const std::uint32_t e = mesh.face_edges[f][ks];
            if (a >= mesh.vertex_count || b >= mesh.vertex_count) fail("face refers to a missing vertex");
            if (e >= E) fail("face refers to a missing edge");
            const auto& ends = mesh.edges[e];
            const bool fits = mesh.aligned[f][ks] ? (ends[0] == a && ends[1] == b) : (ends[0] == b && ends[1] == a);
            if (!fits) fail("edge " + std::to_string(e) + " does not join the vertices of its face side");
        }
}

/// Pairs the two halfedges of every edge that has exactly two faces running it opposite ways;
/// returns the number of faces on each edge.
std::vector<std::uint32_t> IntrinsicTriangulation::Impl::link_twins() {
    const std::size_t E = mesh.edge_count();
    std::vector<std::uint32_t> count(E, 0), second(E, kNone);
    edge_halfedge.assign(E, kNone);
    twin.assign(3 * mesh.face_count(), kNone);
    for (std::uint32_t f = 0; f < mesh.face_count(); ++f)
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t e = mesh.face_edges[f][std::size_t(k)];
            (count[e]++ == 0 ? edge_halfedge[e] : second[e]) = halfedge(f, k);
        }
    for (std::uint32_t e = 0; e < E; ++e) {
        if (count[e] != 2) continue;
        const std::uint32_t h0 = edge_halfedge[e], h1 = second[e];
        const bool opposite = mesh.aligned[face_of(h0)][std::size_t(index_of(h0))] !=
                              mesh.aligned[face_of(h1)][std::size_t(index_of(h1))];
        if (opposite) pair(h0, h1);
    }
    return count;
}

/// Finds each vertex's fan, decides whether it is navigable, and lays out its signposts.
void IntrinsicTriangulation::Impl::classify_vertices(const std::vector<std::uint32_t>& faces_per_edge) {
    const std::uint32_t V = mesh.vertex_count;
    std::vector<std::uint32_t> corner_count(V, 0);
    vertex_corner.assign(V, kNone);
    for (std::uint32_t f = 0; f < mesh.face_count(); ++f)
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t v = mesh.faces[f][std::size_t(k)];
            ++corner_count[v];
            if (vertex_corner[v] == kNone) vertex_corner[v] = halfedge(f, k);
        }
    signpost.assign(3 * mesh.face_count(), 0.0);
    cone_angle.assign(V, 0.0);
    navigable.assign(V, 0);
    on_boundary.assign(V, 0);
    std::vector<std::uint8_t> face_ok(mesh.face_count());
    for (std::uint32_t f = 0; f < mesh.face_count(); ++f) face_ok[f] = !degenerate(lengths(f));

    for (std::uint32_t v = 0; v < V; ++v) {
        if (vertex_corner[v] == kNone) continue;
        // Back up clockwise to where the fan starts (a boundary side), or all the way round.
        std::uint32_t first = vertex_corner[v];
        for (std::uint32_t steps = 0; twin[first] != kNone && steps < corner_count[v]; ++steps) {
            first = clockwise(first);
            if (first == vertex_corner[v]) break;
        }
        const bool boundary = twin[first] == kNone;
        // Walk counter-clockwise, laying down signposts.
        std::uint32_t c = first, visited = 0;
        double total = 0;
        bool ok = true;
        while (true) {
            ++visited;
            ok = ok && face_ok[face_of(c)];
            signpost[c] = total;
            total += angle(face_of(c), index_of(c));
            const std::uint32_t n = counter_clockwise(c);
            if (n == kNone || n == first || visited > corner_count[v]) {
                if (boundary) {
                    // Both ends of the fan must be true boundary, not an edge of 3+ faces.
                    const auto single = [&](std::uint32_t h) {
                        return faces_per_edge[mesh.face_edges[face_of(h)][std::size_t(index_of(h))]] == 1;
                    };
                    ok = ok && n == kNone && single(first) && single(halfedge(face_of(c), prev(index_of(c))));
                } else {
                    ok = ok && n == first;
                }
                break;
            }
            c = n;
        }
        ok = ok && visited == corner_count[v];
        cone_angle[v] = total;
        navigable[v] = ok && total > 0;
        on_boundary[v] = boundary;
        vertex_corner[v] = first;
    }
}

// ------------------------------------------------------------------------------------------
// Fans and directions

/// The next corner counter-clockwise around the corner's vertex, across the side that leaves
/// the corner last (halfedge k+2, which arrives at the vertex); kNone at a boundary.
std::uint32_t IntrinsicTriangulation::Impl::counter_clockwise(std::uint32_t corner) const {
    return twin[halfedge(face_of(corner), prev(index_of(corner)))];
}

/// The next corner clockwise, across the corner's own outgoing halfedge; kNone at a boundary.
std::uint32_t IntrinsicTriangulation::Impl::clockwise(std::uint32_t corner) const {
    const std::uint32_t t = twin[corner];
    return t == kNone ? kNone : halfedge(face_of(t), next(index_of(t)));
}

/// Visits the corners around a navigable vertex (counter-clockwise from vertex_corner, then
/// clockwise from it if a boundary stopped the first pass) until `visit` returns true.
template <class Visit>
void IntrinsicTriangulation::Impl::for_each_corner_at(std::uint32_t v, Visit visit) const {
    const std::uint32_t start = vertex_corner[v];
    const std::size_t cap = twin.size();
    std::uint32_t c = start;
    for (std::size_t steps = 0; steps < cap; ++steps) {
        if (visit(c)) return;
        c = counter_clockwise(c);
        if (c == start) return;
        if (c == kNone) break;
    }
    c = clockwise(start);
    for (std::size_t steps = 0; c != kNone && c != start && steps < cap; ++steps) {
        if (visit(c)) return;
        c = clockwise(c);
    }
}

/// An angle at v brought into its range: modulo the cone angle inside, as is on the boundary.
double IntrinsicTriangulation::Impl::normalize_angle(std::uint32_t v, double a) const {
    return on_boundary[v] ? a : wrap(a, cone_angle[v]);
}

/// The direction that goes straight on through v for a walk that came from direction `back`:
/// half the cone angle round inside (exact at the flat vertices refinement inserts), a half
/// turn at a boundary vertex, or the nearer boundary side if a half turn would leave the surface.
double IntrinsicTriangulation::Impl::straight_on(std::uint32_t v, double back) const {
    const double cone = cone_angle[v];
    if (!on_boundary[v]) return wrap(back + 0.5 * cone, cone);
    if (back + kPi <= cone + kAngleSnap) return std::min(back + kPi, cone);
    if (back - kPi >= -kAngleSnap) return std::max(back - kPi, 0.0);
    return (back + kPi - cone < kPi - back) ? cone : 0.0;
}

/// A heading at v turned by `turn` (radians, counter-clockwise), as in the plane: around a
/// boundary vertex the result is moved by whole turns into [0, cone] where possible.
double IntrinsicTriangulation::Impl::turn_at(std::uint32_t v, double heading, double turn) const {
    const double cone = cone_angle[v];
    if (!on_boundary[v]) return wrap(heading + turn * cone / (2 * kPi), cone);
    double a = heading + turn;
    for (double shift : {0.0, 2 * kPi, -2 * kPi})
        if (a + shift >= -kAngleSnap && a + shift <= cone + kAngleSnap) return std::clamp(a + shift, 0.0, cone);
    return std::clamp(a, 0.0, cone);
}

/// The corner of v's fan that a signpost angle points into, snapping to a side when within
/// kAngleSnap of it (so a walk along an edge is recognised as such).
FanDirection IntrinsicTriangulation::Impl::find_direction(std::uint32_t v, double heading) const {
    const double cone = cone_angle[v];
    const bool boundary = on_boundary[v];
    FanDirection found, best;
    double best_miss = std::numeric_limits<double>::infinity();
    for_each_corner_at(v, [&](std::uint32_t c) {
        const double width = this->angle(face_of(c), index_of(c));
        double offset = heading - signpost[c];
        if (!boundary) {
            offset = wrap(offset, cone);
            if (offset > cone - kAngleSnap) offset -= cone;
        }
        const double miss = offset < 0 ? -offset : std::max(offset - width, 0.0);
        if (miss < best_miss) {
            best_miss = miss;
            best.corner = c;
            best.offset = std::clamp(offset, 0.0, width);
        }
        if (miss > kAngleSnap) return false;
        found = best;
        return true;
    });
    FanDirection d = found.corner != kNone ? found : best;
    const double width = angle(face_of(d.corner), index_of(d.corner));
    if (d.offset <= kAngleSnap) d.kind = FanDirection::along_first;
    else if (d.offset >= width - kAngleSnap) d.kind = FanDirection::along_second;
    return d;
}

// ------------------------------------------------------------------------------------------
// Editing the triangulation

std::uint32_t IntrinsicTriangulation::Impl::add_face() {
    const auto f = std::uint32_t(mesh.face_count());
    mesh.faces.push_back({});
    mesh.face_edges.push_back({});
    mesh.aligned.push_back({});
    twin.insert(twin.end(), 3, kNone);
    signpost.insert(signpost.end(), 3, 0.0);
    rewritten.push_back(1);
    face_version.push_back(0);
    return f;
}

std::uint32_t IntrinsicTriangulation::Impl::add_edge(std::uint32_t a, std::uint32_t b, double length) {
    const auto e = std::uint32_t(mesh.edge_count());
    mesh.edges.push_back({a, b});
    mesh.edge_lengths.push_back(length);
    edge_halfedge.push_back(kNone);
    queued.push_back(0);
    return e;
}

std::uint32_t IntrinsicTriangulation::Impl::add_vertex(double cone, bool boundary) {
    const std::uint32_t v = mesh.vertex_count++;
    cone_angle.push_back(cone);
    navigable.push_back(1);
    on_boundary.push_back(boundary);
    vertex_corner.push_back(kNone);
    return v;
}

/// Writes face f (corners, sides) and points its vertices and edges at it. Its twins are
/// cleared: the caller links them again (relink, pair), having saved the old ones.
void IntrinsicTriangulation::Impl::write_face(std::uint32_t f, std::array<std::uint32_t, 3> v,
                                              std::array<Side, 3> s) {
    mesh.faces[f] = v;
    for (int k = 0; k < 3; ++k) {
        const auto ks = std::size_t(k);
        mesh.face_edges[f][ks] = s[ks].edge;
        mesh.aligned[f][ks] = s[ks].aligned;
        signpost[halfedge(f, k)] = normalize_angle(v[ks], s[ks].signpost);
        twin[halfedge(f, k)] = kNone;
        edge_halfedge[s[ks].edge] = halfedge(f, k);
        vertex_corner[v[ks]] = halfedge(f, k);
    }
    rewritten[f] = 1;
    ++face_version[f];
}

/// After faces region_a, region_b were rewritten: the outer halfedges moved old → new get their
/// twins back (partners outside the region are told the new id; partners that moved too are
/// found among the moves).
void IntrinsicTriangulation::Impl::relink(const std::vector<std::pair<std::uint32_t, std::uint32_t>>& moved,
                                          const std::vector<std::uint32_t>& old_twins,
                                          std::uint32_t region_a, std::uint32_t region_b) {
    for (std::size_t i = 0; i < moved.size(); ++i) {
        const std::uint32_t t = old_twins[i], to = moved[i].second;
        if (t != kNone && (face_of(t) == region_a || face_of(t) == region_b)) {
            for (const auto& [from, dest] : moved)
                if (from == t) twin[to] = dest;
        } else {
            twin[to] = t;
            if (t != kNone) twin[t] = to;
        }
    }
}

// ------------------------------------------------------------------------------------------
// Flips

/// The length edge e would have after a flip, if it may be flipped: two distinct, consistently
/// oriented faces around navigable vertices, a convex quad, and two proper triangles after.
std::optional<double> IntrinsicTriangulation::Impl::flipped_length(std::uint32_t e) const {
    const std::uint32_t h0 = edge_halfedge[e], h1 = twin[h0];
    if (h1 == kNone) return std::nullopt;
    const std::uint32_t f0 = face_of(h0), f1 = face_of(h1);
    if (f0 == f1) return std::nullopt;
    const int k0 = index_of(h0), k1 = index_of(h1);
    const auto& F0 = mesh.faces[f0];
    const auto& F1 = mesh.faces[f1];
    for (std::uint32_t v : {F0[std::size_t(k0)], F0[std::size_t(next(k0))], F0[std::size_t(prev(k0))], F1[std::size_t(prev(k1))]})
        if (!navigable[v]) return std::nullopt;
    // Lengths of a→b→c and b→a→d (a→b the edge).
    const std::array<double, 3> l0{mesh.length(f0, k0), mesh.length(f0, next(k0)), mesh.length(f0, prev(k0))};
    const std::array<double, 3> l1{mesh.length(f1, k1), mesh.length(f1, next(k1)), mesh.length(f1, prev(k1))};
    if (degenerate(l0) || degenerate(l1)) return std::nullopt;
    if (angle_at(l0, 0) + angle_at(l1, 1) >= kPi - kConvexMargin) return std::nullopt;
    if (angle_at(l0, 1) + angle_at(l1, 0) >= kPi - kConvexMargin) return std::nullopt;
    const Vector2d c = layout(l0)[2];
    const Vector2d d_up = layout(l1)[2];
    const Vector2d d(l0[0] - d_up.x(), -d_up.y());
    const double length = (c - d).norm();
    if (degenerate({l0[2], l1[1], length}) || degenerate({l1[2], l0[1], length})) return std::nullopt;
    return length;
}

bool IntrinsicTriangulation::Impl::violates_delaunay(std::uint32_t e) const {
    const std::uint32_t h0 = edge_halfedge[e], h1 = twin[h0];
    if (h1 == kNone) return false;
    const std::array<double, 3> l0 = lengths(face_of(h0)), l1 = lengths(face_of(h1));
    const double area0 = triangle_area(l0[0], l0[1], l0[2]), area1 = triangle_area(l1[0], l1[1], l1[2]);
    if (!(area0 > 0) || !(area1 > 0)) return false;
    const double cot_sum = corner_cot(l0, prev(index_of(h0)), area0) + corner_cot(l1, prev(index_of(h1)), area1);
    return cot_sum < -kDelaunayTolerance;
}

/// Flips edge e (a→b in face (a,b,c), b→a in face (b,a,d)) to c—d: the faces become (c,a,d)
/// and (d,b,c) in the same slots. The new edge's signposts are the neighbouring ones turned by
/// the new corner angles.
void IntrinsicTriangulation::Impl::flip(std::uint32_t e, double new_length) {
    const std::uint32_t h0 = edge_halfedge[e], h1 = twin[h0];
    const std::uint32_t f0 = face_of(h0), f1 = face_of(h1);
    const int k0 = index_of(h0), k1 = index_of(h1);
    const std::uint32_t a = mesh.faces[f0][std::size_t(k0)], b = mesh.faces[f0][std::size_t(next(k0))];
    const std::uint32_t c = mesh.faces[f0][std::size_t(prev(k0))], d = mesh.faces[f1][std::size_t(prev(k1))];
    const std::uint32_t bc = halfedge(f0, next(k0)), ca = halfedge(f0, prev(k0));
    const std::uint32_t ad = halfedge(f1, next(k1)), db = halfedge(f1, prev(k1));
    const Side s_bc = side_of(bc), s_ca = side_of(ca), s_ad = side_of(ad), s_db = side_of(db);
    const std::vector<std::pair<std::uint32_t, std::uint32_t>> moved{
        {ca, halfedge(f0, 0)}, {ad, halfedge(f0, 1)}, {db, halfedge(f1, 0)}, {bc, halfedge(f1, 1)}};
    std::vector<std::uint32_t> old_twins;
    for (const auto& m : moved) old_twins.push_back(twin[m.first]);

    const std::array<double, 3> l_cad{mesh.edge_lengths[s_ca.edge], mesh.edge_lengths[s_ad.edge], new_length};
    const std::array<double, 3> l_dbc{mesh.edge_lengths[s_db.edge], mesh.edge_lengths[s_bc.edge], new_length};
    const double dir_dc = s_db.signpost + angle_at(l_dbc, 0);  // d→b turned to d→c
    const double dir_cd = s_ca.signpost + angle_at(l_cad, 0);  // c→a turned to c→d
    mesh.edges[e] = {c, d};
    mesh.edge_lengths[e] = new_length;
    write_face(f0, {c, a, d}, {s_ca, s_ad, Side{e, false, dir_dc}});
    write_face(f1, {d, b, c}, {s_db, s_bc, Side{e, true, dir_cd}});
    relink(moved, old_twins, f0, f1);
    pair(halfedge(f0, 2), halfedge(f1, 2));
}

void IntrinsicTriangulation::Impl::queue_edges_of(std::uint32_t f, std::deque<std::uint32_t>& queue) {
    for (std::uint32_t e : mesh.face_edges[f])
        if (!queued[e]) queued[e] = 1, queue.push_back(e);
}

/// Flips queued edges that violate the Delaunay condition until none does, re-queueing the
/// sides of each flipped quad. The flip count is capped in proportion to the edge count, so
/// roundoff cannot keep it going forever. Faces flipped are appended to `touched`.
std::size_t IntrinsicTriangulation::Impl::flip_queued(std::deque<std::uint32_t>& queue,
                                                      std::vector<std::uint32_t>* touched) {
    const std::size_t cap = 64 * mesh.edge_count() + 1024;
    std::size_t flips = 0;
    while (!queue.empty()) {
        const std::uint32_t e = queue.front();
        queue.pop_front();
        queued[e] = 0;
        if (flips >= cap || !violates_delaunay(e)) continue;
        const std::optional<double> length = flipped_length(e);
        if (!length) continue;
        const std::uint32_t h0 = edge_halfedge[e];
        const std::uint32_t f0 = face_of(h0), f1 = face_of(twin[h0]);
        flip(e, *length);
        ++flips;
        queue_edges_of(f0, queue);
        queue_edges_of(f1, queue);
        if (touched) touched->insert(touched->end(), {f0, f1});
    }
    return flips;
}

// ------------------------------------------------------------------------------------------
// Vertex insertion

bool IntrinsicTriangulation::Impl::face_navigable(std::uint32_t f) const {
    const auto& v = mesh.faces[f];
    return navigable[v[0]] && navigable[v[1]] && navigable[v[2]] && !degenerate(lengths(f));
}

/// Splits face (a,b,c) at an inner point into (a,b,n), (b,c,n), (c,a,n), the first in f's slot.
bool IntrinsicTriangulation::Impl::insert_in_face(std::uint32_t f, const Bary& b,
                                                  std::vector<std::uint32_t>& touched) {
    const std::array<double, 3> l = lengths(f);
    const std::array<Vector2d, 3> p = layout(l);
    const Vector2d x = b[0] * p[0] + b[1] * p[1] + b[2] * p[2];
    const double ra = (x - p[0]).norm(), rb = (x - p[1]).norm(), rc = (x - p[2]).norm();
    const std::array<double, 3> l_abn{l[0], rb, ra}, l_bcn{l[1], rc, rb}, l_can{l[2], ra, rc};
    if (degenerate(l_abn) || degenerate(l_bcn) || degenerate(l_can)) return false;

    const auto [a, vb, c] = mesh.faces[f];
    const Side s_ab = side_of(halfedge(f, 0)), s_bc = side_of(halfedge(f, 1)), s_ca = side_of(halfedge(f, 2));
    std::vector<std::uint32_t> old_twins{twin[halfedge(f, 0)], twin[halfedge(f, 1)], twin[halfedge(f, 2)]};
    const std::uint32_t n = add_vertex(2 * kPi, false);
    const std::uint32_t e_an = add_edge(a, n, ra), e_bn = add_edge(vb, n, rb), e_cn = add_edge(c, n, rc);
    const std::uint32_t g1 = add_face(), g2 = add_face();
    const double n_b = angle_at(l_abn, 2), n_c = n_b + angle_at(l_bcn, 2);
    write_face(f, {a, vb, n}, {s_ab, Side{e_bn, true, s_bc.signpost + angle_at(l_bcn, 0)}, Side{e_an, false, 0.0}});
    write_face(g1, {vb, c, n}, {s_bc, Side{e_cn, true, s_ca.signpost + angle_at(l_can, 0)}, Side{e_bn, false, n_b}});
    write_face(g2, {c, a, n}, {s_ca, Side{e_an, true, s_ab.signpost + angle_at(l_abn, 0)}, Side{e_cn, false, n_c}});
    relink({{halfedge(f, 0), halfedge(f, 0)}, {halfedge(f, 1), halfedge(g1, 0)}, {halfedge(f, 2), halfedge(g2, 0)}},
           old_twins, f, f);
    pair(halfedge(f, 1), halfedge(g1, 2));
    pair(halfedge(g1, 1), halfedge(g2, 2));
    pair(halfedge(g2, 1), halfedge(f, 2));
    touched.insert(touched.end(), {f, g1, g2});
    return true;
}

/// Splits the edge under halfedge h (a→b in face (a,b,c), and b→a in (b,a,d) unless on the
/// boundary) at fraction t from a. Faces: (a,n,c), (n,b,c) and inside also (b,n,d), (n,a,d).
bool IntrinsicTriangulation::Impl::split_edge(std::uint32_t h, double t, std::vector<std::uint32_t>& touched) {
    const std::uint32_t h1 = twin[h];
    const std::uint32_t f0 = face_of(h), f1 = h1 == kNone ? kNone : face_of(h1);
    if (f0 == f1) return false;
    const int k0 = index_of(h);
    const std::array<double, 3> l0{mesh.length(f0, k0), mesh.length(f0, next(k0)), mesh.length(f0, prev(k0))};
    const double ab = l0[0], ra = t * ab, rb = (1 - t) * ab;
    const double rc = (Vector2d(ra, 0) - layout(l0)[2]).norm();
    if (degenerate({ra, rc, l0[2]}) || degenerate({rb, l0[1], rc})) return false;
    std::array<double, 3> l1{};
    double rd = 0;
    if (h1 != kNone) {
        const int k1 = index_of(h1);
        l1 = {mesh.length(f1, k1), mesh.length(f1, next(k1)), mesh.length(f1, prev(k1))};
        rd = (Vector2d(rb, 0) - layout(l1)[2]).norm();
        if (degenerate({rb, rd, l1[2]}) || degenerate({ra, l1[1], rd})) return false;
    }

    const std::uint32_t e = mesh.face_edges[f0][std::size_t(k0)];
    const std::uint32_t a = mesh.faces[f0][std::size_t(k0)], b = mesh.faces[f0][std::size_t(next(k0))];
    const std::uint32_t c = mesh.faces[f0][std::size_t(prev(k0))];
    const std::uint32_t bc = halfedge(f0, next(k0)), ca = halfedge(f0, prev(k0));
    const Side s_bc = side_of(bc), s_ca = side_of(ca), s_ab = side_of(h);

    const std::uint32_t n = add_vertex(h1 == kNone ? kPi : 2 * kPi, h1 == kNone);
    const std::uint32_t e_nb = add_edge(n, b, rb), e_cn = add_edge(c, n, rc);
    mesh.edges[e] = {a, n};
    mesh.edge_lengths[e] = ra;
    const std::uint32_t g0 = add_face();
    const std::array<double, 3> l_anc{ra, rc, l0[2]}, l_nbc{rb, l0[1], rc};
    const double n_c = angle_at(l_nbc, 0), n_a = n_c + angle_at(l_anc, 1);
    std::vector<std::pair<std::uint32_t, std::uint32_t>> moved{{ca, halfedge(f0, 2)}, {bc, halfedge(g0, 1)}};
    std::vector<std::uint32_t> old_twins{twin[ca], twin[bc]};
    write_face(f0, {a, n, c}, {Side{e, true, s_ab.signpost}, Side{e_cn, false, n_c}, s_ca});
    write_face(g0, {n, b, c}, {Side{e_nb, true, 0.0}, s_bc, Side{e_cn, true, s_ca.signpost + angle_at(l_anc, 2)}});
    if (h1 == kNone) {
        relink(moved, old_twins, f0, f0);
    } else {
        const int k1 = index_of(h1);
        const std::uint32_t d = mesh.faces[f1][std::size_t(prev(k1))];
        const std::uint32_t ad = halfedge(f1, next(k1)), db = halfedge(f1, prev(k1));
        const Side s_ad = side_of(ad), s_db = side_of(db), s_ba = side_of(h1);
        const std::uint32_t e_dn = add_edge(d, n, rd);
        const std::uint32_t g1 = add_face();
        moved.insert(moved.end(), {{db, halfedge(f1, 2)}, {ad, halfedge(g1, 1)}});
        old_twins.insert(old_twins.end(), {twin[db], twin[ad]});
        const std::array<double, 3> l_bnd{rb, rd, l1[2]}, l_nad{ra, l1[1], rd};
        const double n_d = n_a + angle_at(l_nad, 0);
        write_face(f1, {b, n, d}, {Side{e_nb, false, s_ba.signpost}, Side{e_dn, false, n_d}, s_db});
        write_face(g1, {n, a, d}, {Side{e, false, n_a}, s_ad, Side{e_dn, true, s_db.signpost + angle_at(l_bnd, 2)}});
        relink(moved, old_twins, f0, f1);
        pair(halfedge(f0, 0), halfedge(g1, 0));
        pair(halfedge(g0, 0), halfedge(f1, 0));
        pair(halfedge(f1, 1), halfedge(g1, 2));
        touched.insert(touched.end(), {f1, g1});
    }
    pair(halfedge(f0, 1), halfedge(g0, 2));
    vertex_corner[n] = halfedge(g0, 0);  // on the boundary: the fan's first corner
    touched.insert(touched.end(), {f0, g0});
    return true;
}

/// Inserts the circumcenter of face f, found by walking from the face's centroid towards it;
/// a walk stopped by the boundary splits the boundary edge it reached at its midpoint instead.
/// False (nothing changed) where the target is not in a navigable face or too close to a
/// vertex or edge to make proper triangles.
bool IntrinsicTriangulation::Impl::insert_circumcenter(std::uint32_t f, std::vector<std::uint32_t>& touched) {
    const std::array<Vector2d, 3> p = layout(lengths(f));
    const Vector2d centroid = (p[0] + p[1] + p[2]) / 3;
    const Vector2d to_center = circumcenter(p) - centroid;
    const double distance = to_center.norm();
    if (!std::isfinite(distance)) return false;
    Cursor start;
    start.face = f;
    start.bary = {1.0 / 3, 1.0 / 3, 1.0 / 3};
    if (distance == 0) return insert_in_face(f, start.bary, touched);
    start.heading = to_center / distance;
    const WalkResult r = walk(start, distance, nullptr, false);
    if (r.end == WalkEnd::blocked) return false;
    if (r.end == WalkEnd::boundary)
        return face_navigable(face_of(r.halfedge)) && split_edge(r.halfedge, 0.5, touched);
    if (r.where.at_vertex || !face_navigable(r.where.face)) return false;
    const Bary& b = r.where.bary;
    const std::array<Vector2d, 3> q = layout(lengths(r.where.face));
    const std::uint32_t encroached = encroached_boundary(r.where.face, b[0] * q[0] + b[1] * q[1] + b[2] * q[2]);
    if (encroached != kNone) return face_navigable(face_of(encroached)) && split_edge(encroached, 0.5, touched);
    const double on_side = 1e-9;
    const int zeros = int(b[0] < on_side) + int(b[1] < on_side) + int(b[2] < on_side);
    if (zeros == 0) return insert_in_face(r.where.face, b, touched);
    if (zeros > 1) return false;
    const int j = b[0] < on_side ? 0 : b[1] < on_side ? 1 : 2;
    const double t = b[std::size_t(prev(j))] / (b[std::size_t(next(j))] + b[std::size_t(prev(j))]);
    const std::uint32_t h = halfedge(r.where.face, next(j));
    if (twin[h] != kNone && !face_navigable(face_of(twin[h]))) return false;
    return split_edge(h, t, touched);
}

/// A boundary halfedge whose diametral circle holds point x of face f, or kNone. Ruppert's
/// rule: such a point would make ever thinner triangles against the boundary, so the boundary
/// edge is split instead. Only the boundary edges of the faces whose circumcircles hold x (the
/// faces the insertion would rebuild) are candidates; those are found by unfolding outwards.
std::uint32_t IntrinsicTriangulation::Impl::encroached_boundary(std::uint32_t f, const Vector2d& x) const {
    constexpr std::size_t kMaxCavity = 64;
    std::vector<std::pair<std::uint32_t, Vector2d>> cavity{{f, x}};
    for (std::size_t n = 0; n < cavity.size() && n < kMaxCavity; ++n) {
        const auto [g, y] = cavity[n];
        const std::array<Vector2d, 3> p = layout(lengths(g));
        for (int j = 0; j < 3; ++j) {
            const std::uint32_t h = halfedge(g, next(j));
            const Vector2d tail = p[std::size_t(next(j))], head = p[std::size_t(prev(j))];
            const std::uint32_t t = twin[h];
            if (t == kNone) {
                if ((y - 0.5 * (tail + head)).norm() < 0.5 * (head - tail).norm()) return h;
                continue;
            }
            const std::uint32_t g2 = face_of(t);
            const bool seen = std::any_of(cavity.begin(), cavity.end(), [&](const auto& c) { return c.first == g2; });
            if (seen || !face_navigable(g2)) continue;
            // y in g2's layout: same offsets along and across the shared edge.
            const Vector2d e = (head - tail).normalized();
            const double along = (y - tail).dot(e), across = cross(e, y - tail);
            const int i = index_of(t);
            const std::array<Vector2d, 3> q = layout(lengths(g2));
            const Vector2d e2 = (q[std::size_t(i)] - q[std::size_t(next(i))]).normalized();
            const Vector2d y2 = q[std::size_t(next(i))] + along * e2 + across * perp(e2);
            const Vector2d center = circumcenter(q);
            if ((y2 - center).norm() < (q[0] - center).norm()) cavity.emplace_back(g2, y2);
        }
    }
    return kNone;
}

double IntrinsicTriangulation::Impl::smallest_angle(std::uint32_t f, int* corner) const {
    const std::array<double, 3> l = lengths(f);
    int best = 0;
    double smallest = angle_at(l, 0);
    for (int k = 1; k < 3; ++k) {
        const double a = angle_at(l, k);
        if (a < smallest) smallest = a, best = k;
    }
    if (corner) *corner = best;
    return smallest;
}

/// Faces worth a circumcenter: bad, navigable, and whose small angle is not at a vertex whose
/// own total angle is small (no insertion can fix those; Ruppert's 60° rule).
bool IntrinsicTriangulation::Impl::refinable(std::uint32_t f, double target) const {
    int corner = 0;
    if (!(smallest_angle(f, &corner) < target) || !face_navigable(f)) return false;
    return cone_angle[mesh.faces[f][std::size_t(corner)]] >= kPi / 3;
}

// ------------------------------------------------------------------------------------------
// Walking straight across the triangulation

/// Walks `distance` from c along its heading, unfolding the faces crossed, and appends the
/// pieces to `pieces` if given. A boundary (or an edge that is not a two-face, consistently
/// oriented one) ends the walk unless `slide`, which turns the walk along that edge instead —
/// for curves of the input that only touch the boundary through roundoff.
WalkResult IntrinsicTriangulation::Impl::walk(Cursor c, double distance, std::vector<FaceSegment>* pieces,
                                              bool slide) const {
    double left = distance;
    const double done = kLengthSnap * distance;
    for (std::size_t steps = 8 * mesh.face_count() + 64; steps > 0; --steps) {
        std::optional<WalkResult> end = c.at_vertex ? step_from_vertex(c, left, done, pieces)
                                                    : step_in_face(c, left, done, pieces, slide);
        if (end) return *end;
    }
    return {WalkEnd::blocked, c, kNone};
}

namespace {
void emit(std::vector<FaceSegment>* pieces, std::uint32_t f, const Bary& a, const Bary& b, double length, double done) {
    if (pieces && length > done) pieces->push_back({f, a, b});
}
}  // namespace

/// From a vertex: into the corner the heading points at, or along an edge to its end (or to
/// where the distance runs out on it).
std::optional<WalkResult> IntrinsicTriangulation::Impl::step_from_vertex(Cursor& c, double& left, double done,
                                                                         std::vector<FaceSegment>* pieces) const {
    if (left <= done) return WalkResult{WalkEnd::arrived, c, kNone};
    const std::uint32_t v = mesh.faces[c.face][std::size_t(c.corner)];
    if (!navigable[v]) return WalkResult{WalkEnd::blocked, c, kNone};
    const FanDirection dir = find_direction(v, c.angle);
    const std::uint32_t f = face_of(dir.corner);
    const int k = index_of(dir.corner);
    const std::array<double, 3> l = lengths(f);
    const std::array<Vector2d, 3> p = layout(l);
    const Vector2d first_side = (p[std::size_t(next(k))] - p[std::size_t(k)]).normalized();
    c.face = f;
    c.bary = corner_point(k);
    if (dir.kind == FanDirection::inside) {
        c.at_vertex = false;
        c.heading = rotate(first_side, dir.offset);
        return std::nullopt;
    }
    // Along side k → m of face f.
    const int m = dir.kind == FanDirection::along_first ? next(k) : prev(k);
    const Vector2d side = p[std::size_t(m)] - p[std::size_t(k)];
    const double length = side.norm();
    c.heading = side / length;
    if (left < length * (1 - kVertexSnap)) {
        const double s = left / length;
        Bary end{0, 0, 0};
        end[std::size_t(k)] = 1 - s;
        end[std::size_t(m)] = s;
        emit(pieces, f, c.bary, end, left, done);
        c.bary = end;
        c.at_vertex = false;
        left = 0;
        return WalkResult{WalkEnd::arrived, c, kNone};
    }
    emit(pieces, f, c.bary, corner_point(m), length, done);
    left = std::max(left - length, 0.0);
    // The direction back to v at the far end: corner m's second side if the side left corner
    // k first (m = k+1), else corner m's first side.
    const double back = m == next(k) ? signpost[halfedge(f, m)] + angle_at(l, m) : signpost[halfedge(f, m)];
    const std::uint32_t w = mesh.faces[f][std::size_t(m)];
    c.bary = corner_point(m);
    c.corner = m;
    c.angle = navigable[w] ? straight_on(w, normalize_angle(w, back)) : 0.0;
    return std::nullopt;
}

/// Inside (or on a side of) a face: to where the distance runs out, or to the side the heading
/// leaves by — onto the next face, or onto a vertex if that is where the side is reached.
std::optional<WalkResult> IntrinsicTriangulation::Impl::step_in_face(Cursor& c, double& left, double done,
                                                                     std::vector<FaceSegment>* pieces,
                                                                     bool slide) const {
    const std::uint32_t f = c.face;
    const std::array<double, 3> l = lengths(f);
    const double twice_area = 2 * triangle_area(l[0], l[1], l[2]);
    if (!(twice_area > 0)) return WalkResult{WalkEnd::blocked, c, kNone};
    const std::array<Vector2d, 3> p = layout(l);
    const Vector2d u = c.heading;
    // Rate of change of each barycentric coordinate per unit length walked; zeroed where the
    // walk runs along a side it is on.
    std::array<double, 3> rate{};
    int leaving = -1, on_sides = 0, leaving_count = 0;
    for (int j = 0; j < 3; ++j) {
        const auto js = std::size_t(j);
        rate[js] = cross(u, p[std::size_t(next(j))] - p[std::size_t(prev(j))]) / twice_area;
        if (c.bary[js] > 0) continue;
        ++on_sides;
        if (std::abs(rate[js]) * twice_area / l[std::size_t(next(j))] < kAngleSnap) rate[js] = 0;
        if (rate[js] < 0) leaving = j, ++leaving_count;
    }
    if (leaving >= 0 && on_sides == 2) {
        // At a corner and heading out of it: go on from the vertex.
        const int m = c.bary[0] > 0 ? 0 : c.bary[1] > 0 ? 1 : 2;
        const std::uint32_t w = mesh.faces[f][std::size_t(m)];
        c.at_vertex = true;
        c.corner = m;
        c.bary = corner_point(m);
        c.angle = normalize_angle(w, signpost[halfedge(f, m)] + signed_angle(p[std::size_t(next(m))] - p[std::size_t(m)], u));
        return std::nullopt;
    }
    if (leaving >= 0) return cross_edge(c, leaving, c.bary, p, slide);

    int exit = -1;
    double t_exit = std::numeric_limits<double>::infinity();
    for (int j = 0; j < 3; ++j) {
        const auto js = std::size_t(j);
        if (rate[js] >= 0) continue;
        const double t = c.bary[js] / -rate[js];
        if (t < t_exit) t_exit = t, exit = j;
    }
    if (exit < 0 || left <= t_exit) {
        Bary end{};
        for (std::size_t j = 0; j < 3; ++j) end[j] = std::max(c.bary[j] + left * rate[j], 0.0);
        const double sum = end[0] + end[1] + end[2];
        for (double& x : end) x = x / sum < kLengthSnap ? 0.0 : x / sum;
        end = normalized(end, "a walk's end");
        emit(pieces, f, c.bary, end, left, done);
        c.bary = end;
        left = 0;
        return WalkResult{WalkEnd::arrived, c, kNone};
    }
    Bary out{};
    for (std::size_t j = 0; j < 3; ++j) out[j] = std::max(c.bary[j] + t_exit * rate[j], 0.0);
    out[std::size_t(exit)] = 0;
    const double sum = out[0] + out[1] + out[2];
    for (double& x : out) x /= sum;
    left = std::max(left - t_exit, 0.0);
    for (int o : {next(exit), prev(exit)}) {
        if (out[std::size_t(o)] >= kVertexSnap) continue;
        // The side is reached at its end vertex q: go on straight from there. The way back is
        // measured from the corner's first side without clamping it into the corner: a walk
        // that grazes the corner comes from just outside it, and only the unclamped angle
        // keeps its heading.
        const int q = o == next(exit) ? prev(exit) : next(exit);
        emit(pieces, f, c.bary, corner_point(q), t_exit, done);
        const std::uint32_t w = mesh.faces[f][std::size_t(q)];
        const double back = signpost[halfedge(f, q)] + signed_angle(p[std::size_t(next(q))] - p[std::size_t(q)], -u);
        c.at_vertex = true;
        c.corner = q;
        c.bary = corner_point(q);
        c.angle = navigable[w] ? straight_on(w, normalize_angle(w, back)) : 0.0;
        return std::nullopt;
    }
    emit(pieces, f, c.bary, out, t_exit, done);
    return cross_edge(c, exit, out, p, slide);
}

/// Moves the cursor at `point` on the side opposite corner `opposite` of its face into the face
/// across, unfolding the heading: its components along and across the shared edge are kept.
std::optional<WalkResult> IntrinsicTriangulation::Impl::cross_edge(Cursor& c, int opposite, const Bary& point,
                                                                   const std::array<Vector2d, 3>& p,
                                                                   bool slide) const {
    const std::uint32_t f = c.face;
    const int tail = next(opposite), head = prev(opposite);
    const std::uint32_t h = halfedge(f, tail);
    const std::uint32_t t = twin[h];
    const Vector2d edge = (p[std::size_t(head)] - p[std::size_t(tail)]).normalized();
    c.bary = point;
    if (t == kNone) {
        if (!slide) return WalkResult{WalkEnd::boundary, c, h};
        c.heading = edge.dot(c.heading) >= 0 ? edge : Vector2d(-edge);
        return std::nullopt;
    }
    const double along = c.heading.dot(edge), across = cross(edge, c.heading);
    const std::uint32_t g = face_of(t);
    const int i = index_of(t);
    const std::array<Vector2d, 3> q = layout(lengths(g));
    const Vector2d edge_g = (q[std::size_t(i)] - q[std::size_t(next(i))]).normalized();
    const double s = point[std::size_t(head)] / (point[std::size_t(tail)] + point[std::size_t(head)]);
    c.face = g;
    c.bary = {0, 0, 0};
    c.bary[std::size_t(i)] = s;
    c.bary[std::size_t(next(i))] = 1 - s;
    c.heading = (along * edge_g + across * perp(edge_g)).normalized();
    return std::nullopt;
}

/// A cursor at point b of an input face, heading along `toward` (a vector in the input face's
/// layout; may be zero). Found by walking from the corner of the face nearest the point.
Cursor IntrinsicTriangulation::Impl::cursor_in_input(std::uint32_t face, const Bary& b, const Vector2d& toward) const {
    const std::array<double, 3> l = face_lengths(*input, face);
    const std::array<Vector2d, 3> p = layout(l);
    const int i = int(std::max_element(b.begin(), b.end()) - b.begin());
    const std::uint32_t v = input->faces[face][std::size_t(i)];
    const Vector2d x = b[0] * p[0] + b[1] * p[1] + b[2] * p[2];
    const Vector2d offset = x - p[std::size_t(i)];
    const Vector2d first_side = p[std::size_t(next(i))] - p[std::size_t(i)];
    const double base = input_signpost[halfedge(face, i)];
    const double scale = std::max({l[0], l[1], l[2]});
    const bool has_heading = toward.norm() > 0;

    Cursor c;
    c.face = face_of(vertex_corner[v]);
    c.corner = index_of(vertex_corner[v]);
    c.bary = corner_point(c.corner);
    c.at_vertex = true;
    if (offset.norm() <= kLengthSnap * scale) {
        if (has_heading) c.angle = normalize_angle(v, base + signed_angle(first_side, toward));
        return c;
    }
    c.angle = normalize_angle(v, base + signed_angle(first_side, offset));
    c = walk(c, offset.norm(), nullptr, true).where;
    if (!has_heading) return c;
    const double turn = signed_angle(offset, toward);
    if (c.at_vertex) {
        const std::uint32_t w = mesh.faces[c.face][std::size_t(c.corner)];
        if (navigable[w]) c.angle = turn_at(w, c.angle, turn);
    } else {
        c.heading = rotate(c.heading, turn);
    }
    return c;
}

// ------------------------------------------------------------------------------------------
// Public interface

IntrinsicTriangulation::IntrinsicTriangulation(const Triangulation& input) : impl_(std::make_unique<Impl>(input)) {}
IntrinsicTriangulation::~IntrinsicTriangulation() = default;
IntrinsicTriangulation::IntrinsicTriangulation(IntrinsicTriangulation&&) noexcept = default;
IntrinsicTriangulation& IntrinsicTriangulation::operator=(IntrinsicTriangulation&&) noexcept = default;

const Triangulation& IntrinsicTriangulation::triangulation() const { return impl_->mesh; }

std::size_t IntrinsicTriangulation::flip_to_delaunay() {
    std::deque<std::uint32_t> queue;
    for (std::uint32_t e = 0; e < impl_->mesh.edge_count(); ++e) {
        impl_->queued[e] = 1;
        queue.push_back(e);
    }
    return impl_->flip_queued(queue, nullptr);
}

std::size_t IntrinsicTriangulation::refine(double min_angle_degrees, std::size_t max_new_vertices) {
    Impl& m = *impl_;
    flip_to_delaunay();
    const std::size_t budget = max_new_vertices ? max_new_vertices : m.input_vertex_count;
    const double target = min_angle_degrees * kPi / 180;
    if (!(target > 0)) return 0;
    // Worst face first; entries of faces rewritten since they were queued are stale.
    using Entry = std::tuple<double, std::uint32_t, std::uint32_t>;  // angle, face, version
    std::priority_queue<Entry, std::vector<Entry>, std::greater<>> bad;
    const auto consider = [&](std::uint32_t f) {
        if (m.refinable(f, target)) bad.emplace(m.smallest_angle(f, nullptr), f, m.face_version[f]);
    };
    for (std::uint32_t f = 0; f < m.mesh.face_count(); ++f) consider(f);

    std::size_t inserted = 0;
    std::vector<std::uint32_t> touched;
    std::deque<std::uint32_t> queue;
    while (!bad.empty() && inserted < budget) {
        const auto [angle, f, version] = bad.top();
        bad.pop();
        if (version != m.face_version[f]) continue;
        touched.clear();
        if (!m.insert_circumcenter(f, touched)) continue;
        ++inserted;
        for (std::uint32_t g : touched) m.queue_edges_of(g, queue);
        m.flip_queued(queue, &touched);
        // The point may have gone elsewhere (a boundary edge split instead): f is tried again.
        touched.push_back(f);
        std::sort(touched.begin(), touched.end());
        touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
        for (std::uint32_t g : touched) consider(g);
    }
    return inserted;
}

std::vector<FaceSegment> IntrinsicTriangulation::trace(const FaceSegment& s) const {
    const Impl& m = *impl_;
    if (s.face >= m.input_face_count) throw Error("intrinsic triangulation: trace: no input face " + std::to_string(s.face));
    const Bary a = normalized(s.a, "a segment's start"), b = normalized(s.b, "a segment's end");
    if (!m.rewritten[s.face]) return {FaceSegment{s.face, a, b}};
    const std::array<Vector2d, 3> p = layout(face_lengths(*m.input, s.face));
    const Vector2d xa = a[0] * p[0] + a[1] * p[1] + a[2] * p[2];
    const Vector2d xb = b[0] * p[0] + b[1] * p[1] + b[2] * p[2];
    const Vector2d step = xb - xa;
    const Cursor start = m.cursor_in_input(s.face, a, step);
    std::vector<FaceSegment> pieces;
    const WalkResult end = m.walk(start, step.norm(), &pieces, true);
    if (pieces.empty()) return {FaceSegment{end.where.face, end.where.bary, end.where.bary}};
    return pieces;
}

FacePoint IntrinsicTriangulation::locate(const FacePoint& p) const {
    const Impl& m = *impl_;
    if (p.face >= m.input_face_count) throw Error("intrinsic triangulation: locate: no input face " + std::to_string(p.face));
    const Bary b = normalized(p.bary, "a point");
    if (!m.rewritten[p.face]) return {p.face, b};
    const Cursor c = m.cursor_in_input(p.face, b, Vector2d::Zero());
    return {c.face, c.bary};
}

}  // namespace gsd::mesh
