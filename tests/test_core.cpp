#include <doctest/doctest.h>

#include <gsd/core.hpp>
#include <gsd/shapes.hpp>
#include <gsd/spatial.hpp>

#include "spatial/box_tree.hpp"
#include "spatial/morton.hpp"

#include <array>
#include <random>

#include <cmath>

using namespace gsd;

TEST_CASE("grid nodes follow the .npy C-order layout") {
    GridSpec g{3, 4, 5, Box{{-1, -2, -3}, {1, 2, 3}}};
    const Points n = g.nodes();
    REQUIRE(n.rows() == 60);
    // element [i, j, k] is at index (i*ny + j)*nz + k
    const Eigen::Index idx = (2 * 4 + 1) * 5 + 3;
    CHECK(n(idx, 0) == doctest::Approx(1.0));
    CHECK(n(idx, 1) == doctest::Approx(-2.0 + 4.0 / 3.0));
    CHECK(n(idx, 2) == doctest::Approx(-3.0 + 6.0 * 3.0 / 4.0));
    CHECK_THROWS_AS((GridSpec{1, 4, 4, Box{{0, 0, 0}, {1, 1, 1}}}.validate()), Error);
    CHECK_THROWS_AS((GridSpec{4, 4, 4, Box{{0, 0, 0}, {1, 0, 1}}}.validate()), Error);
}

TEST_CASE("grid bricks (a device's order of a grid): every node once, copies clamped, blocks compact") {
    for (const int brick : {2, 4})
        for (const auto& dims : {std::array<int, 3>{2, 2, 2}, {5, 3, 7}, {8, 8, 8}, {9, 2, 13}, {16, 5, 4}}) {
            CAPTURE(brick);
            CAPTURE(dims[0]);
            CAPTURE(dims[1]);
            CAPTURE(dims[2]);
            const GridSpec g{dims[0], dims[1], dims[2], Box{{0, 0, 0}, {1, 1, 1}}};
            const spatial::GridBricks bricks(g, brick);
            const std::size_t per = std::size_t(brick * brick * brick);
            CHECK(bricks.items() % per == 0);
            std::vector<int> seen(g.node_count(), 0);
            for (std::size_t i = 0; i < bricks.items(); ++i) {
                int ijk[3];
                std::size_t linear = 0;
                const bool real = bricks.node(i, ijk, linear);
                for (int a = 0; a < 3; ++a) {
                    REQUIRE(ijk[a] >= 0);
                    REQUIRE(ijk[a] < dims[std::size_t(a)]);
                }
                CHECK(linear == (std::size_t(ijk[0]) * std::size_t(dims[1]) + std::size_t(ijk[1])) * std::size_t(dims[2]) + std::size_t(ijk[2]));
                if (real) ++seen[linear];
            }
            for (const int s : seen) CHECK(s == 1);  // each node exactly once; the rest are copies
            CHECK_THROWS_AS(spatial::GridBricks(g, 3), Error);
            // Every run of 8 items (a software device's subgroup) lies in a 2×2×2 block.
            for (std::size_t i = 0; i < bricks.items(); i += 8) {
                int lo[3] = {1 << 30, 1 << 30, 1 << 30}, hi[3] = {-1, -1, -1};
                for (std::size_t m = i; m < i + 8; ++m) {
                    int ijk[3];
                    std::size_t linear;
                    bricks.node(m, ijk, linear);
                    for (int a = 0; a < 3; ++a) {
                        lo[a] = std::min(lo[a], ijk[a]);
                        hi[a] = std::max(hi[a], ijk[a]);
                    }
                }
                for (int a = 0; a < 3; ++a) CHECK(hi[a] - lo[a] <= 1);
            }
            // Item i's node from first principles: brick i / B³ in C order, its place i % B³ in
            // Morton order (bit 3l + (2 − a) of the place is bit l of the offset along axis a).
            const int bits = brick == 4 ? 2 : 1;
            const std::size_t nb[3] = {std::size_t((dims[0] + brick - 1) / brick), std::size_t((dims[1] + brick - 1) / brick),
                                       std::size_t((dims[2] + brick - 1) / brick)};
            for (std::size_t i = 0; i < bricks.items(); ++i) {
                const std::size_t b = i / per, m = i % per;
                const std::size_t cell[3] = {b / (nb[1] * nb[2]), (b / nb[2]) % nb[1], b % nb[2]};
                int got[3];
                std::size_t linear = 0;
                const bool real = bricks.node(i, got, linear);
                bool inside = true;
                for (int a = 0; a < 3; ++a) {
                    std::size_t offset = 0;
                    for (int l = 0; l < bits; ++l) offset |= ((m >> (3 * l + (2 - a))) & 1u) << l;
                    const std::size_t v = (cell[a] << bits) + offset;
                    inside = inside && v < std::size_t(dims[std::size_t(a)]);
                    REQUIRE(got[a] == int(std::min<std::size_t>(v, std::size_t(dims[std::size_t(a)] - 1))));
                }
                REQUIRE(real == inside);
            }
            // A cursor walked from any item gives node()'s answers (the device's upload and
            // read-back take the items so).
            for (const std::size_t start : {std::size_t(0), std::size_t(1), per - 1, per, bricks.items() / 2 + 3}) {
                if (start >= bricks.items()) continue;
                spatial::GridBricks::Cursor at(bricks, start);
                for (std::size_t i = start; i < bricks.items(); ++i, at.next()) {
                    int want[3], got[3];
                    std::size_t want_linear = 0, got_linear = 0;
                    const bool want_real = bricks.node(i, want, want_linear), got_real = at.node(got, got_linear);
                    REQUIRE(got_real == want_real);
                    REQUIRE(got_linear == want_linear);
                    for (int a = 0; a < 3; ++a) REQUIRE(got[a] == want[a]);
                }
            }
        }
}

