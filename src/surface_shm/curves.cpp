// Curves on the input mesh → pieces inside faces. Consecutive nodes usually share a face (curve
// files are made that way); when they do not, the piece follows the shortest path between them
// within the strip of faces found by Dijkstra on the face graph (unfolded into the plane, the
// "funnel" algorithm), split where it crosses edges.
#include "surface_shm/curves.hpp"
#include "core/disjoint_sets.hpp"

#include "mesh/geometry.hpp"
#include "surface_shm/operators.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <numeric>
#include <optional>
#include <queue>
#include <string>
#include <unordered_map>

namespace gsd::surface_shm {

// The mesh module's types and geometry (src/mesh), which these methods are written over.
using namespace mesh;

namespace {

constexpr double kZero = 1e-12;  // barycentric weights this small are on the side/corner

// ---- canonical points -------------------------------------------------------------------

/// A surface point in its simplest form (an edge point at t = 0 is a vertex, a face point on a
/// side is an edge point), quantized so the same point reached two ways compares equal.
struct PointKey {
    std::uint8_t kind = 0;  // 0 vertex, 1 edge, 2 face
    std::uint32_t index = 0;
    long long qu = 0, qv = 0;
    auto operator<=>(const PointKey&) const = default;
};

long long quantize(double x) { return std::llround(x * 1e9); }

PointKey key_of(const Triangulation& T, const FacePoint& p) {
    const auto& b = p.bary;
    int zeros = 0, nonzero = 0, zero = 0;
    for (int k = 0; k < 3; ++k) {
        if (std::abs(b[std::size_t(k)]) <= kZero) {
            ++zeros;
            zero = k;
        } else {
            nonzero = k;
        }
    }
    if (zeros >= 2) return {0, T.faces[p.face][std::size_t(nonzero)], 0, 0};
    if (zeros == 1) {
        const int h = (zero + 1) % 3;  // the side opposite the zero corner
        const std::uint32_t e = T.face_edges[p.face][std::size_t(h)];
        const double t = T.aligned[p.face][std::size_t(h)] ? b[std::size_t((h + 1) % 3)] : b[std::size_t(h)];
        return {1, e, quantize(t), 0};
    }
    return {2, p.face, quantize(b[1]), quantize(b[2])};
}

// ---- where a point lies ------------------------------------------------------------------

/// Every (face, barycentric) holding a canonical surface point; non-degenerate faces first.
std::vector<FacePoint> holders(const Topology& t, const SurfacePoint& p) {
    const Triangulation& T = t.mesh;
    std::vector<FacePoint> out;
    switch (p.kind) {
        case SurfacePoint::Kind::Vertex:
            for (const std::uint32_t* c = t.vertex_corners.begin(p.index); c != t.vertex_corners.end(p.index); ++c) {
                FacePoint fp{corner_face(*c), {0, 0, 0}};
                fp.bary[std::size_t(corner_index(*c))] = 1;
                out.push_back(fp);
            }
            break;
        case SurfacePoint::Kind::Edge:
            for (const std::uint32_t* h = t.edge_halfedges.begin(p.index); h != t.edge_halfedges.end(p.index); ++h) {
                const std::uint32_t f = corner_face(*h);
                const int k = corner_index(*h);
                FacePoint fp{f, {0, 0, 0}};
                const bool al = T.aligned[f][std::size_t(k)];
                fp.bary[std::size_t(k)] = al ? 1 - p.u : p.u;
                fp.bary[std::size_t((k + 1) % 3)] = al ? p.u : 1 - p.u;
                out.push_back(fp);
            }
            break;
        case SurfacePoint::Kind::Face: out.push_back({p.index, {1 - p.u - p.v, p.u, p.v}}); break;
    }
    std::stable_partition(out.begin(), out.end(), [&](const FacePoint& fp) { return !t.degenerate(fp.face); });
    return out;
}

/// The simplest equivalent form of a point: edge ends become vertices, points on a triangle's
/// side become edge points, so that two forms of one point resolve alike.
SurfacePoint canonical(const Topology& t, const SurfacePoint& p) {
    const Triangulation& T = t.mesh;
    if (p.kind == SurfacePoint::Kind::Edge) {
        if (p.u <= kZero) return SurfacePoint::at_vertex(T.edges[p.index][0]);
        if (p.u >= 1 - kZero) return SurfacePoint::at_vertex(T.edges[p.index][1]);
    }
    if (p.kind == SurfacePoint::Kind::Face) {
        const PointKey k = key_of(T, {p.index, {1 - p.u - p.v, p.u, p.v}});
        if (k.kind == 0) return SurfacePoint::at_vertex(k.index);
        if (k.kind == 1) return SurfacePoint::on_edge(k.index, double(k.qu) * 1e-9);
    }
    return p;
}

std::array<double, 3> clean(std::array<double, 3> b) {
    for (double& x : b) x = std::abs(x) <= kZero ? 0.0 : std::max(0.0, x);
    const double s = b[0] + b[1] + b[2];
    if (s > 0)
        for (double& x : b) x /= s;
    return b;
}

// ---- shortest paths through faces ----------------------------------------------------------

Eigen::Vector3d point_in(const Topology& t, const FacePoint& p) {
    Eigen::Vector3d x = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) x += p.bary[std::size_t(k)] * t.corner_position(p.face, k);
    return x;
}

Eigen::Vector3d centroid(const Topology& t, std::size_t f) {
    return (t.corner_position(f, 0) + t.corner_position(f, 1) + t.corner_position(f, 2)) / 3.0;
}

/// Faces from one holding `from` to one holding `to`, joined through shared edges (Dijkstra on
/// face centroids, non-degenerate faces only). Empty if there is none.
std::vector<std::uint32_t> face_strip(const Topology& t, const std::vector<FacePoint>& from,
                                      const std::vector<FacePoint>& to) {
    // A* over face centroids, guided by the straight distance to the target point. Only the
    // faces it reaches are stored, so short pieces on big meshes cost little; the strip needs
    // to be good, not shortest — the funnel and the rerouting straighten the path inside it.
    const Triangulation& T = t.mesh;
    const Eigen::Vector3d goal = point_in(t, to.front());
    std::unordered_map<std::uint32_t, std::pair<double, std::uint32_t>> best;  // face → (distance, previous)
    std::unordered_map<std::uint32_t, bool> target;
    for (const FacePoint& q : to) target[q.face] = true;
    using Item = std::pair<double, std::uint32_t>;  // (distance + heuristic, face)
    std::priority_queue<Item, std::vector<Item>, std::greater<>> heap;
    auto relax = [&](std::uint32_t f, double d, std::uint32_t previous) {
        auto [it, inserted] = best.try_emplace(f, d, previous);
        if (!inserted && d >= it->second.first) return;
        it->second = {d, previous};
        heap.push({d + (centroid(t, f) - goal).norm(), f});
    };
    for (const FacePoint& p : from)
        if (!t.degenerate(p.face)) relax(p.face, (point_in(t, p) - centroid(t, p.face)).norm(), UINT32_MAX);
    while (!heap.empty()) {
        const std::uint32_t f = heap.top().second;
        const double d = best[f].first;
        if (heap.top().first > d + (centroid(t, f) - goal).norm() + 1e-12 * (1 + d)) {
            heap.pop();  // a stale entry
            continue;
        }
        heap.pop();
        if (target.count(f)) {
            std::vector<std::uint32_t> strip;
            for (std::uint32_t g = f; g != UINT32_MAX; g = best[g].second) strip.push_back(g);
            std::reverse(strip.begin(), strip.end());
            return strip;
        }
        const Eigen::Vector3d cf = centroid(t, f);
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t e = T.face_edges[f][std::size_t(k)];
            for (const std::uint32_t* h = t.edge_halfedges.begin(e); h != t.edge_halfedges.end(e); ++h) {
                const std::uint32_t g = corner_face(*h);
                if (g != f && !t.degenerate(g)) relax(g, d + (centroid(t, g) - cf).norm(), f);
            }
        }
    }
    return {};
}

