// The L1 integration's jump set and the cut triangulation (jumps.hpp).
#include "surface_shm/jumps.hpp"

#include "core/disjoint_sets.hpp"
#include "l1/tension.hpp"
#include "mesh/topology.hpp"
#include "surface_shm/operators.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <unordered_map>

namespace gsd::surface_shm {

namespace {

using mesh::Triangulation;

/// The corner of face f at end `end` (0, 1) of the edge under its halfedge k.
int edge_end_corner(const Triangulation& T, std::size_t f, int k, int end) {
    const bool forward = T.aligned[f][std::size_t(k)] != 0;
    return (end == 0) == forward ? k : (k + 1) % 3;
}

/// φ_f at a point of face f, less the face's level: ⟨Y_f, p − centroid⟩ (face_frame coordinates).
struct FaceLinear {
    FaceFrame frame;
    Eigen::Vector2d centroid;
    double at(const Eigen::Vector2d& p, const Eigen::Vector2d& Y) const { return Y.dot(p - centroid); }
};

FaceLinear face_linear(const Triangulation& T, const std::vector<double>& areas, std::size_t f) {
    FaceLinear L{face_frame(T, f, areas[f]), Eigen::Vector2d::Zero()};
    L.centroid = (L.frame.p[0] + L.frame.p[1] + L.frame.p[2]) / 3.0;
    return L;
}

/// How far Y is from integrable across an edge, per unit length: the jump of its tangential
/// component, |⟨Y_f − Y_g, ê⟩| ∈ [0, 2] (the circulation around the two faces over the edge's
/// length: Polthier–Preuß's rotation at the edge midpoint, made dimensionless).
double edge_curl(const FaceLinear& a, int ka, const Eigen::Vector2d& Ya, const FaceLinear& b, int kb,
                 const Eigen::Vector2d& Yb, const Triangulation& T, std::size_t fa, std::size_t fb) {
    auto tangent = [&](const FaceLinear& L, std::size_t f, int k) {
        const Eigen::Vector2d d = L.frame.p[std::size_t(edge_end_corner(T, f, k, 1))] -
                                  L.frame.p[std::size_t(edge_end_corner(T, f, k, 0))];
        const double n = d.norm();
        return n > 0 ? Eigen::Vector2d(d / n) : Eigen::Vector2d::Zero();
    };
    return std::abs(Ya.dot(tangent(a, fa, ka)) - Yb.dot(tangent(b, fb, kb)));
}

/// The program's terms, built once: a pair of faces across a mesh edge (two terms, one per end
/// of the edge: φ_f − φ_g there is x_f − x_g + offset) and a curve piece's ends tied to the
/// level of its component (φ_f − level = x_f − x_c + offset).
struct FacePair {
    std::uint32_t edge, f, g;
    std::array<double, 2> offset;
    double cost;   ///< per end: w·ℓ/2 (the trapezoid rule)
    bool f_left;   ///< f lies left of the edge's direction (its halfedge runs along it)
};
struct CurveTie {
    std::uint32_t f, component;
    double offset, cost;
};
// The weight of a jump across an edge: 1/(1 + (η/kCurlScale)²) for the field's curl η ∈ [0, 2]
// there (about 0.01 where the field is smooth on the meshes measured, order 1 where it breaks),
// times the nearness to the curves (1 − d/d_max), at least kWeightFloor. Measured on tori with a
// meridian, 3k–100k triangles: uniform weights put part of the jump next to the curve; the curl
// alone puts it there on thin tubes (R/r = 5); with both it lies at the antipode on all of them.
constexpr double kCurlScale = 0.1;
constexpr double kWeightFloor = 0.01;
// The curves' ties to their level, per unit length, against a jump's weight ≤ 1: a jump across a
// curve would move it off its level, which the zero-set constraint then forbids.
constexpr double kCurveTie = 20.0;
// Coarse to fine above 16 patches: patches of 32 faces (a 104k-triangle torus with a meridian:
// step 3 in 1.8 s instead of 112 s for the program over every face, the same 206 jump edges).
constexpr std::size_t kPatchSize = 32;
constexpr double kJumpEdgeLengths = 2.0;
constexpr double kJumpShareOfLargest = 0.1;

struct Terms {
    std::vector<FacePair> pairs;
    std::vector<CurveTie> ties;
    std::vector<std::vector<std::uint32_t>> face_pairs;  // per face: the pairs it is in
};

/// Faces grouped into patches of about `size` by breadth-first growth across pairs, each face's
/// level relative to its patch's first face from integrating Y along the growth tree (the jump
/// across each tree edge is zero at its midpoint).
struct Patches {
    std::vector<std::uint32_t> of;  // per face
    std::vector<double> level;      // per face, relative
    std::uint32_t count = 0;
};

Patches grow_patches(const Terms& t, std::size_t faces, std::size_t size) {
    Patches P;
    P.of.assign(faces, UINT32_MAX);
    P.level.assign(faces, 0.0);
    std::vector<std::uint32_t> queue;
    for (std::uint32_t seed = 0; seed < faces; ++seed) {
        if (P.of[seed] != UINT32_MAX) continue;
        const std::uint32_t id = P.count++;
        P.of[seed] = id;
        queue.assign(1, seed);
        for (std::size_t head = 0; head < queue.size() && queue.size() < size; ++head) {
            const std::uint32_t f = queue[head];
            for (std::uint32_t q : t.face_pairs[f]) {
                const FacePair& pr = t.pairs[q];
                const bool forward = pr.f == f;
                const std::uint32_t g = forward ? pr.g : pr.f;
                if (P.of[g] != UINT32_MAX || queue.size() >= size) continue;
                P.of[g] = id;
                // Zero mean jump: x_f − x_g + mean(offset) = 0 (signs swap when f is the pair's g).
                const double mean = 0.5 * (pr.offset[0] + pr.offset[1]);
                P.level[g] = P.level[f] + (forward ? mean : -mean);
                queue.push_back(g);
            }
        }
    }
    return P;
}

/// Adds Σ_i c_i·|x_l − x_r + o_i| to the program, merged into one term Σc·|x_l − x_r + ô| with
/// ô the cost-weighted median of the o_i (the merged term has its minimum where the sum does)
/// when `merge`; term by term otherwise.
void add_terms(l1::TensionProblem& p, std::uint32_t l, std::uint32_t r, std::vector<std::pair<double, double>>& terms,
               bool merge) {
    if (!merge) {
        for (const auto& [o, c] : terms) p.edges.push_back({l, r, o, c});
        return;
    }
    std::sort(terms.begin(), terms.end());
    double total = 0, below = 0;
    for (const auto& term : terms) total += term.second;
    for (const auto& [o, c] : terms) {
        below += c;
        if (below >= 0.5 * total) {
            p.edges.push_back({l, r, o, total});
            return;
        }
    }
}

/// The program with each face's value tied to a node, x_f = x[node[f]] + level[f]. Terms within
/// one node are constants and left out; terms between two nodes below `merged` (patches) are
/// merged. Returns every face's value.
std::vector<double> solve_restricted(const Terms& t, const std::vector<std::uint32_t>& node,
                                     const std::vector<double>& level, std::size_t nodes, std::size_t components,
                                     std::uint32_t merged, JumpSet& J) {
    l1::TensionProblem p;
    p.nodes = nodes + components;
    // Terms per ordered pair of nodes, gathered to be merged.
    std::unordered_map<std::uint64_t, std::vector<std::pair<double, double>>> between;
    for (const FacePair& pr : t.pairs) {
        const std::uint32_t a = node[pr.f], b = node[pr.g];
        if (a == b) continue;
        const bool swap = a > b;
        auto& terms = between[swap ? (std::uint64_t(b) << 32 | a) : (std::uint64_t(a) << 32 | b)];
        for (int end = 0; end < 2; ++end) {
            const double o = pr.offset[std::size_t(end)] + level[pr.f] - level[pr.g];
            terms.push_back({swap ? -o : o, pr.cost});
        }
    }
    for (const CurveTie& c : t.ties) {
        const std::uint32_t a = node[c.f], b = std::uint32_t(nodes + c.component);
        between[std::uint64_t(a) << 32 | b].push_back({c.offset + level[c.f], c.cost});
    }
    std::vector<std::uint64_t> keys;
    keys.reserve(between.size());
    for (const auto& kv : between) keys.push_back(kv.first);
    std::sort(keys.begin(), keys.end());  // the program's order, so the optimum it picks is reproducible
    for (std::uint64_t k : keys)
        add_terms(p, std::uint32_t(k >> 32), std::uint32_t(k), between[k], std::uint32_t(k >> 32) < merged && std::uint32_t(k) < merged);
    const l1::TensionSolution s = l1::solve_tension_network(p);
    J.lp_nodes = p.nodes;
    J.lp_edges = p.edges.size();
    std::vector<double> x(node.size());
    for (std::size_t f = 0; f < node.size(); ++f) x[f] = level[f] + s.x[node[f]];
    return x;
}

/// The least |jump| along a pair's edge: 0 where the jump changes sign along it.
double least_jump(const FacePair& pr, const std::vector<double>& x) {
    const double j0 = x[pr.f] - x[pr.g] + pr.offset[0], j1 = x[pr.f] - x[pr.g] + pr.offset[1];
    return (j0 > 0) == (j1 > 0) ? std::min(std::abs(j0), std::abs(j1)) : 0.0;
}

/// The jumps φ needs: a jump is the field's own variation, accommodated where its curl makes
/// jumps cheap, up to a few edge lengths h (measured up to 8h on marching-cubes meshes); one
/// across a curve that bounds nothing is the field's period around the handle, the length of a
/// loop (measured 30–250h). Kept: at least 2h all along the edge, and at least a tenth of the
/// largest jump.
double jump_threshold(const Terms& t, const std::vector<double>& x, double h) {
    double largest = 0;
    for (const FacePair& pr : t.pairs) largest = std::max(largest, least_jump(pr, x));
    return std::max(kJumpEdgeLengths * h, kJumpShareOfLargest * largest);
}

/// Removes chains of jump edges that end inside the surface, until every jump edge lies on a
/// loop or runs to the boundary. A jump φ needs — the period of the field around a handle —
/// runs along a closed loop; a chain that stops inside only absorbs the field's curl where it
/// is cheap (far from the curves, at their cut locus), and cutting there would change nothing
/// but the drawing (measured: ε 6e-4 from the L² result on a double torus with a bounding pair).
void prune_dangling(const Triangulation& T, const mesh::Adjacency& halfedges, std::vector<std::int8_t>& cut) {
    std::vector<std::uint32_t> degree(T.vertex_count, 0);
    std::vector<std::uint8_t> boundary(T.vertex_count, 0);
    std::vector<std::vector<std::uint32_t>> at(T.vertex_count);
    for (std::size_t e = 0; e < T.edge_count(); ++e) {
        if (halfedges.count(e) == 1) boundary[T.edges[e][0]] = boundary[T.edges[e][1]] = 1;
        if (!cut[e]) continue;
        for (std::uint32_t v : T.edges[e]) {
            ++degree[v];
            at[v].push_back(std::uint32_t(e));
        }
    }
    std::vector<std::uint32_t> ends;
    for (std::uint32_t v = 0; v < T.vertex_count; ++v)
        if (degree[v] == 1 && !boundary[v]) ends.push_back(v);
    while (!ends.empty()) {
        const std::uint32_t v = ends.back();
        ends.pop_back();
        if (degree[v] != 1) continue;
        for (std::uint32_t e : at[v]) {
            if (!cut[e]) continue;
            cut[e] = 0;
            for (std::uint32_t w : T.edges[e])
                if (--degree[w] == 1 && !boundary[w]) ends.push_back(w);
        }
    }
}

/// The program's terms: the weights (see kCurlScale) and each face's linear φ from Y.
Terms build_terms(const Triangulation& T, const mesh::Adjacency& halfedges, const std::vector<double>& areas,
                  const std::vector<Eigen::Vector2d>& Y, const std::vector<double>& distance, const ResolvedSources& S) {
    const std::size_t F = T.face_count();
    std::vector<FaceLinear> faces;
    faces.reserve(F);
    for (std::size_t f = 0; f < F; ++f) faces.push_back(face_linear(T, areas, f));
    double farthest = 0;
    for (double d : distance)
        if (std::isfinite(d)) farthest = std::max(farthest, d);
    auto nearness = [&](std::size_t e) {  // 1 on the curves, 0 at the farthest point from them
        if (!(farthest > 0)) return 1.0;
        const double d = 0.5 * (distance[T.edges[e][0]] + distance[T.edges[e][1]]);
        return std::isfinite(d) ? std::clamp(1.0 - d / farthest, 0.0, 1.0) : 1.0;
    };

    Terms t;
    t.face_pairs.resize(F);
    // The first face on each edge against each other one (a nonmanifold edge has more than two).
    for (std::size_t e = 0; e < T.edge_count(); ++e) {
        if (halfedges.count(e) < 2) continue;
        const std::uint32_t h0 = *halfedges.begin(e);
        const std::size_t f = mesh::corner_face(h0);
        const int k = mesh::corner_index(h0);
        const double length = T.edge_lengths[e];
        for (const std::uint32_t* it = halfedges.begin(e) + 1; it != halfedges.end(e); ++it) {
            const std::size_t g = mesh::corner_face(*it);
            const int m = mesh::corner_index(*it);
            if (g == f || areas[f] <= 0 || areas[g] <= 0 || !(length > 0)) continue;
            const double eta = edge_curl(faces[f], k, Y[f], faces[g], m, Y[g], T, f, g);
            const double w = std::max(kWeightFloor, nearness(e) / (1.0 + (eta / kCurlScale) * (eta / kCurlScale)));
            FacePair pr{std::uint32_t(e), std::uint32_t(f), std::uint32_t(g), {}, 0.5 * w * length, T.aligned[f][std::size_t(k)] != 0};
            for (int end = 0; end < 2; ++end)
                pr.offset[std::size_t(end)] =
                    faces[f].at(faces[f].frame.p[std::size_t(edge_end_corner(T, f, k, end))], Y[f]) -
                    faces[g].at(faces[g].frame.p[std::size_t(edge_end_corner(T, g, m, end))], Y[g]);
            t.face_pairs[f].push_back(std::uint32_t(t.pairs.size()));
            t.face_pairs[g].push_back(std::uint32_t(t.pairs.size()));
            t.pairs.push_back(pr);
        }
    }
    // Each curve component at one level: both ends of every piece tied to its component's node.
    for (const CurvePiece& c : S.pieces) {
        const std::size_t f = c.segment.face;
        if (areas[f] <= 0) continue;
        Eigen::Vector2d a = Eigen::Vector2d::Zero(), b = Eigen::Vector2d::Zero();
        for (int k = 0; k < 3; ++k) {
            a += c.segment.a[std::size_t(k)] * faces[f].frame.p[std::size_t(k)];
            b += c.segment.b[std::size_t(k)] * faces[f].frame.p[std::size_t(k)];
        }
        const double length = (b - a).norm();
        if (!(length > 0)) continue;
        for (const Eigen::Vector2d& end : {a, b})
            t.ties.push_back({std::uint32_t(f), c.component, faces[f].at(end, Y[f]), 0.5 * kCurveTie * length});
    }
    return t;
}

/// Every face's level at the program's optimum: directly on small meshes; coarse to fine above
/// 16 patches — the program over patches (their terms merged) finds roughly where φ jumps, and
/// the patches there and one ring around them are solved face by face, the rest still tied.
std::vector<double> face_levels(const Terms& t, std::size_t faces, std::size_t components, double h, JumpSet& J) {
    if (faces < 16 * kPatchSize) {
        std::vector<std::uint32_t> own(faces);
        std::iota(own.begin(), own.end(), 0u);
        return solve_restricted(t, own, std::vector<double>(faces, 0.0), faces, components, 0, J);
    }
    const Patches P = grow_patches(t, faces, kPatchSize);
    const std::vector<double> coarse = solve_restricted(t, P.of, P.level, P.count, components, P.count, J);
    const double tau = jump_threshold(t, coarse, h);
    std::vector<std::uint8_t> near(P.count, 0);
    for (const FacePair& pr : t.pairs)
        if (least_jump(pr, coarse) > tau) near[P.of[pr.f]] = near[P.of[pr.g]] = 1;
    std::vector<std::uint8_t> freed = near;
    for (const FacePair& pr : t.pairs)
        if (near[P.of[pr.f]] || near[P.of[pr.g]]) freed[P.of[pr.f]] = freed[P.of[pr.g]] = 1;
    std::vector<std::uint32_t> node(P.of);
    std::vector<double> level(P.level);
    std::uint32_t nodes = P.count;
    for (std::size_t f = 0; f < faces; ++f)
        if (freed[P.of[f]]) {
            node[f] = nodes++;
            level[f] = 0;
        }
    if (nodes == P.count) return coarse;
    return solve_restricted(t, node, level, nodes, components, P.count, J);
}

}  // namespace

JumpSet l1_jumps(const Triangulation& T, const std::vector<double>& areas, const std::vector<Eigen::Vector2d>& Y,
                 const std::vector<double>& distance, const ResolvedSources& S, double h) {
    const mesh::Adjacency halfedges = mesh::corner_adjacency(T.edge_count(), T.face_edges);
    const Terms t = build_terms(T, halfedges, areas, Y, distance, S);
    JumpSet J;
    const std::vector<double> x = face_levels(t, T.face_count(), S.component_count, h, J);
    J.cut.assign(T.edge_count(), 0);
    for (const FacePair& pr : t.pairs)
        J.objective += pr.cost * (std::abs(x[pr.f] - x[pr.g] + pr.offset[0]) + std::abs(x[pr.f] - x[pr.g] + pr.offset[1]));
    const double tau = jump_threshold(t, x, h);
    for (const FacePair& pr : t.pairs)
        if (least_jump(pr, x) > tau && !J.cut[pr.edge]) {
            const bool up = x[pr.f] - x[pr.g] + pr.offset[0] > 0;  // φ higher on f's side
            J.cut[pr.edge] = up == pr.f_left ? 1 : -1;
        }
    prune_dangling(T, halfedges, J.cut);
    J.cut_edges = std::size_t(std::count_if(J.cut.begin(), J.cut.end(), [](std::int8_t c) { return c != 0; }));
    return J;
}

CutTriangulation cut_triangulation(const Triangulation& T, const std::vector<std::int8_t>& cut) {
    const std::size_t F = T.face_count();
    const mesh::Adjacency halfedges = mesh::corner_adjacency(T.edge_count(), T.face_edges);
    // Corners are one vertex where an uncut edge joins them (both ends of the edge).
    detail::DisjointSets corners(3 * F);
    std::vector<std::uint8_t> touched(T.vertex_count, 0);  // the vertex is on a cut edge
    for (std::size_t e = 0; e < T.edge_count(); ++e) {
        if (cut[e]) {
            touched[T.edges[e][0]] = touched[T.edges[e][1]] = 1;
            continue;
        }
        if (halfedges.count(e) < 2) continue;
        const std::uint32_t h0 = *halfedges.begin(e);
        for (const std::uint32_t* it = halfedges.begin(e) + 1; it != halfedges.end(e); ++it)
            for (int end = 0; end < 2; ++end)
                corners.join(mesh::corner_id(mesh::corner_face(*it),
                                             edge_end_corner(T, mesh::corner_face(*it), mesh::corner_index(*it), end)),
                             mesh::corner_id(mesh::corner_face(h0),
                                             edge_end_corner(T, mesh::corner_face(h0), mesh::corner_index(h0), end)));
    }
    // A vertex no cut reaches stays one vertex, whatever its fans (a nonmanifold pinch).
    std::vector<std::uint32_t> first_corner(T.vertex_count, UINT32_MAX);
    for (std::size_t f = 0; f < F; ++f)
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t v = T.faces[f][std::size_t(k)];
            if (touched[v]) continue;
            if (first_corner[v] == UINT32_MAX) first_corner[v] = mesh::corner_id(f, k);
            else corners.join(mesh::corner_id(f, k), first_corner[v]);
        }

