// gsd/accuracy.hpp — how far a result is from a reference: the measures the thesis reports and
// gsd's tests and benchmarks hold the surface methods to. On a SurfaceMesh: the distance error
// of thesis §4.5 and the share of area where signs agree (per-vertex φ), and the share of area
// mislabeled (per-face integer labels, e.g. Surface Winding Numbers).
#pragma once

#include <gsd/export.hpp>

#include <vector>

namespace gsd {

class SurfaceMesh;

/// The error measure of thesis §4.5: ε(φ) = (Σ_i A_i (φ_i − φ⁰_i)²)^½ / ((max φ⁰ − min φ⁰)·𝒜^½),
/// A_i a third of the area of the triangles at vertex i, 𝒜 = Σ A_i. Vertices where either value
/// is not finite are left out.
GSD_EXPORT double surface_distance_error(const SurfaceMesh& mesh, const std::vector<double>& phi,
                                         const std::vector<double>& phi_true);
/// Share of the surface area (vertex areas A_i) where sign(φ) = sign(φ_true); vertices where
/// φ_true is 0 count as agreeing.
GSD_EXPORT double surface_sign_agreement(const SurfaceMesh& mesh, const std::vector<double>& phi,
                                         const std::vector<double>& phi_true);
/// Vertex areas A_i (a third of the incident triangle areas).
GSD_EXPORT std::vector<double> vertex_areas(const SurfaceMesh& mesh);

/// Share of the area where per-face labels differ, after the best global integer shift of
/// `labels` when `up_to_shift` (closed surfaces: winding numbers are defined up to a constant
/// there).
GSD_EXPORT double mislabeled_area(const SurfaceMesh& mesh, const std::vector<int>& labels, const std::vector<int>& truth,
                                  bool up_to_shift);

}  // namespace gsd
