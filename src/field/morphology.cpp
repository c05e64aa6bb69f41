// Opening and closing of a field's shape (gsd/field_algebra.hpp): offsets on a grid with a
// re-distancing between them, so that the second offset acts on a true distance. The
// re-distancing measures the exact distance to the first offset's zero set, meshed by marching
// cubes, with the nearest-triangle search of gsd sdf.
#include <gsd/field_algebra.hpp>
#include <gsd/sdf.hpp>
#include <gsd/spatial.hpp>
#include <gsd/viz.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <unordered_set>

namespace gsd {

std::vector<float> redistance(const GridSpec& grid, const std::vector<float>& values) {
    grid.validate();
    if (values.size() != grid.node_count())
        throw Error("values", std::to_string(values.size()) + " values for a grid of " + std::to_string(grid.node_count()) + " nodes");
    const PolygonMesh zero_set = contour(grid, values, 0.0);
    std::vector<float> out(values.size());
    if (zero_set.face_count() == 0) {  // no surface in the grid: as far as the grid reaches
        const auto far = float(grid.box.diagonal());
        for (std::size_t i = 0; i < values.size(); ++i) out[i] = values[i] < 0 ? -far : far;
        return out;
    }
    MeshSdfOptions o;
    o.sign = SdfSign::none;
    o.device = "cpu";  // exact distances; the nodes' signs are the values'
    const std::vector<double> d = mesh_sdf(zero_set, grid.nodes(), o).phi;
    for (std::size_t i = 0; i < values.size(); ++i) out[i] = float(values[i] < 0 ? -d[i] : d[i]);
    return out;
}

namespace {

class MorphologyField final : public Field {
public:
    MorphologyField(FieldPtr a, double r, bool opening, const GridSpec& grid) : a_(std::move(a)), r_(r), opening_(opening), grid_(grid) {
        const char* name = opening ? "opening" : "closing";
        if (!a_) throw Error(name, "is null: an operator needs a field");
        if (!(r_ > 0 && std::isfinite(r_))) throw Error(name, "the radius must be a finite number > 0");
        grid_.validate();
        check_memory(48.0 * double(grid_.node_count()), name, "a grid of " + std::to_string(grid_.node_count()) + " nodes");
    }

    using Field::evaluate;
    FieldValues evaluate(PointsView q, bool with_gradient, const ProgressFn& progress) const override {
        return solved(progress).evaluate(q, with_gradient);
    }
    FieldValues evaluate(const GridSpec& grid, bool with_gradient, const ProgressFn& progress) const override {
        return solved(progress).evaluate(grid, with_gradient);
    }
    bool has_gradient() const override { return true; }

private:
    // Opening: φ + r (eroded), re-distanced, − r (dilated); closing the other way round.
    const GridField& solved(const ProgressFn& progress) const {
        std::call_once(once_, [&] {
            std::vector<float> v = a_->evaluate(grid_, false, progress).phi;
            const float first = float(opening_ ? r_ : -r_);
            for (float& x : v) x += first;
            v = redistance(grid_, v);
            for (float& x : v) x -= first;
            result_ = std::make_unique<GridField>(grid_, std::move(v));
        });
        return *result_;
    }

    FieldPtr a_;
    double r_;
    bool opening_;
    GridSpec grid_;
    mutable std::once_flag once_;
    mutable std::unique_ptr<GridField> result_;
};

// Opening or closing by resampling (field_algebra.hpp). The first offset's zero set is sampled
// by moving the seeds onto it; the offset field is then re-distanced without a grid: its value at
// x is sign(φ(x) ± r) times the distance from x to those samples, each a disk of half the seeds'
// spacing across, oriented by ∇φ; the second offset is ∓r on top. The sign comes from the
// original field (as robust as it is), the magnitude from the samples (a true distance to the
// offset surface, wherever it was sampled).
class ResampledMorphologyField final : public Field {
public:
    ResampledMorphologyField(FieldPtr a, double r, bool opening, Points seeds)
        : a_(std::move(a)), r_(r), opening_(opening), seeds_(std::move(seeds)) {
        const char* name = opening ? "opening" : "closing";
        if (!a_) throw Error(name, "is null: an operator needs a field");
        if (!a_->has_gradient()) throw Error(name, "resampling needs a field with ∇φ (or give a grid)");
        if (!(r_ > 0 && std::isfinite(r_))) throw Error(name, "the radius must be a finite number > 0");
        if (seeds_.rows() == 0 || seeds_.cols() != 3) throw Error(name, "no seed points on the zero set");
        if (!seeds_.allFinite()) throw Error(name, "the seed points must be finite");
    }

