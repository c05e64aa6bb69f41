// Sources of the Signed Heat Method: oriented area elements from clouds and meshes.
#include <gsd/shm.hpp>
#include <gsd/spatial.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace gsd {

namespace {

using Vec3 = Eigen::Vector3d;

// Appends a triangle's vector area, split into 4^levels congruent pieces so that each piece's
// longest edge is at most max_element (midpoint subdivision).
void add_triangle(const Vec3& a, const Vec3& b, const Vec3& c, double max_element,
                  std::vector<Vec3>& pos, std::vector<Vec3>& vec) {
    const Vec3 area = 0.5 * (b - a).cross(c - a);
    if (!(area.norm() > 0)) return;  // degenerate: no orientation, no area
    const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
    if (longest <= max_element) {
        pos.push_back((a + b + c) / 3);
        vec.push_back(area);
        return;
    }
    const Vec3 ab = 0.5 * (a + b), bc = 0.5 * (b + c), ca = 0.5 * (c + a);
    add_triangle(a, ab, ca, max_element, pos, vec);
    add_triangle(ab, b, bc, max_element, pos, vec);
    add_triangle(ca, bc, c, max_element, pos, vec);
    add_triangle(ab, bc, ca, max_element, pos, vec);
}

ShmSource pack(const std::vector<Vec3>& pos, const std::vector<Vec3>& vec, double spacing) {
    ShmSource s;
    s.positions.resize(Eigen::Index(pos.size()), 3);
    s.vectors.resize(Eigen::Index(pos.size()), 3);
    for (std::size_t i = 0; i < pos.size(); ++i) {
        s.positions.row(Eigen::Index(i)) = pos[i].transpose();
        s.vectors.row(Eigen::Index(i)) = vec[i].transpose();
    }
    s.spacing = spacing;
    return s;
}

}  // namespace

ShmSource shm_source(const PointCloud& cloud) {
    if (cloud.size() < 2) throw Error("the signed heat method needs at least 2 points");
    KdTree tree(cloud.points);
    const std::vector<double> area = point_areas(tree);
    ShmSource s;
    s.positions = cloud.points;
    s.vectors.resize(cloud.size(), 3);
    for (Eigen::Index i = 0; i < cloud.size(); ++i)
        s.vectors.row(i) = area[std::size_t(i)] * cloud.normals.row(i).normalized();
    s.spacing = mean_spacing(tree);
    if (!(s.spacing > 0)) throw Error("all points of the cloud coincide");
    return s;
}

ShmSource shm_source(const PolygonMesh& mesh, double max_element) {
    validate(mesh);
    // h = mean edge length over all face edges (each shared edge counted per face: the mean
    // is what matters).
    double length = 0;
    std::size_t edges = 0;
    for (std::size_t f = 0; f < mesh.face_count(); ++f)
        for (auto k = mesh.offsets[f]; k < mesh.offsets[f + 1]; ++k) {
            const auto next = k + 1 < mesh.offsets[f + 1] ? k + 1 : mesh.offsets[f];
            length += (mesh.vertices.row(mesh.indices[k]) - mesh.vertices.row(mesh.indices[next])).norm();
            ++edges;
        }
    const double h = length / double(edges);
    if (!(h > 0)) throw Error("mesh", "all faces are degenerate (zero area)");
    const double limit = max_element > 0 ? max_element : h;

    std::vector<Vec3> pos, vec;
    pos.reserve(mesh.face_count());
    vec.reserve(mesh.face_count());
    for (std::size_t f = 0; f < mesh.face_count(); ++f) {
        const Vec3 a = mesh.vertices.row(mesh.indices[mesh.offsets[f]]).transpose();
        for (auto k = mesh.offsets[f] + 1; k + 1 < mesh.offsets[f + 1]; ++k)
            add_triangle(a, mesh.vertices.row(mesh.indices[k]).transpose(),
                         mesh.vertices.row(mesh.indices[k + 1]).transpose(), limit, pos, vec);
    }
    if (pos.empty()) throw Error("mesh", "all faces are degenerate (zero area)");
    return pack(pos, vec, h);
}

ShmSource combine(const ShmSource& a, const ShmSource& b) {
    ShmSource s;
    s.positions.resize(a.positions.rows() + b.positions.rows(), 3);
    s.vectors.resize(s.positions.rows(), 3);
    s.positions << a.positions, b.positions;
    s.vectors << a.vectors, b.vectors;
    s.spacing = std::max(a.spacing, b.spacing);
    return s;
}

Box shm_default_bounds(const ShmSource& source) { return padded_cube(bounding_box(source.positions)); }

PoissonSolver poisson_solver_from_name(const std::string& name) {
    if (name == "mg") return PoissonSolver::Multigrid;
    if (name == "cg") return PoissonSolver::CG;
    if (name == "direct") return PoissonSolver::Direct;
    throw Error("--solver", "unknown solver '" + name + "' (mg, cg, direct)");
}

}  // namespace gsd
