// triangulation.hpp — the one description of a triangulated surface that the surface operators
// read: faces, edges with a direction, and edge lengths (the intrinsic metric). The input mesh is
// one (lengths from its vertex positions); an intrinsic Delaunay triangulation is another (same
// vertices, other edges, lengths measured along the input surface). Private to src/mesh and the surface methods above
// it (src/surface_shm, src/swn).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

namespace gsd::mesh {

/// A triangulation given by connectivity and edge lengths only.
///
/// Face f has corners faces[f][0..2]; its halfedge k runs faces[f][k] → faces[f][(k+1)%3] and
/// lies on edge face_edges[f][k]. `aligned[f][k]` says whether that halfedge runs in its edge's
/// direction (edges[e][0] → edges[e][1]). Stored explicitly, not derived from vertex ids, so that
/// an edge may join a vertex to itself and two edges may join the same pair (both happen in
/// intrinsic triangulations). Faces on one edge need not agree on orientation (nonorientable
/// meshes) and an edge may have any number of faces (nonmanifold meshes): operators are
/// assembled face by face and only ever read one face at a time.
struct Triangulation {
    std::uint32_t vertex_count = 0;
    std::vector<std::array<std::uint32_t, 3>> faces;
    std::vector<std::array<std::uint32_t, 3>> face_edges;
    std::vector<std::array<std::uint8_t, 3>> aligned;
    std::vector<std::array<std::uint32_t, 2>> edges;
    std::vector<double> edge_lengths;

    std::size_t face_count() const { return faces.size(); }
    std::size_t edge_count() const { return edges.size(); }
    /// Length of halfedge k of face f (the side opposite corner (k+2)%3).
    double length(std::size_t f, int k) const { return edge_lengths[face_edges[f][std::size_t(k)]]; }
};

/// A point inside (or on the boundary of) one face: barycentric weights of its three corners,
/// summing to 1, all ≥ 0.
struct FacePoint {
    std::uint32_t face = 0;
    std::array<double, 3> bary{1, 0, 0};
};

/// A straight piece of curve inside one face, from a to b (barycentric in that face). Pieces
/// that run along a side of the face have the same corner weight 0 at both ends.
struct FaceSegment {
    std::uint32_t face = 0;
    std::array<double, 3> a{1, 0, 0};
    std::array<double, 3> b{0, 1, 0};
};

}  // namespace gsd::mesh
