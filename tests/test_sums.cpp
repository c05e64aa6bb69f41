// The fast summation engine (src/sums): moments, the winding-number treecode against the
// exact sum, and the screened kernel of SHM step 1 against an independent fine quadrature.
// The GPU kernels are held to these CPU results in test_gpu.cpp.
#include <doctest/doctest.h>

#include <gsd/baselines.hpp>
#include <gsd/pat.hpp>
#include <gsd/shapes.hpp>
#include <gsd/sums.hpp>

#include "sums/sum_tree.hpp"
#include "support.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <random>

using namespace gsd;
using Vec3 = Eigen::Vector3d;

namespace {

PolygonMesh broken(const char* shape, int resolution, std::uint64_t seed) {
    shapes::MeshCorruption d;
    d.holes = 3;
    d.hole_area = 0.2;
    d.flip_fraction = 0.1;
    return shapes::corrupt(shapes::mesh(*shapes::by_name(shape), resolution), d, seed);
}

Points random_queries(int n, double half, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(-half, half);
    Points q(n, 3);
    for (int i = 0; i < n; ++i)
        for (int a = 0; a < 3; ++a) q(i, a) = u(rng);
    return q;
}

// The screened sum by brute force: every triangle split into 4^levels pieces, each a point
// source at its centroid (independent of the tree, its moments and its acceptance rule).
Vec3 screened_by_quadrature(const OrientedElements& e, const Vec3& x, double lambda, int levels, double& r_min) {
    std::vector<std::pair<Vec3, Vec3>> pts;  // centroid, vector area
    for (std::size_t j = 0; j < e.size(); ++j) {
        std::vector<std::array<Vec3, 3>> tris{{e.corners.row(Eigen::Index(3 * j)).transpose(), e.corners.row(Eigen::Index(3 * j + 1)).transpose(),
                                               e.corners.row(Eigen::Index(3 * j + 2)).transpose()}};
        for (int l = 0; l < levels; ++l) {
            std::vector<std::array<Vec3, 3>> next;
            for (const auto& t : tris) {
                const Vec3 ab = (t[0] + t[1]) / 2, bc = (t[1] + t[2]) / 2, ca = (t[2] + t[0]) / 2;
                next.push_back({t[0], ab, ca});
                next.push_back({ab, t[1], bc});
                next.push_back({ca, bc, t[2]});
                next.push_back({ab, bc, ca});
            }
            tris.swap(next);
        }
        const Vec3 v = e.vectors.row(Eigen::Index(j)).transpose() / double(tris.size());
        for (const auto& t : tris) pts.push_back({(t[0] + t[1] + t[2]) / 3, v});
    }
    r_min = INFINITY;
    for (std::size_t j = 0; j < e.size(); ++j)
        r_min = std::min(r_min, std::sqrt(sums::point_triangle_distance2(
                                    x, e.corners.row(Eigen::Index(3 * j)).transpose(), e.corners.row(Eigen::Index(3 * j + 1)).transpose(),
                                    e.corners.row(Eigen::Index(3 * j + 2)).transpose())));
    Vec3 X = Vec3::Zero();
    for (const auto& [y, v] : pts) {
        const double r = (x - y).norm();
        X += v * std::exp(-lambda * (r - r_min)) / r;
    }
    return X;
}

}  // namespace

