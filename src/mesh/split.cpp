// Cutting a mesh along curve pieces (see split.hpp), in three stages (~950 lines: one pipeline
// whose stages share its snapping tolerances; the exact predicates are in predicates.hpp, the
// constrained Delaunay triangulation in delaunay.hpp):
//   1. every piece end is classified — an input vertex, a point on an input edge, or a point
//      inside its triangle — snapping within the tolerance;
//   2. the points on each edge are merged and numbered once, for every triangle on that edge
//      (that is what keeps the new mesh conforming, also across nonmanifold edges);
//   3. every triangle with pieces or side points is re-triangulated in its planar layout: its
//      pieces are cut at their crossings (an arrangement with snapping), then a constrained
//      Delaunay triangulation is built with exact orientation tests. Other triangles are copied.
#include "mesh/split.hpp"
#include "mesh/delaunay.hpp"
#include "mesh/predicates.hpp"

#include "mesh/geometry.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <unordered_map>

namespace gsd::mesh {

namespace {

constexpr std::uint32_t kNone = UINT32_MAX;
constexpr double kTol = kSplitTolerance;
/// × the tolerance: how far new points and triangle heights must stay above zero so that
/// rounded 3D positions keep every orientation (1e-12 of a triangle's size, 10⁴ × rounding).
constexpr double kClearance = 1e-3;

// ---- stage 1: piece ends -----------------------------------------------------------------------

/// A point asked for on an input edge, at parameter t along the edge's direction.
struct EdgeRequest {
    std::uint32_t edge;
    double t;
};

/// Where a piece end lies, after snapping.
struct End {
    enum class Kind : std::uint8_t { Vertex, Edge, Inside };
    Kind kind = Kind::Vertex;
    std::uint32_t index = 0;          // Vertex: the input vertex; Edge: its request
    std::array<double, 3> bary{};     // Inside: weights in the piece's triangle
    std::array<bool, 3> zero{};       // corner k's weight is 0: the end is on the side opposite k
};

/// A piece's ends; `side` is the halfedge it runs along (−1: through the inside).
struct PieceEnds {
    End a, b;
    int side = -1;
    bool empty = false;
};

std::array<double, 3> cleaned(std::array<double, 3> b, std::size_t piece) {
    for (double& x : b) {
        if (!std::isfinite(x)) throw Error("split_along", "piece " + std::to_string(piece) + ": non-finite coordinate");
        x = std::max(x, 0.0);
    }
    const double s = b[0] + b[1] + b[2];
    if (!(s > 0)) throw Error("split_along", "piece " + std::to_string(piece) + ": barycentric weights all zero");
    for (double& x : b) x /= s;
    return b;
}

Eigen::Vector3d point_in(const Topology& t, std::uint32_t f, const std::array<double, 3>& b) {
    return b[0] * t.corner_position(f, 0) + b[1] * t.corner_position(f, 1) + b[2] * t.corner_position(f, 2);
}

int largest(const std::array<double, 3>& x) { return int(std::max_element(x.begin(), x.end()) - x.begin()); }

/// Classifies piece ends, collecting the points they put on edges.
class EndClassifier {
public:
    EndClassifier(const Topology& t, std::vector<EdgeRequest>& requests) : t_(t), requests_(requests) {}
    End classify(std::uint32_t f, const std::array<double, 3>& b);

private:
    End corner(std::uint32_t f, int k) const;
    End on_side(std::uint32_t f, int h, double s, double tol);
    End classify_flat(std::uint32_t f, const std::array<double, 3>& b);

