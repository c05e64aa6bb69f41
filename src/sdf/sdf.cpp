// Signed distance to a mesh as it comes (gsd/sdf.hpp): the sum tree's exact nearest-triangle
// search for the distance; the sign from pseudonormals, the tree's fast winding numbers or the
// grid SHM, chosen by diagnosing the mesh; training samples.
#include <gsd/sdf.hpp>
#include <gsd/shm.hpp>
#include <gsd/sums.hpp>

#include "core/grid_sampling.hpp"
#include "gpu/on_device.hpp"
#include "sdf/sdf_gpu.hpp"
#include "sdf/pseudonormals.hpp"
#include "sdf/triangles.hpp"
#include "spatial/morton.hpp"
#include "sums/sum_tree.hpp"
#include "sums/winding.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <mutex>
#include <random>

namespace gsd {

namespace {

void check(const MeshSdfOptions& o, PointsView queries) {
    if (!(o.inside_threshold > 0 && o.inside_threshold < 1))
        throw Error("MeshSdfOptions::inside_threshold", "must be between 0 and 1 (winding numbers are ≈ 1 inside, 0 outside)");
    if (o.shm_grid < 8 || o.shm_grid > 512) throw Error("MeshSdfOptions::shm_grid", "must be between 8 and 512");
    for (Eigen::Index i = 0; i < queries.rows(); ++i)
        if (!queries.row(i).allFinite()) throw Error("queries", "query " + std::to_string(i) + " is not finite");
}

// Exact distances. The queries are taken in Morton order, each thread over a contiguous run of
// it, in packets of consecutive ones that walk the tree together (neighbours visit nearly the
// same nodes), each packet's search started from the previous one's nearest triangle, whose
// distance prunes it; in blocks, for progress. In input order, 10⁶ random queries around a
// 9·10⁴-face mesh took 3.5× as long (docs/sdf.md). Runs of 16 packets are handed out as threads
// free up: far queries cost many times what near ones do, and Morton order keeps them together
// (a static split of each block took 2.17–2.29 s for those 10⁶ queries, this 1.93–1.98 s in
// packets of 4; packets of 16, SumTree::kNearestLanes, 1.52 s).
std::vector<double> distances(const sums::SumTree& tree, PointsView q, std::vector<std::uint32_t>* nearest_of,
                              const ProgressFn& progress) {
    constexpr int L = sums::SumTree::kNearestLanes;
    const std::size_t n = std::size_t(q.rows());
    std::vector<double> d(n);
    if (nearest_of) nearest_of->resize(n);
    const std::vector<std::uint32_t> order = spatial::morton_order(q);
    constexpr std::size_t kBlock = std::size_t(1) << 16;  // a multiple of L
    for (std::size_t first = 0; first < n; first += kBlock) {
        const std::size_t last = std::min(n, first + kBlock);
        const std::size_t packets = (last - first + L - 1) / L;
#pragma omp parallel
        {
            std::uint32_t nearest = std::uint32_t(tree.size());  // none yet
            double p[3 * L], r[L];
            std::uint32_t each[L];
#pragma omp for schedule(dynamic, 16)
            for (std::size_t k = 0; k < packets; ++k) {
                const std::size_t i0 = first + k * L;
                const int m = int(std::min<std::size_t>(L, last - i0));
                for (int l = 0; l < m; ++l)
                    for (int a = 0; a < 3; ++a) p[3 * l + a] = q(Eigen::Index(order[i0 + std::size_t(l)]), a);
                tree.nearest_triangles(p, m, &nearest, r, nearest_of ? each : nullptr);
                for (int l = 0; l < m; ++l) d[order[i0 + std::size_t(l)]] = r[l];
                if (nearest_of)
                    for (int l = 0; l < m; ++l) (*nearest_of)[order[i0 + std::size_t(l)]] = tree.order()[each[l]];
            }
        }
        if (progress) progress("distance", double(last) / double(n));
    }
    return d;
}

// The distances on the chosen device — the nearest triangle found there in float32, its exact
// distance here — or on the CPU. `device` names where they ran.
std::vector<double> distances_on(const sums::SumTree& tree, PointsView q, const MeshSdfOptions& o,
                                 std::vector<std::uint32_t>* nearest_of, std::string& device, const ProgressFn& progress) {
    std::vector<std::uint32_t> found;
    const gpu::DeviceRun run = gpu::on_device(
        o.device,
        [&](const auto& ctx, std::string& why_not) {
            return sdf::gpu_nearest(ctx, tree, q, o.chunk_size, found, progress, why_not);
        },
        "; the distance runs on the CPU");
    if (!run) {
        device = "cpu";
        return distances(tree, q, nearest_of, progress);
    }
    device = run.device;
    const std::size_t n = std::size_t(q.rows());
    std::vector<double> d(n);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(n); ++i)
        d[std::size_t(i)] = tree.element_distance(q.row(i).transpose(), found[std::size_t(i)]);
    if (nearest_of) {
        nearest_of->resize(n);
        for (std::size_t i = 0; i < n; ++i) (*nearest_of)[i] = tree.order()[found[i]];
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

// ∇φ at each query: the unit vector from its nearest point p, negated inside (0 at p itself).
std::vector<double> gradients(const sdf::Triangles& t, PointsView queries, const std::vector<std::uint32_t>& nearest,
                              const std::vector<std::uint8_t>& inside) {
    std::vector<double> g(3 * nearest.size(), 0.0);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(nearest.size()); ++i) {
        const auto& v = t.triangles[nearest[std::size_t(i)]];
        const Eigen::Vector3d x = queries.row(i).transpose();
        Eigen::Vector3d p;
        sdf::nearest_feature(x, t.vertices.row(v[0]).transpose(), t.vertices.row(v[1]).transpose(),
                             t.vertices.row(v[2]).transpose(), p);
        const Eigen::Vector3d d = x - p;
        const double n = d.norm();
        if (!(n > 0)) continue;
        const Eigen::Vector3d u = (inside[std::size_t(i)] ? -1.0 : 1.0) / n * d;
        for (int a = 0; a < 3; ++a) g[3 * std::size_t(i) + std::size_t(a)] = u[a];
    }
    return g;
}

std::string fmt_number(double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%g", v);
    return b;
}

// The triangles as oriented elements for the sum tree, in their order (so that the tree's
// order() indexes t.triangles).
OrientedElements elements_of(const sdf::Triangles& t) {
    OrientedElements e;
    const auto n = Eigen::Index(t.triangles.size());
    e.corners.resize(3 * n, 3);
    e.vectors.resize(n, 3);
    for (Eigen::Index f = 0; f < n; ++f) {
        const auto& v = t.triangles[std::size_t(f)];
        const Eigen::Vector3d a = t.vertices.row(v[0]), b = t.vertices.row(v[1]), c = t.vertices.row(v[2]);
        e.corners.row(3 * f) = a.transpose();
        e.corners.row(3 * f + 1) = b.transpose();
        e.corners.row(3 * f + 2) = c.transpose();
        e.vectors.row(f) = (0.5 * (b - a).cross(c - a)).transpose();
    }
    return e;
}

// The grid SHM of the mesh as given (SHM needs no repair) for the sign, on the mesh's cube + 10 %.
ShmResult shm_for_sign(const PolygonMesh& mesh, const GridSpec& grid, const MeshSdfOptions& o, const ProgressFn& progress) {
    ShmOptions so;
    so.device = o.device;
    so.chunk_size = o.chunk_size;
    // Step 1 sums the kernel exactly within 2 cells of the mesh, not 6, and interpolates
    // farther out: the sign needs φ's sign, not its value far from the surface. On the
    // broken-mesh bench (docs/sdf.md) every % signed right stayed within 0.01, and the solve
    // of a 9·10⁴-face mesh took 0.05 s less.
    so.interpolation_cells = 2;
    return SignedHeatGrid(shm_source(mesh), grid, so).solve(progress);
}

// Inside where SHM's φ, sampled trilinearly, is negative; queries outside the grid's box are
// outside. For the queries listed in `only` (all if null).
void shm_inside(const GridSpec& grid, const std::vector<float>& phi, PointsView queries, std::vector<std::uint8_t>& inside,
                const std::vector<std::uint32_t>* only = nullptr) {
    const auto n = std::ptrdiff_t(only ? only->size() : std::size_t(queries.rows()));
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t k = 0; k < n; ++k) {
        const auto i = only ? Eigen::Index((*only)[std::size_t(k)]) : Eigen::Index(k);
        const Eigen::Vector3d x = queries.row(i).transpose();
        const bool in_box = (x.array() >= grid.box.lo.array()).all() && (x.array() <= grid.box.hi.array()).all();
        inside[std::size_t(i)] = in_box && detail::trilinear(grid, phi, x, nullptr) < 0;
    }
}

// The queries in `box` (by index), those rows, and values for them put back in place (0 elsewhere).
std::vector<std::uint32_t> in_box(const Box& box, PointsView q) {
    std::vector<std::uint32_t> kept;
    for (Eigen::Index i = 0; i < q.rows(); ++i)
        if ((q.row(i).transpose().array() >= box.lo.array()).all() && (q.row(i).transpose().array() <= box.hi.array()).all())
            kept.push_back(std::uint32_t(i));
    return kept;
}
Points rows_of(PointsView q, const std::vector<std::uint32_t>& rows) {
    Points out(Eigen::Index(rows.size()), 3);
    for (std::size_t k = 0; k < rows.size(); ++k) out.row(Eigen::Index(k)) = q.row(Eigen::Index(rows[k]));
    return out;
}
std::vector<double> scattered(const std::vector<double>& values, const std::vector<std::uint32_t>& rows, std::size_t n) {
    std::vector<double> out(n, 0.0);
    for (std::size_t k = 0; k < rows.size(); ++k) out[rows[k]] = values[k];
    return out;
}

}  // namespace

