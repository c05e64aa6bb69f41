// SignedHeatOctree and OctreeField (gsd/adaptive_shm.hpp): the SHM on a balanced octree.
#include <gsd/adaptive_shm.hpp>
#include <gsd/viz.hpp>

#include "core/clip.hpp"
#include "gpu/on_device.hpp"
#include "shm/diffuse.hpp"
#include "shm/octree.hpp"
#include "shm/octree_poisson.hpp"
#include "shm/redistance.hpp"
#include "shm/veto.hpp"
#include "sums/sum_tree.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#if defined(__GLIBC__)
#include <malloc.h>  // malloc_trim
#endif

namespace gsd {

namespace {

// The level of the zero-set fit's correction: the finest whose cells are at least `scale`
// source spacings wide (AdaptiveShmOptions::fit_scale), never finer than the finest level.
int fit_level(const shm::Octree& tree, double spacing, double scale) {
    if (!(scale > 0)) return tree.depth();
    const double levels = std::log2(tree.box().extent().maxCoeff() / (scale * spacing));
    if (!(levels > 0)) return 0;  // also a scale so large that scale·spacing overflows
    return levels >= tree.depth() ? tree.depth() : int(std::floor(levels));
}

// Hands the heap's freed pages back to the kernel between the stages (glibc: the CLI keeps up
// to 256 MB freed at each arena's top for reuse, and blocks below 64 MB come from the heap; the
// evaluator's tree and step 1's field, freed before the solve, would otherwise stay resident
// through it: 0.5–0.9 GB on a 2·10⁶-point scan).
void release_freed_memory() {
#if defined(__GLIBC__)
    malloc_trim(0);
#endif
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Bytes a node costs at the peak, with its share of the coarser levels and of the octree. The
/// peak is step 3's solve on large grids: on every level a node's segments as two 16-bit steps
/// each way, their weight codes and a byte for the prolongation, its key packed to about a
/// byte; CG's four double vectors and the V-cycle's float one (~60 bytes). On smaller ones it
/// is step 1 (the finest graph with its keys, the 12-byte field, the evaluator's tree over the
/// source) or the veto. Measured, peak resident memory over the estimate's nodes (what the
/// source holds included): 74 B on a 1.1·10⁵-point torus cloud at depth 9 and 75 B on a
/// 2·10⁶-point bunny scan at depth 10, less at depth 11 (docs/shm-adaptive.md); 80 is taken.
constexpr double kBytesPerNode = 80;

// φ on a leaf's lattice of halves, in GridSpec order: 3 points an axis (corners, midpoints,
// center) for a leaf larger than the finest, 2 (its corners) for a finest one. A node gives its
// own value; any other point the mean of the leaf corners around it, as the field interpolates
// (shm::interpolation_weights): the field is trilinear between these points. Returns n.
template <class Values>
int leaf_values(const shm::Octree& tree, const shm::NodeGraph& nodes, const Values& phi, int l, std::uint64_t code,
                std::array<float, 27>& out) {
    const std::uint32_t s = std::uint32_t(1) << (tree.depth() - l);
    const auto c = shm::unmorton3(code);
    const int n = s >= 2 ? 3 : 2;
    const std::uint32_t step = s >= 2 ? s / 2 : s;
    auto at = [&](std::uint32_t i, std::uint32_t j, std::uint32_t k) {
        const std::ptrdiff_t q = nodes.find(shm::morton3(c[0] * s + i * step, c[1] * s + j * step, c[2] * s + k * step));
        return q >= 0 ? double(phi[std::size_t(q)]) : NAN;
    };
    double corner[2][2][2];
    for (std::uint32_t o = 0; o < 8; ++o) {
        const std::uint32_t i = o >> 2 & 1, j = o >> 1 & 1, k = o & 1;
        const double v = at(i * (n - 1), j * (n - 1), k * (n - 1));
        corner[i][j][k] = std::isnan(v) ? 0.0 : v;
    }
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j)
            for (int k = 0; k < n; ++k) {
                double v = at(std::uint32_t(i), std::uint32_t(j), std::uint32_t(k));
                if (std::isnan(v)) {  // not a node: the mean of the corners it lies between
                    double sum = 0;
                    int count = 0;
                    for (int a = 0; a < 2; ++a)
                        for (int b = 0; b < 2; ++b)
                            for (int d = 0; d < 2; ++d)
                                if ((i == 1 || a * (n - 1) == i) && (j == 1 || b * (n - 1) == j) && (k == 1 || d * (n - 1) == k)) {
                                    sum += corner[a][b][d];
                                    ++count;
                                }
                    v = sum / count;
                }
                out[std::size_t((i * n + j) * n + k)] = float(v);
            }
    return n;
}

}  // namespace

// ---- OctreeField ---------------------------------------------------------------------------

struct OctreeField::Impl {
    shm::Octree tree;
    shm::NodeGraph nodes;  // the finest level's (keys alone are kept)
    std::vector<float> phi;
    // Redistanced: the zero set's pieces. |φ| anywhere is the exact distance to them (the nodes'
    // values are; between nodes, interpolating a distance would err by ~s²/(8d) in a leaf of side
    // s at distance d, 1 % of d in the coarse leaves far out), the sign the interpolation's.
    std::shared_ptr<const sums::SumTree> zero_set;