TEST_CASE("point–triangle distance matches dense sampling; the solid angle of a closed mesh is 4π inside") {
    std::mt19937_64 rng(3);
    std::normal_distribution<double> g(0, 1);
    for (int trial = 0; trial < 200; ++trial) {
        const Vec3 a(g(rng), g(rng), g(rng)), b(g(rng), g(rng), g(rng)), c(g(rng), g(rng), g(rng)), x(g(rng), g(rng), g(rng));
        double best = INFINITY;
        const int n = 200;
        for (int i = 0; i <= n; ++i)
            for (int j = 0; i + j <= n; ++j) best = std::min(best, (x - (a + (b - a) * i / n + (c - a) * j / n)).squaredNorm());
        const double d2 = sums::point_triangle_distance2(x, a, b, c);
        CHECK(d2 <= best + 1e-12);
        CHECK(std::sqrt(best) - std::sqrt(d2) < 0.02 * ((b - a).norm() + (c - a).norm()));
    }
    // Degenerate: a segment and a point.
    CHECK(sums::point_triangle_distance2(Vec3(0, 1, 0), Vec3(-1, 0, 0), Vec3(1, 0, 0), Vec3(0, 0, 0)) == doctest::Approx(1.0));
    CHECK(sums::point_triangle_distance2(Vec3(0, 0, 2), Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(0, 0, 0)) == doctest::Approx(4.0));
}

TEST_CASE("tree moments: a node's expansion equals the sum of its triangles' exact second moments") {
    const OrientedElements e = OrientedElements::from_mesh(broken("sphere", 16, 2));
    const sums::SumTree tree(e);
    const auto& root = tree.nodes()[0];
    // M0 is the total vector area; M2_a·tr is Σ v_a (|g − c|² + tr C) — recomputed here from
    // the triangles' corners by the formula for a uniform triangle, E|y − c|² = |g − c|² + Σ|p − g|²/12.
    Vec3 m0 = Vec3::Zero();
    Eigen::Matrix3d tr = Eigen::Matrix3d::Zero();
    const Vec3 c(root.c[0], root.c[1], root.c[2]);
    for (std::size_t j = 0; j < e.size(); ++j) {
        const Vec3 v = e.vectors.row(Eigen::Index(j)).transpose();
        Vec3 p[3];
        for (int k = 0; k < 3; ++k) p[k] = e.corners.row(Eigen::Index(3 * j + k)).transpose();
        const Vec3 g = (p[0] + p[1] + p[2]) / 3;
        double second = (g - c).squaredNorm();
        for (const Vec3& q : p) second += (q - g).squaredNorm() / 12;
        m0 += v;
        for (int a = 0; a < 3; ++a) tr(a, 0) += v[a] * second;
    }
    for (int a = 0; a < 3; ++a) {
        CHECK(root.m0[a] == doctest::Approx(m0[a]).epsilon(1e-10));
        CHECK(root.m2[6 * a] + root.m2[6 * a + 1] + root.m2[6 * a + 2] == doctest::Approx(tr(a, 0)).epsilon(1e-10));
    }
    // Every corner lies in the node's ball and box.
    for (const auto& n : tree.nodes())
        for (std::uint32_t j = n.begin; j < n.end; ++j)
            for (int k = 0; k < 3; ++k) {
                const double* p = tree.corners(j) + 3 * k;
                CHECK(std::hypot(p[0] - n.c[0], p[1] - n.c[1], p[2] - n.c[2]) <= n.rho * (1 + 1e-12));
            }
}

