// The adaptive SHM: the octree (balance, the band, the node graph's volumes), step 3's least
// squares (exact for linear fields on any octree; the multigrid-preconditioned CG converging),
// the field it returns, accuracy against exact distances beside the uniform grid, the sign on
// broken meshes, redistancing, bad input, the device's step 1 against the CPU's, and the CLI
// (queries, the sparse .vdb, the contour).
#include <doctest/doctest.h>

#include <gsd/adaptive_shm.hpp>
#include <gsd/gpu.hpp>
#include <gsd/io.hpp>
#include <gsd/pat.hpp>
#include <gsd/shapes.hpp>
#include <gsd/shm.hpp>

#include "shm/octree.hpp"
#include "shm/octree_poisson.hpp"
#include "support.hpp"

#include <Eigen/Geometry>

#include <chrono>
#include <cmath>
#include <map>
#include <random>
#include <set>

#include <omp.h>

using namespace gsd;

namespace {

const Box kCube{{-1, -1, -1}, {1, 1, 1}};

// An octree over kCube whose cells are split where `distance` (from a cell's center) is below
// the cell's side, balanced.
template <class Distance>
shm::Octree refined_octree(int depth, Distance&& distance) {
    return shm::Octree(kCube, depth, [&](int level, std::span<const std::uint64_t> codes, std::vector<char>& split) {
        const double s = 2.0 / double(1 << level);
        for (std::size_t i = 0; i < codes.size(); ++i) {
            const auto c = shm::unmorton3(codes[i]);
            split[i] = distance(kCube.lo + s * Eigen::Vector3d(c[0] + 0.5, c[1] + 0.5, c[2] + 0.5)) < s;
        }
    });
}

// Refined toward one point (a deep corner of detail).
shm::Octree point_octree(int depth, const Eigen::Vector3d& target) {
    return refined_octree(depth, [&](const Eigen::Vector3d& x) { return (x - target).norm(); });
}

// Refined toward a sphere about the origin.
shm::Octree sphere_octree(int depth, double radius) {
    return refined_octree(depth, [&](const Eigen::Vector3d& x) { return std::abs(x.norm() - radius); });
}

struct Corrupted {
    std::unique_ptr<shapes::Shape> shape;
    ShmSource source;
};

Corrupted corrupted_cloud(const std::string& name, int kind, std::size_t n = 2048) {
    Corrupted c{shapes::by_name(name), {}};
    shapes::Corruption k;
    if (kind == 0) k.position_noise = 0.002;
    if (kind == 1) k.flip_fraction = 0.1;
    if (kind == 2) k.holes = 3;
    c.source = shm_source(shapes::corrupt(c.shape->sample(n, 7), k, 8));
    return c;
}

// Mean |φ − sdf| over the nodes of a 64³ grid on kCube: near the surface (|sdf| < 0.05) and all.
std::pair<double, double> errors(const shapes::Shape& shape, const std::vector<float>& phi) {
    const Points q = GridSpec::cube(64, kCube).nodes();
    double near = 0, all = 0;
    long n_near = 0;
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
        const double t = shape.sdf(q.row(i).transpose()), e = std::abs(phi[std::size_t(i)] - t);
        all += e;
        if (std::abs(t) < 0.05) {
            near += e;
            ++n_near;
        }
    }
    return {near / double(n_near), all / double(q.rows())};
}

}  // namespace

TEST_CASE("octree: 2:1 balance across faces, edges and corners; leaves tile the cube") {
    const shm::Octree tree = point_octree(7, Eigen::Vector3d(0.31, -0.52, 0.77));
    const int D = tree.depth();
    const auto leaves = tree.leaves(D);
    // The compact tree (parents' codes and a bit a cell) answers as a list of cells would.
    CHECK(tree.leaf_count(D) == leaves.size());
    std::size_t cells = 0;
    for (int l = 0; l <= D; ++l) {
        cells += tree.cell_count(l);
        for (std::size_t i = 0; i < tree.cell_count(l); ++i) {
            const std::uint64_t c = tree.cell_code(l, i);
            CHECK(tree.find(l, c) == std::ptrdiff_t(i));
            if (i > 0) CHECK(tree.cell_code(l, i - 1) < c);
            CHECK(tree.has_children(l, i) == (l < D && tree.find(l + 1, c << 3) >= 0));
        }
    }
    CHECK(cells == tree.cell_count());
    CHECK(tree.find(D, ~std::uint64_t(0) >> 4) < 0);
    const shm::Octree root({{-1, -1, -1}, {1, 1, 1}}, 3, [](int, std::span<const std::uint64_t>, std::vector<char>&) {});
    CHECK(root.cell_count() == 1);
    CHECK(root.leaf_count(3) == 1);
    CHECK(root.cell_count(2) == 0);
    CHECK(root.leaf_at(3, {5, 5, 5}) == std::pair<int, std::uint64_t>(0, 0));
    // Leaves tile the cube: their volumes add up to it.
    double volume = 0;
    for (const auto& [l, code] : leaves) volume += std::pow(tree.cell_size(l), 3);
    CHECK(volume == doctest::Approx(8.0).epsilon(1e-12));
    // Balance: the leaf at each lattice point just outside a leaf's corners, edges and faces is
    // at most one level coarser.
    std::size_t checked = 0;
    for (const auto& [l, code] : leaves) {
        const std::uint32_t s = 1u << (D - l);
        const auto c = shm::unmorton3(code);
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz) {
                    const std::int64_t p[3] = {std::int64_t(c[0] * s) + (dx < 0 ? -1 : dx > 0 ? s : 0),
                                               std::int64_t(c[1] * s) + (dy < 0 ? -1 : dy > 0 ? s : 0),
                                               std::int64_t(c[2] * s) + (dz < 0 ? -1 : dz > 0 ? s : 0)};
                    const std::int64_t top = std::int64_t(1) << D;
                    if (p[0] < 0 || p[1] < 0 || p[2] < 0 || p[0] >= top || p[1] >= top || p[2] >= top) continue;
                    const auto [ln, cn] = tree.leaf_at(D, {std::uint32_t(p[0]), std::uint32_t(p[1]), std::uint32_t(p[2])});
                    CHECK(ln >= l - 1);
                    ++checked;
                }
    }
    CHECK(checked > 1000);
    CHECK(tree.leaves(D).size() < std::size_t(1) << (3 * D));  // adaptive: far fewer than a full grid
}

