// Surface Winding Numbers (thesis §6.1; ~1000 lines: the five steps share the corner layout and
// the solver's cached operators): ① the jump Laplace equation on corners, ② its Darboux
// derivative ω, ③ the harmonic part γ by Hodge decomposition, ④ a residual function v that
// integrates γ with minimal L1 jumps (a linear program), ⑤ the curves minus v's jumps as the
// bounding part, solved again for the winding number w.
//
// Functions with jumps live on corners: u(corner) = u_vertex + offset(corner), the offsets
// accumulating the curve's multiplicities while walking around the vertex. Vertices where they
// do not add up to zero (interior ends of open curves) are left out of the system.
#include <gsd/swn.hpp>
#include "core/disjoint_sets.hpp"

#include "surface_shm/cholesky.hpp"
#include "surface_shm/curves.hpp"
#include "surface_shm/operators.hpp"
#include "mesh/cut_graph.hpp"
#include "mesh/halfedges.hpp"
#include "mesh/split.hpp"
#include "l1/tension.hpp"
#include "mesh/topology.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <queue>
#include <tuple>

namespace gsd {

namespace {

using mesh::Adjacency;
using mesh::build_halfedges;
using mesh::ccw;
using mesh::cw;
using mesh::cut_graph;
using mesh::edge_neighbours;
using mesh::Halfedges;
using surface_shm::Cholesky;
using mesh::corner_face;
using mesh::corner_id;
using mesh::corner_index;
using surface_shm::SparseLower;
using mesh::Topology;
using mesh::Triangulation;
using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

constexpr std::uint32_t kNone = UINT32_MAX;
const double kNan = std::numeric_limits<double>::quiet_NaN();

/// The mesh's halfedges; throws unless it is manifold and consistently oriented.
Halfedges manifold_halfedges(const Topology& t) {
    Halfedges H = build_halfedges(t);
    if (!H.manifold())
        throw Error("mesh", "surface winding numbers need a manifold, consistently oriented mesh: " +
                                std::to_string(H.nonmanifold_edges) + " edges have more than two faces and " +
                                std::to_string(H.misoriented_edges) +
                                " join faces that disagree on orientation (the surface Signed Heat Method works on "
                                "such meshes: `gsd swn --method shm`)");
    return H;
}

// ---- the jump Laplace equation (step ①, and the final solve) -----------------------------------

/// Corner offsets of a function that jumps by chain[e] across each edge (left side − right side,
/// "left" of the edge's direction), and the vertices where the jumps around do not close.
struct JumpData {
    std::vector<double> offset;          ///< per corner
    std::vector<std::uint8_t> endpoint;  ///< per vertex: an interior end of the curves
};

/// Crossing from the corner c counter-clockwise into the next face: the jump of a function
/// whose jumps are `chain` (it drops by chain[e] leaving the left side of edge e).
double crossing_jump(const Triangulation& T, std::uint32_t c, const std::vector<double>& chain) {
    const std::uint32_t f = corner_face(c);
    const int h = (corner_index(c) + 2) % 3;  // the incoming halfedge: the edge crossed
    const double g = chain[T.face_edges[f][std::size_t(h)]];
    return T.aligned[f][std::size_t(h)] ? -g : g;
}

JumpData jump_offsets(const Halfedges& H, const std::vector<double>& chain, const std::vector<std::uint8_t>* endpoints) {
    const Triangulation& T = H.t->mesh;
    JumpData J;
    J.offset.assign(3 * T.face_count(), 0.0);
    J.endpoint.assign(T.vertex_count, 0);
    for (std::size_t fan = 0; fan < H.fans(); ++fan) {
        const std::uint32_t* c = H.fan_corners.data() + H.fan_begin[fan];
        const std::size_t n = H.fan_begin[fan + 1] - H.fan_begin[fan];
        double total = 0;
        for (std::size_t i = 0; i < n; ++i) {
            J.offset[c[i]] = total;
            if (i + 1 < n || H.fan_closed[fan]) total += crossing_jump(T, c[i], chain);
        }
        // Around an interior vertex the jumps must add up to zero, else the curves end there.
        if (H.fan_closed[fan] && std::abs(total) > 0.5) J.endpoint[H.fan_vertex[fan]] = 1;
    }
    if (endpoints) J.endpoint = *endpoints;
    return J;
}

/// One end of an outer boundary edge in the boundary-aware solve: weight·(u_vertex + offset)²
/// joins the energy, offset read at `corner` (the edge's face's corner at the vertex).
struct RobinTerm {
    std::uint32_t vertex = 0, corner = 0;
    double weight = 0;
};

/// The weight of side k of face f (a → a') in the jump Laplace equation. Curve ends have no value
/// of u: sides touching one are left out (their faces' other side stays, so the function still
/// feels the neighbours across the end's one-ring). That side alone must not carry a negative
/// weight (an obtuse angle at the end), or K would lose definiteness: it is clamped at 0.
double side_weight(const Halfedges& H, std::size_t f, int k, const std::vector<std::uint8_t>& endpoint) {
    const Triangulation& T = H.t->mesh;
    const std::uint32_t a = T.faces[f][std::size_t(k)], b = T.faces[f][std::size_t((k + 1) % 3)];
    if (a == b || endpoint[a] || endpoint[b]) return 0.0;
    const double w = H.cot_weight[corner_id(f, k)];
    return endpoint[T.faces[f][std::size_t((k + 2) % 3)]] ? std::max(w, 0.0) : w;
}

/// K with the endpoint rows replaced by the identity, always the same pattern (K's), so the
/// analysis of the first factorization serves every later curve.
SparseLower<double> jump_matrix(const Halfedges& H, const std::vector<std::uint8_t>& endpoint,
                                const std::vector<RobinTerm>* robin = nullptr) {
    const Triangulation& T = H.t->mesh;
    SparseLower<double> K(T.vertex_count);
    K.reserve(6 * T.face_count() + T.vertex_count);
    std::vector<double> diagonal(T.vertex_count, 0.0);
    for (std::size_t f = 0; f < T.face_count(); ++f)
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t a = T.faces[f][std::size_t(k)], b = T.faces[f][std::size_t((k + 1) % 3)];
            const double w = side_weight(H, f, k, endpoint);
            diagonal[a] += w;
            diagonal[b] += w;
            if (a != b) K.add(std::max(a, b), std::min(a, b), -w);
        }
    double mean = 0;
    for (double d : diagonal) mean += d;
    mean /= double(std::max<std::size_t>(T.vertex_count, 1));
    // A tiny shift keeps K definite (constant nullspace per component, vertices cut off by the
    // endpoints); the labels are normalized afterwards.
    if (robin)
        for (const RobinTerm& r : *robin)
            if (!endpoint[r.vertex]) diagonal[r.vertex] += r.weight;
    for (std::size_t v = 0; v < T.vertex_count; ++v)
        K.add(v, v, endpoint[v] || diagonal[v] <= 0 ? 1.0 : diagonal[v] + 1e-10 * mean);
    return K;
}

/// The right-hand side of min Σ w (u_c + o_c − u_a − o_a)² over the faces' sides a → c (the offsets
/// o make u jump across the curves), plus Σ weight·(u + o)² over the Robin terms.
std::vector<double> jump_rhs(const Halfedges& H, const JumpData& J, const std::vector<RobinTerm>* robin = nullptr) {
    const Triangulation& T = H.t->mesh;
    std::vector<double> b(T.vertex_count, 0.0);
    for (std::size_t f = 0; f < T.face_count(); ++f)
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t a = T.faces[f][std::size_t(k)], c = T.faces[f][std::size_t((k + 1) % 3)];
            const double w = side_weight(H, f, k, J.endpoint);
            if (w == 0) continue;
            // The offsets' difference moves to the right-hand side.
            const double d = J.offset[corner_id(f, (k + 1) % 3)] - J.offset[corner_id(f, k)];
            b[a] += w * d;
            b[c] -= w * d;
        }
    if (robin)
        for (const RobinTerm& r : *robin)
            if (!J.endpoint[r.vertex]) b[r.vertex] -= r.weight * J.offset[r.corner];
    return b;
}

/// u per corner from vertex values and offsets; NaN at corners of endpoints.
std::vector<double> corner_values(const Triangulation& T, const std::vector<double>& u_vertex, const JumpData& J) {
    std::vector<double> u(3 * T.face_count());
    for (std::size_t f = 0; f < T.face_count(); ++f)
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t v = T.faces[f][std::size_t(k)];
            u[corner_id(f, k)] = J.endpoint[v] ? kNan : u_vertex[v] + J.offset[corner_id(f, k)];
        }
    return u;
}

