// reorient_normals (gsd/spatial.hpp): a cloud's flipped normals turned back by their neighbours'.
#include <gsd/spatial.hpp>

#include "spatial/morton.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace gsd {

namespace {

// Each point's neighbours that vote on its normal, with their weights. A weight falls off with
// the distance (Gaussian of width `width`) and with the offset z from the point's tangent plane
// (Gaussian of width `tangent_width`), so that the other side of a thin part, whose normals face
// the other way, has little say, while a flip (the same line, reversed) does not move a neighbour
// out of the plane. A neighbour behind the point (z < 0 along its normal) whose normal opposes it
// is what the far side of a thin solid looks like from a rightly oriented point: its offset is
// weighed by the narrower `behind_width`, so that a solid thinner than a spacing (a CAD part's
// panel, sampled on both faces) does not outvote the point's own side. Turning a normal changes
// neither the distance nor |z|, so both are found once, for every pass.
struct Votes {
    std::size_t k = 0;                 // voters per point (the k nearest, the point left out)
    std::vector<std::uint32_t> voter;  // point i's: voter[i·k …]
    std::vector<float> weight;         // the Gaussians of distance and offset (tangent_width), ÷ the largest
    std::vector<float> behind;         // … of offset behind_width, signed as z along the normal as given

    Votes(const PointCloud& cloud, const Points& normals, const KdTree& tree, std::size_t neighbors, double width,
          double tangent_width, double behind_width)
        : k(neighbors) {
        const Eigen::Index n = cloud.size();
        voter.assign(std::size_t(n) * k, 0);
        weight.assign(std::size_t(n) * k, 0.0f);
        behind.assign(std::size_t(n) * k, 0.0f);
        // In Morton order: consecutive searches walk the same tree nodes (the input's order may
        // be any, a sampler's is random).
        const std::vector<std::uint32_t> order = spatial::morton_order(cloud.points);
#pragma omp parallel
        {
            std::vector<Neighbor> near;
#pragma omp for schedule(dynamic, 1024)
            for (Eigen::Index o = 0; o < n; ++o) {
                const auto i = Eigen::Index(order[std::size_t(o)]);
                const Eigen::Vector3d p = cloud.points.row(i).transpose(), m = normals.row(i).transpose();
                tree.knn(p, k + 1, near);
                // The exponents first: the weights are taken relative to the largest (a point's
                // verdict does not change under a positive factor), so that a stray point far from
                // every other still weighs its voters as they stand, not all as 0 in float.
                double least = INFINITY;
                std::size_t voters = 0;
                for (const Neighbor& q : near) {
                    if (Eigen::Index(q.index) == i) continue;
                    if (voters++ == k) break;  // the k stored below
                    const Eigen::Vector3d d = cloud.points.row(Eigen::Index(q.index)).transpose() - p;
                    const double r = q.distance / width, a = d.dot(m) / tangent_width;
                    least = std::min(least, r * r + a * a);
                }
                if (!std::isfinite(least)) least = 0;
                std::size_t at = std::size_t(i) * k, end = at + k;
                for (const Neighbor& q : near) {
                    if (Eigen::Index(q.index) == i || at == end) continue;
                    const Eigen::Vector3d d = cloud.points.row(Eigen::Index(q.index)).transpose() - p;
                    const double r = q.distance / width, z = d.dot(m), a = z / tangent_width, b = z / behind_width;
                    voter[at] = std::uint32_t(q.index);
                    // Signed as z, which a weight of 0 keeps too (−0.0).
                    behind[at] = std::copysign(float(std::exp(least - (r * r + b * b))), float(z));
                    weight[at++] = float(std::exp(least - (r * r + a * a)));
                }
            }
        }
    }

    // The voters' verdict on point i's normal: positive when their weighted normals agree with it.
    // `sign`: −1 when i's normal is turned from the one the offsets were taken along.
    double on(const Points& normals, Eigen::Index i, double sign) const {
        const Eigen::Vector3d ni = normals.row(i).transpose();
        double sum = 0;
        for (std::size_t v = std::size_t(i) * k, end = v + k; v < end; ++v) {
            const double agree = normals.row(Eigen::Index(voter[v])).dot(ni);
            const bool behind_now = std::signbit(behind[v]) != (sign < 0);
            sum += (behind_now && agree < 0 ? std::abs(double(behind[v])) : double(weight[v])) * agree;
        }
        return sum;
    }
};

}  // namespace

std::size_t reorient_normals(PointCloud& cloud, const ReorientOptions& options) {
    if (options.neighbors < 2) throw Error("ReorientOptions::neighbors", "must be ≥ 2");
    if (!(options.width > 0) || !std::isfinite(options.width)) throw Error("ReorientOptions::width", "must be finite and > 0");
    if (!(options.tangent_width > 0) || !std::isfinite(options.tangent_width))
        throw Error("ReorientOptions::tangent_width", "must be finite and > 0");
    if (!(options.behind_width > 0) || !(options.behind_width <= options.tangent_width))
        throw Error("ReorientOptions::behind_width", "must be > 0 and ≤ tangent_width");
    if (options.passes < 0) throw Error("ReorientOptions::passes", "must be ≥ 0");
    validate(cloud, "reorient_normals");  // a normal per point, all finite
    const Eigen::Index n = cloud.size();
    if (n <= 2 || options.passes == 0) return 0;
    if (std::uint64_t(n) > std::numeric_limits<std::uint32_t>::max())
        throw Error("reorient_normals", "more than 2^32 points");
    const std::size_t k = std::min(std::size_t(options.neighbors), std::size_t(n) - 1);
    check_memory(double(n) * double(k) * 12, "reorient_normals", "voting on the normals of " + std::to_string(n) + " points");
    const KdTree tree(cloud.points);
    const double h = mean_spacing(tree);
    if (!(h > 0)) return 0;  // most points duplicated (the spacing is 0): no scale to vote at
    // Unit normals vote (a longer one would weigh more, and tilt its tangent plane's offset).
    Points normals = cloud.normals.rowwise().normalized();
    const Votes votes(cloud, normals, tree, k, options.width * h, options.tangent_width * h, options.behind_width * h);
    // Each pass votes with the normals of the one before (all points at once: the result does not
    // depend on the order or the threads), until nothing changes.
    std::vector<char> turn(std::size_t(n), 0), flipped(std::size_t(n), 0);
    for (int pass = 0; pass < options.passes; ++pass) {
        std::size_t changed = 0;
#pragma omp parallel for schedule(static) reduction(+ : changed)
        for (Eigen::Index i = 0; i < n; ++i) {
            turn[std::size_t(i)] = votes.on(normals, i, flipped[std::size_t(i)] ? -1.0 : 1.0) < 0;
            changed += std::size_t(turn[std::size_t(i)]);
        }
        if (changed == 0) break;
        for (Eigen::Index i = 0; i < n; ++i)
            if (turn[std::size_t(i)]) {
                normals.row(i) *= -1;
                cloud.normals.row(i) *= -1;
                flipped[std::size_t(i)] ^= 1;
            }
    }
    std::size_t total = 0;
    for (char f : flipped) total += std::size_t(f);
    return total;
}

}  // namespace gsd
