// reorient_normals (gsd/spatial.hpp): a cloud's flipped normals turned back by their neighbours'.
#include <gsd/spatial.hpp>

#include <cmath>

namespace gsd {

namespace {

// The neighbours' vote on point i's normal (the sum of their normals, weighted): positive when
// they agree with it. Weights fall off with the distance (Gaussian of width `width`) and with
// the offset from i's tangent plane (Gaussian of width `tangent_width`), so that the other side
// of a thin part, whose normals face the other way, has no say, while a flip (the same line,
// reversed) does not move a neighbour out of the plane.
double vote(const PointCloud& cloud, const Points& normals, Eigen::Index i, const std::vector<Neighbor>& near,
            double width, double tangent_width) {
    const Eigen::Vector3d p = cloud.points.row(i).transpose(), n = normals.row(i).transpose();
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const Neighbor& q : near) {
        if (Eigen::Index(q.index) == i) continue;
        const Eigen::Vector3d d = cloud.points.row(Eigen::Index(q.index)).transpose() - p;
        const double r = q.distance / width, z = d.dot(n) / tangent_width;
        sum += std::exp(-(r * r + z * z)) * normals.row(Eigen::Index(q.index)).transpose();
    }
    return sum.dot(n);
}

}  // namespace

std::size_t reorient_normals(PointCloud& cloud, const ReorientOptions& options) {
    if (options.neighbors < 2) throw Error("ReorientOptions::neighbors", "must be ≥ 2");
    if (!(options.width > 0) || !std::isfinite(options.width)) throw Error("ReorientOptions::width", "must be finite and > 0");
    if (!(options.tangent_width > 0) || !std::isfinite(options.tangent_width))
        throw Error("ReorientOptions::tangent_width", "must be finite and > 0");
    if (options.passes < 0) throw Error("ReorientOptions::passes", "must be ≥ 0");
    validate(cloud, "reorient_normals");  // a normal per point, all finite
    const Eigen::Index n = cloud.size();
    if (n <= 2 || options.passes == 0) return 0;
    const KdTree tree(cloud.points);
    const double h = mean_spacing(tree);
    if (!(h > 0)) return 0;  // most points duplicated (the spacing is 0): no scale to vote at
    // Each pass votes with the normals of the one before (all points at once: the result does not
    // depend on the order or the threads), until nothing changes.
    std::vector<char> flipped(std::size_t(n), 0);
    for (int pass = 0; pass < options.passes; ++pass) {
        // Unit normals vote (a longer one would weigh more, and tilt its tangent plane's offset).
        const Points normals = cloud.normals.rowwise().normalized();
        std::size_t changed = 0;
#pragma omp parallel reduction(+ : changed)
        {
            std::vector<Neighbor> near;
#pragma omp for schedule(dynamic, 1024)
            for (Eigen::Index i = 0; i < n; ++i) {
                tree.knn(cloud.points.row(i).transpose(), std::size_t(options.neighbors) + 1, near);
                if (vote(cloud, normals, i, near, options.width * h, options.tangent_width * h) < 0) {
                    cloud.normals.row(i) *= -1;  // row i is this iteration's alone
                    flipped[std::size_t(i)] ^= 1;
                    ++changed;
                }
            }
        }
        if (changed == 0) break;
    }
    std::size_t total = 0;
    for (char f : flipped) total += std::size_t(f);
    return total;
}

}  // namespace gsd