    const Topology& t_;
    std::vector<EdgeRequest>& requests_;
};

End EndClassifier::corner(std::uint32_t f, int k) const {
    End e;
    e.index = t_.mesh.faces[f][std::size_t(k)];
    for (int j = 0; j < 3; ++j) e.zero[std::size_t(j)] = j != k;
    return e;
}

End EndClassifier::on_side(std::uint32_t f, int h, double s, double tol) {
    // s: from corner h towards corner h+1 along halfedge h.
    const double len = t_.mesh.length(f, h);
    if (s * len <= tol) return corner(f, h);
    if ((1 - s) * len <= tol) return corner(f, (h + 1) % 3);
    End e;
    e.kind = End::Kind::Edge;
    e.index = std::uint32_t(requests_.size());
    e.zero[std::size_t((h + 2) % 3)] = true;
    requests_.push_back({t_.mesh.face_edges[f][std::size_t(h)], t_.mesh.aligned[f][std::size_t(h)] ? s : 1 - s});
    return e;
}

End EndClassifier::classify(std::uint32_t f, const std::array<double, 3>& b) {
    if (t_.degenerate(f)) return classify_flat(f, b);
    const auto l = face_lengths(t_.mesh, f);
    const double tol = kTol * std::max({l[0], l[1], l[2]});
    const auto c = layout(l);
    const Vec2 x = b[0] * c[0] + b[1] * c[1] + b[2] * c[2];
    // Distances, not weights: in a sliver a point can be near two sides and far from their corner.
    int nearest = -1;
    double best = tol;
    for (int k = 0; k < 3; ++k)
        if ((x - c[std::size_t(k)]).norm() <= best) {
            best = (x - c[std::size_t(k)]).norm();
            nearest = k;
        }
    if (nearest >= 0) return corner(f, nearest);
    best = tol;
    for (int k = 0; k < 3; ++k) {
        const double d = b[std::size_t(k)] * 2 * t_.face_areas[f] / l[std::size_t((k + 1) % 3)];  // to the side opposite k
        if (d <= best) {
            best = d;
            nearest = k;
        }
    }
    if (nearest < 0) {
        End e;
        e.kind = End::Kind::Inside;
        e.bary = b;
        return e;
    }
    // Onto the side opposite `nearest`, exactly where the weights say if it is on it already.
    const int h = (nearest + 1) % 3;
    const std::size_t i = std::size_t(h), j = std::size_t((h + 1) % 3);
    const Vec2 d = c[j] - c[i];
    const double s = b[std::size_t(nearest)] == 0 ? b[j] / (b[i] + b[j])
                                                   : std::clamp((x - c[i]).dot(d) / d.squaredNorm(), 0.0, 1.0);
    return on_side(f, h, s, tol);
}

End EndClassifier::classify_flat(std::uint32_t f, const std::array<double, 3>& b) {
    // A flat triangle is a segment (or a point): a point inside it lies on its longest side.
    const auto l = face_lengths(t_.mesh, f);
    const double tol = kTol * std::max({l[0], l[1], l[2]});
    const Eigen::Vector3d x = point_in(t_, f, b);
    for (int k = 0; k < 3; ++k)
        if ((x - t_.corner_position(f, k)).norm() <= tol) return corner(f, k);
    for (int k = 0; k < 3; ++k)
        if (b[std::size_t(k)] <= kTol) {
            const std::size_t i = std::size_t((k + 1) % 3), j = std::size_t((k + 2) % 3);
            return on_side(f, int(i), b[j] / (b[i] + b[j]), tol);
        }
    const int h = largest(l);
    const Eigen::Vector3d p = t_.corner_position(f, h), q = t_.corner_position(f, (h + 1) % 3);
    const double len2 = (q - p).squaredNorm();
    return on_side(f, h, len2 > 0 ? std::clamp((x - p).dot(q - p) / len2, 0.0, 1.0) : 0.0, tol);
}

std::vector<PieceEnds> classify_pieces(const Topology& t, const std::vector<FaceSegment>& pieces,
                                       std::vector<EdgeRequest>& requests) {
    EndClassifier classifier(t, requests);
    std::vector<PieceEnds> out(pieces.size());
    for (std::size_t i = 0; i < pieces.size(); ++i) {
        const FaceSegment& s = pieces[i];
        if (s.face >= t.mesh.face_count())
            throw Error("split_along",
                        "piece " + std::to_string(i) + ": triangle " + std::to_string(s.face) + " out of range");
        const auto a = cleaned(s.a, i), b = cleaned(s.b, i);
        const auto l = face_lengths(t.mesh, s.face);
        // Too short to matter: no path, and no points put on edges for it.
        if ((point_in(t, s.face, a) - point_in(t, s.face, b)).norm() <= kTol * std::max({l[0], l[1], l[2]})) {
            out[i].empty = true;
            continue;
        }
        PieceEnds& e = out[i];
        e.a = classifier.classify(s.face, a);
        e.b = classifier.classify(s.face, b);
        for (int k = 0; k < 3; ++k)
            if (e.a.zero[std::size_t(k)] && e.b.zero[std::size_t(k)]) e.side = (k + 1) % 3;
    }
    return out;
}

// ---- stage 2: points on edges ------------------------------------------------------------------

/// The merged points on every edge, numbered after the input vertices in (edge, t) order.
struct EdgePoints {
    std::vector<std::uint32_t> offsets;  // per edge: its points' range in `vertex` and `t`
    std::vector<std::uint32_t> vertex;
    std::vector<double> t;
    std::vector<std::uint32_t> request_vertex;  // per request: the vertex it became
    std::vector<std::uint32_t> request_rank;    // per request: 0 first end, i + 1 point i, count + 1 second end

    std::uint32_t count(std::size_t e) const { return offsets[e + 1] - offsets[e]; }
    /// The vertex at a rank along edge e (ends included).
    std::uint32_t at_rank(const Triangulation& T, std::size_t e, std::uint32_t r) const {
        if (r == 0) return T.edges[e][0];
        if (r == count(e) + 1) return T.edges[e][1];
        return vertex[offsets[e] + r - 1];
    }
};

/// One edge's requests (sorted by t) merged into points: within the tolerance of an end they
/// are that end, within the tolerance of the first point of a run they join the run.
void merge_on_edge(const Topology& t, std::uint32_t e, const std::uint32_t* first, const std::uint32_t* last,
                   const std::vector<EdgeRequest>& requests, EdgePoints& ep) {
    const std::uint32_t base = t.mesh.vertex_count;
    const bool has_length = t.mesh.edge_lengths[e] > 0;  // on a zero-length edge only the ends exist
    const std::uint32_t begin = std::uint32_t(ep.vertex.size());
    double run_start = 0;
    std::vector<std::uint32_t> at_second_end;
    for (const std::uint32_t* r = first; r != last; ++r) {
        const double x = requests[*r].t;
        if (has_length ? x <= kTol : x < 0.5) {
            ep.request_vertex[*r] = t.mesh.edges[e][0];
            ep.request_rank[*r] = 0;
        } else if (!has_length || x >= 1 - kTol) {
            ep.request_vertex[*r] = t.mesh.edges[e][1];
            at_second_end.push_back(*r);
        } else {
            if (ep.vertex.size() == begin || x - run_start > kTol) {
                run_start = x;
                ep.vertex.push_back(base + std::uint32_t(ep.vertex.size()));
                ep.t.push_back(x);
            }
            ep.t.back() = 0.5 * (run_start + x);  // the middle of the run
            ep.request_vertex[*r] = ep.vertex.back();
            ep.request_rank[*r] = std::uint32_t(ep.vertex.size()) - begin;
        }
    }
    const std::uint32_t n = std::uint32_t(ep.vertex.size()) - begin;
    for (std::uint32_t r : at_second_end) ep.request_rank[r] = n + 1;
    ep.offsets[e + 1] = n;
}

EdgePoints merge_edge_points(const Topology& t, const std::vector<EdgeRequest>& requests) {
    std::vector<std::uint32_t> order(requests.size());
    std::iota(order.begin(), order.end(), 0u);
    std::sort(order.begin(), order.end(), [&](std::uint32_t x, std::uint32_t y) {
        const EdgeRequest &a = requests[x], &b = requests[y];
        return a.edge != b.edge ? a.edge < b.edge : a.t < b.t;
    });
    EdgePoints ep;
    ep.offsets.assign(t.mesh.edge_count() + 1, 0);
    ep.request_vertex.resize(requests.size());
    ep.request_rank.resize(requests.size());
    for (std::size_t i = 0; i < order.size();) {
        std::size_t j = i;
        while (j < order.size() && requests[order[j]].edge == requests[order[i]].edge) ++j;
        merge_on_edge(t, requests[order[i]].edge, order.data() + i, order.data() + j, requests, ep);
        i = j;
    }
    std::partial_sum(ep.offsets.begin(), ep.offsets.end(), ep.offsets.begin());
    return ep;
}

/// The rank along edge e of a piece end lying on it.
std::uint32_t rank_on_edge(const Topology& t, const EdgePoints& ep, std::uint32_t e, const End& end) {
    if (end.kind == End::Kind::Edge) return ep.request_rank[end.index];
    return end.index == t.mesh.edges[e][0] ? 0 : ep.count(e) + 1;
}

/// A piece along edge e: the points of that edge from one end to the other.
std::vector<std::uint32_t> edge_path(const Topology& t, const EdgePoints& ep, std::uint32_t e, const PieceEnds& p) {
    const std::uint32_t ra = rank_on_edge(t, ep, e, p.a), rb = rank_on_edge(t, ep, e, p.b);
    std::vector<std::uint32_t> path;
    if (ra == rb) return path;
    for (std::uint32_t r = ra;; r = ra < rb ? r + 1 : r - 1) {
        path.push_back(ep.at_rank(t.mesh, e, r));
        if (r == rb) break;
    }
    return path;
}

// ---- stage 3: one triangle in the plane ------------------------------------------------------------

/// Interior points of one triangle, for merging points closer than the tolerance: a scan while
/// there are few, a grid of tolerance-sized cells beyond that.
class PointIndex {
public:
    void reset(double tol) {
        tol_ = tol;
        ids_.clear();
        if (gridded_) grid_.clear();
        gridded_ = false;
    }

