// Oriented elements and the fast generalized winding number (CPU in double, GPU in float32).
#include "gpu/on_device.hpp"
#include <gsd/spatial.hpp>
#include <gsd/sums.hpp>

#include "spatial/morton.hpp"
#include "sums/sum_tree.hpp"
#include "sums/sums_gpu.hpp"
#include "sums/winding.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <mutex>

namespace gsd {

OrientedElements OrientedElements::from_mesh(const PolygonMesh& mesh) {
    gsd::validate(mesh);
    std::vector<std::array<Eigen::Index, 3>> tri;
    for_each_triangle(mesh, [&](std::size_t, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
        tri.push_back({Eigen::Index(a), Eigen::Index(b), Eigen::Index(c)});
    });
    OrientedElements e;
    e.corners.resize(Eigen::Index(3 * tri.size()), 3);
    e.vectors.resize(Eigen::Index(tri.size()), 3);
    Eigen::Index n = 0;
    for (const auto& t : tri) {
        const Eigen::Vector3d a = mesh.vertices.row(t[0]).transpose(), b = mesh.vertices.row(t[1]).transpose(),
                              c = mesh.vertices.row(t[2]).transpose();
        const Eigen::Vector3d v = 0.5 * (b - a).cross(c - a);
        if (!(v.norm() > 0)) continue;  // no orientation, no area
        e.corners.row(3 * n) = a.transpose();
        e.corners.row(3 * n + 1) = b.transpose();
        e.corners.row(3 * n + 2) = c.transpose();
        e.vectors.row(n) = v.transpose();
        ++n;
    }
    if (n == 0) throw Error("mesh", "all faces are degenerate (zero area)");
    e.corners.conservativeResize(3 * n, 3);
    e.vectors.conservativeResize(n, 3);
    return e;
}

OrientedElements OrientedElements::from_cloud(const PointCloud& cloud) {
    if (cloud.size() < 2) throw Error("cloud", "an oriented cloud needs at least 2 points");
    return from_cloud(cloud, KdTree(cloud.points));
}

OrientedElements OrientedElements::from_cloud(const PointCloud& cloud, const KdTree& tree) {
    const std::vector<double> area = point_areas(tree);
    Points v(cloud.size(), 3);
    for (Eigen::Index i = 0; i < cloud.size(); ++i) v.row(i) = area[std::size_t(i)] * cloud.normals.row(i).normalized();
    return from_points(cloud.points, v);
}

OrientedElements OrientedElements::from_points(const Points& positions, const Points& vector_areas) {
    if (positions.rows() != vector_areas.rows())
        throw Error("vector_areas", "has " + std::to_string(vector_areas.rows()) + " rows for " + std::to_string(positions.rows()) + " points");
    OrientedElements e;
    e.corners.resize(3 * positions.rows(), 3);
    for (Eigen::Index i = 0; i < positions.rows(); ++i)
        for (int k = 0; k < 3; ++k) e.corners.row(3 * i + k) = positions.row(i);
    e.vectors = vector_areas;
    return e;
}

void OrientedElements::validate() const {
    if (vectors.rows() == 0) throw Error("elements", "no elements");
    if (corners.rows() != 3 * vectors.rows())
        throw Error("elements", "corners has " + std::to_string(corners.rows()) + " rows for " + std::to_string(vectors.rows()) +
                                    " elements (3 per element expected)");
    if (!corners.allFinite() || !vectors.allFinite()) throw Error("elements", "non-finite coordinates or vector areas");
    if (corners.cwiseAbs().maxCoeff() > kMaxCoordinate)
        throw Error("elements", "coordinates beyond ±1e30");
    if (vectors.rows() >= (Eigen::Index(1) << 31)) throw Error("elements", "more than 2^31 elements");
}



namespace {

void check_options(const WindingOptions& opt) {
    if (!(opt.beta > 1) || !std::isfinite(opt.beta)) throw Error("WindingOptions::beta", "the opening criterion β must be > 1");
    if (!(opt.tolerance >= 0) || !std::isfinite(opt.tolerance)) throw Error("WindingOptions::tolerance", "the error tolerance must be ≥ 0");
}

}  // namespace

namespace sums {

// The sums over a tree already built: the GPU if the device choice gives one, else the CPU.
WindingResult winding_on_tree(const sums::SumTree& tree, PointsView queries, const WindingOptions& opt,
                              const ProgressFn& progress) {
    if (queries.rows() >= (Eigen::Index(1) << 32)) throw Error("queries", "more than 2^32 queries");
    // One parallel pass for both checks (10⁷ queries: two serial passes took longer than the
    // GPU's sums). NaN fails `<=` and so counts as beyond.
    double largest = 0;
#pragma omp parallel for schedule(static) reduction(max : largest) if (queries.rows() > 65536)
    for (Eigen::Index i = 0; i < queries.rows(); ++i)
        for (int a = 0; a < 3; ++a) {
            const double v = std::abs(queries(i, a));
            largest = std::max(largest, v <= kMaxCoordinate ? v : INFINITY);
        }
    if (largest == INFINITY) {
        if (!queries.allFinite()) throw Error("queries", "non-finite query coordinates");
        // As every input's coordinates: past that their squares overflow, and the spatial
        // order's extent with them.
        throw Error("queries", "query coordinates beyond ±1e30");
    }
    WindingResult out;
    out.w.resize(std::size_t(queries.rows()));  // every entry is written below
    // Both paths take the queries along a Morton curve. It is made before the device is asked
    // for, so that on a first call it overlaps the context's making (gsd's CLI starts that in
    // a thread of its own: DevicePrefetch): 10⁶ queries' order is ~50 ms of one core, the
    // context ~100 ms of another on lavapipe.
    const std::vector<std::uint32_t> order = spatial::morton_order(queries);
    if (!opt.exact && largest > 1e15) {
        log_once("winding: queries beyond ±1e15 are outside float32's safe range; the sums run on the CPU");
    } else if (!opt.exact && gpu::on_device(opt.device, [&](const auto& ctx, std::string& why_not) {
                   return sums::gpu_winding(ctx, tree, queries, order, opt, out, progress, why_not);
               })) {
        return out;
    }
    out.device = "cpu";
    const auto n = std::size_t(queries.rows());
    // Packets of kLanes consecutive queries in that order walk the tree together, from the
    // frontier of their group of 4 packets (the nodes all 32 queries open are skipped: 12 %
    // faster on 10⁶ random queries, results bit-equal); blocks of groups so progress can be
    // reported; within a block, dynamic scheduling.
    constexpr std::size_t lanes = sums::SumTree::kLanes, group = 4 * lanes;
    const std::size_t block = 65536;
    std::size_t terms = 0;
    for (std::size_t first = 0; first < n; first += block) {
        const std::size_t last = std::min(n, first + block);
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : terms)
        for (std::size_t g = first; g < last; g += group) {
            const std::size_t g_end = std::min(last, g + group);
            // The group's frontier: the nodes every one of its queries would open are skipped.
            thread_local sums::SumTree::WindingFrontier frontier;
            if (!opt.exact) {
                double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
                for (std::size_t i = g; i < g_end; ++i)
                    for (int a = 0; a < 3; ++a) {
                        lo[a] = std::min(lo[a], queries(Eigen::Index(order[i]), a));
                        hi[a] = std::max(hi[a], queries(Eigen::Index(order[i]), a));
                    }
                tree.winding_frontier(lo, hi, opt.beta, opt.tolerance, frontier);
            }
            for (std::size_t p = g; p < g_end; p += lanes) {
                const int m = int(std::min(lanes, g_end - p));
                double x[lanes], y[lanes], z[lanes], w[lanes];
                for (int l = 0; l < m; ++l) {
                    const auto q = Eigen::Index(order[p + std::size_t(l)]);
                    x[l] = queries(q, 0);
                    y[l] = queries(q, 1);
                    z[l] = queries(q, 2);
                }
                if (opt.exact) {
                    for (int l = 0; l < m; ++l) w[l] = tree.winding_exact(Eigen::Vector3d(x[l], y[l], z[l]));
                    terms += std::size_t(m) * tree.size();
                } else {
                    tree.winding_from(frontier, x, y, z, m, opt.beta, opt.tolerance, w, terms);
                }
                for (int l = 0; l < m; ++l) out.w[order[p + std::size_t(l)]] = w[l];
            }
        }
        if (progress) progress("winding", double(last) / double(n));
    }
    out.terms = terms;
    return out;
}


WindingResult winding_numbers(const SumTree& tree, PointsView queries, const WindingOptions& opt, const ProgressFn& progress) {
    check_options(opt);
    return winding_on_tree(tree, queries, opt, progress);
}

}  // namespace sums

