// geometry.hpp — intrinsic triangle geometry from edge lengths: areas, angles, cotangents and a
// planar layout of each face. Everything the surface operators need is computed from lengths,
// so the same code serves the input mesh and intrinsic triangulations. Private to src/mesh and the surface methods above
// it (src/surface_shm, src/swn).
#pragma once

#include "mesh/triangulation.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace gsd::mesh {

/// Area of a triangle with sides a, b, c (Kahan's stable form of Heron's formula). 0 when the
/// sides violate the triangle inequality (degenerate or inconsistent lengths).
inline double triangle_area(double a, double b, double c) {
    // Sort so that a ≥ b ≥ c.
    if (a < b) std::swap(a, b);
    if (b < c) std::swap(b, c);
    if (a < b) std::swap(a, b);
    const double p = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c));
    return p > 0 ? 0.25 * std::sqrt(p) : 0.0;
}

/// The lengths of face f's halfedges: l[k] = |corner k → corner k+1|.
inline std::array<double, 3> face_lengths(const Triangulation& T, std::size_t f) {
    return {T.length(f, 0), T.length(f, 1), T.length(f, 2)};
}

/// Face f laid out in the plane: corner 0 at the origin, corner 1 on the +x axis, corner 2 with
/// y ≥ 0 (counter-clockwise: the face's orientation is the plane's).
inline std::array<Eigen::Vector2d, 3> layout(const std::array<double, 3>& l) {
    const double l01 = l[0], l12 = l[1], l20 = l[2];
    const double x = l01 > 0 ? (l01 * l01 + l20 * l20 - l12 * l12) / (2 * l01) : 0.0;
    const double y = l01 > 0 ? 2 * triangle_area(l01, l12, l20) / l01 : 0.0;
    return {Eigen::Vector2d(0, 0), Eigen::Vector2d(l01, 0), Eigen::Vector2d(x, y)};
}

/// Cotangent of the angle at corner k (between the two sides that meet there), from lengths:
/// cot θ = (b² + c² − a²) / (4·area), a the opposite side. `area` must be > 0.
inline double corner_cot(const std::array<double, 3>& l, int k, double area) {
    const double a = l[std::size_t((k + 1) % 3)];  // opposite corner k
    const double b = l[std::size_t(k)];
    const double c = l[std::size_t((k + 2) % 3)];
    return (b * b + c * c - a * a) / (4 * area);
}

/// The angle at corner k, in [0, π], from lengths (law of cosines, clamped).
inline double corner_angle(const std::array<double, 3>& l, int k) {
    const double a = l[std::size_t((k + 1) % 3)];
    const double b = l[std::size_t(k)];
    const double c = l[std::size_t((k + 2) % 3)];
    if (b <= 0 || c <= 0) return 0.0;
    const double q = (b * b + c * c - a * a) / (2 * b * c);
    return std::acos(std::clamp(q, -1.0, 1.0));
}

/// Face areas, 0 for degenerate faces (area below kDegenerateRelativeArea × longest side², or a
/// side longer than kDegenerateSpan typical edges: src/mesh/topology.hpp).
std::vector<double> face_areas(const Triangulation& T);

/// Mean length of the edges of non-degenerate faces (each edge once); 0 if there are none.
double mean_edge_length(const Triangulation& T, const std::vector<double>& areas);

}  // namespace gsd::mesh
