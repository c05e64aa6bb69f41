// Tori from height functions, and their signed distance in curvature form.
//
// The classic torus SDF ‖(‖(x−c)×u‖ − R, ⟨x−c,u⟩)‖ − r subtracts radii that grow without
// bound as the surface flattens, which ruins float32 long before a plane is reached. We
// instead write everything in the point's frame (y = x − q in (e1, e2, n)) and in curvatures:
// multiplying through by k1 and k2 turns every radius into a bounded quantity, and each
// difference of nearly equal terms is rewritten as a quotient (a² − b²)/(a + b) evaluated
// without cancellation. The derivation is in docs/pat.md; geometry() gives the classic form
// that tests compare against.
#include "pat/torus_math.hpp"

#include <gsd/pat.hpp>

#include <Eigen/Geometry>

#include <cmath>

namespace gsd {

Eigen::Vector3d tangent_of(const Eigen::Vector3d& n) {
    // Cross with the coordinate axis least aligned with n: well conditioned for any n.
    const Eigen::Vector3d a = std::abs(n.x()) < 0.57735 ? Eigen::Vector3d::UnitX()
                            : std::abs(n.y()) < 0.57735 ? Eigen::Vector3d::UnitY()
                                                        : Eigen::Vector3d::UnitZ();
    return n.cross(a).normalized();
}

Torus torus_from_jet(const Eigen::Vector3d& p, const Eigen::Vector3d& n, const Eigen::Vector3d& s,
                     const Jet& jet) {
    const Eigen::Vector3d t = n.cross(s);
    const pat::TorusFrame<double> f = pat::torus_from_jet<double>(
        {jet.a00, jet.a10, jet.a01, jet.a11, jet.a20, jet.a02});
    Torus out;
    out.q = p + f.a00 * n;
    out.n = (f.n[0] * s + f.n[1] * t + f.n[2] * n).normalized();
    out.e1 = (f.e1[0] * s + f.e1[1] * t + f.e1[2] * n).normalized();
    out.k1 = f.k1;
    out.k2 = f.k2;
    return out;
}

double torus_sdf(const Torus& t, const Eigen::Vector3d& x, Eigen::Vector3d* gradient) {
    const Eigen::Vector3d e2 = t.n.cross(t.e1);
    const Eigen::Vector3d y = x - t.q;
    const double y1 = y.dot(t.e1), y2 = y.dot(e2), y3 = y.dot(t.n);
    double g[3];
    const double value = pat::torus_sdf_local<double>(t.k1, t.k2, y1, y2, y3, gradient ? g : nullptr);
    if (gradient) *gradient = g[0] * t.e1 + g[1] * e2 + g[2] * t.n;
    return value;
}

TorusGeometry geometry(const Torus& t) {
    if (t.k1 == 0) throw Error("a plane has no finite torus form");
    TorusGeometry out;
    out.u = t.e1;
    out.r = 1.0 / std::abs(t.k1);
    out.R = t.k2 == 0 ? INFINITY : std::abs(1.0 / t.k2 - 1.0 / t.k1);
    out.c = t.k2 == 0 ? Eigen::Vector3d::Constant(INFINITY) : Eigen::Vector3d(t.q + t.n / t.k2);
    out.sign = t.k1 < 0 ? 1.0 : -1.0;
    return out;
}

Torus FittedTori::torus(Eigen::Index i) const {
    const Jet& j = jets[std::size_t(i)];
    return torus_from_jet(points.row(i).transpose(), normals.row(i).transpose(),
                          tangents.row(i).transpose(), j);
}

std::vector<Torus> FittedTori::tori() const {
    std::vector<Torus> out(static_cast<std::size_t>(size()));
#pragma omp parallel for schedule(static)
    for (Eigen::Index i = 0; i < size(); ++i) out[std::size_t(i)] = torus(i);
    return out;
}

}  // namespace gsd