    // φ and its lattice gradient at a point inside the cube (lattice coordinates).
    double value(const Eigen::Vector3d& u, Eigen::Vector3d* gradient) const {
        std::int32_t node[27];
        double w[27], dw[27][3];
        const int n = shm::interpolation_weights(tree, nodes, u, node, w, gradient ? dw : nullptr);
        double v = 0;
        if (gradient) gradient->setZero();
        for (int c = 0; c < n; ++c) {
            const double f = node[c] >= 0 ? double(phi[std::size_t(node[c])]) : 0.0;
            v += w[c] * f;
            if (gradient)
                for (int a = 0; a < 3; ++a) (*gradient)[a] += dw[c][a] * f;
        }
        return v;
    }
};

OctreeField::OctreeField() = default;
OctreeField::~OctreeField() = default;
OctreeField::OctreeField(const OctreeField&) = default;
OctreeField& OctreeField::operator=(const OctreeField&) = default;
OctreeField::OctreeField(OctreeField&&) noexcept = default;
OctreeField& OctreeField::operator=(OctreeField&&) noexcept = default;
OctreeField::OctreeField(std::shared_ptr<const Impl> impl) : impl_(std::move(impl)) {}

namespace {
const OctreeField::Impl& need(const std::shared_ptr<const OctreeField::Impl>& impl) {
    if (!impl) throw Error("OctreeField", "an empty field (default-constructed or moved from)");
    return *impl;
}
}  // namespace

FieldValues OctreeField::evaluate(PointsView q, bool with_gradient, const ProgressFn&) const {
    const Impl& m = need(impl_);
    const auto n = std::ptrdiff_t(q.rows());
    for (std::ptrdiff_t i = 0; i < n; ++i)
        if (!q.row(i).allFinite()) throw Error("queries", "query " + std::to_string(i) + " is not finite");
    FieldValues out;
    out.phi.resize(std::size_t(n));
    if (with_gradient) out.gradient.resize(3 * std::size_t(n));
    out.device = "cpu";
    const Box& box = m.tree.box();
    const double step = m.tree.lattice_step();
#pragma omp parallel
    {
        std::uint32_t hint = std::uint32_t(-1);  // the last query's nearest piece of the zero set
#pragma omp for schedule(static)
        for (std::ptrdiff_t i = 0; i < n; ++i) {
            const Eigen::Vector3d x = q.row(i).transpose();
            const Eigen::Vector3d c = x.cwiseMax(box.lo).cwiseMin(box.hi);
            Eigen::Vector3d g;
            double v = m.value(m.tree.to_lattice(c), with_gradient ? &g : nullptr);
            const Eigen::Vector3d out_of_box = x - c;
            const double d = out_of_box.norm();
            v += d;
            if (m.zero_set && v != 0) v = std::copysign(m.zero_set->nearest_distance(x, INFINITY, &hint), v);
            out.phi[std::size_t(i)] = float(v);
            if (!with_gradient) continue;
            g /= step;
            if (d > 0) {
                for (int a = 0; a < 3; ++a)
                    if (out_of_box[a] != 0) g[a] = 0;
                g += out_of_box / d;
            }
            for (int a = 0; a < 3; ++a) out.gradient[3 * std::size_t(i) + std::size_t(a)] = float(g[a]);
        }
    }
    return out;
}

FieldValues OctreeField::evaluate(const GridSpec& grid, bool with_gradient, const ProgressFn& progress) const {
    grid.validate();
    return evaluate(grid.nodes(), with_gradient, progress);
}

const Box& OctreeField::box() const { return need(impl_).tree.box(); }
int OctreeField::depth() const { return need(impl_).tree.depth(); }
double OctreeField::finest_cell() const { return need(impl_).tree.lattice_step(); }
std::size_t OctreeField::leaf_count() const { return need(impl_).tree.leaf_count(depth()); }
std::size_t OctreeField::node_count() const { return need(impl_).nodes.size(); }
const std::vector<float>& OctreeField::node_values() const { return need(impl_).phi; }

Points OctreeField::node_positions() const {
    const Impl& m = need(impl_);
    Points p(Eigen::Index(m.nodes.size()), 3);
    for (std::size_t i = 0; i < m.nodes.size(); ++i) p.row(Eigen::Index(i)) = m.tree.to_world(shm::unmorton3(m.nodes.keys[i])).transpose();
    return p;
}

void OctreeField::narrow_band(double half_width, std::vector<std::array<std::int32_t, 3>>& ijk, std::vector<float>& phi) const {
    const Impl& m = need(impl_);
    if (!(half_width > 0) || !std::isfinite(half_width)) throw Error("half_width", "must be finite and > 0");
    const double limit = half_width * m.tree.lattice_step();
    const int D = m.tree.depth();
    // (key, level, value): a lattice point on the face between two leaves is emitted by both;
    // the finer leaf's value (a node's own, where it has one) is kept.
    struct Entry {
        std::uint64_t key;
        int level;
        float value;
    };
    std::vector<Entry> entries;
    m.tree.for_each_leaf(D, [&](int l, std::uint64_t code) {
        const std::uint32_t s = std::uint32_t(1) << (D - l);
        const auto c = shm::unmorton3(code);
        std::array<float, 27> v;
        const int n = leaf_values(m.tree, m.nodes, m.phi, l, code, v);
        const float lo = *std::min_element(v.begin(), v.begin() + n * n * n), hi = *std::max_element(v.begin(), v.begin() + n * n * n);
        // The field is trilinear between these points: it stays between their extremes.
        if (lo >= limit || hi <= -limit) return;
        for (std::uint32_t i = 0; i <= s; ++i)
            for (std::uint32_t j = 0; j <= s; ++j)
                for (std::uint32_t k = 0; k <= s; ++k) {
                    const std::array<std::uint32_t, 3> p{c[0] * s + i, c[1] * s + j, c[2] * s + k};
                    const double v = m.value(Eigen::Vector3d(double(p[0]), double(p[1]), double(p[2])), nullptr);
                    entries.push_back({shm::morton3(p[0], p[1], p[2]), l, float(v)});
                }
    });
    std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
        return a.key != b.key ? a.key < b.key : a.level > b.level;
    });
    ijk.clear();
    phi.clear();
    for (std::size_t e = 0; e < entries.size(); ++e) {
        if (e > 0 && entries[e].key == entries[e - 1].key) continue;
        if (!(std::abs(entries[e].value) < limit)) continue;
        const auto p = shm::unmorton3(entries[e].key);
        ijk.push_back({std::int32_t(p[0]), std::int32_t(p[1]), std::int32_t(p[2])});
        phi.push_back(entries[e].value);
    }
}

