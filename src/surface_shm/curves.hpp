// curves.hpp — curves and points on a surface resolved into what the operators consume: straight
// pieces inside single faces (a piece between nodes that share no face follows the shortest
// path through the faces that join them), constraint nodes, point sources, the curve components
// and the open ends of unsigned curves. Private to src/surface_shm (and
// src/swn, which uses it).
#pragma once

#include <gsd/surface.hpp>

#include "mesh/topology.hpp"
#include "mesh/triangulation.hpp"

#include <cstdint>
#include <vector>

namespace gsd::surface_shm {

struct CurvePiece {
    mesh::FaceSegment segment;
    bool is_signed = true;
    std::uint32_t component = 0;  ///< connected component of the curve network
    bool open_a = false;          ///< a is a free end of an unsigned curve (gets an end cap)
    bool open_b = false;
};

struct ResolvedSources {
    std::vector<CurvePiece> pieces;
    std::vector<mesh::FacePoint> points;                  ///< isolated (unsigned) points
    std::vector<mesh::FacePoint> nodes;                   ///< where the level-set constraints hold
    std::vector<std::uint32_t> node_components;     ///< component of each node (points: their own)
    std::uint32_t component_count = 0;
};

/// Resolves sources given on the input mesh into pieces of its triangulation. Throws gsd::Error
/// (naming `where`) for a piece whose ends share no face and no path.
ResolvedSources resolve_sources(const mesh::Topology& topology, const SurfaceSources& sources, const std::string& where = {});

/// The side of face f that a piece lies along (0..2, the halfedge), or −1 if it lies inside.
int piece_side(const mesh::FaceSegment& s);

/// Canonical FacePoint of a SurfacePoint in some non-degenerate face holding it (or any face).
mesh::FacePoint face_point(const mesh::Topology& topology, const SurfacePoint& p);

}  // namespace gsd::surface_shm