TEST_CASE("fast winding numbers: within 1e-3 of the exact sum beyond one edge length, on broken meshes and clouds" * doctest::test_suite("slow")) {
    for (const std::string shape : {"sphere", "torus", "capsule"}) {
        CAPTURE(shape);
        const PolygonMesh m = broken(shape.c_str(), 40, 7);
        const OrientedElements e = OrientedElements::from_mesh(m);
        const int n = test::sized(3000, 600);
        const Points q = random_queries(n, 1.0, 11);
        WindingOptions o;
        o.device = "cpu";
        const WindingResult fast = fast_winding_numbers(e, q, o);
        // The exact sum two ways: the engine's own and the tests' independent brute force.
        o.exact = true;
        const WindingResult exact = fast_winding_numbers(e, q, o);
        const std::vector<double> baseline = test::brute_force_winding(m, q);
        const double h = mean_edge_length(m);
        const sums::SumTree tree(e);
        double worst = 0;
        std::size_t far = 0;
        for (Eigen::Index i = 0; i < q.rows(); ++i) {
            CHECK(exact.w[std::size_t(i)] == doctest::Approx(baseline[std::size_t(i)]).epsilon(1e-9));
            if (tree.nearest_distance(q.row(i).transpose()) < h) continue;
            worst = std::max(worst, std::abs(fast.w[std::size_t(i)] - exact.w[std::size_t(i)]));
            ++far;
        }
        MESSAGE(shape << ": max |fast − exact| = " << worst << " over " << far << " queries; " << double(fast.terms) / n
                      << " terms per query (exact: " << e.size() << ")");
        CHECK(far > n / 3);
        CHECK(worst <= 1e-3);
        CHECK(fast.terms < exact.terms / 5);
    }
    // An oriented cloud: ≈ 1 inside a sphere, ≈ 0 outside.
    const PointCloud cloud = shapes::by_name("sphere")->sample(4000, 5);
    const OrientedElements e = OrientedElements::from_cloud(cloud);
    Points q(2, 3);
    q << 0, 0, 0, 0, 0, 2;
    const WindingResult r = fast_winding_numbers(e, q, {});
    CHECK(r.w[0] == doctest::Approx(1.0).epsilon(0.02));
    CHECK(std::abs(r.w[1]) < 0.01);
}

TEST_CASE("fast winding numbers: a query's result does not depend on the packet it walks the tree in") {
    const PolygonMesh m = broken("torus", 24, 3);
    const OrientedElements e = OrientedElements::from_mesh(m);
    const sums::SumTree tree(e);
    const Points q = random_queries(203, 1.0, 5);
    // Each query alone, then in packets of every size with different companions: bit-equal,
    // and within the tolerance of the exact sum (the packet walk is not a different method).
    std::vector<double> alone(std::size_t(q.rows()));
    std::size_t terms_alone = 0;
    for (Eigen::Index i = 0; i < q.rows(); ++i) alone[std::size_t(i)] = tree.winding(q.row(i).transpose(), 1.5, 5e-3, terms_alone);
    for (int size = 2; size <= sums::SumTree::kLanes; size += 3) {
        CAPTURE(size);
        std::size_t terms = 0;
        for (Eigen::Index first = 0; first < q.rows(); first += size) {
            const int n = int(std::min<Eigen::Index>(size, q.rows() - first));
            double x[sums::SumTree::kLanes], y[sums::SumTree::kLanes], z[sums::SumTree::kLanes], w[sums::SumTree::kLanes];
            for (int l = 0; l < n; ++l) {
                x[l] = q(first + l, 0);
                y[l] = q(first + l, 1);
                z[l] = q(first + l, 2);
            }
            tree.winding(x, y, z, n, 1.5, 5e-3, w, terms);
            for (int l = 0; l < n; ++l) REQUIRE(w[l] == alone[std::size_t(first + l)]);
        }
        CHECK(terms == terms_alone);
    }
    // From the frontier of a box around a group of queries (the nodes all of them would open
    // skipped), as the CPU path walks: bit-equal again.
    std::mt19937_64 rng(8);
    std::uniform_real_distribution<double> u(-1, 1);
    std::size_t skipped = 0;
    for (int group = 0; group < 40; ++group) {
        const double half = 0.02 + 0.1 * (group % 5);  // boxes from small to a fifth of the model
        const Vec3 center(u(rng), u(rng), u(rng));
        double x[sums::SumTree::kLanes], y[sums::SumTree::kLanes], z[sums::SumTree::kLanes], w[sums::SumTree::kLanes];
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (int l = 0; l < sums::SumTree::kLanes; ++l) {
            const Vec3 p = center + half * Vec3(u(rng), u(rng), u(rng));
            x[l] = p[0];
            y[l] = p[1];
            z[l] = p[2];
            for (int a = 0; a < 3; ++a) {
                lo[a] = std::min(lo[a], p[a]);
                hi[a] = std::max(hi[a], p[a]);
            }
        }
        sums::SumTree::WindingFrontier frontier;
        tree.winding_frontier(lo, hi, 1.5, 5e-3, frontier);
        skipped += frontier.nodes.size() > 1 || frontier.nodes[0] != 0;
        std::size_t terms = 0;
        tree.winding_from(frontier, x, y, z, sums::SumTree::kLanes, 1.5, 5e-3, w, terms);
        for (int l = 0; l < sums::SumTree::kLanes; ++l) {
            std::size_t t = 0;
            REQUIRE(w[l] == tree.winding(Vec3(x[l], y[l], z[l]), 1.5, 5e-3, t));
        }
    }
    CHECK(skipped > 20);  // the frontiers did skip nodes
    double worst = 0;
    for (Eigen::Index i = 0; i < q.rows(); ++i)
        if (tree.nearest_distance(q.row(i).transpose()) > mean_edge_length(m))
            worst = std::max(worst, std::abs(alone[std::size_t(i)] - tree.winding_exact(q.row(i).transpose())));
    CHECK(worst <= 1e-3);
    CHECK_THROWS_AS(tree.winding(nullptr, nullptr, nullptr, sums::SumTree::kLanes + 1, 1.5, 5e-3, nullptr, terms_alone), Error);
}