TEST_CASE("octree node graph: each axis's segment volumes add up to the cube's volume") {
    const shm::Octree tree = point_octree(6, Eigen::Vector3d(-0.2, 0.4, 0.1));
    const shm::NodeGraph g = shm::build_node_graph(tree, tree.depth());
    for (int a = 0; a < 3; ++a) {
        double v = 0;
        for (std::size_t i = 0; i < g.size(); ++i) {  // V = weight·ℓ²
            const std::int32_t j = g.next(i, a);
            if (j < 0) continue;
            const double len = double(shm::unmorton3(g.keys[std::size_t(j)])[std::size_t(a)] - shm::unmorton3(g.keys[i])[std::size_t(a)]) *
                               tree.lattice_step();
            v += double(g.weight(i, a)) * len * len;
        }
        CHECK(v == doctest::Approx(8.0).epsilon(1e-6));
    }
    // Every segment joins two nodes along its axis, and hanging nodes exist (levels differ).
    std::map<std::uint32_t, int> lengths;
    for (std::size_t i = 0; i < g.size(); ++i)
        for (int a = 0; a < 3; ++a) {
            const std::int32_t j = g.next(i, a);
            if (j < 0) continue;
            const auto p = shm::unmorton3(g.keys[i]), q = shm::unmorton3(g.keys[std::size_t(j)]);
            for (int b = 0; b < 3; ++b)
                if (b != a) CHECK(p[std::size_t(b)] == q[std::size_t(b)]);
            CHECK(q[std::size_t(a)] > p[std::size_t(a)]);
            CHECK(g.prev(std::size_t(j), a) == std::int32_t(i));
            ++lengths[q[std::size_t(a)] - p[std::size_t(a)]];
        }
    CHECK(lengths.size() >= 4);
    // The weights' table: 0 first (no segment), then the few distinct ones (NodeGraph::weight_code).
    CHECK(g.weights.front() == 0.0f);
    CHECK(g.weights.size() <= std::size_t(7 * (tree.depth() + 6) + 1));
}

TEST_CASE("octree node graph: steps too long for 16 bits are kept aside, the same segments either way") {
    const shm::Octree tree = point_octree(6, Eigen::Vector3d(-0.2, 0.4, 0.1));
    const shm::NodeGraph g = shm::build_node_graph(tree, tree.depth());
    // Steps of more than 3 nodes count as far here: many of them (65534 in use: ~1.5 %).
    const shm::NodeGraph f = shm::build_node_graph(tree, tree.depth(), 3);
    REQUIRE(f.size() == g.size());
    CHECK(f.far_slots.size() > g.size() / 4);
    std::size_t segments = 0;
    for (std::size_t i = 0; i < g.size(); ++i)
        for (int a = 0; a < 3; ++a) {
            CHECK(f.next(i, a) == g.next(i, a));
            CHECK(f.prev(i, a) == g.prev(i, a));
            CHECK(f.weight(i, a) == g.weight(i, a));
            segments += g.next(i, a) >= 0;
        }
    CHECK(segments > 2 * g.size());
    CHECK_THROWS_AS(shm::build_node_graph(tree, tree.depth(), 0), gsd::Error);
    // The keys packed (as the solve holds them) and back: the same keys, the same size; no
    // lookups meanwhile. Small blocks, so that the blocks' seams are crossed.
    shm::NodeGraph p = g;
    REQUIRE(g.size() > 500);
    p.pack_keys(64);
    CHECK(p.keys_packed());
    CHECK(p.keys.empty());
    CHECK(p.size() == g.size());
    CHECK(p.packed_keys.size() < 3 * g.size());  // deltas of neighbours: a byte or two each
    CHECK(p.next(5, 0) == g.next(5, 0));
    CHECK_THROWS_AS(p.find(g.keys[7]), gsd::Error);
    p.unpack_keys();
    CHECK(!p.keys_packed());
    CHECK(p.keys == g.keys);
    CHECK(p.find(g.keys[7]) == 7);
    // find_near finds what find finds from any hint (before, at, after, past the end), and
    // leaves the hint where it found the key.
    for (std::size_t i = 0; i < g.size(); i += 37)
        for (const std::size_t start : {std::size_t(0), i / 2, i, i + 1, (i + g.size()) / 2, g.size() - 1, 10 * g.size()}) {
            std::size_t hint = start;
            CHECK(g.find_near(g.keys[i], hint) == std::ptrdiff_t(i));
            CHECK(hint == i);
            std::size_t miss = start;  // one past a key: a lattice point that is no node, or is one
            const std::uint64_t key = g.keys[i] + 1;
            CHECK(g.find_near(key, miss) == g.find(key));
        }
}