    CutTriangulation out;
    std::vector<std::uint32_t> id(3 * F, UINT32_MAX);
    out.T.faces.resize(F);
    for (std::size_t f = 0; f < F; ++f)
        for (int k = 0; k < 3; ++k) {
            std::uint32_t& v = id[corners.find(mesh::corner_id(f, k))];
            if (v == UINT32_MAX) {
                v = std::uint32_t(out.vertex_of.size());
                out.vertex_of.push_back(T.faces[f][std::size_t(k)]);
            }
            out.T.faces[f][std::size_t(k)] = v;
        }
    out.T.vertex_count = std::uint32_t(out.vertex_of.size());
    // Vertices on no face keep their place at the end (they are cut off in the solve either way).
    // Edges: an uncut one stays one edge; a cut one becomes one edge per face on it.
    out.T.face_edges.resize(F);
    out.T.aligned = T.aligned;
    for (std::size_t e = 0; e < T.edge_count(); ++e) {
        for (std::size_t i = 0; i < halfedges.count(e); ++i) {
            const std::uint32_t h = halfedges.begin(e)[i];
            const std::size_t f = mesh::corner_face(h);
            const int k = mesh::corner_index(h);
            if (i == 0 || cut[e]) {
                out.T.edges.push_back({out.T.faces[f][std::size_t(edge_end_corner(T, f, k, 0))],
                                       out.T.faces[f][std::size_t(edge_end_corner(T, f, k, 1))]});
                out.T.edge_lengths.push_back(T.edge_lengths[e]);
            }
            out.T.face_edges[f][std::size_t(k)] = std::uint32_t(out.T.edges.size() - 1);
        }
    }
    return out;
}

}  // namespace gsd::surface_shm