TEST_CASE("the packet walk's arithmetic: its atan2 and its square-root-free opening test") {
    // atan2_lanes against libm over every octant, magnitudes from 1e-300 to 1e300, the octant
    // and range-reduction boundaries, signed zeros.
    std::mt19937_64 rng(17);
    std::uniform_real_distribution<double> angle(-M_PI, M_PI), exponent(-300, 300);
    double worst = 0;
    for (int i = 0; i < 200000; ++i) {
        const double a = angle(rng), r = std::pow(10.0, exponent(rng));
        const double y = r * std::sin(a), x = r * std::cos(a);
        worst = std::max(worst, std::abs(sums::atan2_lanes(y, x) - std::atan2(y, x)));
    }
    for (const double t : {0.0, 0.41421356237309503, 0.41421356237309509, 1.0, 2.414213562373095, 1e-20, 1e20})
        for (const double sx : {1.0, -1.0})
            for (const double sy : {1.0, -1.0})
                if (t != 0 || sy > 0)
                    worst = std::max(worst, std::abs(sums::atan2_lanes(sy * t, sx) - std::atan2(sy * t, sx)));
    MESSAGE("max |atan2_lanes − std::atan2| = " << worst);
    CHECK(worst <= 4e-15);
    CHECK(sums::atan2_lanes(0.0, 0.0) == 0.0);
    CHECK(sums::atan2_lanes(0.0, -1.0) == doctest::Approx(M_PI).epsilon(1e-15));
    CHECK(sums::atan2_lanes(-0.0, -1.0) == doctest::Approx(-M_PI).epsilon(1e-15));

    // winding_reach2 decides as accept_winding does, away from the boundary itself.
    std::uniform_real_distribution<double> u(0, 1);
    int disagree = 0;
    for (int i = 0; i < 100000; ++i) {
        const double rho = std::pow(10.0, 4 * u(rng) - 2), area = rho * rho * std::pow(10.0, 3 * u(rng) - 2);
        const double beta = 1 + 2 * u(rng), tol = u(rng) < 0.2 ? 0.0 : std::pow(10.0, 3 * u(rng) - 4);
        const double d = rho * std::pow(10.0, 1.5 * u(rng)), d2 = d * d;
        const double q = std::pow(area * rho * rho * rho / M_PI, 0.2);
        const double reach2 = sums::winding_reach2(rho, q, beta, sums::winding_reach_scale(tol));
        if (std::abs(d2 - reach2) <= 1e-9 * reach2) continue;
        disagree += (d2 > reach2) != sums::accept_winding(rho, d2, area, beta, tol);
    }
    CHECK(disagree == 0);
}