TEST_CASE("octree node graph: weights are ℓ·k/4 for whole k ≤ 13, the same on every build, on a box whose cells are not powers of two") {
    // h = 2.2/2^6 needs every bit of a float: summed as floats in the order the threads visit
    // the leaves, the weights would vary from build to build.
    const Box box{{-1.1, -1.1, -1.1}, {1.1, 1.1, 1.1}};
    const shm::Octree tree(box, 6, [&](int level, std::span<const std::uint64_t> codes, std::vector<char>& split) {
        const double s = 2.2 / double(1 << level);
        for (std::size_t i = 0; i < codes.size(); ++i) {
            const auto c = shm::unmorton3(codes[i]);
            split[i] = std::abs((box.lo + s * Eigen::Vector3d(c[0] + 0.5, c[1] + 0.5, c[2] + 0.5)).norm() - 0.7) < s;
        }
    });
    const shm::NodeGraph g = shm::build_node_graph(tree, tree.depth());
    std::set<int> ks;
    for (std::size_t i = 0; i < g.size(); ++i)
        for (int a = 0; a < 3; ++a) {
            const std::int32_t j = g.next(i, a);
            if (j < 0) continue;
            const double len = double(shm::unmorton3(g.keys[std::size_t(j)])[std::size_t(a)] - shm::unmorton3(g.keys[i])[std::size_t(a)]) *
                               tree.lattice_step();
            const double k = 4 * double(g.weight(i, a)) / len;
            CHECK(std::abs(k - std::round(k)) < 1e-6);
            CHECK(std::round(k) >= 1);
            CHECK(std::round(k) <= 13);
            ks.insert(int(std::round(k)));
        }
    CHECK(ks.size() >= 3);  // interior (4), box faces (2, 1), hanging nodes (> 4)
    for (int build = 0; build < 3; ++build) {
        const shm::NodeGraph again = shm::build_node_graph(tree, tree.depth());
        CHECK(again.weights == g.weights);
        CHECK(again.weight_code == g.weight_code);
    }
}

TEST_CASE("octree Poisson: a constant field gives the linear function on any octree; CG converges") {
    // Refined toward a sphere: more nodes than one factorization takes, so the multigrid runs.
    const shm::Octree tree = sphere_octree(7, 0.6);
    // φ = a·(x − x₀), and samples on its zero plane: both the fit of ∇φ to a and the penalty
    // vanish there, so it is the minimizer exactly (the float32 Y the only error).
    const Eigen::Vector3d a = Eigen::Vector3d(0.6, -0.7, 0.3).normalized(), x0(0.05, 0.1, -0.1);
    const Eigen::Vector3d t1 = a.unitOrthogonal(), t2 = a.cross(t1);
    std::vector<shm::ZeroSample> samples;
    for (int i = -10; i <= 10; ++i)
        for (int j = -10; j <= 10; ++j) {
            const Eigen::Vector3d y = x0 + 0.09 * i * t1 + 0.09 * j * t2;
            if (y.cwiseAbs().maxCoeff() < 1) samples.push_back({y, 0.01});
        }
    shm::OctreePoisson poisson(tree, samples, 1.0 / tree.lattice_step());
    const shm::NodeGraph& g = poisson.nodes();
    std::vector<float> Y(3 * g.size());
    for (std::size_t i = 0; i < g.size(); ++i)
        for (int k = 0; k < 3; ++k) Y[3 * i + std::size_t(k)] = float(a[k]);
    shm::OctreePoissonStats stats;
    const std::vector<double> phi = poisson.solve(poisson.divergence(Y), 1e-10, 200, stats);
    CHECK(stats.level_nodes.size() >= 2);        // a multigrid, not a direct solve
    CHECK(stats.residual_history.size() <= 30);  // the V-cycle preconditions well
    CHECK(stats.residual_history.back() <= 1e-10);
    double worst = 0;
    for (std::size_t i = 0; i < g.size(); ++i) {
        const Eigen::Vector3d x = tree.to_world(shm::unmorton3(g.keys[i]));
        worst = std::max(worst, std::abs(phi[i] - a.dot(x - x0)));
    }
    CHECK(worst < 1e-5);
}

