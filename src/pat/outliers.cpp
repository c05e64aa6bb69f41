// PAT's defence against outliers (docs/pat.md, "Outliers"): a point is trusted when the tori of
// its neighbors pass through it.
//
// Why this score: in the blend each point owns the volume nearest to it (λ = C/σ makes the
// weights very sharp), so one stray point with a random normal carves a bubble of wrong sign
// and distance around itself. A point on the surface lies, up to noise, on the osculating
// tori of its neighbors; an outlier at distance D from the surface is ≈ D from all of them.
// Using the neighbors' tori (not the point's own, which is fitted to whatever surrounds it)
// keeps the score meaningful at sharp edges (an edge point lies on both faces' tori), under
// flipped normals (|g| ignores the orientation) and next to holes.
#include "pat/outliers.hpp"
#include "spatial/morton.hpp"

#include <gsd/spatial.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace gsd {

namespace {

// The value at `q` ∈ [0, 1] of the sorted order statistics of v (v is reordered).
double quantile(std::vector<double>& v, double q) {
    const auto k = std::size_t(std::floor(q * double(v.size() - 1)));
    std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
    return v[k];
}

// max(floor, median + f·MAD) of v: a threshold that follows the bulk of the values (the inliers,
// as long as they are the majority) but never drops below `floor`.
double robust_threshold(std::vector<double> v, double floor, double f) {
    const double med = quantile(v, 0.5);
    for (double& x : v) x = std::abs(x - med);
    return std::max(floor, med + f * 1.4826 * quantile(v, 0.5));
}

void check(const OutlierOptions& o) {
    if (o.k < 4 || o.k > 256) throw Error("OutlierOptions::k", "must be in [4, 256]");
    if (!(o.quantile > 0 && o.quantile < 1)) throw Error("OutlierOptions::quantile", "must be in (0, 1)");
    if (!(o.min_score > 0 && std::isfinite(o.min_score))) throw Error("OutlierOptions::min_score", "must be > 0");
    if (!(o.mad_factor >= 0 && std::isfinite(o.mad_factor)))
        throw Error("OutlierOptions::mad_factor", "must be ≥ 0");
    if (!(o.sparsity_factor > 1 && std::isfinite(o.sparsity_factor)))
        throw Error("OutlierOptions::sparsity_factor", "must be > 1");
}

}  // namespace