TEST_CASE("fast winding numbers: a walk that opens every node is the exact sum (meshes and clouds)") {
    // β so large that no node with a radius is expanded: every element is summed by the
    // packet walk's own lane arithmetic, which must then match the reference sum to rounding.
    // (A cloud's leaves of one point have ρ = 0 and are still expanded, exactly: at this β in
    // double, SumTree::single_enough.)
    const PolygonMesh m = broken("capsule", 20, 2);
    const PointCloud c = shapes::by_name("torus")->sample(500, 3);
    for (const OrientedElements& e : {OrientedElements::from_mesh(m), OrientedElements::from_cloud(c)}) {
        const sums::SumTree tree(e);
        const Points q = random_queries(300, 1.2, 9);
        double worst = 0;
        std::size_t terms = 0;
        for (Eigen::Index i = 0; i < q.rows(); ++i) {
            const Vec3 x = q.row(i).transpose();
            worst = std::max(worst, std::abs(tree.winding(x, 1e12, 0, terms) - tree.winding_exact(x)));
        }
        MESSAGE("max |walk − exact| = " << worst);
        CHECK(worst <= 1e-12);
    }
}

TEST_CASE("fast winding numbers: bad input is refused") {
    OrientedElements e;
    Points q = Points::Zero(1, 3);
    CHECK_THROWS_AS(fast_winding_numbers(e, q), Error);
    e = OrientedElements::from_points(Points::Zero(2, 3), Points::Ones(2, 3));
    WindingOptions o;
    o.beta = 1;
    CHECK_THROWS_AS(fast_winding_numbers(e, q, o), Error);
    q(0, 0) = NAN;
    CHECK_THROWS_AS(fast_winding_numbers(e, q), Error);
    e.corners(0, 0) = INFINITY;
    CHECK_THROWS_AS(fast_winding_numbers(e, Points::Zero(1, 3)), Error);
    CHECK_THROWS_AS(OrientedElements::from_points(Points::Zero(2, 3), Points::Ones(3, 3)), Error);
}

TEST_CASE("nearest element: the tree search equals brute force, whatever bound and start element it is given") {
    const PolygonMesh m = broken("torus", 20, 6);
    const sums::SumTree tree(OrientedElements::from_mesh(m));
    const Points q = random_queries(300, 1.3, 12);
    std::mt19937_64 rng(13);
    std::uniform_int_distribution<std::uint32_t> any(0, std::uint32_t(tree.size()) + 5);  // a few past the end: no start
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
        const Vec3 x = q.row(i).transpose();
        auto dist2 = [&](std::uint32_t j) {
            const double* p = tree.corners(j);
            return sums::point_triangle_distance2(x, Vec3(p[0], p[1], p[2]), Vec3(p[3], p[4], p[5]), Vec3(p[6], p[7], p[8]));
        };
        double brute2 = INFINITY;
        for (std::uint32_t j = 0; j < tree.size(); ++j) brute2 = std::min(brute2, dist2(j));
        const double brute = std::sqrt(brute2);
        REQUIRE(tree.nearest_distance(x) == brute);
        // A loose bound, then the exact one (as from a neighbor), with a random start element:
        // the same distance, and the element reported attains it.
        const std::uint32_t start = any(rng);
        for (const double bound : {brute + 0.3, brute}) {
            std::uint32_t nearest = start;
            REQUIRE(tree.nearest_distance(x, bound, &nearest) == brute);
            REQUIRE(nearest < tree.size());
            CHECK(dist2(nearest) == brute2);
        }
    }
}

