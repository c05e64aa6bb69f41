// The field algebra (gsd/field_algebra.hpp) and `gsd field`: a grid as a field against the
// functions it samples, the operators against exact signed distances of spheres, their
// gradients against finite differences, their Lipschitz bounds, bad input, the CLI.
#include <gsd/field_algebra.hpp>
#include <gsd/io.hpp>
#include <gsd/pat.hpp>
#include <gsd/render.hpp>
#include <gsd/sdf.hpp>
#include <gsd/shapes.hpp>
#include <gsd/spatial.hpp>
#include <gsd/viz.hpp>

#include "support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <map>
#include <cmath>
#include <random>

using namespace gsd;
using test::run_cli;
using test::ScratchDir;

namespace {

// A sphere's exact signed distance, written here: the reference the operators are held to.
class SphereField final : public Field {
public:
    SphereField(Eigen::Vector3d c, double r, bool gradient = true) : c_(c), r_(r), gradient_(gradient) {}
    using Field::evaluate;
    FieldValues evaluate(PointsView q, bool with_gradient, const ProgressFn&) const override {
        refuse_gradient(with_gradient && !gradient_, "test spheres");
        FieldValues v;
        v.device = "cpu";
        for (Eigen::Index i = 0; i < q.rows(); ++i) {
            const Eigen::Vector3d d = q.row(i).transpose() - c_;
            v.phi.push_back(float(exact(q.row(i).transpose())));
            if (!with_gradient) continue;
            const Eigen::Vector3d g = d.norm() > 0 ? Eigen::Vector3d(d.normalized()) : Eigen::Vector3d::UnitX();
            for (int a = 0; a < 3; ++a) v.gradient.push_back(float(g[a]));
        }
        return v;
    }
    FieldValues evaluate(const GridSpec& g, bool with_gradient, const ProgressFn& p) const override {
        return evaluate(g.nodes(), with_gradient, p);
    }
    bool has_gradient() const override { return gradient_; }
    double exact(const Eigen::Vector3d& x) const { return (x - c_).norm() - r_; }

private:
    Eigen::Vector3d c_;
    double r_;
    bool gradient_;
};

Points random_points(int n, double half, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(-half, half);
    Points p(n, 3);
    for (int i = 0; i < n; ++i) p.row(i) << u(rng), u(rng), u(rng);
    return p;
}

double phi_at(const Field& f, const Eigen::Vector3d& x) {
    Points q(1, 3);
    q.row(0) = x.transpose();
    return f.evaluate(q).phi[0];
}

}  // namespace

TEST_CASE("GridField: trilinear inside, the nearest value plus the distance outside") {
    const GridSpec g = GridSpec::cube(9, {{-1, -1, -1}, {1, 1, 1}});
    const Eigen::Vector3d slope(0.3, -0.2, 0.5);
    std::vector<float> values(g.node_count());
    const Points nodes = g.nodes();
    for (Eigen::Index i = 0; i < nodes.rows(); ++i) values[std::size_t(i)] = float(slope.dot(nodes.row(i).transpose()) + 0.1);
    const GridField f(g, values);
    // A linear function is its own trilinear interpolant: exact, with its gradient, inside.
    const Points inside = random_points(200, 0.99, 1);
    const FieldValues v = f.evaluate(inside, true);
    for (Eigen::Index i = 0; i < inside.rows(); ++i) {
        CHECK(v.phi[std::size_t(i)] == doctest::Approx(slope.dot(inside.row(i).transpose()) + 0.1).epsilon(1e-5));
        for (int a = 0; a < 3; ++a) CHECK(v.gradient[3 * std::size_t(i) + std::size_t(a)] == doctest::Approx(slope[a]).epsilon(1e-5));
    }
    // Outside: the value at the box's nearest point plus the distance to it.
    Points out(2, 3);
    out.row(0) << 3, 0.5, 0;   // past x only
    out.row(1) << 2, -2, 1.5;  // past three sides
    const FieldValues w = f.evaluate(out, true);
    const Eigen::Vector3d c0(1, 0.5, 0), c1(1, -1, 1);
    CHECK(w.phi[0] == doctest::Approx(slope.dot(c0) + 0.1 + 2).epsilon(1e-5));
    CHECK(w.phi[1] == doctest::Approx(slope.dot(c1) + 0.1 + (Eigen::Vector3d(2, -2, 1.5) - c1).norm()).epsilon(1e-5));
    CHECK(w.gradient[0] == doctest::Approx(1));               // the distance term along x
    CHECK(w.gradient[1] == doctest::Approx(slope.y()));       // the interpolant along y, z
    // Its own grid: the values as they are.
    CHECK(f.evaluate(g).phi == values);
    CHECK_THROWS_AS(GridField(g, std::vector<float>(10)), Error);
    values[3] = NAN;
    CHECK_THROWS_AS(GridField(g, values), Error);
}

TEST_CASE("Booleans, offsets and shells against the exact distances of spheres") {
    const auto a = std::make_shared<SphereField>(Eigen::Vector3d(-0.6, 0, 0), 0.4);
    const auto b = std::make_shared<SphereField>(Eigen::Vector3d(0.6, 0, 0), 0.3);
    const auto c = std::make_shared<SphereField>(Eigen::Vector3d(-0.3, 0, 0), 0.4);  // overlaps a
    const Points q = random_points(500, 1.5, 2);
    // Two spheres apart: their union's distance is the min of theirs, exactly (inside each too).
    const FieldValues u = field_union(a, b)->evaluate(q);
    // a − c and a ∩ c: max(a, −c) and max(a, c), exact where the sign is concerned.
    const FieldValues d = field_difference(a, c)->evaluate(q), i = field_intersection(a, c)->evaluate(q);
    // Offsets of a sphere are spheres: exact; a shell of thickness 2r about it.
    const FieldValues grown = field_offset(a, 0.1)->evaluate(q), shrunk = field_offset(a, -0.1)->evaluate(q);
    const FieldValues shell = field_shell(a, 0.05)->evaluate(q);
    const SphereField a_grown({-0.6, 0, 0}, 0.5), a_shrunk({-0.6, 0, 0}, 0.3);
    for (Eigen::Index k = 0; k < q.rows(); ++k) {
        const Eigen::Vector3d x = q.row(k).transpose();
        const auto j = std::size_t(k);
        CHECK(u.phi[j] == doctest::Approx(std::min(a->exact(x), b->exact(x))).epsilon(1e-6));
        const bool in_a = a->exact(x) < 0, in_c = c->exact(x) < 0;
        if (std::abs(d.phi[j]) > 1e-6) CHECK((d.phi[j] < 0) == (in_a && !in_c));
        if (std::abs(i.phi[j]) > 1e-6) CHECK((i.phi[j] < 0) == (in_a && in_c));
        CHECK(grown.phi[j] == doctest::Approx(a_grown.exact(x)).epsilon(1e-6));
        CHECK(shrunk.phi[j] == doctest::Approx(a_shrunk.exact(x)).epsilon(1e-6));
        CHECK(shell.phi[j] == doctest::Approx(std::abs(a->exact(x)) - 0.05).epsilon(1e-6));
    }
    // On a grid, each operand takes its grid path; the result is the same as at the nodes.
    const GridSpec g = GridSpec::cube(6, {{-1, -1, -1}, {1, 1, 1}});
    const FieldPtr expr = field_union(field_offset(a, 0.05), field_difference(b, c, 0.1), 0.2);
    CHECK(expr->evaluate(g).phi == expr->evaluate(g.nodes()).phi);
}