// ---- steps ② and ③ -------------------------------------------------------------------------------

/// ω = Du: per edge, along its direction, the change of u across it averaged over its faces
/// (jumps forgotten). 0 at edges touching an endpoint.
std::vector<double> darboux_derivative(const Topology& t, const std::vector<double>& u, const JumpData& J) {
    const Triangulation& T = t.mesh;
    std::vector<double> omega(T.edge_count(), 0.0);
    for (std::size_t e = 0; e < T.edge_count(); ++e) {
        if (J.endpoint[T.edges[e][0]] || J.endpoint[T.edges[e][1]]) continue;
        double sum = 0;
        int n = 0;
        for (const std::uint32_t* h = t.edge_halfedges.begin(e); h != t.edge_halfedges.end(e); ++h) {
            const std::uint32_t f = corner_face(*h);
            const int k = corner_index(*h);
            const double d = u[corner_id(f, (k + 1) % 3)] - u[corner_id(f, k)];
            sum += T.aligned[f][std::size_t(k)] ? d : -d;
            ++n;
        }
        if (n) omega[e] = sum / n;
    }
    return omega;
}

/// ⋆1⁻¹ per edge: 1/(cotan weight), kept in [.., 1000] and 1 where the weight is not positive
/// (non-Delaunay edges), as in the reference.
std::vector<double> inverse_hodge1(const Halfedges& H) {
    const Topology& t = *H.t;
    std::vector<double> inv(t.mesh.edge_count(), 1.0);
    for (std::size_t e = 0; e < t.mesh.edge_count(); ++e) {
        double w = 0;
        for (const std::uint32_t* h = t.edge_halfedges.begin(e); h != t.edge_halfedges.end(e); ++h) w += H.cot_weight[*h];
        const double x = 1.0 / w;
        inv[e] = !std::isfinite(x) || x <= 0 ? 1.0 : std::min(x, 1000.0);
    }
    return inv;
}

// ---- step ④: the residual function ----------------------------------------------------------

/// v integrated face by face from γ (corner 0 of each face at 0).
std::vector<double> integrate_in_faces(const Triangulation& T, const std::vector<double>& gamma) {
    std::vector<double> v(3 * T.face_count(), 0.0);
    for (std::size_t f = 0; f < T.face_count(); ++f)
        for (int k = 0; k < 2; ++k) {
            const double g = gamma[T.face_edges[f][std::size_t(k)]];
            v[corner_id(f, k + 1)] = v[corner_id(f, k)] + (T.aligned[f][std::size_t(k)] ? g : -g);
        }
    return v;
}

/// The jump of a corner function across interior edge e, left face minus right face, at the
/// edge's first vertex; and the two faces.
struct EdgeSides {
    std::uint32_t left = kNone, right = kNone;  // faces whose halfedge runs with / against the edge
    std::uint32_t left_corner = kNone, right_corner = kNone;  // their corners at edges[e][0]
};

EdgeSides sides(const Topology& t, std::size_t e) {
    EdgeSides s;
    const Triangulation& T = t.mesh;
    for (const std::uint32_t* h = t.edge_halfedges.begin(e); h != t.edge_halfedges.end(e); ++h) {
        const std::uint32_t f = corner_face(*h);
        const int k = corner_index(*h);
        if (T.aligned[f][std::size_t(k)]) {
            s.left = f;
            s.left_corner = corner_id(f, k);  // the halfedge starts at the edge's first vertex
        } else {
            s.right = f;
            s.right_corner = corner_id(f, (k + 1) % 3);
        }
    }
    return s;
}

/// The residual's linear program, over groups of faces that move together (every face alone:
/// the full program; the components of a cut: the reduced one). Minimizes Σ length_e |J_e| over
/// the edges between different groups, J_e = v_left − v_right; on input curve edges J_e must
/// lie between 0 and the curve's multiplicity ("no extra loops") and costs curve_weight per
/// length. Returns the shift of each group.
struct ResidualLp {
    std::vector<double> shift;
    std::size_t variables = 0, rows = 0;
};

/// Per curve edge: how straight the curve runs there — the length of the two chords from the point
/// a window of curve length before it to its midpoint and on to the point a window after it, over
/// the length along the curve between them. 1 on a straight curve; about 0.5–0.8 on a staircase
/// along mesh edges standing for a smooth one, so that such a curve costs the residual what the
/// curve it stands for would (and not, say, twice a shortcut across the faces beside it). Off
/// the curves: 1.
std::vector<double> curve_straightness(const Topology& t, const std::vector<double>& chain) {
    const Triangulation& T = t.mesh;
    auto on_curve = [&](std::size_t e) { return std::abs(chain[e]) > 1e-9 && T.edges[e][0] != T.edges[e][1]; };
    auto from = [&](std::size_t e) { return chain[e] > 0 ? T.edges[e][0] : T.edges[e][1]; };
    auto to = [&](std::size_t e) { return chain[e] > 0 ? T.edges[e][1] : T.edges[e][0]; };
    // Curve edges leaving and entering each vertex, in the chain's direction.
    std::vector<std::vector<std::uint32_t>> out(T.vertex_count), in(T.vertex_count);
    for (std::size_t e = 0; e < T.edge_count(); ++e)
        if (on_curve(e)) {
            out[from(e)].push_back(std::uint32_t(e));
            in[to(e)].push_back(std::uint32_t(e));
        }
    const double window = 3.0 * t.mean_edge_length;
    constexpr int kMaxSteps = 64;  // tiny pieces of a cut mesh: enough of them, not all
    // From vertex v, follow the curve forward (or backward) while it runs on unbranched, up to
    // the window, not past edge e; adds the length walked, returns where it stopped.
    auto walk = [&](std::uint32_t v, bool forward, std::size_t e, double& along) {
        double l = 0;
        for (int step = 0; step < kMaxSteps && l < window; ++step) {
            if (out[v].size() != 1 || in[v].size() != 1) break;
            const std::uint32_t next = forward ? out[v][0] : in[v][0];
            if (next == e) break;  // a closed curve shorter than the window
            l += T.edge_lengths[next];
            v = forward ? to(next) : from(next);
        }
        along += l;
        return v;
    };
    auto x = [&](std::uint32_t v) -> Eigen::Vector3d { return t.polygons.vertices.row(v).transpose(); };
    std::vector<double> s(T.edge_count(), 1.0);
    for (std::size_t e = 0; e < T.edge_count(); ++e) {
        if (!on_curve(e)) continue;
        double along = T.edge_lengths[e];
        const std::uint32_t head = walk(to(e), true, e, along), tail = walk(from(e), false, e, along);
        const Eigen::Vector3d mid = 0.5 * (x(T.edges[e][0]) + x(T.edges[e][1]));
        // Two chords, through the edge's midpoint: a smooth curve's bend over the window barely
        // counts (a circle of 8 windows' length: 0.97), a staircase's zigzag does.
        const double chords = (x(head) - mid).norm() + (mid - x(tail)).norm();
        if (along > 0) s[e] = std::clamp(chords / along, 0.05, 1.0);
    }
    return s;
}

/// Edge e's term of the residual program: cost per unit length and |J| (1; on curve edges
/// curve_weight times the curve's straightness there, so a staircase along mesh edges costs what
/// the curve it stands for would) and the bounds of J (on curve edges, between 0 and the
/// multiplicity).
struct ResidualTerm {
    double weight, lo = -l1::TensionProblem::kInfinity, hi = l1::TensionProblem::kInfinity;
};
ResidualTerm residual_term(std::size_t e, const std::vector<double>& chain, const std::vector<double>& straightness,
                           const SwnOptions& o) {
    const double m = chain[e];
    if (std::abs(m) <= 1e-9) return {1.0};
    return {o.curve_weight * straightness[e], std::min(0.0, m), std::max(0.0, m)};
}

ResidualLp solve_residual_lp(const Topology& t, const std::vector<double>& v0, const std::vector<std::uint32_t>& group,
                             std::size_t groups, const std::vector<double>& chain,
                             const std::vector<double>& straightness, const SwnOptions& o) {
    const Triangulation& T = t.mesh;
    l1::TensionProblem p;
    p.nodes = groups;
    // Costs in units of the mean edge length: near 1 whatever the mesh's scale.
    const double unit = 1.0 / mesh::mean_edge_length(T, t.face_areas);
    for (std::size_t e = 0; e < T.edge_count(); ++e) {
        const EdgeSides s = sides(t, e);
        if (s.left == kNone || s.right == kNone) continue;
        l1::TensionProblem::Edge edge;
        edge.left = group[s.left];
        edge.right = group[s.right];
        if (edge.left == edge.right) continue;
        edge.offset = v0[s.left_corner] - v0[s.right_corner];
        const ResidualTerm term = residual_term(e, chain, straightness, o);
        // Zero-length edges still cost a little: every cost must be positive.
        edge.cost = term.weight * std::max(T.edge_lengths[e] * unit, 1e-9);
        edge.lo = term.lo;
        edge.hi = term.hi;
        p.edges.push_back(edge);
    }
    const l1::TensionSolution s =
        o.solver == SwnSolver::Clp ? l1::solve_tension_lp(p) : l1::solve_tension_network(p);
    ResidualLp r;
    r.shift = s.x;
    r.variables = groups + 2 * p.edges.size();  // as a linear program: shifts and |J|'s two parts
    r.rows = p.edges.size();
    return r;
}

