// sources.hpp — the right-hand side X₀ of the vector heat step (thesis eq. 4.9) from resolved
// curves and points, and the rows that keep the diffused field normal to the curves
// ("preserve source normals"). Private to src/surface_shm.
#pragma once

#include "surface_shm/curves.hpp"
#include "surface_shm/operators.hpp"
#include "mesh/topology.hpp"

#include <vector>

namespace gsd::surface_shm {

/// A triangulation with what the source assembly reads besides lengths.
struct SolveMesh {
    const mesh::Triangulation* T = nullptr;
    std::vector<double> areas;
    mesh::Adjacency edge_halfedges;
    mesh::Adjacency vertex_corners;

    explicit SolveMesh(const mesh::Triangulation& tri)
        : T(&tri),
          areas(face_areas(tri)),
          edge_halfedges(mesh::corner_adjacency(tri.edge_count(), tri.face_edges)),
          vertex_corners(mesh::corner_adjacency(tri.vertex_count, tri.faces)) {}
};

/// X₀: one complex per edge, in the edge's frame (ê, ê⊥).
///  - signed piece: its normal to the right (so φ grows to the right, φ < 0 on the left) times
///    its length, fed to each edge of its face; a piece along an edge feeds that edge only;
///  - unsigned piece: on each side, the normal pointing to that side, fed to that side's edges;
///    free ends get a half disk of outward directions;
///  - point: a disk of outward directions (weight 1), from its face's corners.
std::vector<Complex> vector_sources(const SolveMesh& M, const ResolvedSources& S);

/// Real-linear constraints Re(c_m^H X) = 0: the component of the diffused field along each
/// signed piece, at its midpoint, vanishes. Each row is sparse (the 3 edges of the face).
struct NormalConstraints {
    std::vector<std::vector<std::pair<std::uint32_t, Complex>>> rows;
};
NormalConstraints normal_constraints(const SolveMesh& M, const ResolvedSources& S);

}  // namespace gsd::surface_shm
