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