/// The strip unfolded into the plane: each face's three corners in 2D, consecutive faces
/// sharing the portal edge between them.
struct Unfolding {
    std::vector<std::array<Eigen::Vector2d, 3>> corners;
    std::vector<std::array<int, 2>> portal;  // portal j (faces j, j+1): local corners (in face j) of its ends
};

/// Local side (halfedge) of face f on the edge it shares with face g.
int shared_side(const Triangulation& T, std::uint32_t f, std::uint32_t g) {
    for (int k = 0; k < 3; ++k)
        for (int j = 0; j < 3; ++j)
            if (T.face_edges[f][std::size_t(k)] == T.face_edges[g][std::size_t(j)]) return k;
    return -1;
}

double cross2(const Eigen::Vector2d& u, const Eigen::Vector2d& v) { return u.x() * v.y() - u.y() * v.x(); }

Eigen::Vector2d place_third(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double la, double lb, bool left) {
    // The point at distance la from a and lb from b, on the chosen side of a → b.
    const double d = (b - a).norm();
    const double x = (la * la - lb * lb + d * d) / (2 * d);
    const double y = std::sqrt(std::max(0.0, la * la - x * x));
    const Eigen::Vector2d u = (b - a) / d;
    const Eigen::Vector2d n(-u.y(), u.x());
    return a + x * u + (left ? y : -y) * n;
}