    /// The nearest indexed point within the tolerance of x, or kNone.
    std::uint32_t find(const std::vector<Vec2>& pos, const Vec2& x) const {
        std::uint32_t best = kNone;
        double best_d = tol_;
        auto consider = [&](std::uint32_t id) {
            const double d = (pos[id] - x).norm();
            if (d <= best_d) {
                best_d = d;
                best = id;
            }
        };
        if (!gridded_) {
            for (std::uint32_t id : ids_) consider(id);
            return best;
        }
        const long long i = cell(x.x()), j = cell(x.y());
        for (long long di = -1; di <= 1; ++di)
            for (long long dj = -1; dj <= 1; ++dj) {
                const auto [lo, hi] = grid_.equal_range(key(i + di, j + dj));
                for (auto it = lo; it != hi; ++it) consider(it->second);
            }
        return best;
    }

    void add(const std::vector<Vec2>& pos, std::uint32_t id) {
        ids_.push_back(id);
        if (!gridded_ && ids_.size() > 32) {
            gridded_ = true;
            for (std::uint32_t x : ids_) grid_.emplace(key(cell(pos[x].x()), cell(pos[x].y())), x);
        } else if (gridded_) {
            grid_.emplace(key(cell(pos[id].x()), cell(pos[id].y())), id);
        }
    }

private:
    long long cell(double x) const { return (long long)std::floor(x / tol_); }
    static std::uint64_t key(long long i, long long j) { return (std::uint64_t(i) << 32) ^ std::uint64_t(std::uint32_t(j)); }

    double tol_ = 0;
    bool gridded_ = false;
    std::vector<std::uint32_t> ids_;
    std::unordered_multimap<std::uint64_t, std::uint32_t> grid_;
};

/// Points bucketed in a uniform grid over their bounding box (about one per cell), for
/// finding the ones in a box.
class PointGrid {
public:
    void build(const std::vector<Vec2>& pos) {
        lo_ = pos[0];
        Vec2 hi = pos[0];
        for (const Vec2& x : pos) {
            lo_ = lo_.cwiseMin(x);
            hi = hi.cwiseMax(x);
        }
        const Vec2 size = (hi - lo_).cwiseMax(1e-300);
        const double cell = std::sqrt(size.x() * size.y() / double(pos.size())) + 1e-300;
        nx_ = std::clamp(int(size.x() / cell) + 1, 1, 4096);
        ny_ = std::clamp(int(size.y() / cell) + 1, 1, 4096);
        inv_ = Vec2(nx_ / size.x(), ny_ / size.y());
        offsets_.assign(std::size_t(nx_ * ny_) + 1, 0);
        for (const Vec2& x : pos) ++offsets_[cell_of(x) + 1];
        std::partial_sum(offsets_.begin(), offsets_.end(), offsets_.begin());
        ids_.resize(pos.size());
        fill_.assign(offsets_.begin(), offsets_.end() - 1);
        for (std::uint32_t i = 0; i < pos.size(); ++i) ids_[fill_[cell_of(pos[i])]++] = i;
    }

    /// Calls f(id) for every point in the cells meeting the box.
    template <class F>
    void visit(double xlo, double xhi, double ylo, double yhi, F&& f) const {
        const int i0 = col(xlo, nx_, lo_.x(), inv_.x()), i1 = col(xhi, nx_, lo_.x(), inv_.x());
        const int j0 = col(ylo, ny_, lo_.y(), inv_.y()), j1 = col(yhi, ny_, lo_.y(), inv_.y());
        for (int j = j0; j <= j1; ++j)
            for (int i = i0; i <= i1; ++i) {
                const std::size_t c = std::size_t(j * nx_ + i);
                for (std::uint32_t k = offsets_[c]; k < offsets_[c + 1]; ++k) f(ids_[k]);
            }
    }

private:
    static int col(double x, int n, double lo, double inv) { return std::clamp(int((x - lo) * inv), 0, n - 1); }
    std::size_t cell_of(const Vec2& x) const {
        return std::size_t(col(x.y(), ny_, lo_.y(), inv_.y()) * nx_ + col(x.x(), nx_, lo_.x(), inv_.x()));
    }