// ---- SignedHeatOctree ----------------------------------------------------------------------

struct SignedHeatOctree::Impl {
    ShmSource source;
    AdaptiveShmOptions opt;
    Box cube;

    shm::KernelParams kernel() const {
        return shm::kernel_params(source, opt.t_coef, opt.cutoff, opt.sum_tolerance);
    }

    double finest() const { return cube.extent().x() / double(std::uint64_t(1) << opt.depth); }

    // Finest cells the octree will have, from the cells of a coarser level the source occupies:
    // a cell of side c = 8h (three levels up) that the source passes through stands for the
    // finest cells of the shell the split rule makes around that much surface: the level
    // D − 1 cells within 2h·√3/2 + max(band·h, grading·2h) of it are split. Measured: 520–600
    // finest cells per occupied cell with the defaults (shells ±5.7h) on torus clouds at depths
    // 9–10 and a 2·10⁶-point bunny scan at depth 11; 640 is taken, scaled with the shell's
    // reach for other options. The count sorts the codes of the source's pieces (triangles split
    // to c, points as they are): it grows with the source's area, not with the box.
    double estimated_finest_cells() const {
        const int coarse = std::max(0, opt.depth - 3);
        const double c = cube.extent().x() / double(std::uint64_t(1) << coarse);
        const double top = double(std::uint64_t(1) << coarse) - 1;
        const double reach = std::sqrt(3.0) + std::max(opt.band, 2 * opt.grading);  // in finest cells
        const double per_cell = 640 * reach / (std::sqrt(3.0) + 4) * std::pow(8.0, opt.depth - coarse - 3);
        // The triangles' pieces at side c number about their area inside the cube over c²;
        // where that alone is past what any machine holds, it is the estimate (the count is not
        // made: it would take that long).
        const OrientedElements& e = source.elements;
        double pieces = 0;
        std::array<Eigen::Vector3d, 9> poly;
        for (Eigen::Index j = 0; j < e.vectors.rows(); ++j) {
            const Eigen::Vector3d a = e.corners.row(3 * j).transpose(), b = e.corners.row(3 * j + 1).transpose(),
                                  d = e.corners.row(3 * j + 2).transpose();
            if (a == b && a == d) {
                pieces += 1;
                continue;
            }
            const int n = detail::clip_triangle_to_box(a, b, d, cube.lo, cube.hi, poly);
            Eigen::Vector3d sum = Eigen::Vector3d::Zero();
            for (int i = 1; i + 1 < n; ++i) sum += (poly[std::size_t(i)] - poly[0]).cross(poly[std::size_t(i + 1)] - poly[0]);
            pieces += 0.5 * sum.norm() / (c * c) + 1;
        }
        if (pieces > 1e8) return std::min(1.5 * pieces * per_cell, std::pow(8.0, opt.depth));
        std::vector<std::uint64_t> codes;
        shm::for_each_sample(source, c, cube, [&](const Eigen::Vector3d& p, double) {
            const Eigen::Vector3d u = (p - cube.lo) / c;
            const auto cell = [&](int a) { return std::uint32_t(std::clamp(std::floor(u[a]), 0.0, top)); };
            codes.push_back(shm::morton3(cell(0), cell(1), cell(2)));
        });
        std::sort(codes.begin(), codes.end());
        const double occupied = double(std::unique(codes.begin(), codes.end()) - codes.begin());
        return std::min(occupied * per_cell, std::pow(8.0, opt.depth));
    }