/// Σ length·|J| (curve_weight on curve edges) over every interior edge, in the units of the
/// mesh, and how far the jumps on curve edges leave [0, multiplicity].
std::pair<double, double> residual_cost(const Topology& t, const std::vector<double>& jumps,
                                        const std::vector<double>& chain, const std::vector<double>& straightness,
                                        const SwnOptions& o) {
    const Triangulation& T = t.mesh;
    double cost = 0, violation = 0;
    for (std::size_t e = 0; e < T.edge_count(); ++e) {
        const ResidualTerm term = residual_term(e, chain, straightness, o);
        cost += term.weight * T.edge_lengths[e] * std::abs(jumps[e]);
        violation = std::max({violation, term.lo - jumps[e], jumps[e] - term.hi});
    }
    return {cost, violation};
}

/// Jumps of a corner function across every interior edge (left − right at the first vertex).
std::vector<double> edge_jumps(const Topology& t, const std::vector<double>& v) {
    std::vector<double> J(t.mesh.edge_count(), 0.0);
    for (std::size_t e = 0; e < t.mesh.edge_count(); ++e) {
        const EdgeSides s = sides(t, e);
        if (s.left != kNone && s.right != kNone) J[e] = v[s.left_corner] - v[s.right_corner];
    }
    return J;
}

// ---- the reduced program's cut ----------------------------------------------------------------

/// Edges beside the runs of curve edges that point against the curve around them: a run (curve
/// edges between ends or junctions) both of whose ends meet pieces of the opposite direction —
/// the chain's boundary is ±2 there — as a reversed piece of a loop leaves it. Every edge of a
/// face with an edge on such a run. Why: a bounding loop with a reversed piece is no boundary;
/// the residual reads the piece as nonbounding, a jump that must close on itself, and the cheap
/// way is right beside the piece. The reduced program's jumps run only along its cut, so
/// without these edges it closed them the long way round, around the handle, and took the
/// broken loop around the tube beside it for the bounding one (tori with a small loop and a
/// loop around the tube, both broken with one reversed piece: 46 % of the area mislabeled on
/// one, 0.07 % with them; gsd-swn-bench broken-loops).
std::vector<std::uint8_t> reversed_run_detours(const Topology& t, const std::vector<double>& chain) {
    const Triangulation& T = t.mesh;
    auto on_curve = [&](std::size_t e) { return std::abs(chain[e]) > 1e-9; };
    std::vector<double> boundary(T.vertex_count, 0.0);
    std::vector<int> degree(T.vertex_count, 0);
    for (std::size_t e = 0; e < T.edge_count(); ++e)
        if (on_curve(e)) {
            boundary[T.edges[e][1]] += chain[e];
            boundary[T.edges[e][0]] -= chain[e];
            ++degree[T.edges[e][0]];
            ++degree[T.edges[e][1]];
        }
    auto is_break = [&](std::uint32_t x) { return std::abs(boundary[x]) > 0.5 || degree[x] != 2; };
    // Runs: curve edges joined through vertices that are no break.
    detail::DisjointSets runs(T.edge_count());
    std::vector<std::int64_t> through(T.vertex_count, -1);
    for (std::size_t e = 0; e < T.edge_count(); ++e)
        if (on_curve(e))
            for (std::uint32_t x : T.edges[e])
                if (!is_break(x)) {
                    if (through[x] < 0) through[x] = std::int64_t(e);
                    else runs.join(std::uint32_t(e), std::uint32_t(through[x]));
                }
    std::map<std::uint32_t, std::pair<int, int>> ends;  // run → (its breaks, those with |boundary| 2)
    for (std::size_t e = 0; e < T.edge_count(); ++e)
        if (on_curve(e))
            for (std::uint32_t x : T.edges[e])
                if (is_break(x)) {
                    auto& c = ends[runs.find(std::uint32_t(e))];
                    ++c.first;
                    c.second += std::abs(boundary[x]) > 1.5;
                }
    std::vector<std::uint8_t> against(T.edge_count(), 0), out(T.edge_count(), 0);
    for (std::size_t e = 0; e < T.edge_count(); ++e)
        if (on_curve(e)) {
            const auto it = ends.find(runs.find(std::uint32_t(e)));
            against[e] = it != ends.end() && it->second.first == 2 && it->second.second == 2;
        }
    for (std::size_t f = 0; f < T.face_count(); ++f)
        if (against[T.face_edges[f][0]] || against[T.face_edges[f][1]] || against[T.face_edges[f][2]])
            for (std::uint32_t e : T.face_edges[f]) out[e] = 1;
    return out;
}

/// Shortest paths along edges from one start at a time; the scratch is kept between starts and
/// only what a search reached is reset.
class EdgeSearch {
public:
    explicit EdgeSearch(const Triangulation& T)
        : T_(T), dist_(T.vertex_count, std::numeric_limits<double>::infinity()), via_(T.vertex_count, kNone) {}
    void start(std::uint32_t s) {
        for (std::uint32_t v : touched_) dist_[v] = std::numeric_limits<double>::infinity();
        touched_.clear();
        heap_ = {};
        dist_[s] = 0;
        touched_.push_back(s);
        heap_.push({0.0, s});
    }
    /// The next vertex settled (nearest first) and its distance; false when none is left.
    bool next(double& d, std::uint32_t& v) {
        while (!heap_.empty()) {
            const auto [dd, vv] = heap_.top();
            heap_.pop();
            if (dd > dist_[vv]) continue;
            d = dd;
            v = vv;
            return true;
        }
        return false;
    }
    /// Offers w, through edge e, from v settled at distance d.
    void relax(double d, std::uint32_t w, std::uint32_t e) {
        const double nd = d + T_.edge_lengths[e];
        if (nd < dist_[w]) {
            if (std::isinf(dist_[w])) touched_.push_back(w);
            dist_[w] = nd;
            via_[w] = e;
            heap_.push({nd, w});
        }
    }
    /// The edges of the path from the start to v, v's end first.
    std::vector<std::uint32_t> path_to(std::uint32_t v, std::uint32_t start) const {
        std::vector<std::uint32_t> edges;
        for (std::uint32_t u = v; u != start;) {
            const std::uint32_t e = via_[u];
            edges.push_back(e);
            u = T_.edges[e][0] == u ? T_.edges[e][1] : T_.edges[e][0];
        }
        return edges;
    }

private:
    using Item = std::pair<double, std::uint32_t>;
    const Triangulation& T_;
    std::vector<double> dist_;
    std::vector<std::uint32_t> via_, touched_;
    std::priority_queue<Item, std::vector<Item>, std::greater<>> heap_;
};

/// Where the full program's jumps may leave the curves: shortest paths along edges (Dijkstra,
/// edge lengths) from each interior curve end to the nearest few ends of the opposite sign, and
/// to the nearest vertex of another piece of the curves (a broken loop can be completed into
/// the middle of a neighbouring curve, along which jumps are nearly free). The reduced program
/// cuts along all of them, so its optimum is the full program's whenever the full optimum's
/// jumps off the curves run along such paths.
std::vector<std::uint8_t> completion_paths(const Topology& t, const std::vector<double>& chain,
                                           const std::vector<std::uint8_t>& endpoint) {
    const Triangulation& T = t.mesh;
    const std::size_t V = T.vertex_count;
    std::vector<std::uint8_t> on_path(T.edge_count(), 0);
    // Signed multiplicity of each end (the chain's boundary there), and the pieces of the curves.
    std::vector<double> end_sign(V, 0.0);
    detail::DisjointSets pieces(V);
    std::vector<std::uint8_t> on_curve(V, 0);
    for (std::size_t e = 0; e < T.edge_count(); ++e) {
        if (chain[e] == 0) continue;
        const auto [a, b] = T.edges[e];
        if (endpoint[a]) end_sign[a] -= chain[e];
        if (endpoint[b]) end_sign[b] += chain[e];
        on_curve[a] = on_curve[b] = 1;
        pieces.join(a, b);
    }
    const std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> nbr = edge_neighbours(T);
    constexpr int kEnds = 3;  // opposite ends reached from each end
    EdgeSearch search(T);
    for (std::uint32_t start = 0; start < V; ++start) {
        if (std::abs(end_sign[start]) < 0.5) continue;
        const bool sign = end_sign[start] > 0;
        const std::uint32_t own = pieces.find(start);
        search.start(start);
        int ends = 0;
        bool other_piece = false;
        double d = 0;
        std::uint32_t v = 0;
        while ((ends < kEnds || !other_piece) && search.next(d, v)) {
            bool take = false;
            if (v != start && std::abs(end_sign[v]) >= 0.5 && (end_sign[v] > 0) != sign && ends < kEnds) {
                ++ends;
                take = true;
            }
            if (!other_piece && on_curve[v] && pieces.find(v) != own) {
                other_piece = true;
                take = true;
            }
            if (take)
                for (std::uint32_t e : search.path_to(v, start)) on_path[e] = 1;
            for (const auto& [w, e] : nbr[v]) search.relax(d, w, e);
        }
    }
    return on_path;
}