namespace {

// Every directed edge once, with its opposite: a closed, consistently oriented 2-manifold.
bool closed_manifold(const PolygonMesh& m) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed;
    for (std::size_t f = 0; f < m.face_count(); ++f) {
        const auto n = m.offsets[f + 1] - m.offsets[f];
        for (std::size_t k = 0; k < n; ++k) directed[{m.indices[m.offsets[f] + k], m.indices[m.offsets[f] + (k + 1) % n]}]++;
    }
    for (const auto& [e, count] : directed)
        if (count != 1 || directed.count({e.second, e.first}) != 1) return false;
    return !directed.empty();
}

}  // namespace

TEST_CASE("Booleans of two PAT fields err no more than 1.2× their worse leaf; offsets contour to closed manifolds near the exact offset" *
          doctest::test_suite("slow")) {
    // Two overlapping spheres, sampled (5,000 points each, with position and normal noise) and
    // fitted: PAT leaves with an error of their own. φ_true of a Boolean: the same Boolean of the
    // exact distances.
    const Eigen::Vector3d ca(-0.25, 0.05, 0), cb(0.3, -0.1, 0.1);
    const double ra = 0.45, rb = 0.35;
    shapes::Corruption noise;
    noise.position_noise = 0.002;
    noise.normal_noise = 0.05;
    const auto a = std::make_shared<TorusField>(JetFitter().fit(shapes::corrupt(shapes::sphere(ca, ra)->sample(5000, 21), noise, 1)));
    const auto b = std::make_shared<TorusField>(JetFitter().fit(shapes::corrupt(shapes::sphere(cb, rb)->sample(5000, 22), noise, 2)));
    const GridSpec g = GridSpec::cube(64, {{-1, -1, -1}, {1, 1, 1}});
    const Points x = g.nodes();
    std::vector<double> ea(x.rows()), eb(x.rows());
    for (Eigen::Index i = 0; i < x.rows(); ++i) {
        ea[std::size_t(i)] = (x.row(i).transpose() - ca).norm() - ra;
        eb[std::size_t(i)] = (x.row(i).transpose() - cb).norm() - rb;
    }
    auto mean_error = [&](const FieldPtr& f, auto&& truth) {
        const FieldValues v = f->evaluate(g);
        double e = 0;
        for (std::size_t i = 0; i < v.phi.size(); ++i) e += std::abs(v.phi[i] - truth(ea[i], eb[i]));
        return e / double(v.phi.size());
    };
    const double err_a = mean_error(a, [](double u, double) { return u; }), err_b = mean_error(b, [](double, double v) { return v; });
    const double worse = std::max(err_a, err_b);
    const double err_u = mean_error(field_union(a, b), [](double u, double v) { return std::min(u, v); });
    const double err_i = mean_error(field_intersection(a, b), [](double u, double v) { return std::max(u, v); });
    const double err_d = mean_error(field_difference(a, b), [](double u, double v) { return std::max(u, -v); });
    MESSAGE("mean |φ − φ_true| on 64³: leaves " << err_a << ", " << err_b << "; union " << err_u << ", intersection " << err_i
                                               << ", difference " << err_d);
    CHECK(err_u <= 1.2 * worse);
    CHECK(err_i <= 1.2 * worse);
    CHECK(err_d <= 1.2 * worse);
    // Offsets of leaf a: closed manifold meshes within 2 × its error + half a cell of the exact
    // offset sphere (both ways: the mesh's vertices to the sphere, the sphere's points to the mesh).
    const double cell = 2.0 / 63;
    for (double r : {-0.1, -0.05, 0.05, 0.1}) {
        CAPTURE(r);
        const PolygonMesh m = contour(g, field_offset(a, r)->evaluate(g).phi, 0.0);
        CHECK(closed_manifold(m));
        double to_sphere = 0;
        for (Eigen::Index v = 0; v < m.vertices.rows(); ++v)
            to_sphere = std::max(to_sphere, std::abs((m.vertices.row(v).transpose() - ca).norm() - (ra + r)));
        const PointCloud on = shapes::sphere(ca, ra + r)->sample(2000, 5);
        MeshSdfOptions unsigned_distance;
        unsigned_distance.sign = SdfSign::none;
        unsigned_distance.device = "cpu";
        const std::vector<double> d = mesh_sdf(m, on.points, unsigned_distance).phi;
        const double to_mesh = *std::max_element(d.begin(), d.end());
        MESSAGE("offset " << r << ": Hausdorff max(" << to_sphere << ", " << to_mesh << "), bound " << 2 * err_a + 0.5 * cell);
        CHECK(std::max(to_sphere, to_mesh) <= 2 * err_a + 0.5 * cell);
    }
}

