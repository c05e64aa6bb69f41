// pseudonormals.cpp — see pseudonormals.hpp.
#include "sdf/pseudonormals.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace gsd::sdf {

namespace {

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
    return std::uint64_t(std::min(a, b)) << 32 | std::max(a, b);
}

double angle(const Eigen::Vector3d& u, const Eigen::Vector3d& v) {
    return std::atan2(u.cross(v).norm(), u.dot(v));
}

}  // namespace

// Where on triangle abc the nearest point to x lies: its corner k (0–2), its side k → k+1
// (3 + k), or inside (6); and the point. The Voronoi regions of the triangle's features, tested
// in turn (Ericson, Real-Time Collision Detection, §5.1.5).
int nearest_feature(const Eigen::Vector3d& x, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                    const Eigen::Vector3d& c, Eigen::Vector3d& p) {
    const Eigen::Vector3d ab = b - a, ac = c - a, ax = x - a;
    const double d1 = ab.dot(ax), d2 = ac.dot(ax);
    if (d1 <= 0 && d2 <= 0) return p = a, 0;
    const Eigen::Vector3d bx = x - b;
    const double d3 = ab.dot(bx), d4 = ac.dot(bx);
    if (d3 >= 0 && d4 <= d3) return p = b, 1;
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return p = a + d1 / (d1 - d3) * ab, 3;  // side ab
    const Eigen::Vector3d cx = x - c;
    const double d5 = ab.dot(cx), d6 = ac.dot(cx);
    if (d6 >= 0 && d5 <= d6) return p = c, 2;
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return p = a + d2 / (d2 - d6) * ac, 5;  // side ca
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) return p = b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b), 4;  // side bc
    const double s = 1 / (va + vb + vc);
    return p = a + ab * (vb * s) + ac * (vc * s), 6;
}

Pseudonormals::Pseudonormals(const Triangles& t) : t_(t) {
    face_.resize(t.triangles.size());
    vertex_.assign(std::size_t(t.vertices.rows()), Eigen::Vector3d::Zero());
    edge_.reserve(3 * t.triangles.size() / 2);
    for (std::size_t f = 0; f < t.triangles.size(); ++f) {
        const auto& v = t.triangles[f];
        const Eigen::Vector3d p[3] = {t.vertices.row(v[0]), t.vertices.row(v[1]), t.vertices.row(v[2])};
        const Eigen::Vector3d n = (p[1] - p[0]).cross(p[2] - p[0]).normalized();
        face_[f] = n;
        for (int k = 0; k < 3; ++k) {
            const Eigen::Vector3d& o = p[k];
            vertex_[v[std::size_t(k)]] += angle(p[(k + 1) % 3] - o, p[(k + 2) % 3] - o) * n;
            // (not operator[]: it value-initializes, and Eigen's vectors start uninitialized)
            edge_.try_emplace(edge_key(v[std::size_t(k)], v[std::size_t((k + 1) % 3)]), Eigen::Vector3d::Zero())
                .first->second += n;
        }
    }
}

bool Pseudonormals::inside(const Eigen::Vector3d& x, std::uint32_t f) const {
    const auto& v = t_.triangles[f];
    const Eigen::Vector3d a = t_.vertices.row(v[0]), b = t_.vertices.row(v[1]), c = t_.vertices.row(v[2]);
    Eigen::Vector3d p;
    const int feature = nearest_feature(x, a, b, c, p);
    const Eigen::Vector3d* n = &face_[f];
    if (feature < 3) {
        n = &vertex_[v[std::size_t(feature)]];
    } else if (feature < 6) {
        const int k = feature - 3;
        n = &edge_.at(edge_key(v[std::size_t(k)], v[std::size_t((k + 1) % 3)]));
    }
    return (x - p).dot(*n) < 0;
}

}  // namespace gsd::sdf