/// The curves closed across their gaps: each interior end where curves arrive (the chain's
/// boundary +k there) joined to ends where they leave (−k) by shortest paths along edges, the
/// best pairs first (a greedy matching; an end joins several others if its multiplicity says
/// so). Paths leave a head forward (into the half-space ahead of the arriving curve), and a
/// pair's score is the path's length times how much the join turns: 3 − cos α − cos β, α between
/// the arriving curve's direction and the path's first few edges, β between the path's last few
/// edges and the leaving curve's direction — 1 for a gap in a straight curve, up to 5 for
/// running back along the piece to its own start (which the nearest end often is when gaps are
/// long).
/// Why: the harmonic part of a broken curve's jump function has fractional periods — a loop
/// around a handle with half of it cut away winds about 0.3 times, two broken loops that bound
/// a band together can wind 0.8 times — and the residual program then read the wrong curves as
/// the ones that bound nothing (or placed a fraction of a jump off every curve). Completed as a
/// person would complete them, the curves wind an integer number of times around each handle.
/// Ends no path joins (another component) stay open.
std::vector<double> closed_chain(const Topology& t, const std::vector<double>& chain, const std::vector<std::uint8_t>& endpoint) {
    const Triangulation& T = t.mesh;
    const std::size_t V = T.vertex_count;
    std::vector<double> end_sign(V, 0.0);  // curves arriving minus leaving
    for (std::size_t e = 0; e < T.edge_count(); ++e) {
        if (chain[e] == 0) continue;
        const auto [a, b] = T.edges[e];
        if (endpoint[a]) end_sign[a] -= chain[e];
        if (endpoint[b]) end_sign[b] += chain[e];
    }
    std::vector<long> capacity(V, 0);  // ends still to join, signed like end_sign
    for (std::size_t v = 0; v < V; ++v) capacity[v] = std::lround(end_sign[v]);
    const std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> nbr = edge_neighbours(T);
    // Heads in a piece of the mesh with no tail (curves that end on its boundary) can join
    // nothing: they are left out rather than searched for across the whole piece each.
    detail::DisjointSets connected(V);
    for (std::size_t e = 0; e < T.edge_count(); ++e) connected.join(T.edges[e][0], T.edges[e][1]);
    std::vector<std::uint8_t> has_tail(V, 0);
    for (std::uint32_t v = 0; v < V; ++v)
        if (capacity[v] < 0) has_tail[connected.find(v)] = 1;
    for (std::uint32_t v = 0; v < V; ++v)
        if (capacity[v] > 0 && !has_tail[connected.find(v)]) capacity[v] = 0;
    // The curves' direction at each end: from a few edges back along the curve (staircases along
    // mesh edges turn at every vertex) to the end, or from the end a few edges on.
    auto x = [&](std::uint32_t v) -> Eigen::Vector3d { return t.polygons.vertices.row(v).transpose(); };
    auto flow = [&](std::uint32_t e, std::uint32_t from) {  // the chain along e leaving `from`
        return T.edges[e][0] == from ? chain[e] : -chain[e];
    };
    auto direction = [&](std::uint32_t end, bool arriving) {
        std::uint32_t v = end, previous = kNone;
        for (int step = 0; step < 4; ++step) {
            std::uint32_t next = kNone;
            for (const auto& [w, e] : nbr[v])
                if (w != previous && (arriving ? flow(e, v) < -0.5 : flow(e, v) > 0.5)) next = w;
            if (next == kNone) break;
            previous = v;
            v = next;
        }
        const Eigen::Vector3d d = arriving ? x(end) - x(v) : x(v) - x(end);
        return d.norm() > 0 ? Eigen::Vector3d(d.normalized()) : Eigen::Vector3d::Zero();
    };
    // The vertices of the piece arriving at a head (followed back while unbranched) and their
    // neighbours, less those within two edges of the head.
    std::vector<std::uint8_t> blocked(V, 0), near(V, 0);
    auto beside_piece = [&](std::uint32_t head) {
        std::vector<std::uint32_t> piece{head}, out;
        for (std::uint32_t v = head, previous = kNone; piece.size() < V;) {
            std::uint32_t next = kNone;
            for (const auto& [w, e] : nbr[v])
                if (w != previous && flow(e, v) < -0.5) next = w;
            if (next == kNone || next == head) break;
            previous = v;
            v = next;
            piece.push_back(v);
        }
        std::vector<std::uint32_t> close{head}, ring{head};  // within two edges of the head
        near[head] = 1;
        for (int step = 0; step < 2; ++step) {
            std::vector<std::uint32_t> next;
            for (std::uint32_t v : ring)
                for (const auto& [w, e] : nbr[v])
                    if (!near[w]) next.push_back(w), close.push_back(w), near[w] = 1;
            ring = std::move(next);
        }
        for (std::uint32_t v : piece) {
            if (!near[v]) out.push_back(v);
            for (const auto& [w, e] : nbr[v])
                if (!near[w]) out.push_back(w);
        }
        for (std::uint32_t v : close) near[v] = 0;
        return out;
    };
    std::vector<Eigen::Vector3d> tangent(V, Eigen::Vector3d::Zero());
    for (std::uint32_t v = 0; v < V; ++v)
        if (capacity[v] != 0) tangent[v] = direction(v, capacity[v] > 0);
    struct Candidate {
        double score;
        std::uint32_t head, tail;
        std::vector<std::uint32_t> edges;  // the path, head to tail
    };
    EdgeSearch search(T);
    constexpr double kClearJoin = 2.0;  // the second best join of a head scores this much worse, or it stays open
    // From each head with ends left, the `reach` nearest tails with ends left, scored.
    auto candidates = [&](int reach) {
        std::vector<Candidate> out;
        for (std::uint32_t head = 0; head < V; ++head) {
            if (capacity[head] <= 0) continue;
            const std::size_t first = out.size();
            search.start(head);
            int found = 0;
            // The ring around the head's own piece is closed to the path (but for the end of the
            // piece near the head): else the way back along the piece to its own start is often
            // as short as the way across the gap.
            const std::vector<std::uint32_t> closed_off = beside_piece(head);
            for (std::uint32_t v : closed_off) blocked[v] = 1;
            double d = 0;
            std::uint32_t v = 0;
            while (found < reach && search.next(d, v)) {
                if (capacity[v] < 0 && v != head) {
                    Candidate c{0, head, v, search.path_to(v, head)};
                    std::vector<std::uint32_t> path{v};  // vertices, tail to head
                    for (std::uint32_t e : c.edges) path.push_back(T.edges[e][0] == path.back() ? T.edges[e][1] : T.edges[e][0]);
                    std::reverse(c.edges.begin(), c.edges.end());
                    std::reverse(path.begin(), path.end());
                    // The path's own direction a few edges from either end (not the chord: a
                    // gap across a thin tube and the way back along the piece share it).
                    const std::size_t k = std::min<std::size_t>(3, path.size() - 1);
                    const Eigen::Vector3d leave = (x(path[k]) - x(head)).normalized();
                    const Eigen::Vector3d arrive = (x(v) - x(path[path.size() - 1 - k])).normalized();
                    c.score = d * (3 - tangent[head].dot(leave) - arrive.dot(tangent[v]));
                    out.push_back(std::move(c));
                    ++found;
                }
                if (blocked[v] && v != head) continue;  // reached (a tail counts), not passed through
                for (const auto& [w, e] : nbr[v]) {
                    // Leave a head forward, along the curve arriving there.
                    if (v == head && (x(w) - x(head)).dot(tangent[head]) <= 0 && tangent[head].squaredNorm() > 0) continue;
                    search.relax(d, w, e);
                }
            }
            for (std::uint32_t u : closed_off) blocked[u] = 0;
            // A head whose two best joins score alike has no clear continuation (half of a loop
            // around a tube: across the gap or around the other way): it stays open.
            auto mine = out.begin() + std::ptrdiff_t(first);
            std::sort(mine, out.end(), [](const Candidate& a, const Candidate& b) { return a.score < b.score; });
            if (out.size() - first >= 2 && mine[1].score < kClearJoin * mine[0].score) out.resize(first);
        }
        std::sort(out.begin(), out.end(), [](const Candidate& a, const Candidate& b) { return a.score < b.score; });
        return out;
    };
    std::vector<double> closed = chain;
    // A few nearest tails per head settle almost every end. The rest look again among the tails
    // left (an unclear head may have become clear), further but bounded: each search is a
    // Dijkstra over the mesh around the head.
    for (int reach : {6, 64}) {
        for (const Candidate& c : candidates(reach)) {
            const long k = std::min(capacity[c.head], -capacity[c.tail]);
            if (k <= 0) continue;
            capacity[c.head] -= k;
            capacity[c.tail] += k;
            std::uint32_t at = c.head;
            for (std::uint32_t e : c.edges) {
                const bool forward = T.edges[e][0] == at;
                closed[e] += forward ? double(k) : -double(k);
                at = forward ? T.edges[e][1] : T.edges[e][0];
            }
        }
        if (std::none_of(capacity.begin(), capacity.end(), [](long c) { return c > 0; })) break;
    }
    return closed;
}