TEST_CASE("octree Poisson: the zero-set fit as a correction on a coarser level") {
    const shm::Octree tree = sphere_octree(7, 0.6);
    const double h = tree.lattice_step(), mu = 1.0 / h;
    // Samples on the sphere of radius 0.6; Y radial about a center off the sphere's, so that
    // φ₀'s zero set (a sphere about that center) misses the samples and the fit has work to do.
    std::vector<shm::ZeroSample> samples;
    std::mt19937 rng(5);
    std::normal_distribution<double> n01;
    for (int i = 0; i < 2000; ++i) {
        const Eigen::Vector3d d(n01(rng), n01(rng), n01(rng));
        samples.push_back({0.6 * d.normalized(), 4 * M_PI * 0.36 / 2000});
    }
    const Eigen::Vector3d center(0.08, -0.05, 0.03);
    shm::OctreePoisson poisson(tree, samples, 0.0);  // φ₀: no penalty, the constant pinned
    const shm::NodeGraph& g = poisson.nodes();
    std::vector<float> Y(3 * g.size());
    for (std::size_t i = 0; i < g.size(); ++i) {
        const Eigen::Vector3d u = (tree.to_world(shm::unmorton3(g.keys[i])) - center).normalized();
        for (int k = 0; k < 3; ++k) Y[3 * i + std::size_t(k)] = float(u[k]);
    }
    const std::vector<double> b = poisson.divergence(Y);
    shm::OctreePoissonStats stats;
    std::vector<double> phi0 = poisson.solve(b, 1e-10, 200, stats);
    REQUIRE(poisson.coarsest_level() == tree.depth() - 2);  // levels 7, 6 (cycled), 5 (factored)
    CHECK(stats.residual_history.back() <= 1e-10);
    MESSAGE("φ₀ to 1e-10: " << stats.residual_history.size() << " CG iterations");
    // The preconditioner works (plain CG takes hundreds), and CG keeps the Laplacian's free
    // constant out of r and z: with it in, the residual climbed back from ~1e-7 and the solve
    // took 14 iterations here.
    CHECK(stats.residual_history.size() <= 8);
    // The same φ₀, to the bit, on one thread as on three: the smoother's order and the sums'
    // do not depend on the threads (the coarsest solve's does not either, with Debian's BLAS:
    // a threaded BLAS that splits its sums by thread would show here).
    {
        const int threads = omp_get_max_threads();
        std::vector<std::vector<double>> by_threads;
        for (const int t : {1, 3}) {
            omp_set_num_threads(t);
            shm::OctreePoissonStats s;
            by_threads.push_back(poisson.solve(b, 1e-10, 200, s));
        }
        omp_set_num_threads(threads);
        CHECK(by_threads[0] == by_threads[1]);
        CHECK(by_threads[0] == phi0);
    }
    // A solve that ends in an exception (here: its progress callback's) leaves the keys unpacked.
    CHECK_THROWS_AS(poisson.solve(b, 1e-10, 200, stats, [](std::string_view, double) { throw Error("stop"); }), Error);
    CHECK(!poisson.nodes().keys_packed());
    CHECK(poisson.nodes().find(poisson.nodes().keys[3]) == 3);
    const double shift = poisson.mean_on_samples(phi0);
    for (double& v : phi0) v -= shift;
    // The fit and the solve as one problem, at μ.
    shm::OctreePoisson joint(tree, samples, mu);
    shm::OctreePoissonStats joint_stats;
    const std::vector<double> phi_joint = joint.solve(b, 1e-10, 200, joint_stats);
    // J(φ) = ½φᵀAφ − bᵀφ with A the operator at μ: what both minimize. μ set twice: from the pin
    // (the coarsest analysed again) and then between two penalties (refactored numerically).
    CHECK_THROWS_AS(poisson.set_penalty(-1), Error);
    std::vector<double> unfit = phi0, no_history;
    CHECK_THROWS_AS(poisson.fit_on_level(unfit, tree.depth(), 1e-10, 200, no_history), Error);  // μ = 0
    poisson.set_penalty(3 * mu);
    poisson.set_penalty(mu);
    shm::OctreePoissonStats again;
    const std::vector<double> phi_again = poisson.solve(b, 1e-10, 200, again);
    double apart = 0;
    for (std::size_t i = 0; i < g.size(); ++i) apart = std::max(apart, std::abs(phi_again[i] - phi_joint[i]));
    CHECK(apart < 1e-6);  // the operator the same as the one built at μ
    const auto J = [&](const std::vector<double>& phi) {
        const std::vector<double> Aphi = poisson.apply(phi);
        double j = 0;
        for (std::size_t i = 0; i < phi.size(); ++i) j += 0.5 * phi[i] * Aphi[i] - b[i] * phi[i];
        return j;
    };
    // On the finest level the correction makes the joint minimizer: φ₀ solves the Poisson part,
    // so the cross term vanishes (up to φ₀'s pin, 1e-9 of the diagonal, and the solves' tolerance).
    std::vector<double> phi_finest = phi0, history;
    poisson.fit_on_level(phi_finest, tree.depth(), 1e-10, 200, history);
    REQUIRE(!history.empty());
    CHECK(history.back() <= 1e-10);
    double worst = 0;
    for (std::size_t i = 0; i < g.size(); ++i) worst = std::max(worst, std::abs(phi_finest[i] - phi_joint[i]));
    CHECK(worst < 1e-5);
    CHECK(std::abs(J(phi_finest) - J(phi_joint)) <= 1e-9 * std::abs(J(phi_joint)));
    // On a coarser level (6: CG cycled from there; 5: the factored level, samples merged twice):
    // the best correction there, so between φ₀ and the joint minimizer, with most of the gain
    // (φ₀'s offset from the samples is smooth).
    const double j0 = J(phi0), jj = J(phi_joint);
    for (int level : {tree.depth() - 1, tree.depth() - 2}) {
        CAPTURE(level);
        std::vector<double> phi = phi0;
        history.clear();
        poisson.fit_on_level(phi, level, 1e-10, 200, history);
        REQUIRE(!history.empty());
        CHECK(history.back() <= 1e-10);
        if (level == tree.depth() - 1) CHECK(history.size() > 1);  // iterated, not factored
        const double jc = J(phi);
        MESSAGE("J: phi0 " << j0 << ", fit on level " << level << " " << jc << ", joint " << jj);
        CHECK(jc < j0 - 0.5 * (j0 - jj));
        CHECK(jc >= jj - 1e-9 * std::abs(jj));
    }
}