namespace detail {

// What mesh_sdf builds before its queries, kept by MeshSdfField between evaluations: the checked
// (and, for the automatic sign, repaired) triangles and the resolved sign at once; the sum tree,
// the pseudonormals and SHM's grid when a query first needs them.
struct MeshSdfState {
    MeshSdfState(const PolygonMesh& m, const MeshSdfOptions& o) : mesh(m), options(o), t(sdf::check_triangles(m)) {
        sign = options.sign;
        diagnosis = t.report.summary();
        if (options.sign == SdfSign::automatic) {
            sign = t.report.clean() ? SdfSign::pseudonormal : SdfSign::winding;
            if (sign == SdfSign::winding) reoriented = sdf::repair_orientation(t);
            diagnosis += t.report.clean() ? ": clean, signed by pseudonormals"
                                          : ": signed by winding numbers, " + std::to_string(reoriented) +
                                                " triangles turned to their patch's orientation" +
                                                (t.report.duplicates ? ", duplicates dropped" : "");
        }
        box = bounding_box(t.vertices);
    }
    const sums::SumTree& sum_tree() const {
        std::call_once(tree_once, [this] { tree = std::make_unique<sums::SumTree>(elements_of(t)); });
        return *tree;
    }
    const sdf::Pseudonormals& pseudonormals() const {
        std::call_once(normals_once, [this] { normals = std::make_unique<sdf::Pseudonormals>(t); });
        return *normals;
    }
    // SHM's φ on shm_grid³ over the mesh's cube + 10 %, solved once.
    const ShmResult& shm(const ProgressFn& progress) const {
        std::call_once(shm_once, [&] {
            shm_grid = GridSpec::cube(options.shm_grid, padded_cube(bounding_box(mesh.vertices)));
            shm_result = shm_for_sign(mesh, shm_grid, options, progress);
        });
        return shm_result;
    }