/// Components of the faces across uncut edges, with γ integrated along a spanning tree of each
/// (consistent: every loop inside a component bounds, and γ is closed).
std::vector<std::uint32_t> cut_components(const Topology& t, const std::vector<std::uint8_t>& cut,
                                          const std::vector<double>& gamma, std::vector<double>& v, std::size_t& count) {
    const Triangulation& T = t.mesh;
    const std::size_t F = T.face_count();
    std::vector<std::uint32_t> comp(F, kNone);
    v.assign(3 * F, 0.0);
    count = 0;
    auto fill_face = [&](std::uint32_t f, int k, double value) {  // corner k of f has `value`
        v[corner_id(f, k)] = value;
        for (int i = 0; i < 2; ++i) {
            const int a = (k + i) % 3;
            const double g = gamma[T.face_edges[f][std::size_t(a)]];
            v[corner_id(f, (a + 1) % 3)] = v[corner_id(f, a)] + (T.aligned[f][std::size_t(a)] ? g : -g);
        }
    };
    std::uint32_t current = 0;
    mesh::face_forest(
        t, [&](std::uint32_t e) { return cut[e] != 0; },
        [&](std::uint32_t f0) {
            current = std::uint32_t(count++);
            comp[f0] = current;
            fill_face(f0, 0, 0.0);
        },
        [&](std::uint32_t f, int k, std::uint32_t h, std::uint32_t g) {
            comp[g] = current;
            // The corner of g at f's corner k (the halfedge's tail in f is its head in g).
            fill_face(g, (corner_index(h) + 1) % 3, v[corner_id(f, k)]);
        });
    return comp;
}

// ---- thesis §6.2: boundary-aware winding numbers -------------------------------------------------

/// The Robin terms of the boundary-aware solve. The jump Laplace equation's natural (Neumann)
/// condition makes w's level sets meet the boundary at right angles; the winding number of the
/// same curves in free space has no such condition. Outside a disk of radius R, a field
/// decaying like a dipole (what a loop looks like from afar) obeys ∂w/∂n = −w/R at the disk's
/// rim, so this "absorbing" condition on the outer boundary loop of each component, with R the
/// radius of a disk of the component's area, lets w leave the surface as if it went on. Inner
/// boundary loops (holes) keep the natural condition: free space goes on through a hole.
std::vector<RobinTerm> robin_terms(const Topology& t) {
    const Triangulation& T = t.mesh;
    // Boundary loops: boundary edges joined through shared vertices.
    detail::DisjointSets loops(T.vertex_count);
    std::vector<std::uint32_t> boundary;
    for (std::size_t e = 0; e < T.edge_count(); ++e)
        if (t.edge_halfedges.count(e) == 1 && !t.degenerate(corner_face(t.edge_halfedges.begin(e)[0]))) {
            boundary.push_back(std::uint32_t(e));
            loops.join(T.edges[e][0], T.edges[e][1]);
        }
    std::map<std::uint32_t, double> loop_length;
    std::map<std::uint32_t, std::uint32_t> loop_component;
    for (std::uint32_t e : boundary) {
        const std::uint32_t r = loops.find(T.edges[e][0]);
        loop_length[r] += T.edge_lengths[e];
        loop_component[r] = t.face_component[corner_face(t.edge_halfedges.begin(e)[0])];
    }
    std::map<std::uint32_t, std::uint32_t> outer;  // component → its longest loop
    for (const auto& [loop, length] : loop_length) {
        auto [it, fresh] = outer.emplace(loop_component[loop], loop);
        if (!fresh && length > loop_length[it->second]) it->second = loop;
    }
    std::map<std::uint32_t, double> area;
    for (std::size_t f = 0; f < T.face_count(); ++f)
        if (!t.degenerate(f)) area[t.face_component[f]] += t.face_areas[f];
    std::vector<RobinTerm> terms;
    for (std::uint32_t e : boundary) {
        const std::uint32_t loop = loops.find(T.edges[e][0]);
        const std::uint32_t component = loop_component[loop];
        if (outer[component] != loop) continue;
        const double alpha = 1.0 / std::sqrt(area[component] / M_PI);
        const std::uint32_t h = t.edge_halfedges.begin(e)[0];
        const std::uint32_t f = corner_face(h);
        for (int k : {corner_index(h), (corner_index(h) + 1) % 3})
            terms.push_back({T.faces[f][std::size_t(k)], corner_id(f, k), 0.5 * alpha * T.edge_lengths[e]});
    }
    return terms;
}

// ---- labels and polylines ------------------------------------------------------------------

/// Per triangle: the mean of its defined corner values.
std::vector<double> face_means(const Triangulation& T, const std::vector<double>& corner) {
    std::vector<double> m(T.face_count(), 0.0);
    for (std::size_t f = 0; f < T.face_count(); ++f) {
        double s = 0;
        int n = 0;
        for (int k = 0; k < 3; ++k)
            if (std::isfinite(corner[corner_id(f, k)])) {
                s += corner[corner_id(f, k)];
                ++n;
            }
        m[f] = n ? s / n : 0.0;
    }
    return m;
}

/// The shift that puts the curves at half-integer levels of a jump function f: the mean value
/// of f just outside the curves (the side it jumps down to; length-weighted) moves to the
/// nearest integer, so rounding cuts halfway up each jump. Without it, rounding broken curves'
/// functions (values drift between gaps) can flip whole regions (the thesis' contouring).
double contour_shift(const Topology& t, const std::vector<double>& f, const std::vector<double>& chain) {
    const Triangulation& T = t.mesh;
    double sum = 0, weight = 0;
    for (std::size_t e = 0; e < T.edge_count(); ++e) {
        if (std::abs(chain[e]) < 0.5) continue;
        for (const std::uint32_t* h = t.edge_halfedges.begin(e); h != t.edge_halfedges.end(e); ++h) {
            const std::uint32_t face = corner_face(*h);
            const int k = corner_index(*h);
            // chain > 0: f drops from the left face (halfedge along the edge) to the right one.
            if (T.aligned[face][std::size_t(k)] == (chain[e] > 0)) continue;
            const double a = f[*h], b = f[corner_id(face, (k + 1) % 3)];
            const double m = std::isfinite(a) && std::isfinite(b) ? 0.5 * (a + b) : std::isfinite(a) ? a : b;
            if (!std::isfinite(m)) continue;
            sum += T.edge_lengths[e] * m;
            weight += T.edge_lengths[e];
        }
    }
    if (!(weight > 0)) return 0.0;
    const double mean = sum / weight;
    return std::round(mean) - mean;
}