TEST_CASE("screened sums (SHM step 1): the treecode's direction matches a fine quadrature, coarse faces included" * doctest::test_suite("slow")) {
    // A coarse broken mesh (faces several times 1/λ near some queries) and queries from on the
    // surface out to the cutoff.
    const PolygonMesh m = broken("torus", 12, 3);
    const OrientedElements e = OrientedElements::from_mesh(m);
    const sums::SumTree tree(e);
    const double h = mean_edge_length(m);
    sums::SumTree::Screened k;
    k.lambda = 1 / h;
    k.cutoff = 40;  // everything counts: the quadrature drops nothing either
    k.r_floor = 1e-6 * h;
    const Points q = random_queries(test::sized(200, 40), 1.0, 5);
    double worst = 0, mean = 0;
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
        const Vec3 x = q.row(i).transpose();
        double r_fast, r_ref;
        std::size_t terms = 0;
        const Vec3 fast = tree.screened(x, k, r_fast, terms);
        const Vec3 ref = screened_by_quadrature(e, x, k.lambda, 5, r_ref);
        CHECK(r_fast == doctest::Approx(r_ref).epsilon(1e-9));
        if (r_ref < 0.5 * h) continue;  // the 4^5-piece quadrature itself is too coarse closer in
        const double angle = std::acos(std::clamp(fast.normalized().dot(ref.normalized()), -1.0, 1.0));
        worst = std::max(worst, angle);
        mean += angle / double(q.rows());
        CHECK((fast - ref).norm() <= 0.02 * ref.norm() + 1e-3 * 2 * M_PI / k.lambda);
    }
    MESSAGE("direction error vs 4^5-piece quadrature: max " << worst << " rad, mean " << mean << " rad");
    CHECK(worst < 0.02);
}

TEST_CASE("screened sums in packets: every query gets what it gets alone, bit for bit, whatever its packet") {
    // Packets mix queries near and far (different r_min, so different cutoffs and decisions),
    // with bounds and a start element as diffuse() passes them, and sizes 1 to 4.
    const PolygonMesh m = broken("torus", 16, 7);
    const sums::SumTree tree(OrientedElements::from_mesh(m));
    const double h = mean_edge_length(m);
    sums::SumTree::Screened k;
    k.lambda = 1 / h;
    k.r_floor = 1e-6 * h;
    const Points q = random_queries(test::sized(240, 60), 1.2, 17);
    constexpr int P = sums::SumTree::kScreenedLanes;
    std::size_t compared = 0;
    for (Eigen::Index first = 0; first < q.rows();) {
        const int n = 1 + int(first % P);
        if (first + n > q.rows()) break;
        double p[3 * P], bound[P], r_min[P], X[3 * P];
        for (int l = 0; l < n; ++l)
            for (int a = 0; a < 3; ++a) p[3 * l + a] = q(first + l, a);
        for (int l = 0; l < n; ++l) bound[l] = tree.nearest_distance(Vec3(p[3 * l], p[3 * l + 1], p[3 * l + 2])) + 0.01 * double(l);
        std::uint32_t nearest = std::uint32_t(first * 7919 % (tree.size() + 3));
        std::size_t terms = 0;
        tree.screened(p, n, k, r_min, X, terms, bound, &nearest);
        std::size_t alone_terms = 0;
        for (int l = 0; l < n; ++l) {
            double r_alone;
            const Vec3 alone = tree.screened(Vec3(p[3 * l], p[3 * l + 1], p[3 * l + 2]), k, r_alone, alone_terms);
            REQUIRE(r_min[l] == r_alone);
            for (int a = 0; a < 3; ++a) REQUIRE(X[3 * l + a] == alone[a]);
            ++compared;
        }
        CHECK(terms == alone_terms);
        first += n;
    }
    CHECK(compared + P > std::size_t(q.rows()));  // every query but a short tail
}

