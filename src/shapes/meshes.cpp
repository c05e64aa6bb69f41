// Closed meshes of the analytic shapes, and the damage the SHM tests inflict on meshes.
#include <gsd/shapes.hpp>
#include <gsd/viz.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

namespace gsd::shapes {

namespace {

double face_area(const PolygonMesh& m, std::size_t f) {
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    const Eigen::Vector3d a = m.vertices.row(m.indices[m.offsets[f]]).transpose();
    for (auto k = m.offsets[f] + 1; k + 1 < m.offsets[f + 1]; ++k)
        v += (m.vertices.row(m.indices[k]).transpose() - a).cross(m.vertices.row(m.indices[k + 1]).transpose() - a);
    return 0.5 * v.norm();
}

Eigen::Vector3d face_center(const PolygonMesh& m, std::size_t f) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (auto k = m.offsets[f]; k < m.offsets[f + 1]; ++k) c += m.vertices.row(m.indices[k]).transpose();
    return c / double(m.face_size(f));
}

}  // namespace

double area(const PolygonMesh& m) {
    double a = 0;
    for (std::size_t f = 0; f < m.face_count(); ++f) a += face_area(m, f);
    return a;
}

PolygonMesh mesh(const Shape& shape, int n) {
    if (n < 8) throw Error("a shape mesh needs a grid of at least 8³");
    // The shape's extent from a dense sampling, padded by c cells: c = 4 on fine grids, 1 on
    // coarse ones (a cell is (extent + 2·pad)/(n − 1), so pad = c·extent/(n − 1 − 2c)).
    const Box b = bounding_box(shape.sample(4096, 0).points);
    const double cells = n >= 24 ? 4.0 : 1.0;
    const double pad = cells * b.extent().maxCoeff() / (n - 1 - 2 * cells);
    GridSpec g = GridSpec::cube(n, Box{b.lo.array() - pad, b.hi.array() + pad});
    std::vector<float> v(g.node_count());
    const Points nodes = g.nodes();
    for (Eigen::Index i = 0; i < nodes.rows(); ++i) v[std::size_t(i)] = float(shape.sdf(nodes.row(i).transpose()));
    return contour(g, v, 0.0);
}

PolygonMesh corrupt(const PolygonMesh& m, const MeshCorruption& c, std::uint64_t seed) {
    validate(m);
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    const std::size_t nf = m.face_count();
    std::vector<double> areas(nf);
    std::vector<Eigen::Vector3d> centers(nf);
    for (std::size_t f = 0; f < nf; ++f) {
        areas[f] = face_area(m, f);
        centers[f] = face_center(m, f);
    }
    const double total = std::accumulate(areas.begin(), areas.end(), 0.0);
    std::vector<char> keep(nf, 1);
    if (c.holes > 0 && c.hole_area > 0) {
        // Each hole removes the faces nearest to a random face center until it has taken its share.
        const double share = c.hole_area * total / c.holes;
        std::vector<std::size_t> order(nf);
        for (int h = 0; h < c.holes; ++h) {
            const std::size_t seed_face = std::size_t(u(rng) * double(nf)) % nf;
            std::iota(order.begin(), order.end(), std::size_t(0));
            std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
                return (centers[a] - centers[seed_face]).squaredNorm() < (centers[b] - centers[seed_face]).squaredNorm();
            });
            double removed = 0;
            for (std::size_t f : order) {
                if (removed >= share) break;
                if (keep[f]) {
                    keep[f] = 0;
                    removed += areas[f];
                }
            }
        }
    }
    PolygonMesh out;
    out.vertices = m.vertices;
    if (c.vertex_noise > 0) {
        std::normal_distribution<double> g(0, c.vertex_noise * bounding_box(m.vertices).diagonal());
        for (Eigen::Index i = 0; i < out.vertices.rows(); ++i)
            for (int a = 0; a < 3; ++a) out.vertices(i, a) += g(rng);
    }
    std::vector<std::uint32_t> face;
    for (std::size_t f = 0; f < nf; ++f) {
        if (!keep[f]) continue;
        face.assign(m.indices.begin() + m.offsets[f], m.indices.begin() + m.offsets[f + 1]);
        if (c.flip_fraction > 0 && u(rng) < c.flip_fraction) std::reverse(face.begin(), face.end());
        out.add_face(face.data(), face.size());
    }
    if (out.face_count() == 0) throw Error("mesh corruption removed every face");
    return out;
}

}  // namespace gsd::shapes
