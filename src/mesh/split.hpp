// split.hpp — a mesh cut along curve pieces, so that every piece runs along edges of the new
// mesh (what Surface Winding Numbers need: curves as integer 1-chains on edges). Private to
// src/mesh and the surface methods above it (src/swn).
//
// Each input triangle holding pieces (or points that other triangles put on its sides) is
// replaced by a triangulation of itself, made in its planar layout: its sides with their points,
// the piece ends inside it and the crossings of its pieces form a planar straight-line graph,
// triangulated with the pieces as constraints (constrained Delaunay). A point on an input edge
// is one vertex, shared by every triangle on that edge, so the new mesh has no T-junctions.
//
// Snapping, with tol = kSplitTolerance × the triangle's longest side: a piece end within tol of
// a corner is the corner, within tol of a side is on the side (orthogonally projected); points
// on an edge merge within kSplitTolerance × the edge's length, and are its end vertex that
// close to an end; points inside merge within tol; a piece passing within tol of a vertex goes
// through it (unless the vertex is within 2·tol of the piece's end: a vertex side by side with
// that end could otherwise be cut in and out forever); pieces that overlap share their common
// parts; a crossing lands on a vertex within tol if there is one. Two pieces meeting a side at
// distinct points may cross closer than tol to it: the crossing stays a new vertex inside if it
// is more than 1e-3·tol from the side, and is the side's nearest point otherwise (points on
// edges are fixed before triangles are split). Paths stay within tol of their pieces but for
// that case (pieces grazing a side) and slivers thinner than a few tol (a few tol there).
//
// Degenerate (zero-area) input triangles are never triangulated in the plane. Such a triangle
// is a segment with its third corner on it: its sides are split at the points its neighbours
// put there (zero-area triangles zipping the two chains of its boundary, so the mesh stays
// conforming), a piece end inside it moves to the nearest point of its longest side, and a
// piece in it follows the vertices in order along the segment. Crossings in it are not looked
// for. A triangle naming one vertex twice, (v, v, w), cannot be split without triangles that
// name a vertex twice again: it is copied as it is (not conforming where its edge v–w is
// split), and a piece in it runs along that edge. Triangles flat to rounding but not
// degenerate (their area from edge lengths is noise) are split in the plane like others: their
// new triangles are consistently oriented, but their normals are noise like theirs.
#pragma once

#include <gsd/core.hpp>

#include "mesh/topology.hpp"
#include "mesh/triangulation.hpp"

#include <cstdint>
#include <vector>

namespace gsd::mesh {

/// Relative distance below which two points are one (see the file comment).
constexpr double kSplitTolerance = 1e-9;

/// A mesh refined so that given curve pieces run along its edges.
struct SplitMesh {
    PolygonMesh mesh;                        ///< triangles; the input's vertices first (same ids), then new ones
    std::vector<std::uint32_t> triangle_of;  ///< per new triangle: the input triangle it lies in
    /// Per input piece (same order as given): the path of new-mesh vertices it runs through, from
    /// its start to its end (at least 2 entries; consecutive entries are joined by an edge of
    /// the new mesh lying on the piece). Empty for a piece of zero length.
    std::vector<std::vector<std::uint32_t>> piece_paths;
};

/// Splits the triangles of `t` holding the pieces. Triangles without pieces are copied as they
/// are. Throws gsd::Error for a piece naming a triangle that does not exist or holding
/// non-finite coordinates.
SplitMesh split_along(const Topology& t, const std::vector<FaceSegment>& pieces);

}  // namespace gsd::mesh