Unfolding unfold(const Topology& t, const std::vector<std::uint32_t>& strip) {
    const Triangulation& T = t.mesh;
    Unfolding U;
    U.corners.resize(strip.size());
    U.corners[0] = layout(face_lengths(T, strip[0]));
    for (std::size_t j = 0; j + 1 < strip.size(); ++j) {
        const std::uint32_t f = strip[j], g = strip[j + 1];
        const int kf = shared_side(T, f, g), kg = shared_side(T, g, f);
        const int fa = kf, fb = (kf + 1) % 3;
        const Eigen::Vector2d A = U.corners[j][std::size_t(fa)], B = U.corners[j][std::size_t(fb)];
        // g's halfedge kg runs ga → gb along the same edge; it runs the same way as f's halfedge
        // exactly when both agree with the edge's direction (faces may disagree on orientation).
        const int ga = kg, gb = (kg + 1) % 3, gc = (kg + 2) % 3;
        const bool same_way = T.aligned[f][std::size_t(kf)] == T.aligned[g][std::size_t(kg)];
        std::array<Eigen::Vector2d, 3> c{};
        c[std::size_t(ga)] = same_way ? A : B;
        c[std::size_t(gb)] = same_way ? B : A;
        // g's third corner: |gc − ga| is halfedge gc (gc → ga), |gc − gb| is halfedge gb (gb → gc);
        // it lies across the shared edge from f's third corner.
        const double to_ga = T.length(g, gc), to_gb = T.length(g, gb);
        const double to_A = same_way ? to_ga : to_gb, to_B = same_way ? to_gb : to_ga;
        const Eigen::Vector2d third_f = U.corners[j][std::size_t((kf + 2) % 3)];
        const bool f_left = cross2(B - A, third_f - A) > 0;
        c[std::size_t(gc)] = place_third(A, B, to_A, to_B, !f_left);
        U.corners[j + 1] = c;
        U.portal.push_back({fa, fb});
    }
    return U;
}

Eigen::Vector2d at(const std::array<Eigen::Vector2d, 3>& c, const std::array<double, 3>& b) {
    return b[0] * c[0] + b[1] * c[1] + b[2] * c[2];
}

std::array<double, 3> bary_of(const std::array<Eigen::Vector2d, 3>& c, const Eigen::Vector2d& x) {
    const double area = cross2(c[1] - c[0], c[2] - c[0]);
    std::array<double, 3> b{cross2(c[1] - x, c[2] - x) / area, cross2(c[2] - x, c[0] - x) / area,
                            cross2(c[0] - x, c[1] - x) / area};
    return clean(b);
}

/// A point of the shortest path: its 2D position, and the last strip face it belongs to
/// (−1 for the start: it lies in face 0; portal index j: it is an end of portal j).
struct PathPoint {
    Eigen::Vector2d x;
    int portal;
};