/// Integer labels from face values, shifted so that the region outside every curve is 0 in each
/// connected component (winding numbers are defined up to a constant per component, and one
/// that no curve touches is all outside): on a component with boundary, the label most of its
/// boundary has; on a closed one the smallest label (a counter-clockwise loop is +1 on its
/// left, so the rest is the least). Degenerate triangles (component UINT32_MAX) follow the
/// whole mesh's zero.
std::vector<int> normalized_labels(const Topology& t, const std::vector<double>& face_value, double shift) {
    const Triangulation& T = t.mesh;
    std::vector<int> label(T.face_count());
    for (std::size_t f = 0; f < T.face_count(); ++f) label[f] = int(std::lround(face_value[f] + shift));
    constexpr std::uint32_t kWhole = UINT32_MAX;  // the whole mesh, and the degenerate triangles
    std::map<std::uint32_t, std::map<int, double>> boundary;  // component → label → boundary length
    std::map<std::uint32_t, int> least;
    for (std::size_t e = 0; e < T.edge_count(); ++e)
        if (t.edge_halfedges.count(e) == 1) {
            const std::uint32_t f = corner_face(t.edge_halfedges.begin(e)[0]);
            boundary[kWhole][label[f]] += T.edge_lengths[e];
            if (t.face_component[f] != kWhole) boundary[t.face_component[f]][label[f]] += T.edge_lengths[e];
        }
    for (std::size_t f = 0; f < T.face_count(); ++f) {
        auto lower = [&](std::uint32_t c) {
            const auto it = least.find(c);
            if (it == least.end() || label[f] < it->second) least[c] = label[f];
        };
        lower(kWhole);
        if (t.face_component[f] != kWhole) lower(t.face_component[f]);
    }
    std::map<std::uint32_t, int> zero;
    for (const auto& [c, l] : least) {
        const auto b = boundary.find(c);
        zero[c] = b == boundary.end() ? l
                                      : std::max_element(b->second.begin(), b->second.end(), [](const auto& x, const auto& y) {
                                            return x.second < y.second;
                                        })->first;
    }
    for (std::size_t f = 0; f < T.face_count(); ++f) label[f] -= zero[t.face_component[f]];
    return label;
}

// ---- the solver ---------------------------------------------------------------------------------

/// What one run of the algorithm produces on the mesh it ran on (the input or a cut copy).
struct CoreResult {
    std::vector<double> u, w;  // per corner
    std::vector<double> bounding_chain;  // per edge: the bounding part of the curves' chain
    std::vector<int> labels, naive_labels;  // per triangle
    Polylines bounding, nonbounding, completed;
    bool simply_connected = true;
    std::size_t lp_variables = 0, lp_rows = 0;
    double lp_objective = 0, lp_violation = 0, seconds_jump = 0, seconds_hodge = 0, seconds_residual = 0,
           seconds_boundary = 0;
};

/// The parts of a run's result that the solver's result takes as they are (the curves' kinds,
/// the program's size and cost, the timings).
void take_curves_and_costs(SwnResult& result, CoreResult& r) {
    result.bounding = std::move(r.bounding);
    result.nonbounding = std::move(r.nonbounding);
    result.completed = std::move(r.completed);
    result.simply_connected = r.simply_connected;
    result.lp_variables = r.lp_variables;
    result.lp_rows = r.lp_rows;
    result.lp_objective = r.lp_objective;
    result.lp_violation = r.lp_violation;
    result.seconds_jump = r.seconds_jump;
    result.seconds_hodge = r.seconds_hodge;
    result.seconds_residual = r.seconds_residual;
    result.seconds_boundary = r.seconds_boundary;
}

/// The operators of one mesh, built on first use and kept.
struct Operators {
    const Topology* t = nullptr;
    Halfedges H;
    bool simply_connected = true;
    bool has_boundary = false;
    std::optional<Cholesky<double>> jump;   // the first factor: its analysis serves later curves
    std::optional<Cholesky<double>> hodge;  // d1 ⋆1⁻¹ d1ᵀ on faces
    std::vector<double> inv_hodge;          // ⋆1⁻¹ per edge
    std::vector<std::uint8_t> cut;          // the reduced program's cut graph
    std::optional<std::vector<RobinTerm>> robin_;  // the boundary-aware condition

    const std::vector<RobinTerm>& robin() {
        if (!robin_) robin_ = robin_terms(*t);
        return *robin_;
    }

    explicit Operators(const Topology& topology)
        : t(&topology), H(manifold_halfedges(topology)), simply_connected(mesh::simply_connected(topology)) {
        for (std::size_t e = 0; e < topology.mesh.edge_count() && !has_boundary; ++e)
            has_boundary = topology.edge_halfedges.count(e) == 1;
    }

    Cholesky<double> factor_jump(const SparseLower<double>& K) {
        if (!jump) {
            jump.emplace(K);
            return Cholesky<double>(*jump, K);
        }
        return Cholesky<double>(*jump, K);
    }

    /// γ = ω − δβ with d δβ = d ω: removes the co-exact part the curve ends put into ω.
    std::vector<double> harmonic_part(const std::vector<double>& omega) {
        const Triangulation& T = t->mesh;
        const std::size_t F = T.face_count();
        if (!hodge) {
            inv_hodge = inverse_hodge1(H);
            SparseLower<double> B(F);
            std::vector<double> diagonal(F, 1e-8);
            for (std::size_t e = 0; e < T.edge_count(); ++e) {
                const EdgeSides s = sides(*t, e);
                for (std::uint32_t f : {s.left, s.right})
                    if (f != kNone) diagonal[f] += inv_hodge[e];
                // The two faces enter d1 with opposite signs (left +, right −).
                if (s.left != kNone && s.right != kNone) B.add(std::max(s.left, s.right), std::min(s.left, s.right), -inv_hodge[e]);
            }
            for (std::size_t f = 0; f < F; ++f) B.add(f, f, diagonal[f]);
            hodge.emplace(B);
        }
        std::vector<double> d_omega(F, 0.0);  // d1 ω: circulation around each face
        for (std::size_t f = 0; f < F; ++f)
            for (int k = 0; k < 3; ++k) {
                const double o = omega[T.face_edges[f][std::size_t(k)]];
                d_omega[f] += T.aligned[f][std::size_t(k)] ? o : -o;
            }
        const std::vector<double> beta = hodge->solve(d_omega);
        std::vector<double> gamma = omega;
        for (std::size_t e = 0; e < T.edge_count(); ++e) {
            const EdgeSides s = sides(*t, e);
            double d1t = 0;  // (d1ᵀ β)_e
            if (s.left != kNone) d1t += beta[s.left];
            if (s.right != kNone) d1t -= beta[s.right];
            gamma[e] -= inv_hodge[e] * d1t;
        }
        return gamma;
    }
};