WindingResult fast_winding_numbers(const OrientedElements& elements, PointsView queries, const WindingOptions& opt,
                                   const ProgressFn& progress) {
    check_options(opt);
    const sums::SumTree tree(elements);
    return winding_on_tree(tree, queries, opt, progress);
}

// ---- WindingField -----------------------------------------------------------------------

struct WindingField::Impl {
    OrientedElements elements;
    WindingOptions options;
    mutable std::mutex mutex;  // concurrent evaluate() calls build the tree once
    mutable std::unique_ptr<sums::SumTree> tree;

    const sums::SumTree& built() const {
        std::lock_guard<std::mutex> lock(mutex);
        if (!tree) tree = std::make_unique<sums::SumTree>(elements);
        return *tree;
    }
};

WindingField::WindingField(OrientedElements elements, WindingOptions options) : impl_(std::make_unique<Impl>()) {
    elements.validate();
    check_options(options);
    impl_->elements = std::move(elements);
    impl_->options = std::move(options);
}

WindingField::~WindingField() = default;
WindingField::WindingField(WindingField&&) noexcept = default;
WindingField& WindingField::operator=(WindingField&&) noexcept = default;

WindingResult WindingField::winding_numbers(PointsView queries, const ProgressFn& progress) const {
    return winding_on_tree(impl_->built(), queries, impl_->options, progress);
}