/// Shortest path from s (in face 0) to e (in the last face) inside the unfolded strip: the
/// "simple stupid funnel" over the portals, each oriented left/right as seen walking the strip.
std::vector<PathPoint> funnel(const Unfolding& U, const Eigen::Vector2d& s, const Eigen::Vector2d& e) {
    const std::size_t n = U.portal.size();
    std::vector<Eigen::Vector2d> left(n + 1), right(n + 1);
    for (std::size_t j = 0; j < n; ++j) {
        Eigen::Vector2d a = U.corners[j][std::size_t(U.portal[j][0])], b = U.corners[j][std::size_t(U.portal[j][1])];
        // Orient so that, walking from face j into face j+1, `left` is on the left.
        const Eigen::Vector2d third = U.corners[j][std::size_t(3 - U.portal[j][0] - U.portal[j][1])];
        if (cross2(b - a, third - a) < 0) std::swap(a, b);  // face j (behind) must lie left of a→b
        left[j] = b;
        right[j] = a;
    }
    left[n] = right[n] = e;
    std::vector<PathPoint> path{{s, -1}};
    Eigen::Vector2d apex = s, fl = s, fr = s;
    int ia = -1, il = -1, ir = -1;
    for (int j = 0; j <= int(n); ++j) {
        const Eigen::Vector2d l = left[std::size_t(j)], r = right[std::size_t(j)];
        // Tighten the right side.
        if (cross2(fr - apex, r - apex) >= 0) {  // r is not to the right of the funnel's right edge
            if (apex == fr || cross2(fl - apex, r - apex) < 0) {
                fr = r;
                ir = j;
            } else {  // r crosses the left edge: the left point becomes an apex
                if (fl != path.back().x) path.push_back({fl, il});
                apex = fl;
                ia = il;
                fr = fl = apex;
                ir = il = ia;
                j = ia;
                continue;
            }
        }
        if (cross2(fl - apex, l - apex) <= 0) {
            if (apex == fl || cross2(fr - apex, l - apex) > 0) {
                fl = l;
                il = j;
            } else {
                if (fr != path.back().x) path.push_back({fr, ir});
                apex = fr;
                ia = ir;
                fr = fl = apex;
                ir = il = ia;
                j = ia;
                continue;
            }
        }
    }
    if (path.back().x == e && path.size() > 1) path.back().portal = int(n);  // the end became an apex
    else path.push_back({e, int(n)});
    return path;
}

/// Intersection parameter of segment p→q with line a→b (as the weight along a→b), clamped.
double portal_crossing(const Eigen::Vector2d& p, const Eigen::Vector2d& q, const Eigen::Vector2d& a,
                       const Eigen::Vector2d& b) {
    const Eigen::Vector2d d = q - p, w = b - a;
    if (std::abs(cross2(w, d)) < 1e-300) return 0.5;
    return std::clamp(cross2(p - a, d) / cross2(w, d), 0.0, 1.0);
}

bool contains(const Triangulation& T, std::uint32_t f, std::uint32_t v) {
    return T.faces[f][0] == v || T.faces[f][1] == v || T.faces[f][2] == v;
}

/// The faces around v from `from` to `to` going the way that does not pass `away` (the next
/// face of the strip after `from`), both ends excluded; empty if the fan is not a clean disk.
std::optional<std::vector<std::uint32_t>> other_way_around(const Topology& t, std::uint32_t v, std::uint32_t from,
                                                           std::uint32_t away, std::uint32_t to) {
    const Triangulation& T = t.mesh;
    std::vector<std::uint32_t> arc;
    // The edge at v that `from` shares with `away`: leave through the other one.
    std::uint32_t g = from, skip = T.face_edges[from][std::size_t(shared_side(T, from, away))];
    for (int step = 0; step < 256; ++step) {
        int c = 0;
        while (c < 3 && T.faces[g][std::size_t(c)] != v) ++c;
        if (c == 3) return std::nullopt;
        const std::uint32_t e1 = T.face_edges[g][std::size_t(c)], e2 = T.face_edges[g][std::size_t((c + 2) % 3)];
        const std::uint32_t out = e1 == skip ? e2 : e1;
        if (t.edge_halfedges.count(out) != 2) return std::nullopt;
        const std::uint32_t* h = t.edge_halfedges.begin(out);
        const std::uint32_t next = corner_face(h[0]) == g ? corner_face(h[1]) : corner_face(h[0]);
        if (next == to) return arc;
        if (next == from || t.degenerate(next)) return std::nullopt;
        arc.push_back(next);
        g = next;
        skip = out;
    }
    return std::nullopt;
}