TEST_CASE("fast winding numbers: the float32 far field keeps its precision wherever the model is; far queries walk in double") {
    const PolygonMesh m = broken("torus", 24, 4);
    const Points q = random_queries(400, 1.0, 11);
    const double h = mean_edge_length(m);
    // The model and its queries at home and 1e7 away from the origin, where float32 coordinates
    // would be 1 apart: the walk's coordinates are centered on the root. Float32 far field
    // against double on the same tree: the same up to ~1e-6. (Nearer than one edge length the
    // vertices' own rounding in double at 1e7 moves exact solid angles by more.)
    for (const double shift : {0.0, 1e7}) {
        CAPTURE(shift);
        const Eigen::RowVector3d offset = shift * Eigen::RowVector3d(1, -3, 2);
        PolygonMesh moved = m;
        moved.vertices.rowwise() += offset;
        const sums::SumTree tree(OrientedElements::from_mesh(moved));
        double worst_precision = 0, worst_error = 0;
        for (Eigen::Index i = 0; i < q.rows(); ++i) {
            const Vec3 x = (q.row(i) + offset).transpose();
            if (!(tree.nearest_distance(x) > h)) continue;
            double single = 0, twice = 0;
            std::size_t terms = 0;
            tree.winding(&x[0], &x[1], &x[2], 1, 1.5, 5e-3, &single, terms, true);
            tree.winding(&x[0], &x[1], &x[2], 1, 1.5, 5e-3, &twice, terms, false);
            worst_precision = std::max(worst_precision, std::abs(single - twice));
            worst_error = std::max(worst_error, std::abs(single - tree.winding_exact(x)));
        }
        MESSAGE("float32 far field − double: " << worst_precision << "; fast − exact: " << worst_error);
        CHECK(worst_precision < 1e-6);
        CHECK(worst_error <= 1e-3);
    }
    // Queries beyond SumTree::kSingleReach root radii walk in double: within 1e-12 of the exact
    // sum (float32 would underflow there), alone or in a packet with near queries.
    const sums::SumTree tree(OrientedElements::from_mesh(m));
    double x[8], y[8], z[8], w[8];
    for (int l = 0; l < 8; ++l) {
        const double r = l < 4 ? 1e6 * (l + 1) : 0.1 * l;
        x[l] = r;
        y[l] = -0.5 * r;
        z[l] = 0.25;
    }
    std::size_t terms = 0;
    tree.winding(x, y, z, 8, 1.5, 5e-3, w, terms);
    for (int l = 0; l < 8; ++l) {
        const double exact = tree.winding_exact(Vec3(x[l], y[l], z[l]));
        CAPTURE(l);
        CHECK(std::abs(w[l] - exact) <= (l < 4 ? 1e-12 : 1e-3));
    }
}

TEST_CASE("fast winding numbers are scale invariant, also at 1e20 (past float32's squares: the GPU hands over to the CPU)") {
    const PolygonMesh m = broken("capsule", 24, 9);
    const Points q = random_queries(500, 1.0, 3);
    WindingOptions o;
    o.device = "gpu";  // the CPU when there is no device
    const WindingResult unit = fast_winding_numbers(OrientedElements::from_mesh(m), q, o);
    for (double scale : {1e-6, 1e20}) {
        CAPTURE(scale);
        PolygonMesh big = m;
        big.vertices *= scale;
        const WindingResult r = fast_winding_numbers(OrientedElements::from_mesh(big), q * scale, o);
        double worst = 0;
        for (std::size_t i = 0; i < r.w.size(); ++i) worst = std::max(worst, std::abs(r.w[i] - unit.w[i]));
        CHECK(worst < 5e-4);  // float32 solid angles at queries next to a face differ by ~1e-4
    }
}