    const PolygonMesh& mesh;
    const MeshSdfOptions options;
    sdf::Triangles t;
    SdfSign sign;
    std::size_t reoriented = 0;
    std::string diagnosis;
    Box box;  // of the triangles' vertices
    mutable GridSpec shm_grid;

private:
    mutable std::once_flag tree_once, normals_once, shm_once;
    mutable std::unique_ptr<sums::SumTree> tree;
    mutable std::unique_ptr<sdf::Pseudonormals> normals;
    mutable ShmResult shm_result;
};

}  // namespace detail

namespace {

// The queries' signed distances from a prepared mesh (`gradient` as MeshSdfOptions::gradient).
MeshSdfResult query(const detail::MeshSdfState& s, PointsView queries, bool gradient, const ProgressFn& progress) {
    const MeshSdfOptions& options = s.options;
    MeshSdfResult r;
    r.degenerate = s.t.report.degenerate;
    r.sign = s.sign;
    r.reoriented = s.reoriented;
    r.diagnosis = s.diagnosis;
    r.triangles = s.t.triangles.size();
    r.device = "cpu";
    if (queries.rows() == 0) return r;
    const sums::SumTree& tree = s.sum_tree();
    std::vector<std::uint32_t> nearest;
    r.phi = distances_on(tree, queries, options, r.sign == SdfSign::pseudonormal || gradient ? &nearest : nullptr, r.device,
                         progress);
    std::vector<std::uint8_t> inside(r.phi.size(), 0);
    switch (r.sign) {
        case SdfSign::automatic:  // resolved by the state
        case SdfSign::none: break;
        case SdfSign::pseudonormal: {
            const sdf::Pseudonormals& normals = s.pseudonormals();
#pragma omp parallel for schedule(static)
            for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(r.phi.size()); ++i)
                inside[std::size_t(i)] = normals.inside(queries.row(i).transpose(), nearest[std::size_t(i)]);
            break;
        }
        case SdfSign::winding: {
            WindingOptions w;
            w.device = options.device;
            w.chunk_size = options.chunk_size;
            // The automatic sign sums only the queries in the mesh's bounding box: what a surface
            // encloses lies in its box, so the rest are outside (w = 0 there). Uniform queries
            // in a cube about a flat part are mostly such.
            const bool automatic = options.sign == SdfSign::automatic;
            const std::vector<std::uint32_t> boxed = automatic ? in_box(s.box, queries) : std::vector<std::uint32_t>{};
            const bool subset = automatic && boxed.size() < std::size_t(queries.rows());
            const Points boxed_queries = subset ? rows_of(queries, boxed) : Points();
            WindingResult wr = sums::winding_numbers(tree, subset ? PointsView(boxed_queries) : queries, w, progress);
            if (subset) wr.w = scattered(wr.w, boxed, r.phi.size());
            for (std::size_t i = 0; i < r.phi.size(); ++i) inside[i] = wr.w[i] > options.inside_threshold;
            r.winding = std::move(wr.w);
            if (wr.device != "cpu") r.device = wr.device;
            if (automatic && s.t.report.boundary_edges > 0) {
                // Holes: where w is near ½ it says little (in front of a large hole, inside a
                // dome whose cap is gone); SHM, which completes the surface across holes, decides.
                std::vector<std::uint32_t> ambiguous;
                for (std::size_t i = 0; i < r.phi.size(); ++i)
                    if (std::abs(r.winding[i] - 0.5) < kSdfAmbiguousWinding) ambiguous.push_back(std::uint32_t(i));
                if (!ambiguous.empty()) {
                    const ShmResult& shm = s.shm(progress);
                    shm_inside(s.shm_grid, shm.phi, queries, inside, &ambiguous);
                }
                r.shm_decided = ambiguous.size();
                r.diagnosis += "; holes: SHM decided the " + std::to_string(ambiguous.size()) +
                               " queries whose winding number was within " + fmt_number(kSdfAmbiguousWinding) + " of 1/2";
            }
            break;
        }
        case SdfSign::shm: {
            const ShmResult& shm = s.shm(progress);
            shm_inside(s.shm_grid, shm.phi, queries, inside);
            if (shm.device != "cpu") r.device = shm.device;
            break;
        }
    }
    for (std::size_t i = 0; i < r.phi.size(); ++i)
        if (inside[i]) r.phi[i] = -r.phi[i];
    if (gradient) r.gradient = gradients(s.t, queries, nearest, inside);
    return r;
}

}  // namespace

