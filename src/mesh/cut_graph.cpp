// cut_graph.cpp — see cut_graph.hpp.
#include "mesh/cut_graph.hpp"
#include "core/disjoint_sets.hpp"

#include <cmath>
#include <functional>
#include <map>
#include <numeric>
#include <queue>

namespace gsd::mesh {

namespace {
constexpr std::uint32_t kNone = UINT32_MAX;
}  // namespace

std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> edge_neighbours(const Triangulation& T) {
    std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> nbr(T.vertex_count);
    for (std::size_t e = 0; e < T.edge_count(); ++e) {
        const auto [a, b] = T.edges[e];
        if (a == b) continue;
        nbr[a].push_back({b, std::uint32_t(e)});
        nbr[b].push_back({a, std::uint32_t(e)});
    }
    return nbr;
}

std::vector<std::uint8_t> cut_graph(const Topology& t) {
    const Triangulation& T = t.mesh;
    const std::size_t V = T.vertex_count, E = T.edge_count();
    // Shortest-path tree of vertices (per component).
    const std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> nbr = edge_neighbours(T);
    std::vector<double> dist(V, INFINITY);
    std::vector<std::uint32_t> parent_edge(V, kNone);
    std::vector<std::uint8_t> in_tree(E, 0);
    for (std::uint32_t root = 0; root < V; ++root) {
        if (dist[root] < INFINITY || nbr[root].empty()) continue;
        using Item = std::pair<double, std::uint32_t>;
        std::priority_queue<Item, std::vector<Item>, std::greater<>> heap;
        dist[root] = 0;
        heap.push({0.0, root});
        while (!heap.empty()) {
            const auto [d, v] = heap.top();
            heap.pop();
            if (d > dist[v]) continue;
            for (const auto& [w, e] : nbr[v]) {
                const double nd = d + T.edge_lengths[e];
                if (nd < dist[w]) {
                    dist[w] = nd;
                    parent_edge[w] = e;
                    heap.push({nd, w});
                }
            }
        }
    }
    for (std::size_t v = 0; v < V; ++v)
        if (parent_edge[v] != kNone) in_tree[parent_edge[v]] = 1;
    // Spanning tree of faces across edges not in the vertex tree (the cotree).
    std::vector<std::uint8_t> in_cotree(E, 0);
    face_forest(
        t, [&](std::uint32_t e) { return in_tree[e] != 0; }, [](std::uint32_t) {},
        [&](std::uint32_t f, int k, std::uint32_t, std::uint32_t) { in_cotree[T.face_edges[f][std::size_t(k)]] = 1; });
    // Each edge in neither tree closes a homology loop: cut along it and its two tree paths to
    // the root.
    std::vector<std::uint8_t> cut(E, 0);
    for (std::size_t e = 0; e < E; ++e) {
        if (in_tree[e] || in_cotree[e] || t.edge_halfedges.count(e) < 2) continue;
        cut[e] = 1;
        for (std::uint32_t v : T.edges[e])
            for (std::uint32_t w = v; parent_edge[w] != kNone;) {
                const std::uint32_t pe = parent_edge[w];
                if (cut[pe]) break;
                cut[pe] = 1;
                w = T.edges[pe][0] == w ? T.edges[pe][1] : T.edges[pe][0];
            }
    }
    return cut;
}

bool simply_connected(const Topology& t) {
    const Triangulation& T = t.mesh;
    const std::size_t F = T.face_count();
    detail::DisjointSets components(T.vertex_count);
    for (std::size_t f = 0; f < F; ++f)
        for (int k = 1; k < 3; ++k) components.join(T.faces[f][std::size_t(k)], T.faces[f][0]);
    struct Count {
        long long v = 0, e = 0, f = 0;
    };
    std::map<std::uint32_t, Count> c;
    for (std::uint32_t v = 0; v < T.vertex_count; ++v)
        if (t.vertex_corners.count(v)) ++c[components.find(v)].v;
    for (std::size_t e = 0; e < T.edge_count(); ++e) ++c[components.find(T.edges[e][0])].e;
    for (std::size_t f = 0; f < F; ++f) ++c[components.find(T.faces[f][0])].f;
    // Boundary loops: components of the boundary edges' vertex graph.
    detail::DisjointSets boundary_loops(T.vertex_count);
    std::vector<std::uint8_t> on_boundary(T.vertex_count, 0);
    for (std::size_t e = 0; e < T.edge_count(); ++e)
        if (t.edge_halfedges.count(e) == 1) {
            on_boundary[T.edges[e][0]] = on_boundary[T.edges[e][1]] = 1;
            boundary_loops.join(T.edges[e][0], T.edges[e][1]);
        }
    std::map<std::uint32_t, long long> loops;
    for (std::uint32_t v = 0; v < T.vertex_count; ++v)
        if (on_boundary[v] && boundary_loops.find(v) == v) ++loops[components.find(v)];
    for (const auto& [r, n] : c) {
        const long long chi = n.v - n.e + n.f, b = loops.count(r) ? loops[r] : 0;
        if (2 - chi - b != 0 || b > 1) return false;  // 2 − χ − b = 2·genus
    }
    return true;
}

}  // namespace gsd::mesh