TEST_CASE("Smooth Booleans: within k/4 of the sharp ones, equal where the operands differ by k or more") {
    const auto a = std::make_shared<SphereField>(Eigen::Vector3d(-0.3, 0, 0), 0.4);
    const auto b = std::make_shared<SphereField>(Eigen::Vector3d(0.3, 0.1, 0), 0.35);
    const double k = 0.2;
    const Points q = random_points(800, 1.2, 3);
    const FieldValues su = field_union(a, b, k)->evaluate(q), si = field_intersection(a, b, k)->evaluate(q),
                      sd = field_difference(a, b, k)->evaluate(q);
    std::size_t blended = 0;
    for (Eigen::Index r = 0; r < q.rows(); ++r) {
        const Eigen::Vector3d x = q.row(r).transpose();
        const double pa = a->exact(x), pb = b->exact(x);
        const auto j = std::size_t(r);
        const double sharp[3] = {std::min(pa, pb), std::max(pa, pb), std::max(pa, -pb)};
        const double gap[3] = {std::abs(pa - pb), std::abs(pa - pb), std::abs(pa + pb)};
        const double smooth[3] = {su.phi[j], si.phi[j], sd.phi[j]};
        const double side[3] = {-1, 1, 1};  // the union rounds below the min, the others above the max
        for (int o = 0; o < 3; ++o) {
            const double shift = side[o] * (smooth[o] - sharp[o]);
            CHECK(shift >= -1e-6);
            CHECK(shift <= k / 4 + 1e-6);
            if (gap[o] >= k) CHECK(smooth[o] == doctest::Approx(sharp[o]).epsilon(1e-6));
        }
        blended += gap[0] < k;
    }
    CHECK(blended > 20);
}

TEST_CASE("Operator gradients match finite differences; composites of distances stay 1-Lipschitz") {
    const auto a = std::make_shared<SphereField>(Eigen::Vector3d(-0.3, 0, 0), 0.4);
    const auto b = std::make_shared<SphereField>(Eigen::Vector3d(0.3, 0.1, 0), 0.35);
    const std::vector<std::pair<const char*, FieldPtr>> fields = {
        {"union", field_union(a, b)},
        {"smooth union", field_union(a, b, 0.3)},
        {"smooth intersection", field_intersection(a, b, 0.3)},
        {"smooth difference", field_difference(a, b, 0.3)},
        {"shell of an offset", field_shell(field_offset(a, 0.1), 0.05)},
    };
    const Points q = random_points(300, 1.2, 4);
    const Points p = random_points(300, 1.2, 5);
    for (const auto& entry : fields) {
        const char* name = entry.first;
        const FieldPtr& f = entry.second;
        CAPTURE(name);
        const FieldValues v = f->evaluate(q, true), w = f->evaluate(p);
        const double h = 1e-4;
        std::size_t checked = 0;
        for (Eigen::Index r = 0; r < q.rows(); ++r) {
            const Eigen::Vector3d x = q.row(r).transpose();
            // Skip the creases of the sharp operators and of |φ| (a kink within h).
            Eigen::Vector3d fd;
            for (int ax = 0; ax < 3; ++ax) {
                const Eigen::Vector3d e = h * Eigen::Vector3d::Unit(ax);
                fd[ax] = (phi_at(*f, x + e) - phi_at(*f, x - e)) / (2 * h);
            }
            const Eigen::Vector3d g(v.gradient[3 * std::size_t(r)], v.gradient[3 * std::size_t(r) + 1], v.gradient[3 * std::size_t(r) + 2]);
            if ((fd - g).norm() > 0.5) continue;  // a crease between the samples
            ++checked;
            CHECK((fd - g).norm() < 2e-2);  // float32 values: differences of 1e-4 carry ~1e-3 noise
            // 1-Lipschitz: no pair of queries farther apart in φ than in space.
            const Eigen::Vector3d y = p.row(r).transpose();
            CHECK(std::abs(double(v.phi[std::size_t(r)]) - double(w.phi[std::size_t(r)])) <= (x - y).norm() * (1 + 1e-6) + 1e-6);
        }
        CHECK(checked > 250);
    }
}

TEST_CASE("Field operators: bad operands and options are errors") {
    const auto a = std::make_shared<SphereField>(Eigen::Vector3d::Zero(), 0.4);
    const auto no_gradient = std::make_shared<SphereField>(Eigen::Vector3d::Zero(), 0.2, false);
    CHECK_THROWS_AS(field_union(a, nullptr), Error);
    CHECK_THROWS_AS(field_union(a, a, -0.1), Error);
    CHECK_THROWS_AS(field_intersection(a, a, NAN), Error);
    CHECK_THROWS_AS(field_offset(a, INFINITY), Error);
    CHECK_THROWS_AS(field_shell(a, -0.1), Error);
    const FieldPtr f = field_union(a, no_gradient);
    CHECK_FALSE(f->has_gradient());
    CHECK_THROWS_AS(f->evaluate(random_points(3, 1, 6), true), Error);
    CHECK(f->evaluate(random_points(3, 1, 6)).phi.size() == 3);
}

TEST_CASE("MeshSdfField is mesh_sdf as a field") {
    const PolygonMesh sphere = shapes::icosphere(2);
    const Points q = random_points(100, 1.5, 7);
    MeshSdfOptions o;
    o.device = "cpu";
    const MeshSdfField f(sphere, o);
    const MeshSdfResult r = mesh_sdf(sphere, q, o);
    const FieldValues v = f.evaluate(q, true);
    REQUIRE(v.gradient.size() == 3 * r.phi.size());
    for (std::size_t i = 0; i < r.phi.size(); ++i) CHECK(v.phi[i] == float(r.phi[i]));
    PolygonMesh bad = sphere;
    bad.vertices(0, 0) = NAN;
    CHECK_THROWS_AS(MeshSdfField(bad, o), Error);
    // A broken mesh, the automatic sign (winding numbers, SHM near w = ½): what the field keeps
    // between evaluations (tree, SHM grid) answers each batch as mesh_sdf does from scratch, and
    // a copy keeps working after the original is gone.
    shapes::MeshCorruption c;
    c.holes = 3;
    c.hole_area = 0.15;
    c.flip_fraction = 0.1;
    const PolygonMesh broken = shapes::corrupt(shapes::mesh(*shapes::torus(Eigen::Vector3d::Zero(), 0.5, 0.2), 32), c, 3);
    auto field = std::make_unique<MeshSdfField>(broken, o);
    const MeshSdfField copy = *field;
    for (std::uint64_t seed : {8, 9}) {
        const Points batch = random_points(400, 1.0, seed);
        const std::vector<double> expected = mesh_sdf(broken, batch, o).phi;
        const FieldValues v = field->evaluate(batch);
        for (std::size_t i = 0; i < expected.size(); ++i) CHECK(v.phi[i] == float(expected[i]));
    }
    field.reset();
    const Points last = random_points(100, 1.0, 10);
    const std::vector<double> expected = mesh_sdf(broken, last, o).phi;
    const FieldValues w = copy.evaluate(last);
    for (std::size_t i = 0; i < expected.size(); ++i) CHECK(w.phi[i] == float(expected[i]));
}