CoreResult run_core(Operators& ops, const std::vector<double>& chain, const SwnOptions& o, const ProgressFn& progress) {
    const Topology& t = *ops.t;
    const Triangulation& T = t.mesh;
    CoreResult r;
    r.simply_connected = ops.simply_connected;
    auto t0 = Clock::now();
    if (progress) progress("jump Laplace equation", 0.1);
    const JumpData J = jump_offsets(ops.H, chain, nullptr);
    const Cholesky<double> K = ops.factor_jump(jump_matrix(ops.H, J.endpoint));
    r.u = corner_values(T, K.solve(jump_rhs(ops.H, J)), J);
    r.naive_labels = normalized_labels(t, face_means(T, r.u), contour_shift(t, r.u, chain));
    r.seconds_jump = seconds_since(t0);
    std::vector<double> bounding_chain = chain;
    JumpData J_final = J;  // the jumps of w
    if (!ops.simply_connected && o.residual != SwnResidual::None) {
        t0 = Clock::now();
        if (progress) progress("Hodge decomposition", 0.3);
        const auto any_end = [](const JumpData& data) {
            return std::any_of(data.endpoint.begin(), data.endpoint.end(), [](std::uint8_t e) { return e != 0; });
        };
        // With close_gaps the program runs on the curves closed across their gaps (closed_chain
        // says why); the bounding part it finds is then taken from the curves as given.
        std::vector<double> lp_chain = chain;
        JumpData JL = J;
        std::vector<double> u_closed;
        const std::vector<double>* u_lp = &r.u;
        if (o.close_gaps && any_end(J)) {
            lp_chain = closed_chain(t, chain, J.endpoint);
            JL = jump_offsets(ops.H, lp_chain, nullptr);
            const Cholesky<double> KL = ops.factor_jump(jump_matrix(ops.H, JL.endpoint));
            u_closed = corner_values(T, KL.solve(jump_rhs(ops.H, JL)), JL);
            u_lp = &u_closed;
        }
        const std::vector<double> omega = darboux_derivative(t, *u_lp, JL);
        const std::vector<double> gamma = any_end(JL) ? ops.harmonic_part(omega) : omega;
        r.seconds_hodge = seconds_since(t0);
        t0 = Clock::now();
        if (progress) progress("residual function (linear program)", 0.5);
        std::vector<double> v;
        std::vector<std::uint32_t> group;
        std::size_t groups = 0;
        if (o.residual == SwnResidual::Full) {
            v = integrate_in_faces(T, gamma);
            group.resize(T.face_count());
            std::iota(group.begin(), group.end(), 0u);
            groups = T.face_count();
        } else {
            if (ops.cut.empty()) ops.cut = cut_graph(t);
            std::vector<std::uint8_t> cut = ops.cut;
            const std::vector<std::uint8_t> paths = completion_paths(t, chain, J.endpoint);
            for (std::size_t e = 0; e < T.edge_count(); ++e)
                cut[e] = cut[e] || paths[e] || std::abs(chain[e]) > 1e-9 || std::abs(lp_chain[e]) > 1e-9;
            const std::vector<std::uint8_t> detours = reversed_run_detours(t, chain);
            for (std::size_t e = 0; e < T.edge_count(); ++e) cut[e] = cut[e] || detours[e];
            group = cut_components(t, cut, gamma, v, groups);
        }
        const std::vector<double> straightness = curve_straightness(t, lp_chain);
        const ResidualLp lp = solve_residual_lp(t, v, group, groups, lp_chain, straightness, o);
        for (std::size_t f = 0; f < T.face_count(); ++f)
            for (int k = 0; k < 3; ++k) v[corner_id(f, k)] += lp.shift[group[f]];
        r.lp_variables = lp.variables;
        r.lp_rows = lp.rows;
        // ⑤ The residual's jumps on the input curves are their nonbounding part; elsewhere they
        // complete it. The bounding part is what remains of the curves.
        const std::vector<double> jumps = edge_jumps(t, v);
        // The full program's cost at v, over every edge: the same measure whichever program
        // found v (the reduced one's own cost leaves out the edges inside its pieces).
        std::tie(r.lp_objective, r.lp_violation) = residual_cost(t, jumps, lp_chain, straightness, o);
        std::vector<double> nonbounding(T.edge_count(), 0.0), completed(T.edge_count(), 0.0);
        for (std::size_t e = 0; e < T.edge_count(); ++e) {
            if (std::abs(chain[e]) > 1e-9) {
                // A completion running over a curve edge can widen its bounds: keep the jump
                // within the curve's own.
                nonbounding[e] = std::clamp(jumps[e], std::min(0.0, chain[e]), std::max(0.0, chain[e]));
                bounding_chain[e] = chain[e] - nonbounding[e];
            } else {
                completed[e] = jumps[e];
            }
        }
        r.nonbounding = mesh::chain_polylines(t, nonbounding);
        r.completed = mesh::chain_polylines(t, completed);
        r.seconds_residual = seconds_since(t0);
        t0 = Clock::now();
        if (progress) progress("winding number", 0.9);
        J_final = jump_offsets(ops.H, bounding_chain, &J.endpoint);
        r.w = corner_values(T, K.solve(jump_rhs(ops.H, J_final)), J_final);
        r.seconds_jump += seconds_since(t0);
    } else {
        r.w = r.u;
    }
    if (o.boundary_aware && ops.has_boundary) {
        t0 = Clock::now();
        if (progress) progress("boundary-aware winding number", 0.95);
        const std::vector<RobinTerm>& robin = ops.robin();
        const Cholesky<double> KR = ops.factor_jump(jump_matrix(ops.H, J.endpoint, &robin));
        r.w = corner_values(T, KR.solve(jump_rhs(ops.H, J_final, &robin)), J_final);
        r.seconds_boundary = seconds_since(t0);
    }
    r.bounding = mesh::chain_polylines(t, bounding_chain);
    r.labels = normalized_labels(t, face_means(T, r.w), contour_shift(t, r.w, bounding_chain));
    r.bounding_chain = std::move(bounding_chain);
    return r;
}

/// The chain of pieces that all run along edges between vertices (1 per piece along its
/// direction), or nothing if some piece does not.
std::optional<std::vector<double>> edge_chain(const Topology& t, const surface_shm::ResolvedSources& S) {
    const Triangulation& T = t.mesh;
    std::vector<double> chain(T.edge_count(), 0.0);
    auto vertex_of = [](const std::array<double, 3>& b) {
        int k = -1;
        for (int i = 0; i < 3; ++i)
            if (b[std::size_t(i)] == 1.0) k = i;
        return k;
    };
    for (const surface_shm::CurvePiece& p : S.pieces) {
        const int side = surface_shm::piece_side(p.segment);
        const int a = vertex_of(p.segment.a), b = vertex_of(p.segment.b);
        if (side < 0 || a < 0 || b < 0 || a == b) return std::nullopt;
        const std::uint32_t f = p.segment.face;
        const std::uint32_t e = T.face_edges[f][std::size_t(side)];
        const std::uint32_t from = T.faces[f][std::size_t(a)];
        chain[e] += T.edges[e][0] == from ? 1.0 : -1.0;
    }
    return chain;
}

/// The share of a chain's edges that is bounding (1 where the chain is empty).
double bounding_share(const std::vector<double>& chain, const std::vector<double>& bounding, std::uint32_t e) {
    return std::abs(chain[e]) > 1e-9 ? std::clamp(bounding[e] / chain[e], 0.0, 1.0) : 1.0;
}

SurfacePoint surface_point(const mesh::FacePoint& p, const Triangulation& T) {
    for (int k = 0; k < 3; ++k)
        if (p.bary[std::size_t(k)] == 1.0) return SurfacePoint::at_vertex(T.faces[p.face][std::size_t(k)]);
    return SurfacePoint::in_triangle(p.face, p.bary[1], p.bary[2]);
}

/// The resolved pieces whose share is at least ½, as curves on the input mesh: consecutive
/// pieces of one component that meet are one curve.
SurfaceSources bounding_pieces(const Topology& t, const surface_shm::ResolvedSources& S, const std::vector<double>& share) {
    SurfaceSources out;
    Eigen::Vector3d last_end(NAN, NAN, NAN);
    std::uint32_t last_component = UINT32_MAX;
    auto at = [&](std::uint32_t f, const std::array<double, 3>& b) {
        Eigen::Vector3d x = Eigen::Vector3d::Zero();
        for (int k = 0; k < 3; ++k) x += b[std::size_t(k)] * t.corner_position(f, k);
        return x;
    };
    for (std::size_t i = 0; i < S.pieces.size(); ++i) {
        const surface_shm::CurvePiece& p = S.pieces[i];
        if (share[i] < 0.5) {
            last_component = UINT32_MAX;
            continue;
        }
        const Eigen::Vector3d a = at(p.segment.face, p.segment.a);
        const bool joins = p.component == last_component && (a - last_end).norm() <= 1e-12 * (1 + a.norm());
        if (!joins) {
            out.curves.emplace_back();
            out.curves.back().nodes.push_back(surface_point({p.segment.face, p.segment.a}, t.mesh));
        }
        out.curves.back().nodes.push_back(surface_point({p.segment.face, p.segment.b}, t.mesh));
        last_end = at(p.segment.face, p.segment.b);
        last_component = p.component;
    }
    return out;
}

std::vector<int> majority_per_face(const SurfaceMesh& mesh, const std::vector<std::uint32_t>& triangle_face,
                                   const std::vector<double>& areas, const std::vector<int>& labels) {
    std::vector<std::map<int, double>> votes(mesh.face_count());
    for (std::size_t f = 0; f < labels.size(); ++f) votes[triangle_face[f]][labels[f]] += areas[f] + 1e-300;
    std::vector<int> out(mesh.face_count(), 0);
    for (std::size_t f = 0; f < out.size(); ++f)
        if (!votes[f].empty())
            out[f] = std::max_element(votes[f].begin(), votes[f].end(),
                                      [](const auto& a, const auto& b) { return a.second < b.second; })->first;
    return out;
}

}  // namespace

SwnResidual swn_residual_from_name(const std::string& name) {
    if (name == "full") return SwnResidual::Full;
    if (name == "reduced") return SwnResidual::Reduced;
    if (name == "none") return SwnResidual::None;
    throw Error("lp", "unknown residual program '" + name + "' (full, reduced, none)");
}

SwnSolver swn_solver_from_name(const std::string& name) {
    if (name == "network") return SwnSolver::Network;
    if (name == "clp") return SwnSolver::Clp;
    throw Error("lp solver", "unknown solver '" + name + "' (network, clp)");
}

struct SurfaceWindingNumbers::Impl {
    SurfaceMesh mesh;
    std::optional<Operators> ops;  // of the input mesh
    explicit Impl(SurfaceMesh m) : mesh(std::move(m)) {}
};

