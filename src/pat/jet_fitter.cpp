// The classic weighted-least-squares jet: a quadratic height function fitted to each point's
// k nearest neighbors in its tangent frame, optionally matching neighbor normals too.
#include <gsd/pat.hpp>
#include <gsd/spatial.hpp>

#include "spatial/morton.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace gsd {

namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

// Fits one point. Works in coordinates scaled by the neighborhood radius ℓ so that the
// normal equations are well conditioned at any cloud scale.
Jet fit_one(const PointCloud& cloud, Eigen::Index i, const Eigen::Vector3d& s,
            const std::vector<Neighbor>& nb, const JetFitterOptions& opt) {
    const Eigen::Vector3d p = cloud.points.row(i).transpose();
    const Eigen::Vector3d n = cloud.normals.row(i).transpose();
    const Eigen::Vector3d t = n.cross(s);
    const double ell = std::max(nb.back().distance, 1e-300);
    const double inv_sigma2 = 1.0 / (opt.sigma_factor * opt.sigma_factor);
    const double min_cos = std::cos(opt.max_normal_angle_deg * M_PI / 180.0);

    Mat6 M = Mat6::Zero();
    Vec6 b = Vec6::Zero();
    double weight_sum = 0;
    for (const Neighbor& j : nb) {
        const Eigen::Vector3d d = (cloud.points.row(j.index).transpose() - p) / ell;
        const double su = d.dot(s), tu = d.dot(t), hu = d.dot(n);
        const double w = std::exp(-(su * su + tu * tu + hu * hu) * inv_sigma2);
        Vec6 row;
        row << 1, su, tu, su * tu, su * su, tu * tu;
        M.noalias() += w * row * row.transpose();
        b.noalias() += w * hu * row;
        weight_sum += w;

        if (opt.normal_weight <= 0) continue;
        const Eigen::Vector3d nj = cloud.normals.row(j.index).transpose();
        const double nn = nj.dot(n);
        if (nn < min_cos) continue;  // steep or flipped neighbor: no usable slope
        const double ws = opt.normal_weight * w;
        Vec6 rs, rt;
        rs << 0, 1, 0, tu, 2 * su, 0;
        rt << 0, 0, 1, su, 0, 2 * tu;
        M.noalias() += ws * (rs * rs.transpose() + rt * rt.transpose());
        b.noalias() += ws * (-nj.dot(s) / nn * rs - nj.dot(t) / nn * rt);
    }
    // A light ridge keeps degenerate neighborhoods (collinear, too few points) solvable and
    // pulls their unknown curvature toward flat rather than toward noise.
    const double ridge = 1e-6 * std::max(weight_sum, 1e-12);
    for (int a = 0; a < 6; ++a) M(a, a) += a >= 3 ? 10 * ridge : ridge;
    const Vec6 x = M.ldlt().solve(b);

    Jet jet;
    jet.a00 = x[0] * ell;
    jet.a10 = x[1];
    jet.a01 = x[2];
    jet.a11 = x[3] / ell;
    jet.a20 = x[4] / ell;
    jet.a02 = x[5] / ell;
    if (!(std::isfinite(jet.a00) && std::isfinite(jet.a10) && std::isfinite(jet.a01) &&
          std::isfinite(jet.a11) && std::isfinite(jet.a20) && std::isfinite(jet.a02)))
        jet = Jet{};  // a failed solve becomes the tangent plane
    return jet;
}

}  // namespace

JetFitter::JetFitter(JetFitterOptions options) : options_(options) {
    if (options_.k < 6) throw Error("JetFitterOptions::k", "the jet fit needs k ≥ 6 neighbors (6 coefficients)");
    if (!(options_.sigma_factor > 0)) throw Error("jet sigma factor must be > 0");
}

FittedTori JetFitter::fit(const PointCloud& cloud, const ProgressFn& progress) const {
    const Eigen::Index n = cloud.size();
    if (n < 2) throw Error("point cloud needs at least 2 points");
    // Measured: 322 B per point at 10⁶, 299 B per point from 10⁶ to 10⁷ (tree, tori, jets, the
    // copy of the cloud); docs/io.md.
    check_memory(384.0 * double(n), "cloud", "fitting jets to " + std::to_string(n) + " points");
    KdTree tree(cloud.points);
    FittedTori out;
    out.points = cloud.points;
    out.normals = cloud.normals;
    out.tangents.resize(n, 3);
    out.jets.resize(std::size_t(n));
    out.spacing = mean_spacing(tree);
    out.fitter = "jet";
    const std::size_t k = std::min<std::size_t>(std::size_t(options_.k), std::size_t(n));

    // In Morton order: consecutive searches walk the same tree nodes and read the same points
    // (a cloud's own order may be random, as a sampler's is). Blocks keep progress reports on
    // the calling thread.
    const std::vector<std::uint32_t> order = spatial::morton_order(cloud.points);
    const Eigen::Index block = 16384;
    for (Eigen::Index first = 0; first < n; first += block) {
        const Eigen::Index last = std::min(n, first + block);
#pragma omp parallel
        {
            std::vector<Neighbor> nb;
#pragma omp for schedule(dynamic, 256)
            for (Eigen::Index o = first; o < last; ++o) {
                const auto i = Eigen::Index(order[std::size_t(o)]);
                const Eigen::Vector3d ni = cloud.normals.row(i).transpose();
                const Eigen::Vector3d s = tangent_of(ni);
                out.tangents.row(i) = s.transpose();
                tree.knn(cloud.points.row(i).transpose(), k, nb);
                out.jets[std::size_t(i)] = fit_one(cloud, i, s, nb, options_);
            }
        }
        if (progress) progress("fit", double(last) / double(n));
    }
    return out;
}

}  // namespace gsd