    Vec2 lo_, inv_;
    int nx_ = 1, ny_ = 1;
    std::vector<std::uint32_t> offsets_, ids_, fill_;
};

/// One input triangle re-triangulated in its planar layout, in local vertex ids: the corners
/// (0, 1, 2), the points on its sides, then points inside (piece ends, crossings). Reused
/// from triangle to triangle.
class Planar {
public:
    Planar(const Topology& t, const EdgePoints& ep) : t_(t), ep_(ep) {}

    /// Sets up triangle f: its corners and the points on its sides.
    void start(std::uint32_t f);
    /// Adds a piece through the inside (none if its ends merge into one point).
    void add_piece(std::uint32_t piece, const End& a, const End& b);
    /// Cuts the pieces where they cross or touch points, until nothing crosses.
    void arrange();
    /// The constrained Delaunay triangulation (local ids, counter-clockwise).
    void triangulate(ConstrainedDelaunay& cdt, std::vector<std::array<std::uint32_t, 3>>& out);
    /// Chain c without loops: the vertices its piece runs through, in order.
    const std::vector<std::uint32_t>& path(std::size_t c);

    std::vector<Vec2> pos;                            // local vertices in the layout
    std::vector<std::uint32_t> global;                // their ids in the new mesh (kNone: new inside)
    std::vector<std::array<double, 3>> bary;          // weights in the triangle (for new ones)
    std::vector<std::vector<std::uint32_t>> chains;   // per piece added: its local vertices in order
    std::vector<std::uint32_t> chain_piece;           // the piece of each chain
    std::size_t chain_count = 0;

private:
    struct Sub {  // a piece of a chain between consecutive vertices, or a boundary side piece
        std::uint32_t chain, index, u, v;  // chain kNone: the boundary
        double xlo, xhi, ylo, yhi;
    };
    struct Insert {  // a vertex to put into a chain between index and index + 1
        std::uint32_t chain, index;
        double lambda;
        std::uint32_t vertex;
    };

    std::uint32_t add_vertex(const Vec2& x, std::uint32_t global_id, const std::array<double, 3>& b, std::uint8_t sides = 0);
    std::uint32_t local_of(const End& e);
    bool arrange_round();
    void collect_subs();
    std::size_t along_side(int h, std::uint32_t v) const;
    void insert_side_points(const Sub& s, int h);
    void find_vertices_on_subs();
    void find_crossings();
    void cross_pair(const Sub& s, const Sub& q);
    void add_insert(const Sub& s, std::uint32_t w);
    bool strictly_inside(const Vec2& x) const;
    std::uint32_t vertex_at(const Vec2& x);
    void apply_inserts();