TEST_CASE("octree multigrid transfers: prolongation reproduces trilinear fields, restriction is its transpose") {
    const shm::Octree tree = sphere_octree(6, 0.5);
    // f = 1 + x + 2y − z + 0.5xy: trilinear, so every coarse cell's interpolation is exact.
    const auto f = [](const Eigen::Vector3d& x) { return 1 + x.x() + 2 * x.y() - x.z() + 0.5 * x.x() * x.y(); };
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int level = 6; level >= 4; --level) {
        const shm::NodeGraph fine = shm::build_node_graph(tree, level), coarse = shm::build_node_graph(tree, level - 1);
        const shm::Prolongation P(tree, fine, coarse);
        REQUIRE(P.fine_size() == fine.size());
        std::vector<double> c(coarse.size()), x(fine.size(), 0.0);
        for (std::size_t i = 0; i < coarse.size(); ++i) c[i] = f(tree.to_world(shm::unmorton3(coarse.keys[i])));
        P.add_to(fine, c, x);
        double worst = 0;
        for (std::size_t i = 0; i < fine.size(); ++i) worst = std::max(worst, std::abs(x[i] - f(tree.to_world(shm::unmorton3(fine.keys[i])))));
        CHECK(worst < 1e-12);
        // ⟨P c, r⟩ = ⟨c, Pᵀ r⟩ for random c and r.
        std::vector<double> r(fine.size()), Ptr(coarse.size()), Pc(fine.size(), 0.0);
        for (double& v : r) v = u(rng);
        for (double& v : c) v = u(rng);
        P.add_to(fine, c, Pc);
        P.restrict_to(fine, r, Ptr);
        double lhs = 0, rhs = 0;
        for (std::size_t i = 0; i < fine.size(); ++i) lhs += Pc[i] * r[i];
        for (std::size_t i = 0; i < coarse.size(); ++i) rhs += c[i] * Ptr[i];
        CHECK(lhs == doctest::Approx(rhs).epsilon(1e-12));
    }
    // Samples merged per cell keep their total area and their area-weighted centroid.
    std::vector<shm::ZeroSample> samples;
    for (int i = 0; i < 2000; ++i) samples.push_back({Eigen::Vector3d(u(rng), u(rng), u(rng)) * 0.9, 0.5 + 0.5 * u(rng)});
    const std::vector<shm::ZeroSample> merged = shm::merge_by_cell(tree, samples, 2);
    CHECK(merged.size() <= 64);
    Eigen::Vector3d m0 = Eigen::Vector3d::Zero(), m1 = Eigen::Vector3d::Zero();
    double a0 = 0, a1 = 0;
    for (const auto& s : samples) m0 += s.area * s.position, a0 += s.area;
    for (const auto& s : merged) m1 += s.area * s.position, a1 += s.area;
    CHECK(a1 == doctest::Approx(a0));
    CHECK((m1 - m0).norm() < 1e-9 * a0);
}

TEST_CASE("OctreeField: node values at nodes, the distance outside the cube, gradients by finite differences") {
    const Corrupted c = corrupted_cloud("capsule", -1, 1024);
    AdaptiveShmOptions o;
    o.depth = test::sized(6, 5);
    o.bounds = kCube;
    o.device = Device::cpu();
    const AdaptiveShmResult r = SignedHeatOctree(c.source, o).solve();
    const OctreeField& f = r.field;
    CHECK(f.node_count() == r.nodes);
    const Points nodes = f.node_positions();
    const FieldValues at_nodes = f.evaluate(nodes);
    for (Eigen::Index i = 0; i < nodes.rows(); i += 97) CHECK(at_nodes.phi[std::size_t(i)] == doctest::Approx(f.node_values()[std::size_t(i)]).epsilon(1e-6));
    // Outside: φ at the cube's nearest point plus the distance.
    Points out(2, 3), in(2, 3);
    out << 1.5, 0.2, 0.1, -1.0, -3.0, 0.4;
    in << 1.0, 0.2, 0.1, -1.0, -1.0, 0.4;
    const FieldValues vo = f.evaluate(out), vi = f.evaluate(in);
    CHECK(vo.phi[0] == doctest::Approx(vi.phi[0] + 0.5).epsilon(1e-6));
    CHECK(vo.phi[1] == doctest::Approx(vi.phi[1] + 2.0).epsilon(1e-6));
    // Gradients against differences. φ is piecewise trilinear and continuous, so a difference
    // across an octant's face averages two slopes: such queries (forward and backward
    // differences disagree) are skipped, and most queries are not among them.
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-0.8, 0.8);
    Points q(40, 3);
    for (Eigen::Index i = 0; i < q.rows(); ++i) q.row(i) << u(rng), u(rng), u(rng);
    const FieldValues g = f.evaluate(q, true);
    const double e = 1e-4;
    int compared = 0;
    for (Eigen::Index i = 0; i < q.rows(); ++i)
        for (int a = 0; a < 3; ++a) {
            Points p = q.row(i), m = q.row(i);
            p(0, a) += e;
            m(0, a) -= e;
            const double here = f.evaluate(q.row(i)).phi[0], ahead = f.evaluate(p).phi[0], behind = f.evaluate(m).phi[0];
            const double forward = (ahead - here) / e, backward = (here - behind) / e;
            if (std::abs(forward - backward) > 1e-2) continue;
            ++compared;
            CHECK(std::abs(g.gradient[3 * std::size_t(i) + std::size_t(a)] - 0.5 * (forward + backward)) < 5e-3);
        }
    CHECK(compared >= 100);
}

