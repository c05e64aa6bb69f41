// Sources of the Signed Heat Method: oriented area elements from clouds and meshes.
#include <gsd/shm.hpp>
#include <gsd/spatial.hpp>

#include "shm/diffuse.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <optional>
#include <cmath>
#include <cstdio>

namespace gsd {

namespace {

using Vec3 = Eigen::Vector3d;

/// Distance from x to a box (0 inside).
double box_distance(const Vec3& x, const Box& box) {
    return (x.cwiseMax(box.lo).cwiseMin(box.hi) - x).norm();
}

/// Splits faces into pieces by midpoint subdivision and emits each piece's vector area at its
/// centroid. A piece is split while its longest edge exceeds max_element — or, away from the
/// focus box (the grid), a quarter of its distance to the box: far pieces are summed from
/// afar, where a coarse piece is as good as its parts, so cropping a large mesh with tight
/// bounds costs pieces near the box only. Iterative (an explicit stack), so no recursion
/// depth depends on the data; `emit` returns false to stop early.
class FaceSplitter {
public:
    FaceSplitter(double max_element, const std::optional<Box>& focus)
        : max_element_(max_element), has_focus_(focus.has_value()), focus_(focus.value_or(Box{})) {}

    template <class Emit>
    bool split(const Vec3& a, const Vec3& b, const Vec3& c, Emit&& emit) {
        stack_.clear();
        stack_.push_back({a, b, c});
        while (!stack_.empty()) {
            const std::array<Vec3, 3> t = stack_.back();
            stack_.pop_back();
            const Vec3 area = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]);
            if (!(area.norm() > 0)) continue;  // degenerate: no orientation, no area
            const Vec3 centroid = (t[0] + t[1] + t[2]) / 3;
            const double longest = std::max({(t[1] - t[0]).norm(), (t[2] - t[1]).norm(), (t[0] - t[2]).norm()});
            const double far = has_focus_ ? std::max(0.0, box_distance(centroid, focus_) - longest) : 0.0;
            if (longest <= std::max(max_element_, 0.25 * far)) {
                if (!emit(centroid, area)) return false;
                continue;
            }
            const Vec3 ab = 0.5 * (t[0] + t[1]), bc = 0.5 * (t[1] + t[2]), ca = 0.5 * (t[2] + t[0]);
            stack_.push_back({t[0], ab, ca});
            stack_.push_back({ab, t[1], bc});
            stack_.push_back({ca, bc, t[2]});
            stack_.push_back({ab, bc, ca});
        }
        return true;
    }

private:
    double max_element_;
    bool has_focus_;
    Box focus_;  // (a plain Box: GCC 12 misreads an optional here as maybe uninitialized)
    std::vector<std::array<Vec3, 3>> stack_;
};

}  // namespace

ShmSource shm_source(const PointCloud& cloud) {
    if (cloud.size() < 2) throw Error("the signed heat method needs at least 2 points");
    // One kd-tree for both the point areas and the spacing.
    const KdTree tree(cloud.points);
    ShmSource s;
    s.elements = OrientedElements::from_cloud(cloud, tree);
    s.spacing = mean_spacing(tree);
    if (!(s.spacing > 0)) throw Error("all points of the cloud coincide");
    return s;
}

ShmSource shm_source(const PolygonMesh& mesh) {
    validate(mesh);
    // h = mean edge length over all face edges (each shared edge counted per face: the mean
    // is what matters).
    const double h = mean_edge_length(mesh);
    if (!(h > 0)) throw Error("mesh", "all faces are degenerate (zero area)");
    ShmSource s;
    s.elements = OrientedElements::from_mesh(mesh);
    s.spacing = h;
    return s;
}

ShmSource combine(const ShmSource& a, const ShmSource& b) {
    ShmSource s;
    s.elements.corners.resize(a.elements.corners.rows() + b.elements.corners.rows(), 3);
    s.elements.vectors.resize(a.elements.vectors.rows() + b.elements.vectors.rows(), 3);
    s.elements.corners << a.elements.corners, b.elements.corners;
    s.elements.vectors << a.elements.vectors, b.elements.vectors;
    s.spacing = std::max(a.spacing, b.spacing);
    return s;
}

Box shm_default_bounds(const ShmSource& source) { return padded_cube(bounding_box(source.elements.corners)); }

PoissonSolver poisson_solver_from_name(const std::string& name) {
    if (name == "mg") return PoissonSolver::Multigrid;
    if (name == "cg") return PoissonSolver::CG;
    if (name == "direct") return PoissonSolver::Direct;
    throw Error("solver", "unknown solver '" + name + "' (mg, cg, direct)");
}

namespace shm_detail {

void for_each_sample(const ShmSource& source, double max_element, const Box& focus,
                     const std::function<void(const Eigen::Vector3d&, double)>& emit) {
    const OrientedElements& e = source.elements;
    FaceSplitter splitter(max_element, focus);
    for (Eigen::Index j = 0; j < e.vectors.rows(); ++j) {
        const Vec3 a = e.corners.row(3 * j).transpose(), b = e.corners.row(3 * j + 1).transpose(),
                   c = e.corners.row(3 * j + 2).transpose();
        if (a == b && a == c) {
            emit(a, e.vectors.row(j).norm());
            continue;
        }
        splitter.split(a, b, c, [&](const Vec3& p, const Vec3& v) {
            emit(p, v.norm());
            return true;
        });
    }
}

}  // namespace shm_detail

}  // namespace gsd
