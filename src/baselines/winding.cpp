#include <gsd/baselines.hpp>

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
        for (const auto& t : tri) {
            // Van Oosterom–Strackee: tan(Ω/2) = a·(b×c) / (|a||b||c| + (a·b)|c| + (b·c)|a| + (c·a)|b|).
            const Eigen::Vector3d a = t[0] - x, b = t[1] - x, c = t[2] - x;
            const double la = a.norm(), lb = b.norm(), lc = c.norm();
            const double num = a.dot(b.cross(c));
            const double den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
            sum += 2 * std::atan2(num, den);
        }
        w[std::size_t(q)] = sum / (4 * M_PI);
    }
    return w;
}

}  // namespace gsd
