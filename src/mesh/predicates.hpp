// predicates.hpp — planar geometric predicates for meshing in a triangle's layout: exact
// orientation (a filter, then Shewchuk-style expansions when the sign is near zero), proper
// segment crossing built on it, and an in-circle test with a margin (used only to choose
// between valid triangulations). Private to src/mesh.
#pragma once

#include <Eigen/Core>

namespace gsd::mesh {

using Vec2 = Eigen::Vector2d;

/// The 2D cross product u × v (z component).
inline double cross(const Vec2& u, const Vec2& v) { return u.x() * v.y() - u.y() * v.x(); }

/// +1 if a, b, c turn counter-clockwise, −1 clockwise, 0 if collinear — exactly.
int orient(const Vec2& a, const Vec2& b, const Vec2& c);

/// Whether segments ab and cd cross at a point inside both (not at an end, not overlapping).
bool properly_cross(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d);

/// d clearly inside the circle through the counter-clockwise a, b, c (not exact: see predicates.cpp).
bool in_circle(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d);

}  // namespace gsd::mesh