TEST_CASE("adaptive SHM: near the surface as good as the uniform 64³ grid with a fraction of its nodes; redistanced, the whole box better" *
          doctest::test_suite("slow")) {
    for (const std::string name : {"torus", "rounded-box"})
        for (int kind : {0, 1, 2}) {
            CAPTURE(name);
            CAPTURE(kind);
            const Corrupted c = corrupted_cloud(name, kind);
            ShmOptions uo;
            uo.device = Device::cpu();
            const ShmResult ur = SignedHeatGrid(c.source, GridSpec::cube(64, kCube), uo).solve();
            const auto [u_near, u_all] = errors(*c.shape, ur.phi);
            AdaptiveShmOptions o;
            o.depth = 7;
            o.bounds = kCube;
            o.device = Device::cpu();
            const AdaptiveShmResult r = SignedHeatOctree(c.source, o).solve();
            CHECK(r.residual_history.back() <= o.tolerance);
            REQUIRE(!r.fit_history.empty());
            CHECK(r.fit_history.back() <= o.tolerance);
            const auto [a_near, a_all] = errors(*c.shape, r.field.evaluate(GridSpec::cube(64, kCube).nodes()).phi);
            o.redistance = true;
            const AdaptiveShmResult rd = SignedHeatOctree(c.source, o).solve();
            const auto [d_near, d_all] = errors(*c.shape, rd.field.evaluate(GridSpec::cube(64, kCube).nodes()).phi);
            MESSAGE(name << " kind " << kind << ": uniform 64³ near " << u_near << " all " << u_all << "; depth 7 (" << r.nodes
                         << " nodes) near " << a_near << " all " << a_all << "; redistanced near " << d_near << " all " << d_all);
            CHECK(r.nodes < GridSpec::cube(128, kCube).node_count() / 4);
            CHECK(r.fit_level < o.depth);  // 2048 points: the fit is smoother than the finest cells
            CHECK(a_near < 0.92 * u_near);
            CHECK(d_near < 1.1 * u_near);
            CHECK(d_all < 0.75 * u_all);  // |φ| exact between the nodes too
        }
}

TEST_CASE("adaptive SHM redistanced: |φ| the exact distance to the zero set between nodes too, far out as near") {
    // A clean capsule: SHM's zero set is close to it, so the exact SDF stands for the distance to
    // that zero set; an interpolated distance would err by ~s²/(8d) in the coarse leaves far out.
    const auto shape = shapes::by_name("capsule");
    AdaptiveShmOptions o;
    o.depth = test::sized(7, 6);
    o.bounds = kCube;
    o.device = Device::cpu();
    o.redistance = true;
    const AdaptiveShmResult r = SignedHeatOctree(shm_source(shape->sample(4096, 3)), o).solve();
    CHECK(r.zero_set_triangles > 0);
    std::mt19937 rng(4);
    std::uniform_real_distribution<double> u(-1, 1);
    Points q(20000, 3);
    for (Eigen::Index i = 0; i < q.rows(); ++i) q.row(i) << u(rng), u(rng), u(rng);
    const std::vector<float> phi = r.field.evaluate(q).phi;
    double near = 0, far = 0;
    long n_near = 0, n_far = 0;
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
        const double t = shape->sdf(q.row(i).transpose()), e = std::abs(phi[std::size_t(i)] - t);
        if (std::abs(t) < 0.1) near += e, ++n_near;
        if (std::abs(t) > 0.5) far += e, ++n_far;
    }
    near /= double(n_near);
    far /= double(n_far);
    MESSAGE("mean |φ − sdf| near " << near << ", farther than 0.5 " << far);
    CHECK(far < 1.5 * near + 1e-4);
    // At the nodes the field holds the values the solve made.
    const Points nodes = r.field.node_positions();
    const FieldValues at_nodes = r.field.evaluate(nodes);
    for (Eigen::Index i = 0; i < nodes.rows(); i += 101)
        CHECK(at_nodes.phi[std::size_t(i)] == doctest::Approx(r.field.node_values()[std::size_t(i)]).epsilon(1e-5));
}