    // Nodes: about 1.3 a finest cell (the coarser levels' cells and the corners at the band's
    // edge add 29–30 % on the inputs above).
    double estimated_bytes() const { return 1.3 * estimated_finest_cells() * kBytesPerNode; }

    shm::Octree build_octree(const sums::SumTree& tree) const {
        const double h = finest();
        return shm::Octree(cube, opt.depth, [&](int level, std::span<const std::uint64_t> codes, std::vector<char>& split) {
            const double s = cube.extent().x() / double(std::uint64_t(1) << level);
            const double reach = 0.5 * std::sqrt(3.0) * s + std::max(opt.band * h, opt.grading * s);
            const auto n = std::ptrdiff_t(codes.size());
#pragma omp parallel
            {
                std::uint32_t hint = std::uint32_t(-1);  // the last cell's nearest element
#pragma omp for schedule(dynamic, 256)
                for (std::ptrdiff_t i = 0; i < n; ++i) {
                    const auto c = shm::unmorton3(codes[std::size_t(i)]);
                    const Eigen::Vector3d center = cube.lo + s * Eigen::Vector3d(c[0] + 0.5, c[1] + 0.5, c[2] + 0.5);
                    split[std::size_t(i)] = tree.nearest_distance(center, reach, &hint) < reach;
                }
            }
        });
    }
};