TEST_CASE("mean edge length: every face's edges, a shared edge once per face") {
    PolygonMesh m;
    m.vertices.resize(5, 3);
    m.vertices << 0, 0, 0, 3, 0, 0, 3, 4, 0, 0, 4, 0, 0, 0, 7;
    m.add_face({0, 1, 2});     // edges 3, 4, 5
    m.add_face({0, 1, 2, 3});  // edges 3, 4, 3, 4
    CHECK(mean_edge_length(m) == doctest::Approx((3 + 4 + 5 + 3 + 4 + 3 + 4) / 7.0).epsilon(1e-15));
    CHECK(mean_edge_length(PolygonMesh{}) == 0.0);
}

TEST_CASE("validate rejects bad clouds without changing them; normalize_normals scales the normals") {
    PointCloud c;
    CHECK_THROWS_AS(validate(c), Error);
    c.points = Points::Random(4, 3);
    c.normals = Points::Constant(4, 3, 2.0);
    validate(c);
    CHECK(c.normals.row(0).norm() == doctest::Approx(2.0 * std::sqrt(3.0)));  // checked, not changed
    normalize_normals(c);
    CHECK(c.normals.row(0).norm() == doctest::Approx(1.0));
    c.normals(2, 1) = NAN;
    CHECK_THROWS_AS(validate(c), Error);
    c.normals.row(2).setZero();
    CHECK_THROWS_AS(validate(c), Error);
    c.normals.row(2) << 0, 0, 1;
    c.points(1, 0) = INFINITY;
    CHECK_THROWS_AS(validate(c), Error);
}

TEST_CASE("analytic shapes: samples lie on the surface with the SDF's gradient as normal") {
    for (const char* name : {"sphere", "torus", "capsule", "rounded-box"}) {
        CAPTURE(name);
        auto s = shapes::by_name(name);
        const PointCloud c = s->sample(2000, 7);
        REQUIRE(c.size() == 2000);
        double worst = 0, worst_n = 0;
        for (Eigen::Index i = 0; i < c.size(); ++i) {
            const Eigen::Vector3d p = c.points.row(i).transpose();
            const Eigen::Vector3d n = c.normals.row(i).transpose();
            worst = std::max(worst, std::abs(s->sdf(p)));
            // finite-difference gradient of the exact SDF equals the sampled normal
            const double e = 1e-6;
            Eigen::Vector3d g;
            for (int k = 0; k < 3; ++k) {
                Eigen::Vector3d d = Eigen::Vector3d::Zero();
                d[k] = e;
                g[k] = (s->sdf(p + d) - s->sdf(p - d)) / (2 * e);
            }
            worst_n = std::max(worst_n, (g - n).norm());
        }
        CHECK(worst < 1e-12);
        CHECK(worst_n < 1e-4);
    }
}

