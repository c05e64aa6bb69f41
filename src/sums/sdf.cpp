// Signed distance to a mesh as it comes: the sum tree's exact nearest-triangle search for the
// distance, its fast winding numbers for the sign (gsd/sdf.hpp).
#include <gsd/sdf.hpp>
#include <gsd/sums.hpp>

#include "spatial/morton.hpp"
#include "sums/sum_tree.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>

namespace gsd {

namespace {

void check(const MeshSdfOptions& o, PointsView queries) {
    if (!(o.inside_threshold > 0 && o.inside_threshold < 1))
        throw Error("MeshSdfOptions::inside_threshold", "must be between 0 and 1 (winding numbers are ≈ 1 inside, 0 outside)");
    for (Eigen::Index i = 0; i < queries.rows(); ++i)
        if (!queries.row(i).allFinite()) throw Error("queries", "query " + std::to_string(i) + " is not finite");
}

// Exact distances. The queries are taken in Morton order, each thread over a contiguous run of
// it, in packets of consecutive ones that walk the tree together (neighbours visit nearly the
// same nodes), each packet's search started from the previous one's nearest triangle, whose
// distance prunes it; in blocks, for progress. In input order, 10⁶ random queries around a
// 9·10⁴-face mesh took 3.5× as long (docs/sdf.md).
std::vector<double> distances(const sums::SumTree& tree, PointsView q, const ProgressFn& progress) {
    constexpr int L = sums::SumTree::kScreenedLanes;
    const std::size_t n = std::size_t(q.rows());
    std::vector<double> d(n);
    const std::vector<std::uint32_t> order = spatial::morton_order(q);
    constexpr std::size_t kBlock = std::size_t(1) << 16;  // a multiple of L
    for (std::size_t first = 0; first < n; first += kBlock) {
        const std::size_t last = std::min(n, first + kBlock);
        const std::size_t packets = (last - first + L - 1) / L;
#pragma omp parallel
        {
            std::uint32_t nearest = std::uint32_t(tree.size());  // none yet
            double p[3 * L], r[L];
#pragma omp for schedule(static)
            for (std::size_t k = 0; k < packets; ++k) {
                const std::size_t i0 = first + k * L;
                const int m = int(std::min<std::size_t>(L, last - i0));
                for (int l = 0; l < m; ++l)
                    for (int a = 0; a < 3; ++a) p[3 * l + a] = q(Eigen::Index(order[i0 + std::size_t(l)]), a);
                tree.nearest_lanes(p, m, nullptr, &nearest, r);
                for (int l = 0; l < m; ++l) d[order[i0 + std::size_t(l)]] = r[l];
            }
        }
        if (progress) progress("distance", double(last) / double(n));
    }
    return d;
}

// The samples' random numbers, the same on every platform (the standard distributions are
// not): doubles in [0, 1) from the top 53 bits, normals by Box–Muller.
class SampleRandom {
public:
    explicit SampleRandom(std::uint64_t seed) : engine_(seed) {}
    double uniform() { return double(engine_() >> 11) * 0x1.0p-53; }
    Eigen::Vector3d normal3() {
        Eigen::Vector3d g;
        for (int a = 0; a < 3; ++a) {
            if (!have_) {
                const double r = std::sqrt(-2 * std::log(1 - uniform())), t = 2 * M_PI * uniform();
                spare_ = r * std::sin(t);
                have_ = true;
                g[a] = r * std::cos(t);
            } else {
                have_ = false;
                g[a] = spare_;
            }
        }
        return g;
    }

private:
    std::mt19937_64 engine_;
    double spare_ = 0;
    bool have_ = false;
};

void check(const SdfSampleOptions& o, std::size_t count) {
    if (count == 0) throw Error("samples", "must be at least 1");
    // The samples, their Morton order and the sums' per-query state: ~100 bytes a sample.
    check_memory(100.0 * double(count), "samples", std::to_string(count) + " samples");
    if (!(o.uniform_fraction >= 0 && o.uniform_fraction <= 1))
        throw Error("SdfSampleOptions::uniform_fraction", "must be between 0 and 1");
    if (o.near_sigma.empty() && o.uniform_fraction < 1)
        throw Error("SdfSampleOptions::near_sigma", "needs at least one σ unless every sample is uniform");
    for (double s : o.near_sigma)
        if (!(s > 0 && std::isfinite(s))) throw Error("SdfSampleOptions::near_sigma", "every σ must be a positive number");
}

// Points uniform on the mesh's surface by area: a triangle by its share of the area, then a
// point uniform in it.
class SurfaceSampler {
public:
    explicit SurfaceSampler(const PolygonMesh& mesh) : mesh_(mesh) {
        double total = 0;
        for_each_triangle(mesh, [&](std::size_t, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
            const Eigen::Vector3d pa = mesh.vertices.row(a), pb = mesh.vertices.row(b), pc = mesh.vertices.row(c);
            const double area = 0.5 * (pb - pa).cross(pc - pa).norm();
            if (!(area > 0)) return;
            total += area;
            cumulative_.push_back(total);
            corners_.push_back({a, b, c});
        });
    }
    bool empty() const { return corners_.empty(); }
    Eigen::Vector3d point(SampleRandom& rng) const {
        const double u = rng.uniform() * cumulative_.back();
        const std::size_t t = std::min<std::size_t>(
            std::size_t(std::upper_bound(cumulative_.begin(), cumulative_.end(), u) - cumulative_.begin()),
            corners_.size() - 1);
        const double r1 = std::sqrt(rng.uniform()), r2 = rng.uniform();
        const auto& c = corners_[t];
        return (1 - r1) * Eigen::Vector3d(mesh_.vertices.row(c[0])) + r1 * (1 - r2) * Eigen::Vector3d(mesh_.vertices.row(c[1])) +
               r1 * r2 * Eigen::Vector3d(mesh_.vertices.row(c[2]));
    }

private:
    const PolygonMesh& mesh_;
    std::vector<double> cumulative_;
    std::vector<std::array<std::uint32_t, 3>> corners_;
};

}  // namespace

MeshSdfResult mesh_sdf(const PolygonMesh& mesh, PointsView queries, const MeshSdfOptions& options,
                       const ProgressFn& progress) {
    validate(mesh, "mesh");
    check(options, queries);
    MeshSdfResult r;
    for_each_triangle(mesh, [&](std::size_t, std::uint32_t, std::uint32_t, std::uint32_t) { ++r.triangles; });
    OrientedElements elements = OrientedElements::from_mesh(mesh);  // drops zero-area triangles
    r.degenerate = r.triangles - elements.size();
    r.triangles = elements.size();
    r.device = "cpu";
    if (queries.rows() == 0) return r;
    const sums::SumTree tree(elements);
    r.phi = distances(tree, queries, progress);
    if (options.sign == SdfSign::winding) {
        WindingOptions w;
        w.device = options.device;
        w.chunk_size = options.chunk_size;
        WindingResult wr = WindingField(std::move(elements), w).winding_numbers(queries, progress);
        for (std::size_t i = 0; i < r.phi.size(); ++i)
            if (wr.w[i] > options.inside_threshold) r.phi[i] = -r.phi[i];
        r.winding = std::move(wr.w);
        r.device = wr.device;
    }
    return r;
}

SdfSamples sample_sdf(const PolygonMesh& mesh, std::size_t count, const SdfSampleOptions& options,
                      const ProgressFn& progress) {
    validate(mesh, "mesh");
    check(options, count);
    SdfSamples out;
    const Box box = bounding_box(mesh.vertices);
    out.center = 0.5 * (box.lo + box.hi);
    out.radius = 0;
    for (Eigen::Index v = 0; v < mesh.vertices.rows(); ++v)
        out.radius = std::max(out.radius, (Eigen::Vector3d(mesh.vertices.row(v)) - out.center).norm());
    if (!(out.radius > 0)) throw Error("mesh", "all vertices coincide");
    const SurfaceSampler surface(mesh);
    if (surface.empty()) throw Error("mesh", "every face has zero area: there is no surface to sample");

    const auto uniform = std::size_t(std::llround(double(count) * options.uniform_fraction));
    const std::size_t near = count - uniform, kinds = options.near_sigma.size();
    out.points.resize(Eigen::Index(count), 3);
    SampleRandom rng(options.seed);
    Eigen::Index row = 0;
    for (std::size_t k = 0; k < kinds; ++k) {
        const std::size_t n = near / kinds + (k < near % kinds ? 1 : 0);
        const double sigma = options.near_sigma[k] * out.radius;
        for (std::size_t i = 0; i < n; ++i) out.points.row(row++) = surface.point(rng) + sigma * rng.normal3();
    }
    for (std::size_t i = 0; i < uniform; ++i) {
        const Eigen::Vector3d u(rng.uniform(), rng.uniform(), rng.uniform());
        out.points.row(row++) = out.center + out.radius * (2 * u - Eigen::Vector3d::Ones());
    }
    MeshSdfResult r = mesh_sdf(mesh, out.points, options, progress);
    out.phi = std::move(r.phi);
    out.triangles = r.triangles;
    out.degenerate = r.degenerate;
    out.device = std::move(r.device);
    if (options.normalize) {
        out.points = ((out.points.rowwise() - out.center.transpose()) / out.radius).eval();
        for (double& d : out.phi) d /= out.radius;
    }
    return out;
}

}  // namespace gsd
