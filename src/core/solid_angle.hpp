// solid_angle.hpp — the signed solid angle of a triangle seen from a point, the exact term of
// every winding number gsd sums (the treecode's leaves, the exact sum, the GWN baseline; the
// shaders and the treecode's vectorized lanes have their own copies, in GLSL and with an atan2
// that vectorizes). Private to the library.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cmath>

namespace gsd::detail {

/// Ω of the triangle (a, b, c) seen from x, in [−2π, 2π], positive when x sees the corners
/// counter-clockwise (Van Oosterom & Strackee 1983):
/// tan(Ω/2) = a·(b×c) / (|a||b||c| + (a·b)|c| + (b·c)|a| + (c·a)|b|), corners taken from x.
inline double triangle_solid_angle(const Eigen::Vector3d& x, const Eigen::Vector3d& a0, const Eigen::Vector3d& b0,
                                   const Eigen::Vector3d& c0) {
    const Eigen::Vector3d a = a0 - x, b = b0 - x, c = c0 - x;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    const double num = a.dot(b.cross(c));
    const double den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    return 2 * std::atan2(num, den);
}

}  // namespace gsd::detail
