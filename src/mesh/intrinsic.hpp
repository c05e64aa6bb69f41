// intrinsic.hpp — intrinsic Delaunay triangulations (thesis §4.4, fig. 4.6; Sharp, Soliman &
// Crane 2019, "Navigating intrinsic triangulations"; Gillespie et al. 2021): the same surface
// (the same metric) triangulated by other edges, found by edge flips and optional vertex
// insertion, without changing the input mesh. Curves drawn on the input are traced into the new
// triangulation. Private to src/mesh and the surface methods above
// it (src/surface_shm, src/swn).
#pragma once

#include "mesh/triangulation.hpp"

#include <cstddef>
#include <memory>
#include <vector>

namespace gsd::mesh {

class IntrinsicTriangulation {
public:
    /// Starts as a copy of `input` (which must outlive this object).
    explicit IntrinsicTriangulation(const Triangulation& input);
    ~IntrinsicTriangulation();
    IntrinsicTriangulation(IntrinsicTriangulation&&) noexcept;
    IntrinsicTriangulation& operator=(IntrinsicTriangulation&&) noexcept;

    /// Flips edges until every flippable edge is locally Delaunay (opposite angles sum ≤ π).
    /// Returns the number of flips.
    std::size_t flip_to_delaunay();

    /// Inserts vertices (circumcenters, Chew's second algorithm) until no angle is below
    /// `min_angle_degrees` or `max_new_vertices` were inserted; keeps the triangulation Delaunay.
    /// New vertices get ids from input.vertex_count on. Returns the number inserted.
    std::size_t refine(double min_angle_degrees, std::size_t max_new_vertices);

    /// The current triangulation (vertex ids of the input first).
    const Triangulation& triangulation() const;

    /// A straight segment inside an input face, as the pieces it crosses in the current
    /// triangulation, in order from s.a to s.b (piece i's b is piece i+1's a).
    std::vector<FaceSegment> trace(const FaceSegment& s) const;

    /// The face of the current triangulation that holds a point of an input face, and its
    /// barycentric coordinates there.
    FacePoint locate(const FacePoint& p) const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace gsd::mesh
