// predicates.cpp — see predicates.hpp. The triangulations built on these tests stay valid only
// if every orientation test is right, also for points on a side of a triangle (collinear to
// rounding): tests near zero are redone exactly.
#include "mesh/predicates.hpp"

#include <cmath>

namespace gsd::mesh {

namespace {

/// a + b as s + e exactly (s the rounded sum, e its error).
void two_sum(double a, double b, double& s, double& e) {
    s = a + b;
    const double bv = s - a, av = s - bv;
    e = (a - av) + (b - bv);
}

/// Sign of the exact sum of n ≤ 12 doubles: they are added into an expansion (components that
/// do not overlap, increasing in magnitude, zeros dropped) whose largest component has the sign.
int exact_sign(const double* x, int n) {
    double h[12];
    int m = 0;
    for (int i = 0; i < n; ++i) {
        double q = x[i];
        int k = 0;
        for (int j = 0; j < m; ++j) {
            double s, e;
            two_sum(q, h[j], s, e);
            if (e != 0) h[k++] = e;
            q = s;
        }
        if (q != 0) h[k++] = q;
        m = k;
    }
    return m == 0 ? 0 : (h[m - 1] > 0 ? 1 : -1);
}

}  // namespace

/// +1 if a, b, c turn counter-clockwise, −1 clockwise, 0 if collinear — exactly.
int orient(const Vec2& a, const Vec2& b, const Vec2& c) {
    const double l = (a.x() - c.x()) * (b.y() - c.y());
    const double r = (a.y() - c.y()) * (b.x() - c.x());
    const double det = l - r;
    const double bound = 4e-16 * (std::abs(l) + std::abs(r));  // above the rounding of det
    if (det > bound) return 1;
    if (det < -bound) return -1;
    // det = ax·by − ax·cy − cx·by − ay·bx + ay·cx + cy·bx, each product split exactly by fma.
    double t[12];
    const double p[6][2] = {{a.x(), b.y()}, {-a.x(), c.y()}, {-c.x(), b.y()},
                            {-a.y(), b.x()}, {a.y(), c.x()},  {c.y(), b.x()}};
    for (int i = 0; i < 6; ++i) {
        t[2 * i] = p[i][0] * p[i][1];
        t[2 * i + 1] = std::fma(p[i][0], p[i][1], -t[2 * i]);
    }
    return exact_sign(t, 12);
}

/// Whether segments ab and cd cross at a point inside both (not at an end, not overlapping).
bool properly_cross(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
    if (orient(a, b, c) * orient(a, b, d) >= 0) return false;
    return orient(c, d, a) * orient(c, d, b) < 0;
}

/// d clearly inside the circle through the counter-clockwise a, b, c. Not exact: it only chooses
/// between two valid triangulations, and the margin above rounding keeps flips from cycling.
/// Computed about a, which callers make an end of the edge to flip: a triangle flattened
/// against that edge (its corners 1e-8 apart) then still finds a far point inside its circle.
bool in_circle(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
    const Vec2 p = b - a, q = c - a, r = d - a;
    const double lp = p.squaredNorm(), lq = q.squaredNorm(), lr = r.squaredNorm();
    const double det = lp * cross(q, r) + lq * cross(r, p) + lr * cross(p, q);
    const double scale = lp * (std::abs(q.x() * r.y()) + std::abs(q.y() * r.x())) +
                         lq * (std::abs(r.x() * p.y()) + std::abs(r.y() * p.x())) +
                         lr * (std::abs(p.x() * q.y()) + std::abs(p.y() * q.x()));
    return -det > 1e-12 * scale;  // about a, the determinant is negative for d inside
}

}  // namespace gsd::mesh