namespace {

// Where the ray o + t·d first meets the sphere (−1: never).
double sphere_hit(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& c, double r) {
    const Eigen::Vector3d oc = o - c;
    const double b = d.dot(oc), disc = b * b - (oc.squaredNorm() - r * r);
    if (disc < 0) return -1;
    const double t = -b - std::sqrt(disc);
    return t >= 0 ? t : -1;
}

}  // namespace

TEST_CASE("render_field of a composite: the union of two spheres as ray casting sees it") {
    const auto a = std::make_shared<SphereField>(Eigen::Vector3d(-0.35, 0, 0), 0.4);
    const auto b = std::make_shared<SphereField>(Eigen::Vector3d(0.4, 0.1, 0), 0.3, /*gradient=*/false);
    FieldRenderOptions o;
    o.width = 64;
    o.height = 48;
    o.supersample = 1;
    o.device = "cpu";
    o.eye = Eigen::Vector3d(0.4, 0.6, 2.2);  // close: the spheres fill much of the picture
    const Box box{{-1, -1, -1}, {1, 1, 1}};
    // b has no ∇φ: the shading takes central differences there.
    const RenderedField r = render_field(*field_union(a, b), box, o);
    // A hit is where |φ| < ε (1e-4 of the box's diagonal) along the ray: at most ε/|cos θ| deep
    // of the surface, θ between the ray and the surface's normal there.
    const double eps = 1e-4 * box.diagonal();
    std::size_t differ = 0, both = 0, beyond = 0;
    for (int y = 0; y < r.render_height; ++y)
        for (int x = 0; x < r.render_width; ++x) {
            const Eigen::Vector3d d = r.camera.ray(x, y, r.render_width, r.render_height);
            const Eigen::Vector3d ca(-0.35, 0, 0), cb(0.4, 0.1, 0);
            const double ta = sphere_hit(r.camera.eye, d, ca, 0.4), tb = sphere_hit(r.camera.eye, d, cb, 0.3);
            const bool first_a = ta >= 0 && (tb < 0 || ta <= tb);
            const double exact = first_a ? ta : tb;
            const double t = r.depth[std::size_t(y) * std::size_t(r.render_width) + std::size_t(x)];
            if ((t >= 0) != (exact >= 0)) {
                ++differ;
                continue;
            }
            if (t < 0) continue;
            ++both;
            const Eigen::Vector3d p = r.camera.eye + exact * d;
            const double cosine = std::abs(d.dot((p - (first_a ? ca : cb)).normalized()));
            beyond += std::abs(t - exact) > eps / std::max(cosine, 0.02) + 1e-5;
        }
    MESSAGE("masks differ at " << differ << " of " << r.depth.size() << " pixels; " << beyond << " of " << both
                               << " hits deeper than ε/|cos θ|");
    CHECK(both > 600);
    CHECK(double(differ) <= 0.01 * double(r.depth.size()));
    CHECK(beyond == 0);
}

TEST_CASE("render_field of a composite marches as the CPU reference does a field alone") {
    // PAT of a sampled torus, alone (the per-ray CPU reference) and as offset(·, 0): a composite,
    // marched a band of rays at a time with φ in float32.
    const auto torus = shapes::torus(Eigen::Vector3d::Zero(), 0.5, 0.2);
    const PointCloud cloud = torus->sample(3000, 2);
    JetFitterOptions jo;
    const auto pat = std::make_shared<TorusField>(JetFitter(jo).fit(cloud));
    FieldRenderOptions o;
    o.width = 64;
    o.height = 48;
    o.supersample = 1;
    o.device = "cpu";
    // The same camera for both: an explicit eye, looking at the center of the cloud's box, which
    // both subjects share (the cloud's box for PAT, `box` for the composite).
    o.eye = Eigen::Vector3d(0.8, 0.9, 1.6);
    const Box box = padded_cube(bounding_box(cloud.points));
    const RenderedField alone = render_field(*pat, box, o), composite = render_field(*field_offset(pat, 0), box, o);
    REQUIRE(alone.depth.size() == composite.depth.size());
    std::size_t differ = 0, hits = 0;
    double worst = 0;
    for (std::size_t p = 0; p < alone.depth.size(); ++p) {
        if ((alone.depth[p] >= 0) != (composite.depth[p] >= 0)) ++differ;
        else if (alone.depth[p] >= 0) worst = std::max(worst, double(std::abs(alone.depth[p] - composite.depth[p]))), ++hits;
    }
    MESSAGE("masks differ at " << differ << " pixels; largest depth difference " << worst);
    CHECK(hits > 300);
    CHECK(differ <= alone.depth.size() / 100);
    CHECK(worst < 1e-3 * box.diagonal());
}

namespace {

// An axis-aligned box's exact signed distance.
class BoxField final : public Field {
public:
    BoxField(Eigen::Vector3d lo, Eigen::Vector3d hi) : c_(0.5 * (lo + hi)), h_(0.5 * (hi - lo)) {}
    using Field::evaluate;
    FieldValues evaluate(PointsView q, bool with_gradient, const ProgressFn&) const override {
        refuse_gradient(with_gradient, "test boxes");
        FieldValues v;
        for (Eigen::Index i = 0; i < q.rows(); ++i) {
            const Eigen::Vector3d d = (q.row(i).transpose() - c_).cwiseAbs() - h_;
            v.phi.push_back(float(d.cwiseMax(0.0).norm() + std::min(d.maxCoeff(), 0.0)));
        }
        return v;
    }
    FieldValues evaluate(const GridSpec& g, bool with_gradient, const ProgressFn& p) const override {
        return evaluate(g.nodes(), with_gradient, p);
    }
    bool has_gradient() const override { return false; }

private:
    Eigen::Vector3d c_, h_;
};

// The volume where φ < 0, each node weighing its cell's share inside (½ − φ/h clamped to
// [0, 1]: a node on the surface counts half).
double volume_inside(const Field& f, const GridSpec& g) {
    const FieldValues v = f.evaluate(g);
    const Eigen::Vector3d cell = g.box.extent().cwiseQuotient(Eigen::Vector3d(g.nx - 1, g.ny - 1, g.nz - 1));
    double n = 0;
    for (float x : v.phi) n += std::clamp(0.5 - double(x) / cell.x(), 0.0, 1.0);
    return n * cell.prod();
}

}  // namespace