TEST_CASE("area-uniform sampling: the share of samples in a region matches its area") {
    // Capsule: cylinder part has area 2πrL, caps 4πr².
    auto s = shapes::capsule({-0.4, 0, 0}, {0.4, 0, 0}, 0.3);
    const PointCloud c = s->sample(40000, 3);
    int on_cylinder = 0;
    for (Eigen::Index i = 0; i < c.size(); ++i) on_cylinder += std::abs(c.points(i, 0)) < 0.4;
    const double expect = 2 * M_PI * 0.3 * 0.8 / s->area();
    CHECK(double(on_cylinder) / 40000 == doctest::Approx(expect).epsilon(0.02));
}

TEST_CASE("kd-tree neighbors agree with brute force; spacing and areas are sane") {
    auto s = shapes::sphere({0, 0, 0}, 0.5);
    const PointCloud c = s->sample(3000, 11);
    KdTree tree(c.points);
    const Eigen::Vector3d q(0.1, -0.3, 0.55);
    auto nb = tree.knn(q, 10);
    std::vector<double> d;
    for (Eigen::Index i = 0; i < c.size(); ++i) d.push_back((c.points.row(i).transpose() - q).norm());
    std::sort(d.begin(), d.end());
    REQUIRE(nb.size() == 10);
    for (int i = 0; i < 10; ++i) CHECK(nb[std::size_t(i)].distance == doctest::Approx(d[std::size_t(i)]));
    std::vector<Neighbor> ball;
    tree.radius(q, d[24] * 1.000001, ball);
    CHECK(ball.size() == 25);
    // Mean nearest-neighbor spacing of N uniform points on area A is ≈ 0.5·sqrt(A/N).
    const double h = mean_spacing(tree);
    CHECK(h == doctest::Approx(0.5 * std::sqrt(s->area() / 3000)).epsilon(0.15));
    const auto areas = point_areas(tree);
    double total = 0;
    for (double a : areas) total += a;
    CHECK(total == doctest::Approx(s->area()).epsilon(0.25));
}

// Normals of `c` that point against the shape's outward normal (its SDF's gradient).
long wrong_normals(const shapes::Shape& shape, const PointCloud& c) {
    long wrong = 0;
    for (Eigen::Index i = 0; i < c.size(); ++i) {
        const Eigen::Vector3d p = c.points.row(i).transpose(), n = c.normals.row(i).transpose();
        Eigen::Vector3d g;
        for (int a = 0; a < 3; ++a) {
            const Eigen::Vector3d e = 1e-6 * Eigen::Vector3d::Unit(a);
            g[a] = shape.sdf(p + e) - shape.sdf(p - e);
        }
        wrong += g.dot(n) < 0;
    }
    return wrong;
}

