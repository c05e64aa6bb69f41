// halfedges.hpp — halfedge connectivity of a manifold, consistently oriented triangle mesh on top
// of Topology: twins, the corner fans around each vertex and the cotan weight of each halfedge.
// Halfedge ids are corner ids (3f + k: the halfedge leaving corner k of face f). Private to
// src/mesh and the surface methods above it (src/swn walks functions with jumps around fans).
#pragma once

#include "mesh/topology.hpp"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace gsd::mesh {

/// Twins, corner fans around vertices and cotan weights of a manifold, oriented mesh.
struct Halfedges {
    static constexpr std::uint32_t kNone = UINT32_MAX;

    const Topology* t = nullptr;
    std::vector<std::uint32_t> twin;   ///< per halfedge 3f+k, kNone on the boundary
    std::vector<double> cot_weight;    ///< per halfedge: ½ cot of the angle across it (0: degenerate face)
    // Fans: the corners at a vertex, counter-clockwise; a vertex has one fan, or several if it
    // is a bowtie. fan_of[c] indexes fans.
    std::vector<std::uint32_t> fan_corners, fan_begin{0}, fan_vertex, fan_of;
    std::vector<std::uint8_t> fan_closed;
    /// What keeps the mesh from being manifold and oriented (then only the twins of the good
    /// edges are set, and no weights or fans are built).
    std::size_t nonmanifold_edges = 0;  ///< edges with more than two faces
    std::size_t misoriented_edges = 0;  ///< edges joining two faces that disagree on orientation

    bool manifold() const { return nonmanifold_edges == 0 && misoriented_edges == 0; }
    std::size_t fans() const { return fan_vertex.size(); }
};

/// The corner after corner c counter-clockwise around its vertex, or kNone at the boundary.
std::uint32_t ccw(const Halfedges& H, std::uint32_t c);

/// The corner before corner c (clockwise), or kNone at the boundary.
std::uint32_t cw(const Halfedges& H, std::uint32_t c);

/// The halfedges of `t` (kept by pointer: it must outlive the result). Check manifold() before use.
Halfedges build_halfedges(const Topology& t);

}  // namespace gsd::mesh
