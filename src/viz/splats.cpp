// Point clouds drawn as small discs (splats) so that render_surface can picture values on them.
#include <gsd/viz.hpp>

#include <Eigen/Geometry>

#include <cmath>
#include <numbers>

namespace gsd {

PolygonMesh splat_mesh(const Points& points, const Points& normals, const std::vector<double>& radii) {
    if (normals.rows() != points.rows() || radii.size() != std::size_t(points.rows()))
        throw Error("splats", std::to_string(points.rows()) + " points, " + std::to_string(normals.rows()) + " normals and " +
                                  std::to_string(radii.size()) + " radii: the counts must agree");
    if (points.rows() == 0) throw Error("splats", "no points");
    if (std::size_t(points.rows()) > std::size_t(UINT32_MAX) / kSplatVertices)
        throw Error("splats", "too many points to draw as splats");
    constexpr int rim = int(kSplatVertices) - 1;
    PolygonMesh m;
    m.vertices.resize(points.rows() * Eigen::Index(kSplatVertices), 3);
    m.indices.reserve(std::size_t(points.rows()) * 3 * rim);
    m.offsets.reserve(std::size_t(points.rows()) * rim + 1);
    for (Eigen::Index i = 0; i < points.rows(); ++i) {
        const Eigen::Vector3d c = points.row(i).transpose();
        const Eigen::Vector3d n = normals.row(i).transpose();
        if (!c.allFinite() || !(n.norm() > 0) || !std::isfinite(radii[std::size_t(i)]) || !(radii[std::size_t(i)] >= 0))
            throw Error("splats", "point " + std::to_string(i) + ": non-finite position, zero normal or bad radius");
        const Eigen::Vector3d u = n.normalized().unitOrthogonal() * radii[std::size_t(i)];
        const Eigen::Vector3d w = n.normalized().cross(u);
        const auto base = std::uint32_t(i * Eigen::Index(kSplatVertices));
        m.vertices.row(base) = c.transpose();
        for (int k = 0; k < rim; ++k) {
            const double a = 2 * std::numbers::pi * k / rim;
            m.vertices.row(base + 1 + std::uint32_t(k)) = (c + std::cos(a) * u + std::sin(a) * w).transpose();
            // Counter-clockwise seen from the normal: the splat's front faces the normal.
            m.add_face({base, base + 1 + std::uint32_t(k), base + 1 + std::uint32_t((k + 1) % rim)});
        }
    }
    return m;
}

}  // namespace gsd