/// One pass of strip improvement: at every bend of the path around a vertex v where the angle
/// on v's other side is below π (so going around that side is shorter), the strip's faces
/// around v are replaced by the faces on the other side. Bends are handled last to first so
/// that strip indices before them stay valid. False if nothing changed: the path is then a
/// geodesic (or the remaining bends sit at vertices whose fans are not clean disks).
bool reroute(const Topology& t, std::vector<std::uint32_t>& strip, const Unfolding& U, const std::vector<PathPoint>& path) {
    const Triangulation& T = t.mesh;
    bool changed = false;
    std::size_t limit = strip.size();  // runs must end before the previous (later) reroute
    for (std::size_t k = path.size() - 1; k-- > 1;) {
        const int j = path[k].portal;
        if (j < 0 || std::size_t(j) + 1 >= limit) continue;
        const auto& corners = U.corners[std::size_t(j)];
        const int local = corners[std::size_t(U.portal[std::size_t(j)][0])] == path[k].x ? U.portal[std::size_t(j)][0]
                                                                                          : U.portal[std::size_t(j)][1];
        const std::uint32_t v = T.faces[strip[std::size_t(j)]][std::size_t(local)];
        double total = 0;  // the angle around v
        for (const std::uint32_t* c = t.vertex_corners.begin(v); c != t.vertex_corners.end(v); ++c)
            total += corner_angle(face_lengths(T, corner_face(*c)), corner_index(*c));
        const Eigen::Vector2d u = path[k - 1].x - path[k].x, w = path[k + 1].x - path[k].x;
        const double bend = std::atan2(std::abs(cross2(u, w)), u.dot(w));  // angle on the free side, ≤ π
        if (total - 2 * std::numbers::pi + bend >= std::numbers::pi - 1e-9) continue;
        std::size_t s = std::size_t(j), e = std::size_t(j + 1);
        while (s > 0 && contains(T, strip[s - 1], v)) --s;
        while (e + 1 < limit && contains(T, strip[e + 1], v)) ++e;
        const auto arc = other_way_around(t, v, strip[s], strip[s + 1], strip[e]);
        if (!arc) continue;
        std::vector<std::uint32_t> rerouted(strip.begin(), strip.begin() + std::ptrdiff_t(s + 1));
        rerouted.insert(rerouted.end(), arc->begin(), arc->end());
        rerouted.insert(rerouted.end(), strip.begin() + std::ptrdiff_t(e), strip.end());
        if (rerouted == strip) continue;
        strip = std::move(rerouted);
        changed = true;
        limit = s;
    }
    return changed;
}

// ---- the resolver ------------------------------------------------------------------------

class Resolver {
public:
    Resolver(const Topology& t, const std::string& where) : t_(t), where_(where) {}

    void add_curve(const SurfaceCurve& c, std::size_t index) {
        for (std::size_t i = 0; i + 1 < c.nodes.size(); ++i) add_segment(c.nodes[i], c.nodes[i + 1], c.is_signed, index, i);
    }

    void add_point(const SurfacePoint& p) { out_.points.push_back(face_point(t_, p)); }

    ResolvedSources finish();

private:
    void add_piece(const FaceSegment& s, bool is_signed) {
        CurvePiece c;
        c.segment = s;
        c.segment.a = clean(s.a);
        c.segment.b = clean(s.b);
        c.is_signed = is_signed;
        if (key_of(t_.mesh, {s.face, c.segment.a}) == key_of(t_.mesh, {s.face, c.segment.b})) return;  // no length
        out_.pieces.push_back(c);
    }