TEST_CASE("Opening removes a fin thinner than 2r and keeps the block; closing fills a slot narrower than 2r") {
    const double r = 0.06;
    const GridSpec grid = GridSpec::cube(97, {{-1.1, -1.1, -1.1}, {1.1, 1.1, 1.1}});
    const auto block = std::make_shared<BoxField>(Eigen::Vector3d(-0.6, -0.6, -0.6), Eigen::Vector3d(0.6, 0.6, 0.6));
    // A fin 0.08 thick (< 2r) standing out of one side.
    const auto fin = std::make_shared<BoxField>(Eigen::Vector3d(0.5, -0.04, -0.3), Eigen::Vector3d(0.95, 0.04, 0.3));
    const FieldPtr opened = field_opening(field_union(block, fin), r, grid);
    Points at(2, 3);
    at.row(0) << 0.8, 0, 0;  // in the fin
    at.row(1) << 0, 0, 0;    // deep in the block
    const FieldValues o = opened->evaluate(at);
    CHECK(o.phi[0] > 0);
    CHECK(o.phi[1] < -0.5);
    // The block keeps its volume within 5 % (an opening only rounds its edges by r), measured on
    // a finer grid of the part away from the fin.
    const GridSpec half = GridSpec::cube(81, {{-0.8, -0.8, -0.8}, {0.8, 0.8, 0.8}});
    const double kept = volume_inside(*opened, half), exact = volume_inside(*block, half);
    MESSAGE("opening: volume " << kept << " of the block's " << exact);
    CHECK(std::abs(kept - exact) < 0.05 * exact);
    // A slot 0.08 wide (< 2r) cut into the block from above: closed.
    const auto slot = std::make_shared<BoxField>(Eigen::Vector3d(-0.04, -0.7, 0.1), Eigen::Vector3d(0.04, 0.7, 0.7));
    const FieldPtr slotted = field_difference(block, slot);
    Points in_slot(1, 3);
    in_slot.row(0) << 0, 0, 0.4;
    CHECK(slotted->evaluate(in_slot).phi[0] > 0);
    const FieldPtr closed = field_closing(slotted, r, grid);
    CHECK(closed->evaluate(in_slot).phi[0] < 0);
    // A slot wider than 2r stays open.
    const auto wide = std::make_shared<BoxField>(Eigen::Vector3d(-0.1, -0.7, 0.1), Eigen::Vector3d(0.1, 0.7, 0.7));
    CHECK(field_closing(field_difference(block, wide), r, grid)->evaluate(in_slot).phi[0] > 0);
    CHECK_THROWS_AS(field_opening(block, 0, grid), Error);
    CHECK_THROWS_AS(field_closing(nullptr, r, grid), Error);
}

namespace {

// Points on a box's faces, uniform by area, with their outward normals (inward with `flip`),
// except those `keep` turns away.
template <class Keep>
void sample_box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double spacing, bool flip, Keep&& keep,
                std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& n, std::mt19937_64& rng) {
    std::uniform_real_distribution<double> u(0, 1);
    for (int axis = 0; axis < 3; ++axis)
        for (int side = 0; side < 2; ++side) {
            const int a = (axis + 1) % 3, b = (axis + 2) % 3;
            const double area = (hi[a] - lo[a]) * (hi[b] - lo[b]);
            const auto count = std::size_t(area / (spacing * spacing));
            for (std::size_t k = 0; k < count; ++k) {
                Eigen::Vector3d x;
                x[axis] = side ? hi[axis] : lo[axis];
                x[a] = lo[a] + u(rng) * (hi[a] - lo[a]);
                x[b] = lo[b] + u(rng) * (hi[b] - lo[b]);
                if (!keep(x)) continue;
                Eigen::Vector3d normal = Eigen::Vector3d::Zero();
                normal[axis] = (side ? 1.0 : -1.0) * (flip ? -1.0 : 1.0);
                p.push_back(x);
                n.push_back(normal);
            }
        }
}

PointCloud cloud_of(const std::vector<Eigen::Vector3d>& p, const std::vector<Eigen::Vector3d>& n) {
    PointCloud c;
    c.points.resize(Eigen::Index(p.size()), 3);
    c.normals.resize(Eigen::Index(p.size()), 3);
    for (std::size_t i = 0; i < p.size(); ++i) {
        c.points.row(Eigen::Index(i)) = p[i].transpose();
        c.normals.row(Eigen::Index(i)) = n[i].transpose();
    }
    return c;
}

bool in_box(const Eigen::Vector3d& x, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
    return (x.array() > lo.array()).all() && (x.array() < hi.array()).all();
}

// The morphology tests' shapes, sampled every `spacing` on their faces: the block [−0.6, 0.6]³
// with a fin of half thickness `half` standing out of its +x face (the points of each box's faces
// outside the other box), or with a slot of half width `half` cut into it from above (the block's
// faces outside the slot, the slot's walls and floor inside the block, normals into the slot).
PointCloud block_with_fin(double half, double spacing, std::mt19937_64& rng) {
    const Eigen::Vector3d blo(-0.6, -0.6, -0.6), bhi(0.6, 0.6, 0.6), flo(0.6, -half, -0.3), fhi(0.95, half, 0.3);
    std::vector<Eigen::Vector3d> p, n;
    sample_box(blo, bhi, spacing, false, [&](const Eigen::Vector3d& x) { return !in_box(x, flo - Eigen::Vector3d(0.01, 0, 0), fhi); }, p, n, rng);
    sample_box(flo, fhi, spacing, false, [&](const Eigen::Vector3d& x) { return x.x() > 0.6 + 1e-9; }, p, n, rng);
    return cloud_of(p, n);
}
PointCloud block_with_slot(double half, double spacing, std::mt19937_64& rng) {
    const Eigen::Vector3d blo(-0.6, -0.6, -0.6), bhi(0.6, 0.6, 0.6), slo(-half, -0.7, 0.1), shi(half, 0.7, 0.7);
    std::vector<Eigen::Vector3d> p, n;
    sample_box(blo, bhi, spacing, false, [&](const Eigen::Vector3d& x) { return !in_box(x, slo, shi + Eigen::Vector3d(0, 0, 0.01)); }, p, n, rng);
    sample_box(slo, shi, spacing, true, [&](const Eigen::Vector3d& x) { return in_box(x, blo, bhi); }, p, n, rng);
    return cloud_of(p, n);
}

}  // namespace