    const Topology& t_;
    const EdgePoints& ep_;
    std::uint32_t face_ = 0;
    std::array<Vec2, 3> corner_;
    std::array<double, 3> length_{};
    double tol_ = 0;
    std::vector<std::uint8_t> sides_;                              // per local vertex: the sides it lies on (bits)
    std::vector<std::uint32_t> boundary_;                          // local ids, counter-clockwise
    std::vector<std::uint32_t> boundary_at_;                       // per local vertex: its index in boundary_
    std::array<std::size_t, 4> side_start_{};                      // side h: boundary_[side_start_[h] ..= side_start_[h+1]]
    std::vector<std::pair<std::uint32_t, std::uint32_t>> by_global_;  // (global, local) of the boundary
    PointIndex index_;
    std::vector<Sub> subs_;
    std::vector<Insert> inserts_;
    PointGrid grid_;
    std::vector<std::uint32_t> where_, scratch_, fresh_;
    std::vector<std::array<std::uint32_t, 2>> segments_;
};

std::uint32_t Planar::add_vertex(const Vec2& x, std::uint32_t global_id, const std::array<double, 3>& b,
                                 std::uint8_t sides) {
    pos.push_back(x);
    sides_.push_back(sides);
    global.push_back(global_id);
    bary.push_back(b);
    where_.push_back(kNone);
    return std::uint32_t(pos.size() - 1);
}

void Planar::start(std::uint32_t f) {
    const Triangulation& T = t_.mesh;
    face_ = f;
    length_ = face_lengths(T, f);
    corner_ = layout(length_);
    tol_ = kTol * std::max({length_[0], length_[1], length_[2]});
    pos.clear();
    sides_.clear();
    global.clear();
    bary.clear();
    where_.clear();
    boundary_.clear();
    by_global_.clear();
    chain_count = 0;
    chain_piece.clear();
    index_.reset(tol_);
    for (int k = 0; k < 3; ++k) {
        std::array<double, 3> b{};
        b[std::size_t(k)] = 1;
        add_vertex(corner_[std::size_t(k)], T.faces[f][std::size_t(k)], b, std::uint8_t((1 << k) | (1 << ((k + 2) % 3))));
    }
    for (int h = 0; h < 3; ++h) {
        // Side h runs corner h → h+1; its edge's points come in edge order, reversed if the
        // halfedge runs against the edge.
        side_start_[std::size_t(h)] = boundary_.size();
        boundary_.push_back(std::uint32_t(h));
        const std::uint32_t e = T.face_edges[f][std::size_t(h)];
        const bool aligned = T.aligned[f][std::size_t(h)];
        const std::uint32_t n = ep_.count(e);
        for (std::uint32_t i = 0; i < n; ++i) {
            const std::uint32_t at = ep_.offsets[e] + (aligned ? i : n - 1 - i);
            const double s = aligned ? ep_.t[at] : 1 - ep_.t[at];
            std::array<double, 3> b{};
            b[std::size_t(h)] = 1 - s;
            b[std::size_t((h + 1) % 3)] = s;
            boundary_.push_back(add_vertex((1 - s) * corner_[std::size_t(h)] + s * corner_[std::size_t((h + 1) % 3)],
                                           ep_.vertex[at], b, std::uint8_t(1 << h)));
        }
    }
    side_start_[3] = boundary_.size();
    boundary_at_.assign(pos.size(), kNone);
    for (std::uint32_t i = 0; i < boundary_.size(); ++i) boundary_at_[boundary_[i]] = i;
    for (std::uint32_t v : boundary_) by_global_.push_back({global[v], v});
    std::sort(by_global_.begin(), by_global_.end());
}

std::uint32_t Planar::local_of(const End& e) {
    if (e.kind == End::Kind::Inside) {
        const Vec2 x = e.bary[0] * corner_[0] + e.bary[1] * corner_[1] + e.bary[2] * corner_[2];
        const std::uint32_t near = index_.find(pos, x);
        if (near != kNone) return near;
        const std::uint32_t v = add_vertex(x, kNone, e.bary);
        index_.add(pos, v);
        return v;
    }
    const std::uint32_t g = e.kind == End::Kind::Vertex ? e.index : ep_.request_vertex[e.index];
    const auto it = std::lower_bound(by_global_.begin(), by_global_.end(), std::make_pair(g, 0u));
    if (it == by_global_.end() || it->first != g) throw Error("split_along", "internal: a piece end is not on its triangle");
    return it->second;
}

void Planar::add_piece(std::uint32_t piece, const End& a, const End& b) {
    if (a.kind == End::Kind::Inside && b.kind == End::Kind::Inside) {
        // Checked first, so that a piece of no length leaves no stray vertex behind.
        const Vec2 d =
            (a.bary[1] - b.bary[1]) * (corner_[1] - corner_[0]) + (a.bary[2] - b.bary[2]) * (corner_[2] - corner_[0]);
        if (d.norm() <= tol_) return;
    }
    const std::uint32_t u = local_of(a), v = local_of(b);
    if (u == v) return;
    if (chains.size() <= chain_count) chains.emplace_back();
    chains[chain_count].assign({u, v});
    chain_piece.push_back(piece);
    ++chain_count;
}

void Planar::collect_subs() {
    subs_.clear();
    auto add = [&](std::uint32_t chain, std::uint32_t index, std::uint32_t u, std::uint32_t v) {
        const Vec2 &a = pos[u], &b = pos[v];
        subs_.push_back({chain, index, u, v, std::min(a.x(), b.x()), std::max(a.x(), b.x()), std::min(a.y(), b.y()),
                         std::max(a.y(), b.y())});
    };
    for (std::uint32_t c = 0; c < chain_count; ++c)
        for (std::uint32_t i = 0; i + 1 < chains[c].size(); ++i) add(c, i, chains[c][i], chains[c][i + 1]);
    for (std::uint32_t i = 0; i < boundary_.size(); ++i)
        add(kNone, i, boundary_[i], boundary_[(i + 1) % boundary_.size()]);
}

void Planar::add_insert(const Sub& s, std::uint32_t w) {
    if (w == s.u || w == s.v) return;
    const Vec2 d = pos[s.v] - pos[s.u];
    inserts_.push_back({s.chain, s.index, (pos[w] - pos[s.u]).dot(d) / d.squaredNorm(), w});
}

std::size_t Planar::along_side(int h, std::uint32_t v) const {
    // Corner h+1 ends side h; for side 2 that is corner 0, which starts the boundary list.
    if (v == std::uint32_t((h + 1) % 3)) return h == 2 ? boundary_.size() : side_start_[std::size_t(h) + 1];
    return boundary_at_[v];
}

void Planar::insert_side_points(const Sub& s, int h) {
    // A piece part along side h (it happens when snapping puts a piece through a point of the
    // side) is cut at exactly the side's points between its ends, by their order, whatever the
    // rounding of their positions: it then runs along the boundary's own edges.
    const std::size_t i = along_side(h, s.u), j = along_side(h, s.v);
    for (std::size_t k = std::min(i, j) + 1; k < std::max(i, j); ++k) add_insert(s, boundary_[k]);
}

void Planar::find_vertices_on_subs() {
    // A vertex within the tolerance of a piece (not at its ends) lies on it: the piece is cut
    // there. This also cuts collinear overlapping pieces into shared parts.
    grid_.build(pos);
    for (const Sub& s : subs_) {
        if (s.chain == kNone) continue;
        if (const std::uint8_t common = sides_[s.u] & sides_[s.v]) {
            insert_side_points(s, common & 1 ? 0 : common & 2 ? 1 : 2);
            continue;
        }
        const Vec2 a = pos[s.u], d = pos[s.v] - a;
        grid_.visit(s.xlo - tol_, s.xhi + tol_, s.ylo - tol_, s.yhi + tol_, [&](std::uint32_t w) {
            if (w == s.u || w == s.v) return;
            const double lambda = (pos[w] - a).dot(d) / d.squaredNorm();
            const double dist = (a + lambda * d - pos[w]).norm();
            if (!(lambda > 0 && lambda < 1) || dist > tol_) return;
            // Near it: unless it is within twice that of an end (two vertices side by side,
            // each near the other's piece to a common end, would take turns splitting those;
            // beyond 2·tol they cannot both be). On it (within the clearance): always, or the
            // triangle it makes with the piece would be too flat to keep its orientation.
            const bool near_end = (pos[w] - a).norm() <= 2 * tol_ || (pos[w] - pos[s.v]).norm() <= 2 * tol_;
            if (!near_end || dist <= kClearance * tol_ || orient(a, pos[s.v], pos[w]) == 0)
                inserts_.push_back({s.chain, s.index, lambda, w});
        });
    }
}

bool Planar::strictly_inside(const Vec2& x) const {
    // Inside every side piece's half-plane: inside the boundary (exactly), which is convex but
    // for rounding.
    for (std::size_t i = 0; i < boundary_.size(); ++i)
        if (orient(pos[boundary_[i]], pos[boundary_[(i + 1) % boundary_.size()]], x) <= 0) return false;
    return true;
}

std::uint32_t Planar::vertex_at(const Vec2& x) {
    // A crossing: a vertex within the tolerance if there is one. Else a new vertex — but two
    // pieces meeting a side at distinct points can cross right next to it (closer than the
    // tolerance): a new vertex there must stay clear of the side by far more than rounding
    // (kClearance, so that the thin triangles it makes keep their orientation in 3D too), or
    // it becomes the side's nearest point.
    const std::uint32_t near = index_.find(pos, x);
    if (near != kNone) return near;
    std::uint32_t best = kNone;
    double best_d = INFINITY;
    bool near_side = false, too_near = false;
    for (int h = 0; h < 3; ++h) {
        const Vec2 &a = corner_[std::size_t(h)], &b = corner_[std::size_t((h + 1) % 3)];
        const double d = cross(b - a, x - a) / length_[std::size_t(h)];
        if (d > tol_) continue;
        near_side = true;
        too_near = too_near || d <= kClearance * tol_;
        for (std::size_t i = side_start_[std::size_t(h)]; i <= side_start_[std::size_t(h) + 1]; ++i) {
            const std::uint32_t w = boundary_[i % boundary_.size()];
            if ((pos[w] - x).norm() < best_d) {
                best_d = (pos[w] - x).norm();
                best = w;
            }
        }
    }
    if (near_side && (best_d <= tol_ || too_near || !strictly_inside(x))) return best;
    const double area = cross(corner_[1] - corner_[0], corner_[2] - corner_[0]);
    const std::array<double, 3> b{cross(corner_[1] - x, corner_[2] - x) / area, cross(corner_[2] - x, corner_[0] - x) / area,
                                  cross(corner_[0] - x, corner_[1] - x) / area};
    const std::uint32_t v = add_vertex(x, kNone, b);
    index_.add(pos, v);
    return v;
}

void Planar::cross_pair(const Sub& s, const Sub& q) {
    const Vec2 &a = pos[s.u], &b = pos[s.v], &c = pos[q.u], &d = pos[q.v];
    if (!properly_cross(a, b, c, d)) return;
    const Vec2 r = b - a;
    const double lambda = std::clamp(cross(c - a, d - c) / cross(r, d - c), 0.0, 1.0);
    const Vec2 x = a + lambda * r;
    if (q.chain == kNone) {
        // Through the boundary (rounding at a side): the piece meets the side's nearer end.
        add_insert(s, (c - x).norm() <= (d - x).norm() ? q.u : q.v);
        return;
    }
    const std::uint32_t w = vertex_at(x);
    add_insert(s, w);
    add_insert(q, w);
}

void Planar::find_crossings() {
    // Sweep over x: only pairs whose x ranges overlap are tested.
    std::sort(subs_.begin(), subs_.end(), [](const Sub& a, const Sub& b) { return a.xlo < b.xlo; });
    for (std::size_t i = 0; i < subs_.size(); ++i)
        for (std::size_t j = i + 1; j < subs_.size() && subs_[j].xlo <= subs_[i].xhi; ++j) {
            const Sub &s = subs_[i], &q = subs_[j];
            if ((s.chain == kNone && q.chain == kNone) || s.yhi < q.ylo || q.yhi < s.ylo) continue;
            if (s.u == q.u || s.u == q.v || s.v == q.u || s.v == q.v) continue;
            if (s.chain == kNone) cross_pair(q, s);
            else cross_pair(s, q);
        }
}

const std::vector<std::uint32_t>& Planar::path(std::size_t c) {
    // A chain can come back to a vertex (snapping put it through two vertices closer than the
    // pieces' crossings could tell apart); its path skips the loop. The arrangement keeps
    // loops: undoing them there could undo and redo the same cut forever.
    scratch_.clear();
    for (std::uint32_t v : chains[c]) {
        if (where_[v] != kNone) {
            while (scratch_.back() != v) {
                where_[scratch_.back()] = kNone;
                scratch_.pop_back();
            }
            continue;
        }
        where_[v] = std::uint32_t(scratch_.size());
        scratch_.push_back(v);
    }
    for (std::uint32_t v : scratch_) where_[v] = kNone;
    return scratch_;
}

void Planar::apply_inserts() {
    std::sort(inserts_.begin(), inserts_.end(), [](const Insert& a, const Insert& b) {
        if (a.chain != b.chain) return a.chain < b.chain;
        return a.index != b.index ? a.index < b.index : a.lambda < b.lambda;
    });
    for (std::size_t i = 0; i < inserts_.size();) {
        const std::uint32_t c = inserts_[i].chain;
        fresh_.clear();
        auto push = [&](std::uint32_t v) {
            if (fresh_.empty() || fresh_.back() != v) fresh_.push_back(v);
        };
        for (std::uint32_t k = 0; k < chains[c].size(); ++k) {
            push(chains[c][k]);
            for (; i < inserts_.size() && inserts_[i].chain == c && inserts_[i].index == k; ++i) push(inserts_[i].vertex);
        }
        chains[c].swap(fresh_);
    }
}

bool Planar::arrange_round() {
    collect_subs();
    inserts_.clear();
    // Points on pieces first: overlapping pieces then share their common parts exactly, and
    // only what is left can cross.
    find_vertices_on_subs();
    if (inserts_.empty()) find_crossings();
    if (inserts_.empty()) return false;
    apply_inserts();
    return true;
}

void Planar::arrange() {
    // Usually three rounds: points on pieces, crossings, nothing left; snapping can bend a
    // piece slightly and make new crossings, which later rounds cut.
    for (int round = 0; arrange_round(); ++round)
        if (round == 64)
            throw Error("split_along", "triangle " + std::to_string(face_) + ": the crossings of its pieces do not settle");
}

void Planar::triangulate(ConstrainedDelaunay& cdt, std::vector<std::array<std::uint32_t, 3>>& out) {
    segments_.clear();
    for (std::uint32_t c = 0; c < chain_count; ++c)
        for (std::size_t i = 0; i + 1 < chains[c].size(); ++i) segments_.push_back({chains[c][i], chains[c][i + 1]});
    cdt.run(pos, kClearance * tol_, boundary_, segments_, out);
}

// ---- degenerate triangles ----------------------------------------------------------------------

/// Position of a new-mesh vertex: an input vertex, or one of `extra` (numbered after them).
Eigen::Vector3d position_of(const Topology& t, const std::vector<Eigen::Vector3d>& extra, std::uint32_t v) {
    const std::uint32_t n = t.mesh.vertex_count;
    return v < n ? Eigen::Vector3d(t.polygons.vertices.row(v).transpose()) : extra[v - n];
}

/// A flat triangle split at the points on its sides. It is a segment from A to B (its longest
/// side) with the third corner C between them, so its boundary is two chains from A to B —
/// along AB, and through C — each in order along the segment. Zipping them together in that
/// order joins every two vertices consecutive along the segment by an edge: a piece follows
/// those. (Zero-area triangles, oriented like the boundary so that orientation stays consistent.)
struct FlatSplit {
    std::vector<std::array<std::uint32_t, 3>> triangles;  // global ids
    std::vector<std::uint32_t> along;                     // all boundary vertices, A to B
};

FlatSplit split_flat_triangle(const Topology& t, const EdgePoints& ep, const std::vector<Eigen::Vector3d>& extra,
                              std::uint32_t f) {
    const Triangulation& T = t.mesh;
    std::vector<std::uint32_t> poly;
    std::array<std::size_t, 3> corner_at{};
    for (int h = 0; h < 3; ++h) {
        corner_at[std::size_t(h)] = poly.size();
        poly.push_back(T.faces[f][std::size_t(h)]);
        const std::uint32_t e = T.face_edges[f][std::size_t(h)], n = ep.count(e);
        for (std::uint32_t i = 0; i < n; ++i)
            poly.push_back(ep.vertex[ep.offsets[e] + (T.aligned[f][std::size_t(h)] ? i : n - 1 - i)]);
    }
    const std::size_t n = poly.size();
    const int h = largest(face_lengths(T, f));
    const std::size_t a = corner_at[std::size_t(h)], b = corner_at[std::size_t((h + 1) % 3)];
    std::vector<std::size_t> side{a}, other{a};  // polygon positions, A → B
    for (std::size_t i = (a + 1) % n; i != (b + 1) % n; i = (i + 1) % n) side.push_back(i);
    for (std::size_t i = (a + n - 1) % n; i != (b + n - 1) % n; i = (i + n - 1) % n) other.push_back(i);
    const Eigen::Vector3d pa = position_of(t, extra, poly[a]), d = position_of(t, extra, poly[b]) - pa;
    auto x = [&](std::size_t i) { return d.squaredNorm() > 0 ? (position_of(t, extra, poly[i]) - pa).dot(d) : 0.0; };
    FlatSplit out;
    out.along.push_back(poly[a]);
    auto emit = [&](std::size_t p, std::size_t q, std::size_t r) {
        std::array<std::size_t, 3> c{p, q, r};
        std::sort(c.begin(), c.end());  // polygon order: the triangle turns like the boundary
        out.triangles.push_back({poly[c[0]], poly[c[1]], poly[c[2]]});
    };
    std::size_t i = 1, j = 1;
    while (i + 1 < side.size() || j + 1 < other.size()) {
        const bool take_side = j + 1 == other.size() || (i + 1 < side.size() && x(side[i]) <= x(other[j]));
        const bool first = i == 1 && j == 1;  // the first step only leaves A
        if (take_side) {
            if (!first) emit(side[i - 1], side[i], other[j - 1]);
            out.along.push_back(poly[side[i++]]);
        } else {
            if (!first) emit(other[j - 1], other[j], side[i - 1]);
            out.along.push_back(poly[other[j++]]);
        }
    }
    emit(side[i - 1], b, other[j - 1]);
    out.along.push_back(poly[b]);
    return out;
}

/// The vertices along a flat triangle from one piece end to the other.
std::vector<std::uint32_t> flat_path(const std::vector<std::uint32_t>& along, std::uint32_t a, std::uint32_t b) {
    const auto ia = std::find(along.begin(), along.end(), a), ib = std::find(along.begin(), along.end(), b);
    if (ia == along.end() || ib == along.end())
        throw Error("split_along", "internal: a piece end is not on its flat triangle");
    if (ia <= ib) return {ia, ib + 1};
    std::vector<std::uint32_t> path(ib, ia + 1);
    std::reverse(path.begin(), path.end());
    return path;
}

// ---- assembly ----------------------------------------------------------------------------------

/// Builds the new mesh triangle by triangle, in input order.
class Assembler {
public:
    Assembler(const Topology& t, const std::vector<FaceSegment>& pieces)
        : t_(t), pieces_(pieces), ends_(classify_pieces(t, pieces, requests_)),
          ep_(merge_edge_points(t, requests_)), planar_(t, ep_) {}