    void add_segment(const SurfacePoint& p0, const SurfacePoint& q0, bool is_signed, std::size_t curve, std::size_t i);
    void add_path(const std::vector<FacePoint>& P, const std::vector<FacePoint>& Q, bool is_signed, std::size_t curve,
                  std::size_t i);

    const Topology& t_;
    const std::string& where_;
    ResolvedSources out_;
};

void Resolver::add_segment(const SurfacePoint& p0, const SurfacePoint& q0, bool is_signed, std::size_t curve,
                           std::size_t i) {
    const SurfacePoint p = canonical(t_, p0), q = canonical(t_, q0);
    const std::vector<FacePoint> P = holders(t_, p), Q = holders(t_, q);
    // Prefer a shared non-degenerate face; both on one edge counts (any face of the edge).
    for (int pass = 0; pass < 2; ++pass)
        for (const FacePoint& a : P)
            for (const FacePoint& b : Q)
                if (a.face == b.face && (pass == 1 || !t_.degenerate(a.face))) {
                    add_piece({a.face, a.bary, b.bary}, is_signed);
                    return;
                }
    add_path(P, Q, is_signed, curve, i);
}

void Resolver::add_path(const std::vector<FacePoint>& P, const std::vector<FacePoint>& Q, bool is_signed,
                        std::size_t curve, std::size_t i) {
    std::vector<std::uint32_t> strip = face_strip(t_, P, Q);
    if (strip.empty())
        throw Error(where_, "curve " + std::to_string(curve + 1) + ", segment " + std::to_string(i + 1) +
                                ": its ends share no face and no path joins them on the mesh");
    auto in_face = [](const std::vector<FacePoint>& list, std::uint32_t f) {
        for (const FacePoint& x : list)
            if (x.face == f) return x;
        return list.front();
    };
    const FacePoint ps = in_face(P, strip.front()), qs = in_face(Q, strip.back());
    // The shortest path inside the first strip may bend around a vertex that the true geodesic
    // passes on its other side: reroute the strip there until no bend can be shortened.
    Unfolding U;
    std::vector<PathPoint> path;
    for (int round = 0;; ++round) {
        U = unfold(t_, strip);
        path = funnel(U, at(U.corners.front(), ps.bary), at(U.corners.back(), qs.bary));
        if (round == 1000 || !reroute(t_, strip, U, path)) break;
    }
    // Each straight section between path points crosses the portals strictly between them.
    for (std::size_t k = 0; k + 1 < path.size(); ++k) {
        const PathPoint& a = path[k];
        const PathPoint& b = path[k + 1];
        Eigen::Vector2d from = a.x;
        std::size_t face = std::size_t(a.portal + 1);
        for (int j = a.portal + 1; j < b.portal; ++j) {
            const auto& c = U.corners[std::size_t(j)];
            const Eigen::Vector2d pa = c[std::size_t(U.portal[std::size_t(j)][0])];
            const Eigen::Vector2d pb = c[std::size_t(U.portal[std::size_t(j)][1])];
            const double w = portal_crossing(a.x, b.x, pa, pb);
            const Eigen::Vector2d x = (1 - w) * pa + w * pb;
            add_piece({strip[face], bary_of(c, from), bary_of(c, x)}, is_signed);
            from = x;
            face = std::size_t(j + 1);
        }
        const std::size_t last = std::min<std::size_t>(face, strip.size() - 1);
        add_piece({strip[last], bary_of(U.corners[last], from), bary_of(U.corners[last], b.x)}, is_signed);
    }
}

