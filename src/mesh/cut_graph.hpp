// cut_graph.hpp — graph queries on a mesh's edges: the vertex–edge adjacency, a cut graph that
// leaves every component a disk (tree–cotree), and whether every component is a disk or a
// sphere. Private to src/mesh and the surface methods above it (src/swn integrates closed
// 1-forms inside the cut).
#pragma once

#include "mesh/topology.hpp"

#include <cstdint>
#include <utility>
#include <vector>

namespace gsd::mesh {

/// Per vertex: (neighbour, edge) through every edge that joins two distinct vertices.
std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> edge_neighbours(const Triangulation& T);

/// A spanning forest of the faces across the edges that are not `blocked(e)`: depth first from
/// each face not reached yet, in face order. Calls `root(f)` for each tree's first face, then
/// `cross(f, k, h, g)` for each face g first reached from face f across f's edge k (h: g's
/// halfedge on that edge).
template <class Blocked, class Root, class Cross>
void face_forest(const Topology& t, Blocked&& blocked, Root&& root, Cross&& cross) {
    const Triangulation& T = t.mesh;
    std::vector<std::uint8_t> seen(T.face_count(), 0);
    std::vector<std::uint32_t> stack;
    for (std::uint32_t f0 = 0; f0 < T.face_count(); ++f0) {
        if (seen[f0]) continue;
        seen[f0] = 1;
        root(f0);
        stack.assign(1, f0);
        while (!stack.empty()) {
            const std::uint32_t f = stack.back();
            stack.pop_back();
            for (int k = 0; k < 3; ++k) {
                const std::uint32_t e = T.face_edges[f][std::size_t(k)];
                if (blocked(e)) continue;
                for (const std::uint32_t* h = t.edge_halfedges.begin(e); h != t.edge_halfedges.end(e); ++h) {
                    const std::uint32_t g = corner_face(*h);
                    if (seen[g]) continue;
                    seen[g] = 1;
                    cross(f, k, *h, g);
                    stack.push_back(g);
                }
            }
        }
    }
}

/// A cut graph: edges whose removal leaves every component of the mesh a disk (tree–cotree:
/// a spanning tree of vertices by shortest paths, a spanning tree of faces across the other
/// edges, and the edges in neither, each closed into a loop through the vertex tree). Within a
/// component of the mesh minus the cut, every loop bounds, so a closed 1-form integrates
/// without ambiguity.
std::vector<std::uint8_t> cut_graph(const Topology& t);

/// Every connected component a disk or a sphere (genus 0, at most one boundary loop): then the
/// jump harmonic function already labels regions and steps ②–⑤ are not needed.
bool simply_connected(const Topology& t);

}  // namespace gsd::mesh