namespace {

// The zero set of φ as a triangle soup: each leaf where φ changes sign, contoured on its own
// (gsd::contour on its lattice of halves, leaf_values). Pieces of neighbouring leaves need not
// meet exactly, which the distance to the soup does not mind.
PolygonMesh zero_set_soup(const shm::Octree& tree, const shm::NodeGraph& nodes, const std::vector<double>& phi) {
    const int D = tree.depth();
    const std::vector<std::pair<int, std::uint64_t>> leaves = tree.leaves(D);
    std::vector<PolygonMesh> pieces(leaves.size());
#pragma omp parallel for schedule(dynamic, 1024)
    for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(leaves.size()); ++i) {
        const auto [l, code] = leaves[std::size_t(i)];
        const std::uint32_t s = std::uint32_t(1) << (D - l);
        const auto c = shm::unmorton3(code);
        std::array<float, 27> values;
        const int n = leaf_values(tree, nodes, phi, l, code, values);
        const std::vector<float> v(values.begin(), values.begin() + n * n * n);
        const bool negative = std::any_of(v.begin(), v.end(), [](float x) { return x < 0; }),
                   positive = std::any_of(v.begin(), v.end(), [](float x) { return x >= 0; });
        if (!(negative && positive)) continue;
        const Eigen::Vector3d lo = tree.to_world({c[0] * s, c[1] * s, c[2] * s});
        const GridSpec cell{n, n, n, Box{lo, lo + Eigen::Vector3d::Constant(tree.cell_size(l))}};
        pieces[std::size_t(i)] = contour(cell, v, 0.0);
    }
    PolygonMesh soup;
    std::size_t vertices = 0;
    for (const PolygonMesh& p : pieces) vertices += std::size_t(p.vertices.rows());
    soup.vertices.resize(Eigen::Index(vertices), 3);
    Eigen::Index at = 0;
    for (const PolygonMesh& p : pieces) {
        if (p.face_count() == 0) continue;
        soup.vertices.middleRows(at, p.vertices.rows()) = p.vertices;
        for (std::size_t f = 0; f < p.face_count(); ++f) {
            std::uint32_t idx[8];
            const std::size_t n = std::min<std::size_t>(p.face_size(f), 8);
            for (std::size_t k = 0; k < n; ++k) idx[k] = std::uint32_t(at) + p.indices[p.offsets[f] + k];
            soup.add_face(idx, n);
        }
        at += p.vertices.rows();
    }
    return soup;
}

Box cube_of(const Box& b) {
    const double side = b.extent().maxCoeff();
    return {b.lo, b.lo + Eigen::Vector3d::Constant(side)};
}

}  // namespace

SignedHeatOctree::SignedHeatOctree(ShmSource source, AdaptiveShmOptions options) {
    if (source.size() == 0) throw Error("the signed heat method needs a non-empty source");
    const auto positive = [](double x) { return x > 0 && std::isfinite(x); };
    if (!positive(source.spacing)) throw Error("the source has no spacing (all samples coincide?)");
    if (options.depth < 1 || options.depth > shm::Octree::kMaxDepth)
        throw Error("AdaptiveShmOptions::depth", "must be in [1, " + std::to_string(shm::Octree::kMaxDepth) + "]");
    if (!(options.band >= 0) || !(options.band <= 1e3)) throw Error("AdaptiveShmOptions::band", "must be in [0, 1000] cells");
    if (!(options.grading >= 0) || !(options.grading <= 1e3)) throw Error("AdaptiveShmOptions::grading", "must be in [0, 1000]");
    if (!positive(options.t_coef)) throw Error("AdaptiveShmOptions::t_coef", "the diffusion time coefficient must be finite and > 0");
    if (!positive(options.cutoff)) throw Error("AdaptiveShmOptions::cutoff", "the kernel cutoff must be finite and > 0");
    if (!(options.sum_tolerance > 0) || !(options.sum_tolerance <= 1))
        throw Error("AdaptiveShmOptions::sum_tolerance", "the step 1 sum tolerance must be in (0, 1]");
    if (!positive(options.tolerance)) throw Error("AdaptiveShmOptions::tolerance", "must be finite and > 0");
    if (options.max_iterations < 1) throw Error("AdaptiveShmOptions::max_iterations", "must be ≥ 1");
    if (!(options.fit_zero_set >= 0) || !std::isfinite(options.fit_zero_set))
        throw Error("AdaptiveShmOptions::fit_zero_set", "the zero-set weight must be finite and ≥ 0");
    if (!(options.fit_scale >= 0) || !std::isfinite(options.fit_scale))
        throw Error("AdaptiveShmOptions::fit_scale", "the fit's scale must be finite and ≥ 0");
    if (!(options.veto_winding >= 0) || !(options.veto_winding < 1))
        throw Error("AdaptiveShmOptions::veto_winding", "the outside veto's winding number must be in [0, 1) (0: no veto)");
    if (!(options.veto_slope >= 0) || !std::isfinite(options.veto_slope))
        throw Error("AdaptiveShmOptions::veto_slope", "must be finite and ≥ 0");
    if (!positive(options.veto_margin)) throw Error("AdaptiveShmOptions::veto_margin", "must be finite and > 0");
    source.elements.validate();
    Box cube;
    if (options.bounds) {
        validate_box(*options.bounds, "AdaptiveShmOptions::bounds");
        cube = cube_of(*options.bounds);
    } else {
        cube = shm_default_bounds(source);
    }
    validate_box(cube, "AdaptiveShmOptions::bounds");
    impl_ = std::make_unique<Impl>(Impl{std::move(source), std::move(options), cube});
}