TEST_CASE("adaptive SHM: a cloud's outliers left out first (the CLI's default) keep their bubbles out of φ") {
    const auto shape = shapes::by_name("capsule");
    shapes::Corruption k;
    k.outlier_fraction = 0.02;
    const PointCloud cloud = shapes::corrupt(shape->sample(2048, 7), k, 8);
    std::size_t dropped = 0;
    const PointCloud kept = without_outliers(cloud, {}, &dropped);
    CHECK(dropped >= 20);  // of the 41 made, some land on the surface
    CHECK(dropped <= 60);
    std::size_t clean_dropped = 1;
    without_outliers(shape->sample(2048, 7), {}, &clean_dropped);
    CHECK(clean_dropped == 0);
    AdaptiveShmOptions o;
    o.depth = test::sized(6, 5);
    o.bounds = kCube;
    o.device = Device::cpu();
    const auto [with_near, with_all] = errors(*shape, SignedHeatOctree(shm_source(cloud), o).solve().field.evaluate(GridSpec::cube(64, kCube).nodes()).phi);
    const auto [without_near, without_all] = errors(*shape, SignedHeatOctree(shm_source(kept), o).solve().field.evaluate(GridSpec::cube(64, kCube).nodes()).phi);
    MESSAGE("outliers kept: near " << with_near << " all " << with_all << "; left out: near " << without_near << " all " << without_all);
    CHECK(without_near < 0.5 * with_near);
    CHECK(without_all < 0.5 * with_all);
}

TEST_CASE("adaptive SHM: broken meshes signed right away from the surface" * doctest::test_suite("slow")) {
    const auto shape = shapes::by_name("torus");
    const PolygonMesh broken = shapes::corrupt(shapes::mesh(*shape, 40), shapes::MeshCorruption{4, 0.2, 0.1, 0}, 5);
    AdaptiveShmOptions o;
    o.depth = 7;
    o.bounds = kCube;
    o.device = Device::cpu();
    const AdaptiveShmResult r = SignedHeatOctree(shm_source(broken), o).solve();
    const GridSpec g = GridSpec::cube(64, kCube);
    const Points q = g.nodes();
    const std::vector<float> phi = r.field.evaluate(q).phi;
    const double cell = 2.0 / 63;
    long inside = 0, inside_right = 0, outside = 0, outside_right = 0;
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
        const double t = shape->sdf(q.row(i).transpose());
        if (std::abs(t) < 2 * cell) continue;
        (t < 0 ? inside : outside)++;
        if (t < 0 && phi[std::size_t(i)] < 0) ++inside_right;
        if (t > 0 && phi[std::size_t(i)] > 0) ++outside_right;
    }
    MESSAGE("inside " << double(inside_right) / double(inside) << ", outside " << double(outside_right) / double(outside));
    CHECK(double(inside_right) >= 0.95 * double(inside));
    CHECK(double(outside_right) >= 0.99 * double(outside));
}

TEST_CASE("adaptive SHM: bad input ends quickly with a result or a clear error") {
    // One triangle with a vertex at 1e30: the cube is 1e30 wide; the octree stays small.
    PolygonMesh m;
    m.vertices.resize(3, 3);
    m.vertices << 0, 0, 0, 1, 0, 0, 0, 1, 1e30;
    m.add_face({0, 1, 2});
    AdaptiveShmOptions o;
    o.depth = 8;
    o.device = Device::cpu();
    const auto t0 = std::chrono::steady_clock::now();
    try {
        const AdaptiveShmResult r = SignedHeatOctree(shm_source(m), o).solve();
        CHECK(r.nodes > 0);
        for (float v : r.field.node_values()) CHECK(std::isfinite(v));
    } catch (const Error& e) {
        MESSAGE(std::string(e.what()));
    }
    CHECK(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < 20);
    // Bounds much smaller than the faces.
    PolygonMesh big;
    big.vertices.resize(3, 3);
    big.vertices << -1e3, -1e3, 0, 1e3, -1e3, 0, 0, 1e3, 0;
    big.add_face({0, 1, 2});
    o.bounds = Box{{-1e-3, -1e-3, -1e-3}, {1e-3, 1e-3, 1e-3}};
    o.depth = 6;
    const auto t1 = std::chrono::steady_clock::now();
    const AdaptiveShmResult r = SignedHeatOctree(shm_source(big), o).solve();
    Points above(1, 3), below(1, 3);
    above << 0, 0, 5e-4;
    below << 0, 0, -5e-4;
    CHECK(r.field.evaluate(above).phi[0] > 0);
    CHECK(r.field.evaluate(below).phi[0] < 0);
    CHECK(std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count() < 20);
    // Options out of range and an empty source.
    AdaptiveShmOptions bad;
    bad.depth = 21;
    CHECK_THROWS_AS(SignedHeatOctree(shm_source(big), bad), Error);
    bad.depth = 5;
    bad.band = std::nan("");
    CHECK_THROWS_AS(SignedHeatOctree(shm_source(big), bad), Error);
    CHECK_THROWS_AS(SignedHeatOctree(ShmSource{}, AdaptiveShmOptions{}), Error);
    // A budget the estimate exceeds: refused before anything is built (a sheet at 2^20 cells a side).
    PolygonMesh square;
    square.vertices.resize(4, 3);
    square.vertices << -0.5, -0.5, 0, 0.5, -0.5, 0, 0.5, 0.5, 0, -0.5, 0.5, 0;
    square.add_face({0, 1, 2, 3});
    AdaptiveShmOptions deep;
    deep.depth = 20;
    deep.device = Device::cpu();
    CHECK_THROWS_WITH_AS(SignedHeatOctree(shm_source(square), deep).solve(), doctest::Contains("memory budget"), Error);
}