    using Field::evaluate;
    FieldValues evaluate(PointsView q, bool with_gradient, const ProgressFn& progress) const override {
        return redistanced(Points(q), with_gradient, progress);
    }
    FieldValues evaluate(const GridSpec& grid, bool with_gradient, const ProgressFn& progress) const override {
        grid.validate();
        return redistanced(grid.nodes(), with_gradient, progress);
    }
    bool has_gradient() const override { return true; }

private:
    // The offset surface's samples, made at the first evaluation.
    const PointCloud& samples(const ProgressFn& progress) const {
        std::call_once(once_, [&] { build(progress); });
        return samples_;
    }

    // The side of the first offset: −1 for an opening (inward), +1 for a closing.
    double side() const { return opening_ ? -1.0 : 1.0; }

    FieldValues redistanced(const Points& x, bool with_gradient, const ProgressFn& progress) const {
        const PointCloud& p = samples(progress);
        const double shift = side() * r_;  // the first offset: φ − shift
        FieldValues v = a_->evaluate(x, false);
        if (with_gradient) v.gradient.assign(3 * std::size_t(x.rows()), 0.0f);
        const Eigen::Index n = x.rows();
#pragma omp parallel for schedule(dynamic, 256)
        for (Eigen::Index i = 0; i < n; ++i) {
            const Eigen::Vector3d q = x.row(i).transpose();
            Eigen::Vector3d g = Eigen::Vector3d::Zero();
            double d = std::numeric_limits<double>::infinity();
            if (p.size() > 0) {
                for (const Neighbor& nb : tree_->knn(q, kNeighbors)) {
                    // The distance to a disk of radius s/2 about the sample, normal to n.
                    const Eigen::Vector3d o = q - p.points.row(nb.index).transpose(), nrm = p.normals.row(nb.index).transpose();
                    const double h = nrm.dot(o);
                    const Eigen::Vector3d t = o - h * nrm;
                    const double tl = t.norm(), excess = std::max(tl - 0.5 * spacing_, 0.0);
                    const double dd = std::sqrt(h * h + excess * excess);
                    if (dd < d) {
                        d = dd;
                        g = h * nrm + (tl > 0 ? excess / tl : 0.0) * t;  // from the disk's nearest point to q
                    }
                }
            } else {
                d = far_;
            }
            const double sgn = double(v.phi[std::size_t(i)]) - shift < 0 ? -1.0 : 1.0;
            v.phi[std::size_t(i)] = float(sgn * d + shift);
            if (with_gradient && d > 0 && std::isfinite(d))
                for (int a = 0; a < 3; ++a) v.gradient[3 * std::size_t(i) + std::size_t(a)] = float(sgn * g[a] / d);
        }
        v.device = "cpu";
        return v;
    }