    SplitMesh run();

private:
    void group_pieces();
    void copy(std::uint32_t f);
    bool on_edge(const End& end, std::uint32_t e) const;
    void keep_twice_named(std::uint32_t f);
    void split_flat(std::uint32_t f);
    void split_planar(std::uint32_t f);
    void emit(std::uint32_t f, std::uint32_t a, std::uint32_t b, std::uint32_t c);
    std::uint32_t end_vertex(const End& e) const {
        return e.kind == End::Kind::Vertex ? e.index : ep_.request_vertex[e.index];
    }

    const Topology& t_;
    const std::vector<FaceSegment>& pieces_;
    std::vector<EdgeRequest> requests_;
    std::vector<PieceEnds> ends_;
    EdgePoints ep_;
    Planar planar_;
    ConstrainedDelaunay cdt_;
    SplitMesh out_;
    std::vector<Eigen::Vector3d> extra_;        // positions of the new vertices
    std::vector<std::uint32_t> inside_offsets_;  // pieces through the inside, by triangle
    std::vector<std::uint32_t> inside_;
    std::vector<std::uint8_t> touched_;
    std::vector<std::array<std::uint32_t, 3>> local_;
};

void Assembler::group_pieces() {
    const std::size_t F = t_.mesh.face_count();
    inside_offsets_.assign(F + 1, 0);
    touched_.assign(F, 0);
    for (std::size_t i = 0; i < pieces_.size(); ++i)
        if (!ends_[i].empty && ends_[i].side < 0) ++inside_offsets_[pieces_[i].face + 1];
    std::partial_sum(inside_offsets_.begin(), inside_offsets_.end(), inside_offsets_.begin());
    inside_.resize(inside_offsets_.back());
    std::vector<std::uint32_t> fill(inside_offsets_.begin(), inside_offsets_.end() - 1);
    for (std::uint32_t i = 0; i < pieces_.size(); ++i)
        if (!ends_[i].empty && ends_[i].side < 0) {
            inside_[fill[pieces_[i].face]++] = i;
            touched_[pieces_[i].face] = 1;
        }
    // Every triangle on an edge with points is split there.
    for (std::size_t e = 0; e < t_.mesh.edge_count(); ++e)
        if (ep_.count(e) > 0)
            for (const std::uint32_t* h = t_.edge_halfedges.begin(e); h != t_.edge_halfedges.end(e); ++h)
                touched_[corner_face(*h)] = 1;
}

void Assembler::emit(std::uint32_t f, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    out_.mesh.indices.insert(out_.mesh.indices.end(), {a, b, c});
    out_.mesh.offsets.push_back(std::uint32_t(out_.mesh.indices.size()));
    out_.triangle_of.push_back(f);
}

void Assembler::copy(std::uint32_t f) {
    const auto& v = t_.mesh.faces[f];
    emit(f, v[0], v[1], v[2]);
}

bool Assembler::on_edge(const End& end, std::uint32_t e) const {
    if (end.kind == End::Kind::Edge) return requests_[end.index].edge == e;
    return end.index == t_.mesh.edges[e][0] || end.index == t_.mesh.edges[e][1];
}

void Assembler::keep_twice_named(std::uint32_t f) {
    // A triangle naming one vertex twice, (v, v, w), is the segment v–w, and both its long
    // sides are the edge v–w: it has no two distinct chains to zip and stays as it is; a piece
    // in it runs along that edge.
    copy(f);
    for (std::uint32_t k = inside_offsets_[f]; k < inside_offsets_[f + 1]; ++k) {
        const std::uint32_t i = inside_[k];
        for (std::uint32_t e : t_.mesh.face_edges[f])
            if (on_edge(ends_[i].a, e) && on_edge(ends_[i].b, e)) {
                out_.piece_paths[i] = edge_path(t_, ep_, e, ends_[i]);
                break;
            }
    }
}

void Assembler::split_flat(std::uint32_t f) {
    const auto& c = t_.mesh.faces[f];
    if (c[0] == c[1] || c[1] == c[2] || c[2] == c[0]) return keep_twice_named(f);
    const FlatSplit split = split_flat_triangle(t_, ep_, extra_, f);
    for (const auto& tri : split.triangles) emit(f, tri[0], tri[1], tri[2]);
    for (std::uint32_t k = inside_offsets_[f]; k < inside_offsets_[f + 1]; ++k) {
        const std::uint32_t i = inside_[k];
        out_.piece_paths[i] = flat_path(split.along, end_vertex(ends_[i].a), end_vertex(ends_[i].b));
    }
}

void Assembler::split_planar(std::uint32_t f) {
    Planar& p = planar_;
    p.start(f);
    for (std::uint32_t k = inside_offsets_[f]; k < inside_offsets_[f + 1]; ++k) {
        const std::uint32_t i = inside_[k];
        p.add_piece(i, ends_[i].a, ends_[i].b);
    }
    p.arrange();
    p.triangulate(cdt_, local_);
    const std::uint32_t base = t_.mesh.vertex_count;
    for (std::size_t v = 0; v < p.global.size(); ++v)
        if (p.global[v] == kNone) {
            p.global[v] = base + std::uint32_t(extra_.size());
            extra_.push_back(point_in(t_, f, p.bary[v]));
        }
    for (const auto& tri : local_) emit(f, p.global[tri[0]], p.global[tri[1]], p.global[tri[2]]);
    for (std::size_t c = 0; c < p.chain_count; ++c) {
        const std::vector<std::uint32_t>& local = p.path(c);
        if (local.size() < 2) continue;
        std::vector<std::uint32_t>& path = out_.piece_paths[p.chain_piece[c]];
        for (std::uint32_t v : local) path.push_back(p.global[v]);
    }
}

SplitMesh Assembler::run() {
    const Triangulation& T = t_.mesh;
    out_.piece_paths.resize(pieces_.size());
    for (std::size_t i = 0; i < pieces_.size(); ++i)
        if (!ends_[i].empty && ends_[i].side >= 0)
            out_.piece_paths[i] = edge_path(t_, ep_, T.face_edges[pieces_[i].face][std::size_t(ends_[i].side)], ends_[i]);
    group_pieces();
    for (std::size_t e = 0; e < T.edge_count(); ++e)
        for (std::uint32_t i = ep_.offsets[e]; i < ep_.offsets[e + 1]; ++i) {
            const double s = ep_.t[i];
            extra_.push_back((1 - s) * t_.polygons.vertices.row(T.edges[e][0]).transpose() +
                             s * t_.polygons.vertices.row(T.edges[e][1]).transpose());
        }
    out_.mesh.indices.reserve(3 * T.face_count() + 6 * inside_.size());
    out_.mesh.offsets.reserve(T.face_count() + 2 * inside_.size() + 1);
    out_.triangle_of.reserve(T.face_count() + 2 * inside_.size());
    for (std::uint32_t f = 0; f < T.face_count(); ++f) {
        if (!touched_[f]) copy(f);
        else if (t_.degenerate(f)) split_flat(f);
        else split_planar(f);
    }
    const Eigen::Index n = t_.polygons.vertices.rows();
    out_.mesh.vertices.resize(n + Eigen::Index(extra_.size()), 3);
    out_.mesh.vertices.topRows(n) = t_.polygons.vertices;
    for (std::size_t i = 0; i < extra_.size(); ++i) out_.mesh.vertices.row(n + Eigen::Index(i)) = extra_[i].transpose();
    return std::move(out_);
}

}  // namespace

SplitMesh split_along(const Topology& t, const std::vector<FaceSegment>& pieces) {
    return Assembler(t, pieces).run();
}

}  // namespace gsd::mesh
