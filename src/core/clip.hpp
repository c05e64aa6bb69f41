// Clipping a triangle to an axis-aligned box: the part of an element that a computation over
// that box can see. Loops over an element's pieces (samples, quadrature, subdivisions) run over
// this part, so that their work is bounded by the box, never by the element's own extent: a
// triangle with a corner at 1e30 costs what its part inside the box costs (issue "no input
// hangs gsd"; docs/io.md, "Work bounds"). Private to the library.
#pragma once

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>

namespace gsd::detail {

/// The part of triangle (a, b, c) inside the box [lo, hi] (faces included): a convex polygon of
/// at most 9 corners in the triangle's orientation (Sutherland–Hodgman against the six faces).
/// Returns the number of corners (0 when they do not meet; fewer than 3: no area inside).
inline int clip_triangle_to_box(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                                std::array<Eigen::Vector3d, 9>& out) {
    using Vec3 = Eigen::Vector3d;
    std::array<Vec3, 9> poly{a, b, c}, next;
    int n = 3;
    for (int axis = 0; axis < 3 && n > 0; ++axis) {
        for (int side = 0; side < 2 && n > 0; ++side) {
            const double plane = side ? hi[axis] : lo[axis];
            // Signed distance to the plane, ≥ 0 inside.
            auto inside = [&](const Vec3& p) { return side ? plane - p[axis] : p[axis] - plane; };
            int m = 0;
            // Convex ∩ half-space gains at most one corner per plane (≤ 9 in all); a corner past
            // that can only come from rounding on a sliver and is dropped.
            auto push = [&](const Vec3& p) {
                if (m < 9) next[std::size_t(m++)] = p;
            };
            for (int i = 0; i < n; ++i) {
                const Vec3& p = poly[std::size_t(i)];
                const Vec3& q = poly[std::size_t((i + 1) % n)];
                const double dp = inside(p), dq = inside(q);
                if (dp >= 0) push(p);
                if ((dp >= 0) != (dq >= 0)) {
                    // The crossing, stepped from the inside end: it lands in the box's range
                    // even when the other end is astronomically far.
                    const bool p_in = dp >= 0;
                    const Vec3& in = p_in ? p : q;
                    const Vec3& away = p_in ? q : p;
                    const double din = std::abs(p_in ? dp : dq), dout = std::abs(p_in ? dq : dp);
                    Vec3 x = in + (away - in) * (din / (din + dout));
                    x[axis] = plane;
                    for (int done = 0; done < axis; ++done)  // rounding alone moves it off those
                        x[done] = std::clamp(x[done], lo[done], hi[done]);
                    push(x);
                }
            }
            poly = next;
            n = m;
        }
    }
    out = poly;
    return n;
}

}  // namespace gsd::detail