TEST_CASE("Opening and closing on point clouds (PAT), without a mesh in between") {
    std::mt19937_64 rng(12);
    const double r = 0.06, spacing = 0.02;
    const GridSpec grid = GridSpec::cube(test::sized(81, 49), {{-1.1, -1.1, -1.1}, {1.1, 1.1, 1.1}});
    Points at(3, 3);
    at.row(0) << 0.8, 0, 0;  // in the fin (opening) 
    at.row(1) << 0, 0, 0;    // deep in the block
    at.row(2) << 0, 0, 0.4;  // in the slot (closing)
    {
        // A block with a fin 0.08 thick: the points of each box's faces outside the other box.
        const PointCloud cloud = block_with_fin(0.04, spacing, rng);
        const auto pat = std::make_shared<TorusField>(JetFitter().fit(cloud));
        const FieldValues before = pat->evaluate(at), after = field_opening(pat, r, grid)->evaluate(at);
        MESSAGE("opening on a cloud of " << cloud.size() << " points: fin " << before.phi[0] << " → " << after.phi[0]);
        CHECK(before.phi[0] < 0);
        CHECK(after.phi[0] > 0);
        CHECK(after.phi[1] < -0.4);
    }
    {
        // A block with a slot 0.08 wide from above: the block's faces outside the slot, the
        // slot's walls and floor inside the block (normals into the slot).
        const PointCloud cloud = block_with_slot(0.04, spacing, rng);
        const auto pat = std::make_shared<TorusField>(JetFitter().fit(cloud));
        const FieldValues before = pat->evaluate(at), after = field_closing(pat, r, grid)->evaluate(at);
        MESSAGE("closing on a cloud of " << cloud.size() << " points: slot " << before.phi[2] << " → " << after.phi[2]);
        CHECK(before.phi[2] > 0);
        CHECK(after.phi[2] < 0);
        CHECK(after.phi[1] < -0.4);
    }
}

TEST_CASE("Opening and closing of a cloud by resampling: no grid, no mesh; the block's volume kept") {
    std::mt19937_64 rng(5);
    const double r = 0.06, spacing = 0.02;
    Points at(3, 3);
    at.row(0) << 0.8, 0, 0;  // in the fin (opening)
    at.row(1) << 0, 0, 0;    // deep in the block
    at.row(2) << 0, 0, 0.4;  // in the slot (closing)
    // Volume by counting cell centers inside: cells of 0.025 (0.05 under the sanitizers) over
    // [−1.1, 1.1]³, whose faces the block's faces at ±0.6 fall on, so the count of the exact
    // block is its volume exactly.
    const int cells = test::sized(88, 44);
    const double cell = 2.2 / cells, block_volume = 1.2 * 1.2 * 1.2;
    const double c0 = -1.1 + 0.5 * cell, c1 = 1.1 - 0.5 * cell;
    const GridSpec volume_grid = GridSpec::cube(cells, {{c0, c0, c0}, {c1, c1, c1}});
    auto inside_volume = [&](const Field& f) {
        const FieldValues v = f.evaluate(volume_grid);
        return double(std::count_if(v.phi.begin(), v.phi.end(), [](float x) { return x < 0; })) * cell * cell * cell;
    };
    {
        // A block with a fin 0.05 thick (< 2r): the opening removes the fin, keeps the block.
        const PointCloud cloud = block_with_fin(0.025, spacing, rng);
        const auto pat = std::make_shared<TorusField>(JetFitter().fit(cloud));
        const FieldPtr opened = field_opening(pat, r, cloud.points);
        const FieldValues before = pat->evaluate(at), after = opened->evaluate(at);
        const double volume = inside_volume(*opened);
        MESSAGE("original: center " << before.phi[1] << ", inside volume " << inside_volume(*pat));
        MESSAGE("opening by resampling: fin " << before.phi[0] << " → " << after.phi[0] << "; inside volume " << volume
                                              << " (the block: " << block_volume << ")");
        CHECK(before.phi[0] < 0);
        CHECK(after.phi[0] > 0);
        CHECK(after.phi[1] < -0.4);
        CHECK(std::abs(volume - block_volume) <= 0.05 * block_volume);
    }
    {
        // A block with a slot 0.08 wide (< 2r) from above: the closing fills it.
        const PointCloud cloud = block_with_slot(0.04, spacing, rng);
        const auto pat = std::make_shared<TorusField>(JetFitter().fit(cloud));
        const FieldPtr closed = field_closing(pat, r, cloud.points);
        const FieldValues before = pat->evaluate(at), after = closed->evaluate(at);
        const double volume = inside_volume(*closed);
        MESSAGE("original: center " << before.phi[1] << ", inside volume " << inside_volume(*pat));
        MESSAGE("closing by resampling: slot " << before.phi[2] << " → " << after.phi[2] << "; inside volume " << volume
                                               << " (the block: " << block_volume << ")");
        CHECK(before.phi[2] > 0);
        CHECK(after.phi[2] < 0);
        CHECK(after.phi[1] < -0.4);
        CHECK(std::abs(volume - block_volume) <= 0.05 * block_volume);
    }
    {
        // The error resampling adds: a sphere (radius 0.5, exact distance) is its own opening and
        // closing by r = 0.1; 4,000 seeds on it (spacing ≈ 0.028).
        const auto sphere = std::make_shared<SphereField>(Eigen::Vector3d::Zero(), 0.5);
        Points seeds(4000, 3);
        for (int i = 0; i < 4000; ++i) {  // a Fibonacci sphere
            const double z = 1 - (i + 0.5) / 2000.0, rho = std::sqrt(1 - z * z), a = 2.399963229728653 * i;
            seeds.row(i) << 0.5 * rho * std::cos(a), 0.5 * rho * std::sin(a), 0.5 * z;
        }
        const Points x = random_points(4000, 0.9, 3);
        for (const FieldPtr& f : {field_opening(sphere, 0.1, seeds), field_closing(sphere, 0.1, seeds)}) {
            const FieldValues v = f->evaluate(x);
            double mean = 0, worst = 0, near = 0;
            std::size_t near_count = 0;
            for (Eigen::Index i = 0; i < x.rows(); ++i) {
                const double e = std::abs(v.phi[std::size_t(i)] - sphere->exact(x.row(i).transpose()));
                mean += e / double(x.rows());
                worst = std::max(worst, e);
                if (std::abs(sphere->exact(x.row(i).transpose())) < 0.1) near += e, ++near_count;
            }
            MESSAGE("a sphere's opening, then closing, by resampling: mean error " << mean << ", within 0.1 of the surface "
                                  << near / double(near_count) << ", largest " << worst);
            CHECK(mean < 0.01);
            CHECK(worst < 0.05);
        }
    }
    // Bad input.
    const auto flat = std::make_shared<SphereField>(Eigen::Vector3d::Zero(), 0.5, /*gradient=*/false);
    CHECK_THROWS_AS(field_opening(flat, r, at), Error);
    CHECK_THROWS_AS(field_closing(nullptr, r, at), Error);
    CHECK_THROWS_AS(field_opening(std::make_shared<SphereField>(Eigen::Vector3d::Zero(), 0.5), r, Points(0, 3)), Error);
    // An opening wider than the shape erodes it all: outside everywhere.
    const auto small = std::make_shared<SphereField>(Eigen::Vector3d::Zero(), 0.05);
    Points on(4, 3);
    on << 0.05, 0, 0, -0.05, 0, 0, 0, 0.05, 0, 0, 0, -0.05;
    const FieldValues gone = field_opening(small, 0.2, on)->evaluate(at);
    CHECK(std::all_of(gone.phi.begin(), gone.phi.end(), [](float v) { return v > 0; }));
}