SurfaceWindingNumbers::SurfaceWindingNumbers(SurfaceMesh mesh) {
    // Measured: 2.7–3.6 KiB per vertex at 10⁶ (operators, factorizations, the residual program),
    // plus the process's own ~11 MiB, which at 10⁵ vertices made a plain 4 KiB too little; docs/io.md.
    check_memory(32.0 * (1 << 20) + 4096.0 * double(mesh.vertex_count()), "mesh",
                 "Surface Winding Numbers on " + std::to_string(mesh.vertex_count()) + " vertices");
    impl_ = std::make_unique<Impl>(std::move(mesh));
}
SurfaceWindingNumbers::~SurfaceWindingNumbers() = default;
SurfaceWindingNumbers::SurfaceWindingNumbers(SurfaceWindingNumbers&&) noexcept = default;
SurfaceWindingNumbers& SurfaceWindingNumbers::operator=(SurfaceWindingNumbers&&) noexcept = default;
const SurfaceMesh& SurfaceWindingNumbers::mesh() const { return impl_->mesh; }

SwnResult SurfaceWindingNumbers::solve(const SurfaceSources& curves, const SwnOptions& options,
                                       const ProgressFn& progress) {
    const auto start = Clock::now();
    if (!(options.curve_weight >= 0 && options.curve_weight <= 1))
        throw Error("SwnOptions::curve_weight", "must be in (0, 1], or 0 for the program's default");
    SwnOptions o = options;
    if (o.curve_weight == 0)
        o.curve_weight = o.residual == SwnResidual::Full ? kSwnFullCurveWeight : kSwnReducedCurveWeight;
    if (curves.curves.empty()) throw Error("curves", "no curves: winding numbers need oriented curves");
    if (!curves.points.empty()) throw Error("curves", "isolated points have no winding number: give curves only");
    for (const SurfaceCurve& c : curves.curves)
        if (!c.is_signed) throw Error("curves", "winding numbers need oriented (signed) curves");
    const SurfaceMesh& mesh = impl_->mesh;
    validate(curves, mesh, "curves");
    const Topology& t = mesh.topology();
    const surface_shm::ResolvedSources S = surface_shm::resolve_sources(t, curves, "curves");
    if (S.pieces.empty()) throw Error("curves", "every curve has zero length");
    SwnResult result;
    if (const auto on_edges = edge_chain(t, S)) {
        if (!impl_->ops) impl_->ops.emplace(t);
        CoreResult r = run_core(*impl_->ops, *on_edges, o, progress);
        std::vector<double> share(S.pieces.size());
        for (std::size_t i = 0; i < S.pieces.size(); ++i) {
            const surface_shm::CurvePiece& p = S.pieces[i];
            const std::uint32_t e = t.mesh.face_edges[p.segment.face][std::size_t(surface_shm::piece_side(p.segment))];
            share[i] = bounding_share(*on_edges, r.bounding_chain, e);
        }
        result.bounding_curves = bounding_pieces(t, S, share);
        result.labels = majority_per_face(mesh, t.triangle_face, t.face_areas, r.labels);
        result.naive_labels = majority_per_face(mesh, t.triangle_face, t.face_areas, r.naive_labels);
        result.w.resize(t.mesh.face_count());
        for (std::size_t f = 0; f < t.mesh.face_count(); ++f)
            for (int k = 0; k < 3; ++k) result.w[f][std::size_t(k)] = r.w[corner_id(f, k)];
        take_curves_and_costs(result, r);
    } else {
        // Curves off the edges: cut a copy of the mesh along them, solve there.
        std::vector<mesh::FaceSegment> pieces;
        for (const surface_shm::CurvePiece& p : S.pieces) pieces.push_back(p.segment);
        const mesh::SplitMesh cut = mesh::split_along(t, pieces);
        const SurfaceMesh split_mesh(cut.mesh, "cut mesh");
        const Topology& st = split_mesh.topology();
        std::vector<double> chain(st.mesh.edge_count(), 0.0);
        for (const auto& path : cut.piece_paths)
            for (std::size_t i = 0; i + 1 < path.size(); ++i) {
                const std::uint32_t e = st.find_edge(path[i], path[i + 1]);
                if (e == UINT32_MAX) throw Error("curves", "internal: a cut piece does not run along an edge");
                chain[e] += st.mesh.edges[e][0] == path[i] ? 1.0 : -1.0;
            }
        Operators ops(st);
        CoreResult r = run_core(ops, chain, o, progress);
        std::vector<double> share(S.pieces.size(), 1.0);
        for (std::size_t i = 0; i < S.pieces.size(); ++i) {
            const auto& path = cut.piece_paths[i];
            double sum = 0, length = 0;
            for (std::size_t k = 0; k + 1 < path.size(); ++k) {
                const std::uint32_t e = st.find_edge(path[k], path[k + 1]);
                sum += st.mesh.edge_lengths[e] * bounding_share(chain, r.bounding_chain, e);
                length += st.mesh.edge_lengths[e];
            }
            if (length > 0) share[i] = sum / length;
        }
        result.bounding_curves = bounding_pieces(t, S, share);
        // Labels per input face by area majority; w at input corners from a sub-triangle there.
        std::vector<std::uint32_t> input_face(st.mesh.face_count());
        for (std::size_t f = 0; f < input_face.size(); ++f) input_face[f] = t.triangle_face[cut.triangle_of[f]];
        result.labels = majority_per_face(mesh, input_face, st.face_areas, r.labels);
        result.naive_labels = majority_per_face(mesh, input_face, st.face_areas, r.naive_labels);
        result.w.assign(t.mesh.face_count(), {kNan, kNan, kNan});
        for (std::size_t f = 0; f < st.mesh.face_count(); ++f) {
            const std::uint32_t in = cut.triangle_of[f];
            for (int k = 0; k < 3; ++k)
                for (int j = 0; j < 3; ++j)
                    if (st.mesh.faces[f][std::size_t(k)] == t.mesh.faces[in][std::size_t(j)] &&
                        std::isnan(result.w[in][std::size_t(j)]))
                        result.w[in][std::size_t(j)] = r.w[corner_id(f, k)];
        }
        take_curves_and_costs(result, r);
        result.split = true;
    }
    // Corners at curve ends carry no value of their own: the mean of the triangle's others.
    for (auto& c : result.w) {
        double s = 0;
        int n = 0;
        for (double x : c)
            if (std::isfinite(x)) {
                s += x;
                ++n;
            }
        for (double& x : c)
            if (!std::isfinite(x)) x = n ? s / n : 0.0;
    }
    result.seconds_total = seconds_since(start);
    if (progress) progress("done", 1.0);
    return result;
}

std::vector<int> shm_labels(const SurfaceMesh& mesh, const std::vector<double>& phi) {
    if (phi.size() != mesh.vertex_count()) throw Error("shm_labels", "expected one value per vertex");
    const Topology& t = mesh.topology();
    std::map<std::uint32_t, double> largest;  // per component, max |φ|
    double overall = 0;
    for (std::size_t f = 0; f < t.mesh.face_count(); ++f)
        for (std::uint32_t v : t.mesh.faces[f])
            if (std::isfinite(phi[v])) {
                double& m = largest[t.face_component[f]];  // degenerate triangles: UINT32_MAX
                m = std::max(m, std::abs(phi[v]));
                overall = std::max(overall, std::abs(phi[v]));
            }
    std::vector<int> tri(t.mesh.face_count());
    for (std::size_t f = 0; f < tri.size(); ++f) {
        if (largest[t.face_component[f]] <= 1e-6 * overall) continue;  // unreached
        double s = 0;
        for (std::uint32_t v : t.mesh.faces[f]) s += phi[v];
        tri[f] = s < 0 ? 1 : 0;
    }
    return majority_per_face(mesh, t.triangle_face, t.face_areas, tri);
}

std::vector<int> vertex_labels(const SurfaceMesh& mesh, const std::vector<int>& face_labels) {
    if (face_labels.size() != mesh.face_count())
        throw Error("vertex_labels", std::to_string(face_labels.size()) + " labels for " + std::to_string(mesh.face_count()) + " faces");
    const Topology& t = mesh.topology();
    std::vector<std::map<int, double>> area(mesh.vertex_count());
    for (std::size_t f = 0; f < t.mesh.face_count(); ++f)
        if (t.face_areas[f] > 0)
            for (std::uint32_t v : t.mesh.faces[f]) area[v][face_labels[t.triangle_face[f]]] += t.face_areas[f];
    std::vector<int> labels(mesh.vertex_count(), 0);
    for (std::size_t v = 0; v < labels.size(); ++v) {
        double best = 0;
        for (const auto& [label, a] : area[v])  // ascending labels: a tie keeps the smaller
            if (a > best) best = a, labels[v] = label;
    }
    return labels;
}

}  // namespace gsd
