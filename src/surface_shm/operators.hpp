// operators.hpp — discrete operators on a triangulation, assembled face by face so that
// nonmanifold and nonorientable meshes need no special case (thesis §4.3–4.4):
//  - the cotan Laplacian (vertices), lumped vertex masses;
//  - the Crouzeix–Raviart connection Laplacian L∇ (edge midpoints, complex encoding: the value
//    at edge e is a tangent vector in the frame (ê, ê⊥) of e, ê its direction) and CR mass M;
//  - face fields from CR fields, and the divergence of a face field onto vertices.
// Everything reads only lengths (intrinsic), so the same code serves intrinsic triangulations.
// Private to src/surface_shm (and
// src/swn, which uses it).
#pragma once

#include "surface_shm/cholesky.hpp"
#include "mesh/geometry.hpp"
#include "mesh/triangulation.hpp"

#include <Eigen/Core>

#include <complex>
#include <vector>

namespace gsd::surface_shm {

using Complex = std::complex<double>;

/// One face seen in its own plane (geometry::layout): corner positions, the unit direction of
/// each halfedge's *edge* (its canonical direction, as a complex number), corner cotangents.
struct FaceFrame {
    double area = 0;
    std::array<Eigen::Vector2d, 3> p;
    std::array<Complex, 3> edge_dir;  ///< edge of halfedge k: its direction in this face's plane
    std::array<double, 3> cot{};      ///< cot of the angle at corner k
};
FaceFrame face_frame(const mesh::Triangulation& T, std::size_t f, double area);

/// Cotan Laplacian (positive semi-definite), lower triangle. Every pair of vertices sharing a
/// face gets an entry (0 for degenerate faces), so constraint rows that live in one face never
/// add fill. Vertices on no non-degenerate face get 1 on the diagonal (cut off from the solve).
SparseLower<double> cotan_laplacian(const mesh::Triangulation& T, const std::vector<double>& areas);

/// The pieces on which the cotan Laplacian's nullspace is constant: vertices joined through
/// non-degenerate faces. `pins` holds one vertex of each piece (vertices on no such face form
/// no piece: they are already fixed); component[v] indexes `pins`, or UINT32_MAX.
struct StiffnessComponents {
    std::vector<std::uint32_t> component;
    std::vector<std::uint32_t> pins;
};
StiffnessComponents stiffness_components(const mesh::Triangulation& T, const std::vector<double>& areas);
/// Lumped vertex masses: a third of the incident face areas.
std::vector<double> vertex_masses(const mesh::Triangulation& T, const std::vector<double>& areas);

/// M + t·L∇ of the Crouzeix–Raviart vector heat step, Hermitian positive definite, lower
/// triangle. Edges on no non-degenerate face get 1 on the diagonal.
SparseLower<Complex> vector_heat_operator(const mesh::Triangulation& T, const std::vector<double>& areas, double t);

/// The CR vector field X (one complex per edge) averaged over each face and normalized:
/// Y_f in face f's plane (FaceFrame coordinates), unit or 0 where X vanishes there.
/// Returns the number of non-degenerate faces where X vanished.
std::size_t normalized_face_field(const mesh::Triangulation& T, const std::vector<double>& areas,
                                  const std::vector<Complex>& X, std::vector<Eigen::Vector2d>& Y);

/// g_i = Σ_f A_f ⟨Y_f, ∇λ_i⟩: the right-hand side of min ∫|∇φ − Y|² (so K φ = g).
std::vector<double> face_field_divergence(const mesh::Triangulation& T, const std::vector<double>& areas,
                                          const std::vector<Eigen::Vector2d>& Y);

}  // namespace gsd::surface_shm