TEST_CASE("redistance: the exact distance to the zero set, the signs kept") {
    // A sphere's distance squared-and-scaled (same zero set, wrong magnitudes) comes back as the
    // distance to marching cubes' mesh of its zero set: within a fraction of a cell of the true one.
    const GridSpec g = GridSpec::cube(41, {{-1, -1, -1}, {1, 1, 1}});
    const Points nodes = g.nodes();
    std::vector<float> v(g.node_count());
    for (Eigen::Index i = 0; i < nodes.rows(); ++i) v[std::size_t(i)] = float(3 * (nodes.row(i).squaredNorm() - 0.25));
    const std::vector<float> d = redistance(g, v);
    const double cell = 2.0 / 40;
    for (Eigen::Index i = 0; i < nodes.rows(); ++i) CHECK(std::abs(d[std::size_t(i)] - (nodes.row(i).norm() - 0.5)) < 0.1 * cell);
    // No zero set: ± the diagonal.
    const std::vector<float> far = redistance(g, std::vector<float>(g.node_count(), 1.0f));
    CHECK(far[0] == doctest::Approx(g.box.diagonal()));
}

TEST_CASE("gsd field: an expression over meshes and grids, and its errors") {
    ScratchDir dir("field");
    const std::string s = dir.file("s.obj"), t = dir.file("t.obj");
    REQUIRE(run_cli("mesh sphere -r 24 -o " + s).exit_code == 0);
    REQUIRE(run_cli("mesh torus -r 24 -o " + t).exit_code == 0);
    const std::string bounds = " --grid 12 --bounds -1.5 -1.5 -1.5 1.5 1.5 1.5 --device cpu ";
    REQUIRE(run_cli("sdf " + s + bounds + "-o " + dir.file("s.npy")).exit_code == 0);
    REQUIRE(run_cli("sdf " + t + bounds + "-o " + dir.file("t.npy")).exit_code == 0);
    const auto r = run_cli("field \"smooth_union(" + dir.file("s.npy") + ", offset(" + t + ", 0.05), 0.1)\"" + bounds + "-o " +
                           dir.file("u.npy") + " --gradient " + dir.file("g.npy"));
    REQUIRE_MESSAGE(r.exit_code == 0, r.output);
    const auto phi_s = io::read_npy(dir.file("s.npy")).data, phi_t = io::read_npy(dir.file("t.npy")).data;
    const auto u = io::read_npy(dir.file("u.npy"));
    REQUIRE(u.size() == phi_s.size());
    CHECK(io::read_npy(dir.file("g.npy")).size() == 3 * u.size());
    for (std::size_t i = 0; i < u.size(); ++i) {
        const double x = phi_s[i], y = phi_t[i] - 0.05, h = std::max(0.1 - std::abs(x - y), 0.0);
        CHECK(u.data[i] == doctest::Approx(std::min(x, y) - h * h / 0.4).epsilon(1e-5));
    }
    // Errors say where and what.
    const auto unknown = run_cli("field \"blend(" + s + ", " + t + ")\"" + bounds + "-o " + dir.file("x.npy"));
    CHECK(unknown.exit_code == 1);
    CHECK(unknown.output.find("at character 1") != std::string::npos);
    CHECK(unknown.output.find("unknown operator 'blend'") != std::string::npos);
    const auto unclosed = run_cli("field \"union(" + s + ", " + t + "\"" + bounds + "-o " + dir.file("x.npy"));
    CHECK(unclosed.exit_code == 1);
    CHECK(unclosed.output.find("expected ',' or ')'") != std::string::npos);
    CHECK(run_cli("field \"offset(0.1, " + s + ")\"" + bounds + "-o " + dir.file("x.npy")).output.find("takes a field here") !=
          std::string::npos);
    CHECK(run_cli("field \"union(" + s + ", " + dir.file("missing.obj") + ")\"" + bounds + "-o " + dir.file("x.npy")).exit_code == 1);
    std::string deep = s;
    for (int k = 0; k < 100; ++k) deep = "offset(" + deep + ", 0.001)";
    const auto too_deep = run_cli("field \"" + deep + "\"" + bounds + "-o " + dir.file("x.npy"));
    CHECK(too_deep.exit_code == 1);
    CHECK(too_deep.output.find("nested deeper than 64") != std::string::npos);
    CHECK_FALSE(test::file_exists(dir.file("x.npy")));
    // The same expression rendered (gsd render --expr), and a bad one refused before any work.
    const auto rendered = run_cli("render --expr \"smooth_union(" + dir.file("s.npy") + ", offset(" + t + ", 0.05), 0.1)\" --size 48 36 "
                                  "--device cpu -o " + dir.file("u.png"));
    REQUIRE_MESSAGE(rendered.exit_code == 0, rendered.output);
    CHECK(test::file_exists(dir.file("u.png")));
    CHECK(run_cli("render --expr \"union(" + s + "\" -o " + dir.file("x.png")).exit_code == 1);
    CHECK(run_cli("render " + s + " --expr \"union(" + s + ", " + t + ")\" -o " + dir.file("x.png")).exit_code == 2);
}

#ifdef GSD_HAVE_VULKAN
#include <gsd/vulkan.hpp>