PointConfidence pat::score_points(const FittedTori& tori, const std::vector<Torus>& t,
                                     const OutlierOptions& options) {
    check(options);
    const Eigen::Index n = tori.size();
    PointConfidence out;
    out.score.assign(std::size_t(n), 0.0);
    out.sparsity.assign(std::size_t(n), 1.0);
    out.confidence.assign(std::size_t(n), 1.0f);
    if (n < options.k + 1) return out;  // too few points to judge any of them: trust all

    const KdTree tree(tori.points);
    const auto k = std::size_t(options.k);
    // The k nearest other points of each point, k per row (k + 1 are asked for and the point
    // itself, wherever a duplicate put it, is skipped), and ℓ_i, the distance to the k-th: a
    // local length that adapts to density.
    std::vector<double> ell(static_cast<std::size_t>(n));
    std::vector<std::uint32_t> nbrs(static_cast<std::size_t>(n) * k);
    // Both passes go in Morton order: consecutive points search the same tree nodes and read the
    // same neighbours' tori (a cloud's own order may be random, as a sampler's is).
    const std::vector<std::uint32_t> order = spatial::morton_order(tori.points);
#pragma omp parallel
    {
        std::vector<Neighbor> nb;
#pragma omp for schedule(dynamic, 256)
        for (Eigen::Index o = 0; o < n; ++o) {
            const auto i = Eigen::Index(order[std::size_t(o)]);
            tree.knn(tori.points.row(i).transpose(), k + 1, nb);
            std::uint32_t* ids = &nbrs[std::size_t(i) * k];
            std::size_t m = 0;
            for (const Neighbor& c : nb)
                if (c.index != std::uint32_t(i) && m < k) ids[m++] = c.index;
            ell[std::size_t(i)] = nb.back().distance;
        }
    }
    // Score s_i = (q-quantile over neighbors j of |g_j(p_i)|) / (median over j of ℓ_j): how far
    // the point sits from its neighbors' surfaces, in units of their own spacing.
    std::vector<double> score(static_cast<std::size_t>(n));
#pragma omp parallel
    {
        std::vector<double> dist, len;
#pragma omp for schedule(dynamic, 256)
        for (Eigen::Index o = 0; o < n; ++o) {
            const auto i = Eigen::Index(order[std::size_t(o)]);
            const Eigen::Vector3d p = tori.points.row(i).transpose();
            dist.clear();
            len.clear();
            for (std::size_t m = 0; m < k; ++m) {
                const std::uint32_t j = nbrs[std::size_t(i) * k + m];
                len.push_back(ell[j]);
                const double g = std::abs(torus_sdf(t[j], p));
                dist.push_back(std::isfinite(g) ? g : std::numeric_limits<double>::max());
            }
            const double scale = quantile(len, 0.5);
            const double d = quantile(dist, options.quantile);
            // Coincident neighbors (scale 0) with the point on their tori: a perfect score.
            score[std::size_t(i)] = scale > 0 ? d / scale : (d > 0 ? std::numeric_limits<double>::max() : 0.0);
        }
    }
    // The residual threshold adapts to the cloud's own noise, so a noisy scan keeps its points;
    // the floor min_score keeps a clean cloud, whose residuals are all tiny, whole.
    out.threshold = robust_threshold(score, options.min_score, options.mad_factor);
    // Outliers far from the surface have only each other as neighbors, and random points' tori
    // pass near random points often enough to vouch for each other; what gives them away is
    // that they are sparse: their k-th neighbor is many times farther than the cloud's typical
    // one (which the surface points set). That threshold adapts too, so a cloud sampled
    // unevenly on purpose (a scan, denser near the scanner) keeps its sparse parts.
    std::vector<double> tmp = ell;
    const double typical = quantile(tmp, 0.5);
    for (std::size_t i = 0; i < std::size_t(n); ++i)
        out.sparsity[i] = typical > 0 ? ell[i] / typical : (ell[i] > 0 ? std::numeric_limits<double>::max() : 1.0);
    out.sparsity_threshold = robust_threshold(out.sparsity, options.sparsity_factor, options.mad_factor);
    for (std::size_t i = 0; i < std::size_t(n); ++i) {
        out.score[i] = score[i];
        const double r = std::max(score[i] / out.threshold, out.sparsity[i] / out.sparsity_threshold);
        // A smooth confidence, 1/2 exactly at the threshold; points below 1/2 are outliers.
        out.confidence[i] = r < 1e6 ? float(1.0 / (1.0 + r * r * r * r)) : 0.0f;
        if (out.is_outlier(i)) ++out.outliers;
    }
    return out;
}

PointConfidence point_confidence(const FittedTori& tori, const OutlierOptions& options) {
    return pat::score_points(tori, tori.tori(), options);
}

PointCloud without_outliers(const PointCloud& cloud, const OutlierOptions& options, std::size_t* dropped) {
    const PointConfidence c = point_confidence(JetFitter().fit(cloud), options);
    std::vector<Eigen::Index> keep;
    keep.reserve(std::size_t(cloud.size()));
    for (Eigen::Index i = 0; i < cloud.size(); ++i)
        if (!c.is_outlier(std::size_t(i))) keep.push_back(i);
    if (dropped) *dropped = std::size_t(cloud.size()) - keep.size();
    PointCloud out;
    out.points.resize(Eigen::Index(keep.size()), 3);
    out.normals.resize(Eigen::Index(keep.size()), 3);
    for (std::size_t k = 0; k < keep.size(); ++k) {
        out.points.row(Eigen::Index(k)) = cloud.points.row(keep[k]);
        out.normals.row(Eigen::Index(k)) = cloud.normals.row(keep[k]);
    }
    return out;
}

}  // namespace gsd
