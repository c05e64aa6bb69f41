// triangles.hpp — a mesh as the signed distance sees it: its non-degenerate triangles over
// welded vertices, what is wrong with it (boundary, nonmanifold and misoriented edges,
// duplicated triangles, components), and the repairs the winding-number sign takes (duplicates
// dropped, each manifold patch oriented one way). Private to src/sdf.
#pragma once

#include <gsd/core.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace gsd::sdf {

using Triangle = std::array<std::uint32_t, 3>;

/// What check_triangles found. Counts are of edges (an edge: two welded vertices).
struct TriangleReport {
    std::size_t triangles = 0;           ///< fanned triangles of the input
    std::size_t degenerate = 0;          ///< zero-area ones, left out
    std::size_t welded_vertices = 0;     ///< vertices merged into another at the same position
    std::size_t duplicates = 0;          ///< triangles over the same three vertices as an earlier one
    std::size_t boundary_edges = 0;      ///< edges of one triangle (holes)
    std::size_t nonmanifold_edges = 0;   ///< edges of three or more
    std::size_t misoriented_edges = 0;   ///< edges whose two triangles run along them the same way
    std::size_t components = 0;          ///< pieces joined through manifold edges
    bool overlapping_components = false; ///< two components' bounding boxes overlap

    /// Closed, manifold, consistently oriented, no duplicates, components apart: the mesh
    /// pseudonormals sign exactly (self-intersections are not looked for).
    bool clean() const {
        return boundary_edges == 0 && nonmanifold_edges == 0 && misoriented_edges == 0 && duplicates == 0 &&
               !overlapping_components;
    }
    /// One line for -v: what was found.
    std::string summary() const;
};

/// A mesh's triangles: vertex positions (welded: equal coordinates are one vertex) and the
/// non-degenerate triangles over them, in for_each_triangle order.
struct Triangles {
    Points vertices;
    std::vector<Triangle> triangles;
    std::vector<std::uint32_t> source;  ///< per triangle: its index among the input's fanned triangles
    std::vector<std::uint8_t> duplicate;  ///< per triangle: over the same three vertices as an earlier one
    TriangleReport report;
};

/// The mesh's triangles and its diagnosis. Throws Error if every triangle is degenerate.
Triangles check_triangles(const PolygonMesh& mesh);

/// The triangles the winding-number sign should use: duplicates dropped, and in each component
/// (triangles joined through manifold edges) every triangle turned to agree with its
/// neighbours, the component keeping the orientation most of its area had. Returns how many
/// triangles it turned.
std::size_t repair_orientation(Triangles& t);

}  // namespace gsd::sdf