void WindingField::prepare() const {
    // Only for a device. The tree's build (OpenMP) on this thread starts a second team of threads
    // beside the caller's: worth it where the pipeline's making is hidden as well, not on the
    // CPU path (a 10⁶-query run there was 20 % slower on 2 cores).
    if (impl_->options.exact) return;
    try {
        gpu::on_device(impl_->options.device, [&](const auto& ctx, std::string&) {
            sums::gpu_prepare_winding(ctx, impl_->built(), impl_->options);
            return true;
        });
    } catch (const std::exception&) {
        // The evaluation meets the same and says so.
    }
}

namespace {
FieldValues as_field_values(const WindingResult& r) {
    FieldValues v;
    v.phi.assign(r.w.begin(), r.w.end());
    v.device = r.device;
    return v;
}
}  // namespace

FieldValues WindingField::evaluate(PointsView queries, bool with_gradient, const ProgressFn& progress) const {
    refuse_gradient(with_gradient, "winding numbers");
    return as_field_values(winding_numbers(queries, progress));
}

FieldValues WindingField::evaluate(const GridSpec& grid, bool with_gradient, const ProgressFn& progress) const {
    refuse_gradient(with_gradient, "winding numbers");
    grid.validate();
    return as_field_values(winding_numbers(grid.nodes(), progress));
}

const OrientedElements& WindingField::elements() const { return impl_->elements; }
const WindingOptions& WindingField::options() const { return impl_->options; }

}  // namespace gsd