ResolvedSources Resolver::finish() {
    const Triangulation& T = t_.mesh;
    // Components: union–find over the canonical keys of the piece ends.
    std::map<PointKey, std::uint32_t> ids;
    detail::DisjointSets components;
    auto id_of = [&](const PointKey& k) {
        auto [it, inserted] = ids.try_emplace(k, std::uint32_t(components.size()));
        if (inserted) components.add();
        return it->second;
    };
    std::vector<std::array<std::uint32_t, 2>> ends(out_.pieces.size());
    std::map<std::uint32_t, int> unsigned_degree;
    for (std::size_t i = 0; i < out_.pieces.size(); ++i) {
        const CurvePiece& c = out_.pieces[i];
        ends[i] = {id_of(key_of(T, {c.segment.face, c.segment.a})), id_of(key_of(T, {c.segment.face, c.segment.b}))};
        components.join(ends[i][0], ends[i][1]);
        if (!c.is_signed) {
            ++unsigned_degree[ends[i][0]];
            ++unsigned_degree[ends[i][1]];
        }
    }
    std::map<std::uint32_t, std::uint32_t> component;
    for (std::size_t i = 0; i < out_.pieces.size(); ++i) {
        CurvePiece& c = out_.pieces[i];
        c.component = component.try_emplace(components.find(ends[i][0]), std::uint32_t(component.size())).first->second;
        if (!c.is_signed) {
            c.open_a = unsigned_degree[ends[i][0]] == 1;
            c.open_b = unsigned_degree[ends[i][1]] == 1;
        }
    }
    // Constraint nodes: each distinct piece end once, then the isolated points.
    std::vector<std::uint8_t> seen(components.size(), 0);
    for (std::size_t i = 0; i < out_.pieces.size(); ++i)
        for (int s = 0; s < 2; ++s) {
            if (seen[ends[i][std::size_t(s)]]) continue;
            seen[ends[i][std::size_t(s)]] = 1;
            const CurvePiece& c = out_.pieces[i];
            out_.nodes.push_back({c.segment.face, s == 0 ? c.segment.a : c.segment.b});
            out_.node_components.push_back(c.component);
        }
    out_.component_count = std::uint32_t(component.size());
    for (const FacePoint& p : out_.points) {
        out_.nodes.push_back(p);
        out_.node_components.push_back(out_.component_count++);
    }
    return std::move(out_);
}

}  // namespace

int piece_side(const FaceSegment& s) {
    for (int k = 0; k < 3; ++k)
        if (std::abs(s.a[std::size_t(k)]) <= kZero && std::abs(s.b[std::size_t(k)]) <= kZero) return (k + 1) % 3;
    return -1;
}

FacePoint face_point(const Topology& t, const SurfacePoint& p) {
    const std::vector<FacePoint> h = holders(t, canonical(t, p));
    if (h.empty()) throw Error("a source point lies on a vertex that no face uses");
    FacePoint f = h.front();
    f.bary = clean(f.bary);
    return f;
}

ResolvedSources resolve_sources(const Topology& t, const SurfaceSources& sources, const std::string& where) {
    Resolver r(t, where);
    for (std::size_t c = 0; c < sources.curves.size(); ++c) r.add_curve(sources.curves[c], c);
    for (const SurfacePoint& p : sources.points) r.add_point(p);
    return r.finish();
}

}  // namespace gsd::surface_shm

namespace gsd {

Polylines source_polylines(const SurfaceMesh& mesh, const SurfaceSources& sources) {
    const mesh::Topology& t = mesh.topology();
    auto at = [&](const mesh::FacePoint& p) {
        Eigen::Vector3d x = Eigen::Vector3d::Zero();
        for (int k = 0; k < 3; ++k) x += p.bary[std::size_t(k)] * t.corner_position(p.face, k);
        return x;
    };
    Polylines out;
    for (const SurfaceCurve& c : sources.curves) {
        SurfaceSources one;
        one.curves.push_back(c);
        const surface_shm::ResolvedSources r = surface_shm::resolve_sources(t, one, "curve");
        std::vector<Eigen::Vector3d> line;
        for (const surface_shm::CurvePiece& p : r.pieces) {
            const Eigen::Vector3d a = at({p.segment.face, p.segment.a}), b = at({p.segment.face, p.segment.b});
            // Pieces come in curve order; a gap (a skipped zero-length piece aside) starts a new line.
            if (!line.empty() && (line.back() - a).norm() > 1e-12 * (1 + a.norm())) {
                out.push_back(std::move(line));
                line.clear();
            }
            if (line.empty()) line.push_back(a);
            line.push_back(b);
        }
        if (!line.empty()) out.push_back(std::move(line));
    }
    for (const SurfacePoint& p : sources.points) out.push_back({position(mesh, p)});
    return out;
}

}  // namespace gsd