    // The seeds moved onto φ = ±r: a step of r along ±∇φ, then Newton steps; kept where they land
    // on it about r from the nearest seed, one per cell of half the seeds' spacing.
    void build(const ProgressFn& progress) const {
        const double target = side() * r_;
        const Eigen::Index n = seeds_.rows();
        FieldValues v = a_->evaluate(seeds_, true);
        Points y(n, 3);
        for (Eigen::Index i = 0; i < n; ++i) {
            const Eigen::Vector3d g = gradient_at(v, i);
            const double len = g.norm();
            y.row(i) = seeds_.row(i) + (len > 0 ? target / len : 0.0) * g.transpose();
        }
        for (int step = 0; step < kNewtonSteps; ++step) {
            v = a_->evaluate(y, true);
            for (Eigen::Index i = 0; i < n; ++i) {
                const Eigen::Vector3d g = gradient_at(v, i);
                const double g2 = g.squaredNorm();
                if (g2 > 1e-12) y.row(i) -= ((double(v.phi[std::size_t(i)]) - target) / g2) * g.transpose();
            }
            if (progress) progress("resample", double(step + 1) / kNewtonSteps);
        }
        v = a_->evaluate(y, true);
        const KdTree seeds(seeds_);
        spacing_ = seed_spacing(seeds);
        far_ = bounding_box(seeds_).diagonal() + r_;
        std::vector<Eigen::Index> kept;
        for (Eigen::Index i = 0; i < n; ++i) {
            if (!y.row(i).allFinite() || std::abs(double(v.phi[std::size_t(i)]) - target) > kOnSurface * r_) continue;
            const double d = seeds.knn(y.row(i).transpose(), 1)[0].distance;
            if (d >= kNearest[0] * r_ && d <= kNearest[1] * r_) kept.push_back(i);
        }
        kept = thinned(y, kept, spacing_);
        samples_.points.resize(Eigen::Index(kept.size()), 3);
        samples_.normals.resize(Eigen::Index(kept.size()), 3);
        for (std::size_t k = 0; k < kept.size(); ++k) {
            samples_.points.row(Eigen::Index(k)) = y.row(kept[k]);
            samples_.normals.row(Eigen::Index(k)) = gradient_at(v, kept[k]).normalized().transpose();
        }
        if (!kept.empty()) tree_ = std::make_unique<KdTree>(samples_.points);
    }

    static Eigen::Vector3d gradient_at(const FieldValues& v, Eigen::Index i) {
        const auto j = 3 * std::size_t(i);
        return {v.gradient[j], v.gradient[j + 1], v.gradient[j + 2]};
    }

    // The seeds' typical spacing: the median distance to the nearest other seed (of up to 4096).
    double seed_spacing(const KdTree& tree) const {
        const Eigen::Index n = seeds_.rows(), step = std::max<Eigen::Index>(1, n / 4096);
        std::vector<double> d;
        for (Eigen::Index i = 0; i < n; i += step) {
            const auto nb = tree.knn(seeds_.row(i).transpose(), 2);
            if (nb.size() == 2) d.push_back(nb[1].distance);
        }
        if (d.empty()) return 0;
        std::nth_element(d.begin(), d.begin() + std::ptrdiff_t(d.size() / 2), d.end());
        return d[d.size() / 2];
    }

    // One sample per cell of half the seeds' spacing: an offset gathers a convex edge's seeds
    // into a few points (an opening's) and piles of near-duplicates only cost time.
    static std::vector<Eigen::Index> thinned(const Points& y, const std::vector<Eigen::Index>& kept, double spacing) {
        if (!(spacing > 0)) return kept;
        const double cell = 0.5 * spacing;
        std::unordered_set<std::uint64_t> taken;
        std::vector<Eigen::Index> out;
        for (Eigen::Index i : kept) {
            std::uint64_t key = 0;
            for (int a = 0; a < 3; ++a) key = key * 2097143u + std::uint64_t(std::int64_t(std::floor(y(i, a) / cell)) & 0x1fffff);
            if (taken.insert(key).second) out.push_back(i);
        }
        return out;
    }

    static constexpr int kNewtonSteps = 3;
    static constexpr double kOnSurface = 0.05;         // |φ − target| ≤ 5 % of r
    static constexpr double kNearest[2] = {0.8, 1.5};  // the nearest seed at 0.8r … 1.5r
    static constexpr std::size_t kNeighbors = 4;       // samples whose disks are measured

    FieldPtr a_;
    double r_;
    bool opening_;
    Points seeds_;
    mutable std::once_flag once_;
    mutable PointCloud samples_;
    mutable std::unique_ptr<KdTree> tree_;
    mutable double spacing_ = 0, far_ = 0;
};

}  // namespace

FieldPtr field_opening(FieldPtr a, double r, Points seeds) {
    return std::make_shared<ResampledMorphologyField>(std::move(a), r, true, std::move(seeds));
}
FieldPtr field_closing(FieldPtr a, double r, Points seeds) {
    return std::make_shared<ResampledMorphologyField>(std::move(a), r, false, std::move(seeds));
}

FieldPtr field_opening(FieldPtr a, double r, const GridSpec& grid) {
    return std::make_shared<MorphologyField>(std::move(a), r, true, grid);
}
FieldPtr field_closing(FieldPtr a, double r, const GridSpec& grid) {
    return std::make_shared<MorphologyField>(std::move(a), r, false, grid);
}

}  // namespace gsd