SignedHeatOctree::~SignedHeatOctree() = default;
SignedHeatOctree::SignedHeatOctree(SignedHeatOctree&&) noexcept = default;
SignedHeatOctree& SignedHeatOctree::operator=(SignedHeatOctree&&) noexcept = default;

Box SignedHeatOctree::cube() const { return impl_->cube; }
double SignedHeatOctree::estimated_bytes() const { return impl_->estimated_bytes(); }

AdaptiveShmResult SignedHeatOctree::solve(const ProgressFn& progress) const {
    const Impl& m = *impl_;
    AdaptiveShmResult out;
    out.estimated_bytes = m.estimated_bytes();
    check_memory(out.estimated_bytes, "AdaptiveShmOptions::depth",
                 "an adaptive grid of depth " + std::to_string(m.opt.depth) + " (about " +
                     std::to_string(std::llround(m.estimated_finest_cells())) + " finest cells)");

    auto t0 = std::chrono::steady_clock::now();
    if (progress) progress("octree", 0.0);
    // The split rule's nearest-element tree lives only while the octree is built (step 1's
    // evaluator builds its own).
    auto field = std::make_shared<OctreeField::Impl>(OctreeField::Impl{m.build_octree(sums::SumTree(m.source.elements)), {}, {}});
    const shm::Octree& tree = field->tree;
    out.cells = tree.cell_count();
    out.leaves = tree.leaf_count(tree.depth());
    for (int l = 0; l <= tree.depth(); ++l) out.leaves_per_level.push_back(tree.childless_count(l));
    // The estimate again, now from the leaves themselves (about a node each).
    check_memory(double(out.leaves) * 1.15 * kBytesPerNode, "AdaptiveShmOptions::depth",
                 "an adaptive grid of " + std::to_string(out.leaves) + " leaves");
    out.seconds_octree = seconds_since(t0);

    // The finest level's nodes first: step 1 runs at them, and its field (12 bytes a node) is
    // folded into the divergence (8) before the other levels and the operators exist, so the
    // two never hold memory together.
    t0 = std::chrono::steady_clock::now();
    if (progress) progress("nodes", 0.0);
    shm::NodeGraph finest = shm::build_node_graph(tree, tree.depth());
    out.nodes = finest.size();
    out.seconds_setup = seconds_since(t0);

    // Step 1–2 at every node, in chunks: a node's position is its key's, made when needed.
    t0 = std::chrono::steady_clock::now();
    const auto key_position = [&](const std::vector<std::uint64_t>& keys, std::size_t i) { return tree.to_world(shm::unmorton3(keys[i])); };
    std::unique_ptr<shm::DirectionEvaluator> eval;
    gpu::on_device(m.opt.device, [&](const auto& ctx, std::string& why_not) {
        eval = shm::make_gpu_evaluator(ctx, m.source, m.kernel(), m.opt.chunk_size, why_not);
        return eval != nullptr;
    });
    if (!eval) eval = shm::make_cpu_evaluator(m.source, m.kernel());
    out.device = eval->device();
    std::vector<float> Y(3 * finest.size());
    {
        constexpr std::size_t kChunk = std::size_t(1) << 20;
        const std::size_t n = finest.size();
        Points x;
        std::vector<float> y;
        std::vector<double> r_min;
        for (std::size_t first = 0; first < n; first += kChunk) {
            const std::size_t count = std::min(kChunk, n - first);
            x.resize(Eigen::Index(count), 3);
#pragma omp parallel for schedule(static)
            for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(count); ++i) x.row(i) = key_position(finest.keys, first + std::size_t(i)).transpose();
            const ProgressFn part = progress ? ProgressFn([&](std::string_view stage, double f) {
                progress(stage, (double(first) + f * double(count)) / double(n));
            })
                                             : ProgressFn();
            out.kernel_terms += eval->evaluate(x, y, r_min, part);
            std::copy(y.begin(), y.end(), Y.begin() + std::ptrdiff_t(3 * first));
        }
    }
    eval.reset();
    release_freed_memory();
    out.seconds_diffuse = seconds_since(t0);

    // Step 3's operators on every level.
    t0 = std::chrono::steady_clock::now();
    const double h = tree.lattice_step();
    // The zero-set fit's samples, one per finest cell: the source's pieces inside a cell merged
    // into their area-weighted centroid with their total area. The fit is soft and a cell wide
    // at its finest, so what it loses is how the pieces spread inside one cell; what it gains is
    // a penalty whose size is the surface's cells, not the source's pieces.
    std::vector<shm::ZeroSample> samples;
    shm::for_each_sample(m.source, h, tree.box(), [&](const Eigen::Vector3d& p, double area) { samples.push_back({p, area}); });
    samples = shm::merge_by_cell(tree, samples, tree.depth());
    // Step 3 is two solves, as on the uniform grid: φ₀ (no penalty: its constant pinned, the
    // coarsest factor as sparse as the Laplacian) shifted by its mean on the source, then the
    // fit's correction (fit_on_level).
    const double penalty = 0;
    if (progress) progress("operators", 0.0);
    auto solver = std::make_unique<shm::OctreePoisson>(tree, std::move(finest), std::move(samples), penalty);
    shm::OctreePoisson& poisson = *solver;
    std::vector<double> b = poisson.divergence(Y);
    std::vector<float>().swap(Y);
    release_freed_memory();
    out.seconds_setup += seconds_since(t0);

    // Step 3.
    t0 = std::chrono::steady_clock::now();
    shm::OctreePoissonStats stats;
    std::vector<double> phi = poisson.solve(std::move(b), m.opt.tolerance, m.opt.max_iterations, stats, progress);
    out.multigrid_nodes = stats.level_nodes;
    out.residual_history = stats.residual_history;
    const double shift = poisson.mean_on_samples(phi);
    for (double& v : phi) v -= shift;
    out.seconds_solve = seconds_since(t0);
    t0 = std::chrono::steady_clock::now();
    if (m.opt.fit_zero_set > 0) {
        poisson.set_penalty(m.opt.fit_zero_set / h);
        out.fit_level = poisson.fit_on_level(phi, fit_level(tree, m.source.spacing, m.opt.fit_scale), m.opt.tolerance,
                                             m.opt.max_iterations, out.fit_history,
                                             progress ? ProgressFn([&](std::string_view, double f) { progress("fit", f); }) : ProgressFn());
    }
    out.seconds_fit = seconds_since(t0);

    // The solver is done: its keys move to the field, and the rest is let go before the veto
    // builds its own tree over the source.
    field->nodes.level = poisson.nodes().level;
    field->nodes.keys = poisson.take_finest_keys();
    solver.reset();
    release_freed_memory();
    const shm::NodeGraph& nodes = field->nodes;
    const auto position = [&](std::size_t i) { return key_position(nodes.keys, i); };

    t0 = std::chrono::steady_clock::now();
    if (m.opt.veto_winding > 0)
        out.vetoed_nodes = shm::veto_outside(m.source, {m.opt.veto_winding, m.opt.veto_slope, m.opt.veto_margin}, phi, position);
    out.seconds_veto = seconds_since(t0);

    if (m.opt.redistance) {
        t0 = std::chrono::steady_clock::now();
        if (progress) progress("redistance", 0.0);
        field->zero_set = shm::zero_set_tree(zero_set_soup(tree, nodes, phi));
        if (field->zero_set) shm::redistance(*field->zero_set, phi, position);
        out.zero_set_triangles = field->zero_set ? field->zero_set->size() : 0;
        out.seconds_redistance = seconds_since(t0);
    }

    field->phi.assign(phi.begin(), phi.end());
    std::vector<double>().swap(phi);
    out.field = OctreeField(std::move(field));
    return out;
}

}  // namespace gsd
