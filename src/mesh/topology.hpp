// topology.hpp — the mesh-topology room shared by the surface methods (surface SHM, SWN): the
// triangulated input with the edge numbering of curve files, edge and vertex adjacency, areas.
// Private to src/mesh and the surface methods above it (src/surface_shm, src/swn); users see it through gsd::SurfaceMesh.
#pragma once

#include <gsd/core.hpp>

#include "mesh/triangulation.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace gsd::mesh {

/// Compressed lists: item i owns ids[offsets[i] .. offsets[i+1]).
struct Adjacency {
    std::vector<std::uint32_t> offsets{0};
    std::vector<std::uint32_t> ids;

    std::size_t count(std::size_t i) const { return offsets[i + 1] - offsets[i]; }
    const std::uint32_t* begin(std::size_t i) const { return ids.data() + offsets[i]; }
    const std::uint32_t* end(std::size_t i) const { return ids.data() + offsets[i + 1]; }
};

/// A halfedge or corner id: 3·face + k.
inline std::uint32_t corner_id(std::size_t f, int k) { return std::uint32_t(3 * f + std::size_t(k)); }
inline std::uint32_t corner_face(std::uint32_t c) { return c / 3; }
inline int corner_index(std::uint32_t c) { return int(c % 3); }

struct Topology {
    PolygonMesh polygons;                     ///< the input, as given
    Triangulation mesh;                       ///< its triangulation; lengths from the positions
    std::vector<std::uint32_t> triangle_face; ///< input face of each triangle
    std::uint32_t file_edge_count = 0;        ///< edges numbered from the faces' sides
    Adjacency edge_halfedges;                 ///< per edge: the halfedges (3f+k) on it
    Adjacency vertex_corners;                 ///< per vertex: the corners (3f+k) at it
    std::vector<double> face_areas;           ///< 0 for degenerate triangles
    std::vector<std::uint32_t> face_component;///< non-degenerate triangles joined through edges
                                              ///< (UINT32_MAX for degenerate ones)
    double mean_edge_length = 0;              ///< over the edges of non-degenerate triangles

    bool degenerate(std::size_t f) const { return face_areas[f] <= 0; }
    /// The component of a non-degenerate triangle holding a vertex, edge point or face point
    /// (`kind` 0, 1, 2 as in SurfacePoint), or UINT32_MAX if only degenerate ones hold it.
    std::uint32_t component_of(int kind, std::uint32_t index) const;
    /// The edge joining two vertices, or UINT32_MAX (the first one if several).
    std::uint32_t find_edge(std::uint32_t a, std::uint32_t b) const;
    /// Position of corner k of triangle f.
    Eigen::Vector3d corner_position(std::size_t f, int k) const {
        return polygons.vertices.row(mesh.faces[f][std::size_t(k)]).transpose();
    }
};

/// For items referenced by face corners (vertices by `faces`, edges by `face_edges`): the
/// corners/halfedges (3f+k) that reference each item.
Adjacency corner_adjacency(std::size_t items, const std::vector<std::array<std::uint32_t, 3>>& per_corner);

/// Edges with |value[e]| > ½ as 3D polylines along their direction (flipped where the value is
/// negative), chained where one ends where the next starts.
Polylines chain_polylines(const Topology& t, const std::vector<double>& value);

/// Triangulates and numbers a validated mesh (see gsd::SurfaceMesh for the rules).
Topology build_topology(PolygonMesh mesh);

/// Area below which a triangle counts as degenerate: relative to its longest side squared (flat
/// to rounding), and relative to the mesh's mean edge length squared (vanishingly small).
constexpr double kDegenerateRelativeArea = 1e-14;
constexpr double kDegenerateAbsoluteArea = 1e-12;
/// A face whose longest side exceeds this many typical edge lengths (the robust mean) counts as
/// degenerate too: it is a stray vertex's, and kept, its stiffness against its neighbours'
/// (10¹⁸ apart for a vertex 10⁹ edges away) makes the operators impossible to factor in double.
constexpr double kDegenerateSpan = 1e6;

}  // namespace gsd::mesh