TEST_CASE("reorient_normals: scattered flips turned back, a thin part's two sides left alone") {
    for (const std::string name : {"torus", "rounded-box", "capsule"}) {
        CAPTURE(name);
        const auto shape = shapes::by_name(name);
        const PointCloud clean = shape->sample(2048, 3);
        CHECK(wrong_normals(*shape, clean) == 0);
        PointCloud c = clean;
        CHECK(reorient_normals(c) == 0);  // nothing to turn on a clean cloud
        CHECK(c.normals == clean.normals);
        shapes::Corruption k;
        k.flip_fraction = 0.1;
        for (double noise : {0.0, 0.002}) {
            k.position_noise = noise;
            PointCloud f = shapes::corrupt(clean, k, 4);
            const long before = wrong_normals(*shape, f);
            CHECK(before > 150);
            const std::size_t turned = reorient_normals(f);
            const long after = wrong_normals(*shape, f);
            MESSAGE(name << " noise " << noise << ": " << before << " normals wrong, " << turned << " turned, " << after << " wrong after");
            CHECK(after <= 5);  // of 212 (0–3 measured: the rounded box's edges)
            CHECK(long(turned) >= before - after);
        }
        // One in five flipped: flips touch, a pass can turn a pair of them against each other, and
        // later passes settle it (measured here: 6, 0, 0 of 382 left wrong).
        k.flip_fraction = 0.2;
        k.position_noise = 0;
        PointCloud f = shapes::corrupt(clean, k, 5);
        const long before = wrong_normals(*shape, f);
        CHECK(before > 300);
        reorient_normals(f);
        const long after = wrong_normals(*shape, f);
        MESSAGE(name << " 20 % flipped: " << before << " normals wrong, " << after << " wrong after");
        CHECK(after <= 12);
        ReorientOptions one;
        one.passes = 1;
        PointCloud g = shapes::corrupt(clean, k, 5);
        reorient_normals(g, one);
        CHECK(wrong_normals(*shape, g) >= after);  // passes only settle
    }
    // Plates 1.5, 0.5 and 0.25 spacings thick (a CAD part's panels, sampled on both faces): each
    // side's normals face away from the other's; none is turned. The far side lies behind each
    // point; without behind_width's narrower Gaussian the two thinner plates had 925 and 1600
    // of their 4000 normals turned.
    for (double thickness : {1.5, 0.5, 0.25}) {
        CAPTURE(thickness);
        std::mt19937 rng(9);
        std::uniform_real_distribution<double> u(-0.5, 0.5);
        PointCloud plate;
        plate.points.resize(4000, 3);
        plate.normals.resize(4000, 3);
        for (Eigen::Index i = 0; i < 4000; ++i) {
            const double side = i % 2 ? 1 : -1;
            plate.points.row(i) << u(rng), u(rng), 0;
            plate.normals.row(i) << 0, 0, side;
        }
        const double h = mean_spacing(plate.points);
        for (Eigen::Index i = 0; i < 4000; ++i) plate.points(i, 2) = plate.normals(i, 2) * 0.5 * thickness * h;
        const PointCloud before = plate;
        CHECK(reorient_normals(plate) == 0);
        CHECK(plate.normals == before.normals);
        ReorientOptions bad;
        bad.width = 0;
        CHECK_THROWS_AS(reorient_normals(plate, bad), Error);
        bad = {};
        bad.behind_width = 0.6;  // wider than tangent_width
        CHECK_THROWS_AS(reorient_normals(plate, bad), Error);
        bad.behind_width = NAN;
        CHECK_THROWS_AS(reorient_normals(plate, bad), Error);
    }
    // A stray point hundreds of spacings from the rest, its normal across the direction to them
    // (the torus's top faces in front of it and agreeing, its bottom faces behind and opposing):
    // its voters' weights all underflow as they stand, and a rule that kept only the behind ones'
    // sign turned it back and forth with every pass. Its verdict must settle: the same after 7
    // passes as after 8.
    {
        const auto torus = shapes::by_name("torus");
        PointCloud c = torus->sample(2048, 3);
        c.points.conservativeResize(2049, 3);
        c.normals.conservativeResize(2049, 3);
        c.points.row(2048) << 30, 0, 0;
        c.normals.row(2048) << 0, 0, 1;
        PointCloud seven = c, eight = c;
        ReorientOptions o;
        o.passes = 7;
        reorient_normals(seven, o);
        o.passes = 8;
        reorient_normals(eight, o);
        CHECK(seven.normals == eight.normals);
        CHECK(eight.normals.topRows(2048) == c.normals.topRows(2048));  // the torus keeps its own
    }
}

TEST_CASE("BoxTree (the blend's search, shared with the GPU) finds what nanoflann finds") {
    auto s = shapes::torus({0, 0, 0}, 0.5, 0.2);
    const PointCloud c = s->sample(20000, 4);
    const spatial::BoxTree box(c.points);
    KdTree kd(c.points);
    std::mt19937_64 rng(2);
    std::uniform_real_distribution<double> u(-1.2, 1.2);
    std::vector<Neighbor> a, b;
    for (int q = 0; q < 300; ++q) {
        // Far queries, and queries on the surface.
        const Eigen::Vector3d x = q % 2 ? Eigen::Vector3d(u(rng), u(rng), u(rng))
                                        : Eigen::Vector3d(c.points.row(q * 31).transpose()) + Eigen::Vector3d::Constant(1e-3);
        box.knn(x, 32, a);
        kd.knn(x, 32, b);
        REQUIRE(a.size() == 32);
        for (int m = 0; m < 32; ++m) CHECK(a[std::size_t(m)].distance == doctest::Approx(b[std::size_t(m)].distance).epsilon(1e-12));
        box.radius(x, 0.05, a);
        kd.radius(x, 0.05, b);
        CHECK(a.size() == b.size());
    }
    // Tiny sets: fewer points than k, a single point.
    Points two(2, 3);
    two << 0, 0, 0, 1, 0, 0;
    const spatial::BoxTree t2(two);
    t2.knn({0.9, 0, 0}, 32, a);
    REQUIRE(a.size() == 2);
    CHECK(a[0].index == 1);
}