TEST_CASE("one Field interface: PAT, a baseline and winding numbers sampled through const Field&") {
    const PointCloud cloud = shapes::sphere({0, 0, 0}, 0.5)->sample(1500, 4);
    const TorusField pat(JetFitter().fit(cloud), BlendOptions{});
    const BaselineField sspd(Baseline::Sspd, cloud, BlendOptions{});
    const WindingField winding(OrientedElements::from_mesh(shapes::icosphere(3, 0.5)));
    Points q(4, 3);
    q << 0, 0, 0, 0.1, -0.2, 0.05, 0.9, 0, 0, -0.7, 0.7, 0;
    // Inside/outside the same way for all three: φ < 0 inside for the distances, w ≈ 1 for winding.
    auto inside = [](const Field& f, const FieldValues& v, std::size_t i) {
        return dynamic_cast<const WindingField*>(&f) ? v.phi[i] > 0.5f : v.phi[i] < 0.0f;
    };
    for (const Field* f : {static_cast<const Field*>(&pat), static_cast<const Field*>(&sspd), static_cast<const Field*>(&winding)}) {
        const FieldValues v = f->evaluate(q);
        REQUIRE(v.phi.size() == 4);
        CHECK(inside(*f, v, 0));
        CHECK(inside(*f, v, 1));
        CHECK_FALSE(inside(*f, v, 2));
        CHECK_FALSE(inside(*f, v, 3));
        // A grid through the same interface: node values equal the points' evaluation.
        const GridSpec g{3, 2, 2, Box{{-0.6, -0.6, -0.6}, {0.6, 0.6, 0.6}}};
        const FieldValues on_grid = f->evaluate(g);
        const FieldValues at_nodes = f->evaluate(g.nodes());
        REQUIRE(on_grid.phi.size() == 12);
        for (std::size_t i = 0; i < 12; ++i) CHECK(on_grid.phi[i] == doctest::Approx(at_nodes.phi[i]).epsilon(1e-6));
        // The caller's memory read in place: x, y, z, w records of doubles and of floats.
        std::vector<double> records(16, 0.0);
        std::vector<float> records_f(16, 0.0f);
        for (Eigen::Index i = 0; i < 4; ++i)
            for (int a = 0; a < 3; ++a) {
                records[std::size_t(4 * i + a)] = q(i, a);
                records_f[std::size_t(4 * i + a)] = float(q(i, a));
            }
        const Eigen::Map<const Points, 0, Eigen::OuterStride<>> mapped(records.data(), 4, 3, Eigen::OuterStride<>(4));
        const Eigen::Map<const PointsF, 0, Eigen::OuterStride<>> mapped_f(records_f.data(), 4, 3, Eigen::OuterStride<>(4));
        const FieldValues from_map = f->evaluate(mapped);
        const FieldValues from_floats = f->evaluate(mapped_f);
        const FieldValues rounded = f->evaluate(Points(q.cast<float>().cast<double>()));
        for (std::size_t i = 0; i < 4; ++i) {
            CHECK(from_map.phi[i] == v.phi[i]);
            CHECK(from_floats.phi[i] == rounded.phi[i]);
        }
        if (f->has_gradient()) {
            CHECK(f->evaluate(q, true).gradient.size() == 12);
        } else {
            try {
                (void)f->evaluate(q, true);
                FAIL("a gradient was offered by a field without one");
            } catch (const Error& e) {
                CHECK(e.where() == "with_gradient");
            }
        }
    }
}

TEST_CASE("WindingField: the tree built once equals fast_winding_numbers; options checked up front") {
    const PolygonMesh mesh = shapes::torus_mesh(24, 12);
    OrientedElements e = OrientedElements::from_mesh(mesh);
    WindingOptions o;
    o.device = "cpu";
    const WindingField field(e, o);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(-1, 1);
    Points q(500, 3);
    for (Eigen::Index i = 0; i < q.rows(); ++i)
        for (int a = 0; a < 3; ++a) q(i, a) = u(rng);
    const WindingResult direct = fast_winding_numbers(e, q, o);
    for (int pass = 0; pass < 2; ++pass) {  // the second pass reuses the tree
        const WindingResult cached = field.winding_numbers(q);
        REQUIRE(cached.w.size() == direct.w.size());
        for (std::size_t i = 0; i < direct.w.size(); ++i) CHECK(cached.w[i] == direct.w[i]);
        CHECK(cached.terms == direct.terms);
    }
    WindingOptions bad;
    bad.beta = 0.5;
    try {
        WindingField f(e, bad);
        FAIL("β = 0.5 accepted");
    } catch (const Error& err) {
        CHECK(err.where() == "WindingOptions::beta");
    }
}
