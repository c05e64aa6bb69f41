#include <gsd/baselines.hpp>

#include "core/solid_angle.hpp"

#include <Eigen/Geometry>

#include <array>
#include <cmath>

namespace gsd {

std::vector<double> winding_numbers(const PolygonMesh& mesh, const Points& queries) {
    validate(mesh);
    // Fan every face into triangles once.
    std::vector<std::array<Eigen::Vector3d, 3>> tri;
    for_each_triangle(mesh, [&](std::size_t, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
        tri.push_back({mesh.vertices.row(a).transpose(), mesh.vertices.row(b).transpose(), mesh.vertices.row(c).transpose()});
    });
    std::vector<double> w(std::size_t(queries.rows()));
#pragma omp parallel for schedule(dynamic, 64)
    for (Eigen::Index q = 0; q < queries.rows(); ++q) {
        const Eigen::Vector3d x = queries.row(q).transpose();
        double sum = 0;
        for (const auto& t : tri) sum += detail::triangle_solid_angle(x, t[0], t[1], t[2]);
        w[std::size_t(q)] = sum / (4 * M_PI);
    }
    return w;
}

}  // namespace gsd