TEST_CASE("adaptive SHM on a device: step 1 agrees with the CPU's") {
    const gpu::Selection sel = gpu::select("gpu");
    REQUIRE(sel.context);
    const Corrupted c = corrupted_cloud("torus", 1, 1024);
    AdaptiveShmOptions o;
    o.depth = test::sized(6, 5);
    o.bounds = kCube;
    o.device = Device::cpu();
    const AdaptiveShmResult cpu = SignedHeatOctree(c.source, o).solve();
    o.device = "gpu";
    const AdaptiveShmResult dev = SignedHeatOctree(c.source, o).solve();
    CHECK(dev.device != "cpu");
    REQUIRE(dev.nodes == cpu.nodes);
    double worst = 0;
    for (std::size_t i = 0; i < cpu.nodes; ++i)
        worst = std::max(worst, double(std::abs(dev.field.node_values()[i] - cpu.field.node_values()[i])));
    MESSAGE("device vs CPU: max |Δφ| " << worst);
    CHECK(worst <= 1e-4 * kCube.diagonal());
}

TEST_CASE("gsd shm adaptive: queries, the sparse .vdb and a closed contour") {
    const test::ScratchDir dir("shm_adaptive");
    REQUIRE(test::run_cli("sample torus -n 1500 -o " + dir.file("t.ply")).exit_code == 0);
    // Queries: the CLI's φ is the library's.
    Points q(5, 3);
    q << 0.5, 0, 0, 0.75, 0, 0, 0, 0, 0, 0.875, 0.875, 0.25, 0.25, 0.375, 0.0625;  // exact in float32
    std::vector<float> qf;
    for (Eigen::Index i = 0; i < q.rows(); ++i)
        for (int a = 0; a < 3; ++a) qf.push_back(float(q(i, a)));
    io::write_npy(dir.file("q.npy"), {5, 3}, qf);
    const std::string common = " --depth 6 --device cpu --bounds -1 -1 -1 1 1 1";
    const test::RunResult rq = test::run_cli("shm adaptive " + dir.file("t.ply") + common + " --queries " + dir.file("q.npy") +
                                             " -o " + dir.file("phi.npy"));
    REQUIRE_MESSAGE(rq.exit_code == 0, rq.output);
    const io::NpyArray phi = io::read_npy(dir.file("phi.npy"));
    AdaptiveShmOptions o;
    o.depth = 6;
    o.device = Device::cpu();
    o.bounds = kCube;
    const FieldValues lib = SignedHeatOctree(shm_source(io::read_point_cloud(dir.file("t.ply"))), o).solve().field.evaluate(q);
    REQUIRE(phi.data.size() == 5);
    for (int i = 0; i < 5; ++i) CHECK(phi.data[std::size_t(i)] == doctest::Approx(lib.phi[std::size_t(i)]).epsilon(1e-6));
    CHECK(phi.data[0] < -0.15);  // on the torus's core circle
    CHECK(phi.data[2] > 0.2);    // in its hole
    // A .vdb without --queries needs no --grid; with the contour, closed and facing outward.
    const test::RunResult rv = test::run_cli("shm adaptive " + dir.file("t.ply") + common + " -o " + dir.file("t.vdb") +
                                             " --contour " + dir.file("t.obj"));
    REQUIRE_MESSAGE(rv.exit_code == 0, rv.output);
    const PolygonMesh mesh = io::read_mesh(dir.file("t.obj"));
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> edges;
    double volume = 0;
    for_each_triangle(mesh, [&](std::size_t, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
        for (auto [u, v] : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}}) ++edges[{std::min(u, v), std::max(u, v)}];
        volume += mesh.vertices.row(a).dot(mesh.vertices.row(b).cross(mesh.vertices.row(c))) / 6;
    });
    for (const auto& [e, n] : edges) CHECK(n == 2);
    CHECK(volume == doctest::Approx(2 * M_PI * M_PI * 0.5 * 0.2 * 0.2).epsilon(0.1));
    // The .vdb: a level set whose voxels sit on the octree's finest lattice.
    const auto [grid, values] = io::read_vdb(dir.file("t.vdb"));
    const double step = grid.box.extent().x() / (grid.nx - 1);
    CHECK(step == doctest::Approx(2.0 / 64).epsilon(1e-9));
    // Bad uses: a .npy with nothing to sample, and queries into a .vdb.
    CHECK(test::run_cli("shm adaptive " + dir.file("t.ply") + common + " -o " + dir.file("x.npy")).exit_code == 2);
    CHECK(test::run_cli("shm adaptive " + dir.file("t.ply") + common + " --queries " + dir.file("q.npy") + " -o " + dir.file("x.vdb")).exit_code == 2);
    CHECK_FALSE(test::file_exists(dir.file("x.npy")));
}