#include "gpu/field_device.hpp"

namespace {

// A composite of every kind of leaf: PAT (a device program), a mesh's exact distance and a test
// sphere (none: evaluated on the CPU between copies), through every operator.
struct MixedComposite {
    FieldPtr pat, mesh, sphere, composite;
    MixedComposite() {
        const PointCloud cloud = shapes::torus(Eigen::Vector3d::Zero(), 0.5, 0.2)->sample(3000, 4);
        pat = std::make_shared<TorusField>(JetFitter(JetFitterOptions{}).fit(cloud));
        mesh = std::make_shared<MeshSdfField>(shapes::mesh(*shapes::sphere(Eigen::Vector3d(0.3, 0.2, 0.1), 0.35), 24));
        sphere = std::make_shared<SphereField>(Eigen::Vector3d(-0.4, 0, 0.1), 0.3);
        composite = field_difference(field_union(pat, field_offset(mesh, 0.05), 0.1), field_shell(sphere, 0.08), 0.05);
        composite = field_intersection(composite, field_offset(sphere, 0.9));  // a fourth leaf: the sphere again
    }
};

}  // namespace

TEST_CASE("a composite on a device: its leaves into device buffers, one pass combining them, equal to the CPU") {
    const auto ctx = gpu::select("gpu").context;
    REQUIRE(ctx);
    const MixedComposite m;
    REQUIRE(m.composite->device_program() != nullptr);
    CHECK(m.mesh->device_program() == nullptr);
    // No leaf with a device program: nothing to gain on a device, so no program.
    CHECK(field_union(m.mesh, m.sphere)->device_program() == nullptr);
    const Points x = random_points(3000, 1.0, 17);
    for (bool gradient : {false, true}) {
        CAPTURE(gradient);
        const FieldValues cpu = m.composite->evaluate(x, gradient);
        const FieldValues dev = gpu::evaluate_points(*m.composite, ctx, x, gradient);
        CHECK(dev.device != "cpu");
        double worst = 0;
        std::size_t turned = 0;  // queries where float32 picked the other operand of a kink
        for (std::size_t i = 0; i < cpu.phi.size(); ++i) {
            worst = std::max(worst, double(std::abs(cpu.phi[i] - dev.phi[i])));
            if (!gradient) continue;
            double g = 0;
            for (std::size_t a = 0; a < 3; ++a) g = std::max(g, double(std::abs(cpu.gradient[3 * i + a] - dev.gradient[3 * i + a])));
            turned += g > 1e-3;
        }
        MESSAGE("largest |φ_device − φ_cpu| " << worst << (gradient ? "; gradients off by > 1e-3 at " + std::to_string(turned) : std::string()));
        CHECK(worst <= 1e-5 * 2 * std::sqrt(3.0));
        CHECK(turned <= cpu.phi.size() / 200);
    }
    // A field without a program through evaluate_into: the CPU's values at the float32 queries, copied in.
    const Points xf = x.cast<float>().cast<double>();
    const FieldValues cpu = m.mesh->evaluate(xf), dev = gpu::evaluate_points(*m.mesh, ctx, x, false);
    CHECK(std::equal(cpu.phi.begin(), cpu.phi.end(), dev.phi.begin()));
    // A gradient asked of a composite with a leaf that has none.
    const auto flat = std::make_shared<SphereField>(Eigen::Vector3d::Zero(), 0.5, /*gradient=*/false);
    CHECK_THROWS_WITH_AS(gpu::evaluate_points(*field_union(m.pat, flat), ctx, x, true), doctest::Contains("gradient"), Error);
}

TEST_CASE("gsd field --device gpu combines a composite on the device: the CPU's values") {
    REQUIRE(gpu::select("gpu").context);
    ScratchDir dir("field-device");
    const std::string cloud = dir.file("torus.ply"), tori = dir.file("torus.tori");
    REQUIRE(run_cli("sample torus -n 3000 -o " + cloud).exit_code == 0);
    REQUIRE(run_cli("pat fit " + cloud + " -o " + tori).exit_code == 0);
    const std::string expr = " \"smooth_union(offset(" + tori + ", 0.02), shell(" + tori + ", 0.05), 0.1)\" --grid 16 ";
    const auto cpu = run_cli("-v field" + expr + "--device cpu -o " + dir.file("cpu.npy"));
    const auto dev = run_cli("-v field" + expr + "--device gpu -o " + dir.file("gpu.npy"));
    REQUIRE_MESSAGE(cpu.exit_code == 0, cpu.output);
    REQUIRE_MESSAGE(dev.exit_code == 0, dev.output);
    CHECK(dev.output.find("points on cpu") == std::string::npos);  // "-v": where it was evaluated
    const auto a = io::read_npy(dir.file("cpu.npy")), b = io::read_npy(dir.file("gpu.npy"));
    REQUIRE(a.size() == b.size());
    double worst = 0;
    for (std::size_t i = 0; i < a.size(); ++i) worst = std::max(worst, double(std::abs(a.data[i] - b.data[i])));
    MESSAGE("largest |φ_gpu − φ_cpu| over 16³: " << worst);
    CHECK(worst < 1e-5);
}

TEST_CASE("render_field of a composite draws the same picture on the device as on the CPU") {
    REQUIRE(gpu::select("gpu").context);
    const MixedComposite m;
    FieldRenderOptions o;
    o.width = 96;
    o.height = 72;
    o.supersample = 1;
    o.eye = Eigen::Vector3d(1.2, 1.4, 2.0);
    const Box box{{-1, -1, -1}, {1, 1, 1}};
    o.device = "cpu";
    const RenderedField cpu = render_field(*m.composite, box, o);
    o.device = "gpu";
    const RenderedField dev = render_field(*m.composite, box, o);
    CHECK(dev.device != "cpu");
    REQUIRE(cpu.depth.size() == dev.depth.size());
    std::size_t differ = 0, hits = 0;
    for (std::size_t p = 0; p < cpu.depth.size(); ++p) {
        differ += (cpu.depth[p] >= 0) != (dev.depth[p] >= 0);
        hits += cpu.depth[p] >= 0;
    }
    MESSAGE("hit masks differ at " << differ << " of " << cpu.depth.size() << " pixels (" << hits << " hits on the CPU); device: "
                                   << dev.device);
    CHECK(hits > 500);
    CHECK(double(differ) <= 1e-3 * double(cpu.depth.size()));
}
#endif