MeshSdfResult mesh_sdf(const PolygonMesh& mesh, PointsView queries, const MeshSdfOptions& options,
                       const ProgressFn& progress) {
    validate(mesh, "mesh");
    check(options, queries);
    const detail::MeshSdfState state(mesh, options);
    return query(state, queries, options.gradient, progress);
}

SdfSign sdf_sign_from_name(const std::string& name) {
    if (name == "auto") return SdfSign::automatic;
    if (name == "winding") return SdfSign::winding;
    if (name == "pseudonormal") return SdfSign::pseudonormal;
    if (name == "shm") return SdfSign::shm;
    if (name == "none") return SdfSign::none;
    throw Error("sign", "must be auto, winding, pseudonormal, shm or none, not '" + name + "'");
}

const char* sdf_sign_name(SdfSign sign) {
    switch (sign) {
        case SdfSign::automatic: return "auto";
        case SdfSign::winding: return "winding";
        case SdfSign::pseudonormal: return "pseudonormal";
        case SdfSign::shm: return "shm";
        case SdfSign::none: return "none";
    }
    return "?";
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
    out.sign = r.sign;
    out.diagnosis = std::move(r.diagnosis);
    out.device = std::move(r.device);
    if (options.normalize) {
        out.points = ((out.points.rowwise() - out.center.transpose()) / out.radius).eval();
        for (double& d : out.phi) d /= out.radius;
    }
    return out;
}

