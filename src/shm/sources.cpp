// Sources of the Signed Heat Method: oriented area elements from clouds and meshes.
#include <gsd/shm.hpp>
#include <gsd/spatial.hpp>

#include "core/clip.hpp"
#include "shm/diffuse.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

namespace gsd {

namespace {

using Vec3 = Eigen::Vector3d;

/// Emits (centroid, vector area) of pieces of a triangle no longer than max_element.
/// Triangles inside the box are split at their edge midpoints (four similar pieces); pieces cut
/// from a triangle at the box's faces, which can be needles, are bisected at their longest edge
/// instead, so that a needle of length L costs about L / max_element pieces, not its square.
/// Either way a piece is never longer than the box's diagonal, so the count per triangle is at
/// most (2 · diagonal / max_element)² (a few times the cells the piece meets). Iterative (an
/// explicit stack): no recursion depth depends on the data.
class FaceSplitter {
public:
    explicit FaceSplitter(double max_element) : max_element_(max_element) {}

    template <class Emit>
    void split(const Vec3& a, const Vec3& b, const Vec3& c, bool bisect, Emit&& emit) {
        stack_.clear();
        stack_.push_back({a, b, c});
        while (!stack_.empty()) {
            const std::array<Vec3, 3> t = stack_.back();
            stack_.pop_back();
            const Vec3 area = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]);
            if (!(area.norm() > 0)) continue;  // degenerate: no orientation, no area
            const double len[3] = {(t[1] - t[0]).norm(), (t[2] - t[1]).norm(), (t[0] - t[2]).norm()};
            const int longest = int(std::max_element(len, len + 3) - len);
            if (len[longest] <= max_element_) {
                emit((t[0] + t[1] + t[2]) / 3, area);
                continue;
            }
            if (bisect) {
                // Corners i, j = i + 1 span the longest edge; k is opposite. Same orientation.
                const int i = longest, j = (i + 1) % 3, k = (i + 2) % 3;
                const Vec3 m = 0.5 * (t[std::size_t(i)] + t[std::size_t(j)]);
                stack_.push_back({t[std::size_t(i)], m, t[std::size_t(k)]});
                stack_.push_back({m, t[std::size_t(j)], t[std::size_t(k)]});
                continue;
            }
            const Vec3 ab = 0.5 * (t[0] + t[1]), bc = 0.5 * (t[1] + t[2]), ca = 0.5 * (t[2] + t[0]);
            stack_.push_back({t[0], ab, ca});
            stack_.push_back({ab, t[1], bc});
            stack_.push_back({ca, bc, t[2]});
            stack_.push_back({ab, bc, ca});
        }
    }

private:
    double max_element_;
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

namespace shm {

void for_each_sample(const ShmSource& source, double max_element, const Box& focus,
                     const std::function<void(const Eigen::Vector3d&, double)>& emit) {
    const OrientedElements& e = source.elements;
    // Never finer than a millionth of the box: a stated floor on top of the caller's cell, so
    // that the count per triangle stays (2·10⁶·√3)² at worst whatever the caller asks.
    FaceSplitter splitter(std::max(max_element, 1e-6 * focus.diagonal()));
    std::array<Vec3, 9> poly;
    for (Eigen::Index j = 0; j < e.vectors.rows(); ++j) {
        const Vec3 a = e.corners.row(3 * j).transpose(), b = e.corners.row(3 * j + 1).transpose(),
                   c = e.corners.row(3 * j + 2).transpose();
        if (a == b && a == c) {
            if ((a.array() >= focus.lo.array()).all() && (a.array() <= focus.hi.array()).all())
                emit(a, e.vectors.row(j).norm());
            continue;
        }
        const int n = detail::clip_triangle_to_box(a, b, c, focus.lo, focus.hi, poly);
        if (n < 3) continue;  // misses the box (or touches it along an edge: no area there)
        const bool whole = n == 3 && poly[0] == a && poly[1] == b && poly[2] == c;
        for (int i = 1; i + 1 < n; ++i)  // a fan over the convex part inside
            splitter.split(poly[0], poly[std::size_t(i)], poly[std::size_t(i + 1)], !whole,
                           [&](const Vec3& p, const Vec3& v) { emit(p, v.norm()); });
    }
}

}  // namespace shm

}  // namespace gsd