std::vector<float> sample_rows(const SdfSamples& s) {
    const std::size_t n = s.phi.size();
    std::vector<float> rows(4 * n);
    for (std::size_t i = 0; i < n; ++i) {
        for (int c = 0; c < 3; ++c) rows[4 * i + std::size_t(c)] = float(s.points(Eigen::Index(i), c));
        rows[4 * i + 3] = float(s.phi[i]);
    }
    return rows;
}

MeshSdfField::MeshSdfField(PolygonMesh mesh, MeshSdfOptions options) {
    validate(mesh, "mesh");
    check(options, Points(0, 3));
    mesh_ = std::make_shared<const PolygonMesh>(std::move(mesh));
    state_ = std::make_shared<const detail::MeshSdfState>(*mesh_, options);
}

const PolygonMesh& MeshSdfField::mesh() const { return *mesh_; }

FieldValues MeshSdfField::evaluate(PointsView queries, bool with_gradient, const ProgressFn& progress) const {
    check(state_->options, queries);
    const MeshSdfResult r = query(*state_, queries, with_gradient, progress);
    FieldValues v;
    v.phi.assign(r.phi.begin(), r.phi.end());
    v.gradient.assign(r.gradient.begin(), r.gradient.end());
    v.device = r.device;
    return v;
}

FieldValues MeshSdfField::evaluate(const GridSpec& grid, bool with_gradient, const ProgressFn& progress) const {
    grid.validate();
    check_memory(80.0 * double(grid.node_count()), "grid", "a grid of " + std::to_string(grid.node_count()) + " nodes");
    return evaluate(grid.nodes(), with_gradient, progress);
}

}  // namespace gsd
