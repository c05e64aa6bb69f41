// The field renderer (gsd/render.hpp): the CPU march against ray–sphere intersections, the
// shaders against the CPU reference on a Vulkan device (lavapipe in CI), option errors.
#include <doctest/doctest.h>

#include <gsd/field_algebra.hpp>
#include <gsd/gpu.hpp>
#include <gsd/io.hpp>
#include <gsd/pat.hpp>
#include <gsd/render.hpp>
#include <gsd/shapes.hpp>

#include "render/render.hpp"
#include "support.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <optional>
#include <string>
#include <utility>
#include <vector>

using namespace gsd;

namespace {

constexpr double kRadius = 0.6;

// The exact signed distance of the sphere of radius kRadius at the origin, on a grid.
std::vector<float> sphere_grid(const GridSpec& g) {
    std::vector<float> v(g.node_count());
    for (int i = 0; i < g.nx; ++i)
        for (int j = 0; j < g.ny; ++j)
            for (int k = 0; k < g.nz; ++k)
                v[(std::size_t(i) * std::size_t(g.ny) + std::size_t(j)) * std::size_t(g.nz) + std::size_t(k)] =
                    float(g.node(i, j, k).norm() - kRadius);
    return v;
}

// Where the ray hits the sphere (−1: it misses).
double sphere_hit(const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
    const double b = d.dot(o), c = o.squaredNorm() - kRadius * kRadius, disc = b * b - c;
    return disc < 0 ? -1.0 : -b - std::sqrt(disc);
}

struct Agreement {
    std::size_t pixels = 0, mask_differs = 0, both_hit = 0;
    std::vector<double> depth_errors;  // where both hit
    double mask_fraction() const { return double(mask_differs) / double(pixels); }
    double depth_quantile(double q) const {
        std::vector<double> e = depth_errors;
        std::sort(e.begin(), e.end());
        return e.empty() ? 0.0 : e[std::min(e.size() - 1, std::size_t(q * double(e.size())))];
    }
};

Agreement against_sphere(const RenderedField& r) {
    Agreement a;
    for (int y = 0; y < r.render_height; ++y)
        for (int x = 0; x < r.render_width; ++x) {
            const double t = r.depth[std::size_t(y) * std::size_t(r.render_width) + std::size_t(x)];
            const double exact = sphere_hit(r.camera.eye, r.camera.ray(x, y, r.render_width, r.render_height));
            ++a.pixels;
            if ((t >= 0) != (exact >= 0)) ++a.mask_differs;
            else if (t >= 0) a.depth_errors.push_back(std::abs(t - exact));
        }
    a.both_hit = a.depth_errors.size();
    return a;
}

Agreement between(const RenderedField& a, const RenderedField& b) {
    REQUIRE(a.depth.size() == b.depth.size());
    Agreement g;
    for (std::size_t p = 0; p < a.depth.size(); ++p) {
        ++g.pixels;
        if ((a.depth[p] >= 0) != (b.depth[p] >= 0)) ++g.mask_differs;
        else if (a.depth[p] >= 0) g.depth_errors.push_back(std::abs(double(a.depth[p]) - double(b.depth[p])));
    }
    g.both_hit = g.depth_errors.size();
    return g;
}

// Share of image bytes that differ by more than `tol` levels.
double image_difference(const Image& a, const Image& b, int tol) {
    REQUIRE(a.rgb.size() == b.rgb.size());
    std::size_t over = 0;
    for (std::size_t i = 0; i < a.rgb.size(); ++i) over += std::abs(int(a.rgb[i]) - int(b.rgb[i])) > tol;
    return double(over) / double(a.rgb.size());
}

FittedTori fitted_sphere(std::size_t n) {
    const PointCloud cloud = shapes::sphere({0, 0, 0}, kRadius)->sample(n, 3);
    return JetFitter().fit(cloud);
}

FieldRenderOptions small(const std::string& device) {
    FieldRenderOptions o;
    o.width = 64;
    o.height = 48;
    o.device = device;
    return o;
}

const Box kBox{{-1, -1, -1}, {1, 1, 1}};

// Sets environment variables for its lifetime and restores what they were, even when a
// REQUIRE or an exception leaves the scope early.
class ScopedEnv {
public:
    explicit ScopedEnv(std::vector<std::pair<const char*, const char*>> vars) {
        for (const auto& [name, value] : vars) {
            const char* old = std::getenv(name);
            saved_.push_back({name, old ? std::optional<std::string>(old) : std::nullopt});
            setenv(name, value, 1);
        }
    }
    ~ScopedEnv() {
        for (const auto& [name, old] : saved_) {
            if (old) setenv(name.c_str(), old->c_str(), 1);
            else unsetenv(name.c_str());
        }
    }
    ScopedEnv(const ScopedEnv&) = delete;
    ScopedEnv& operator=(const ScopedEnv&) = delete;

private:
    std::vector<std::pair<std::string, std::optional<std::string>>> saved_;
};

// φ = +0.5 for x < 0.45 and −0.5 beyond: a sheet where the sign jumps, with |φ| large on both
// sides, so the cells on either side of it are empty (of opposite signs).
class JumpField final : public Field {
public:
    FieldValues evaluate(PointsView q, bool with_gradient, const ProgressFn&) const override {
        refuse_gradient(with_gradient, "JumpField");
        FieldValues v;
        for (Eigen::Index i = 0; i < q.rows(); ++i) v.phi.push_back(q(i, 0) < 0.45 ? 0.5f : -0.5f);
        v.device = "cpu";
        return v;
    }
    FieldValues evaluate(const GridSpec& g, bool with_gradient, const ProgressFn& progress) const override {
        const Points x = g.nodes();
        return evaluate(PointsView(x), with_gradient, progress);
    }
    bool has_gradient() const override { return false; }
};

}  // namespace

TEST_CASE("render: a grid of the sphere's exact distance is hit where the rays meet the sphere") {
    const GridSpec g = GridSpec::cube(48, kBox);
    const std::vector<float> phi = sphere_grid(g);
    FieldRenderOptions o = small("cpu");
    o.view_from = {0.3, -0.5, 1.0};
    const RenderedField r = render_field(g, phi, o);
    CHECK(r.device == "cpu");
    CHECK(r.image.width == 64);
    CHECK(r.image.height == 48);
    const Agreement a = against_sphere(r);
    MESSAGE("mask differs at " << a.mask_differs << " of " << a.pixels << " pixels; depth error median "
                               << a.depth_quantile(0.5) << ", max " << a.depth_quantile(1.0));
    REQUIRE(a.both_hit > 500);  // the sphere fills a good part of the frame
    CHECK(a.mask_fraction() <= 0.01);
    // Trilinear interpolation of |x| − R is off by about h²/(8R) = 4e-4 near the sphere; the
    // depth error grows toward the silhouette, where rays graze the surface.
    CHECK(a.depth_quantile(0.5) <= 1e-3);
    CHECK(a.depth_quantile(0.95) <= 2e-3);
    CHECK(r.hit_fraction == doctest::Approx(double(a.both_hit + a.mask_differs) / double(a.pixels)).epsilon(0.05));
}

TEST_CASE("render: PAT of a sampled sphere shows the sphere") {
    const TorusField field(fitted_sphere(3000), BlendOptions{});
    FieldRenderOptions o = small("cpu");
    const RenderedField r = render_field(field, kBox, o);
    const Agreement a = against_sphere(r);
    MESSAGE("mask differs at " << a.mask_differs << " of " << a.pixels << " pixels; depth error median "
                               << a.depth_quantile(0.5) << ", 95% " << a.depth_quantile(0.95));
    REQUIRE(a.both_hit > 500);
    CHECK(a.mask_fraction() <= 0.02);
    CHECK(a.depth_quantile(0.95) <= 5e-3);
}

// Empty-space skipping (FieldRenderOptions::skip_empty_space) lets rays cross cells whose
// corners say they hold no surface, by the march's own trust in |φ| as a distance: the picture
// must be the plain march's, up to the rays it steps differently near a surface.
TEST_CASE("render: skipping empty space draws what the plain march draws") {
    auto same_picture = [](const char* what, const RenderedField& skip, const RenderedField& plain, double depth_tol) {
        // Cells were found empty (and not by the plain march): there was something to skip.
        CHECK(skip.empty_cells > 0);
        CHECK(plain.empty_cells == 0);
        const Agreement a = between(skip, plain);
        const double image_off = image_difference(skip.image, plain.image, 8);
        MESSAGE(std::string(what) << ": mask differs at " << a.mask_differs << " of " << a.pixels << " pixels; depth 99% "
                     << a.depth_quantile(0.99) << "; image bytes off by > 8: " << image_off);
        REQUIRE(a.both_hit > 300);
        CHECK(a.mask_fraction() <= 0.005);
        CHECK(a.depth_quantile(0.99) <= depth_tol);
        CHECK(image_off <= 0.01);
    };
    FieldRenderOptions skip = small("cpu"), plain = small("cpu");
    plain.skip_empty_space = false;
    SUBCASE("PAT of a sampled torus") {
        const PointCloud cloud = shapes::torus({0, 0, 0}, 0.55, 0.2)->sample(2500, 5);
        const TorusField field(JetFitter().fit(cloud), BlendOptions{});
        skip.view_from = plain.view_from = {0.2, 1.0, 0.7};
        same_picture("torus", render_field(field, kBox, skip), render_field(field, kBox, plain), 1e-3);
    }
    SUBCASE("PAT of the demo cloud (holes, noise): the blend's creases and the closed holes stay") {
        const PointCloud cloud = io::read_point_cloud(std::string(GSD_SOURCE_DIR) + "/data/demo/torus-holey.ply");
        const TorusField field(JetFitter().fit(cloud), BlendOptions{});
        const Box box = padded_cube(bounding_box(cloud.points));
        same_picture("demo cloud", render_field(field, box, skip), render_field(field, box, plain), 1e-3 * box.diagonal());
    }
    SUBCASE("a composite field (the wavefront march), against the exact sphere too") {
        const GridSpec g = GridSpec::cube(48, kBox);
        const auto sphere = std::make_shared<GridField>(g, sphere_grid(g));
        const FieldPtr both = field_union(sphere, sphere);  // the sphere again, as a composite
        skip.view_from = plain.view_from = {0.3, -0.5, 1.0};
        const RenderedField r = render_field(*both, kBox, skip);
        // The march takes a hit anywhere |φ| is under its tolerance (1e-4 of the box diagonal):
        // two marches that step differently, as they do once the skip starts at the box's face,
        // may stop on either side of the surface, twice that apart along a ray facing it.
        same_picture("union of a sphere with itself", r, render_field(*both, kBox, plain), 2e-4 * kBox.diagonal());
        const Agreement a = against_sphere(r);
        CHECK(a.mask_fraction() <= 0.01);
        CHECK(a.depth_quantile(0.5) <= 1e-3);
    }
    SUBCASE("a step into an empty cell of the other sign still sees the crossing") {
        // Rays along +x: the march steps from the cells before the sheet into the empty cells
        // beyond it. Skipping on from there, as a skip into cells of any sign would, loses the
        // sheet; its sign against the last sample's must stop the skip. (A far, narrow camera:
        // every ray leaves the box through its far face, well past the sheet. A ray leaving
        // through a side within a step of the sheet would miss it in the plain march, which
        // does not sample the box's exit.)
        const JumpField jump;
        skip.eye = plain.eye = Eigen::Vector3d(-20, 0, 0);
        skip.fov_degrees = plain.fov_degrees = 4;
        const RenderedField r = render_field(jump, kBox, skip), p = render_field(jump, kBox, plain);
        same_picture("a jump of sign at x = 0.45", r, p, 1e-3);
        CHECK(r.hit_fraction > 0.9);  // the sheet fills the frame
    }
}

// A ray starts its march on the box's face, where the empty-space grid's cell index is 0 or n
// up to rounding: the skip must start there (it did not, for every ray entering through a far
// face and some through a near one, and such rays sampled φ at the box's face first).
TEST_CASE("render: a ray starting on the box's face skips the empty cells from there") {
    render::EmptySpace e;  // 4³ cells of side 0.5 over [−1, 1]³, all empty and positive
    e.lo = Eigen::Vector3d(-1, -1, -1);
    e.h = 0.5;
    e.n[0] = e.n[1] = e.n[2] = 4;
    e.bits.assign(2 * e.words(), 0u);
    for (std::size_t c = 0; c < e.cell_count(); ++c) e.bits[c >> 5] |= 1u << (c & 31);
    for (int a = 0; a < 3; ++a)
        for (const double side : {-1.0, 1.0}) {
            Eigen::Vector3d o(0.1, -0.3, 0.2), d = Eigen::Vector3d::Zero();
            o[a] = side;
            d[a] = -side;  // inward
            CAPTURE(a);
            CAPTURE(side);
            CHECK(e.skip(o, d, 0.0, 0) >= 2.0);  // across the whole grid
            o[a] = side * (1 + 1e-12);            // rounded a hair outside
            CHECK(e.skip(o, d, 0.0, 0) >= 2.0);
            o[a] = side * 1.01;  // truly outside: no skip
            CHECK(e.skip(o, d, 0.0, 0) == 0.0);
        }
}

// The wavefront march hands its calls of at most kFewPoints points (a band's last rays) to the
// field's host evaluator where there is one: the same field, so the same picture, and the
// device's name stays the one its other calls gave.
TEST_CASE("render: the wavefront's last few rays go to the host evaluator, the picture unchanged") {
    auto sphere = [](const Points& x, bool gradient, const char* device) {
        FieldValues v;
        v.device = device;
        for (Eigen::Index i = 0; i < x.rows(); ++i) {
            const Eigen::Vector3d p = x.row(i).transpose();
            v.phi.push_back(float(p.norm() - 0.6));
            if (gradient)
                for (int a = 0; a < 3; ++a) v.gradient.push_back(float(p[a] / std::max(p.norm(), 1e-12)));
        }
        return v;
    };
    FieldRenderOptions o = small("cpu");
    o.width = 96;
    o.height = 72;
    const render::Camera cam = render::make_camera(kBox, o, o.width, o.height);
    const render::March m = render::make_march(kBox, o);
    std::size_t device_calls = 0, few_calls = 0, largest_few = 0, smallest_device = SIZE_MAX;
    render::PointEvaluator plain;
    plain.has_gradient = true;
    plain.evaluate = [&](const Points& x, bool gradient) { return sphere(x, gradient, "the device"); };
    render::PointEvaluator tail = plain;
    tail.shares_cores = true;
    tail.evaluate = [&](const Points& x, bool gradient) {
        ++device_calls;
        smallest_device = std::min(smallest_device, std::size_t(x.rows()));
        return sphere(x, gradient, "the device");
    };
    tail.evaluate_few = [&](const Points& x, bool gradient) {
        few_calls += x.rows() > 0;
        largest_few = std::max(largest_few, std::size_t(x.rows()));
        return sphere(x, gradient, "cpu");
    };
    std::string plain_device, tail_device;
    const std::vector<float> a = render::march_wavefront(plain, cam, m, plain_device, {});
    const std::vector<float> b = render::march_wavefront(tail, cam, m, tail_device, {});
    CHECK(few_calls > 0);
    CHECK(largest_few <= render::PointEvaluator::kFewPoints);
    CHECK(smallest_device > render::PointEvaluator::kFewPoints);  // (∇φ at the hits: ~450 points)
    CHECK(tail_device == "the device");
    CHECK(a == b);
    std::size_t hit = 0;
    for (std::size_t p = 0; p < a.size(); p += 4) hit += a[p] > 0;
    CHECK(hit > 200);  // the sphere is in the picture
}

TEST_CASE("render: shading faces the light, a color field colors the surface") {
    const GridSpec g = GridSpec::cube(40, kBox);
    const std::vector<float> phi = sphere_grid(g);
    // Color by x: blue on the left of the picture (x < 0 seen from +z), red on the right.
    std::vector<float> x_values(g.node_count());
    for (int i = 0; i < g.nx; ++i)
        for (int j = 0; j < g.ny; ++j)
            for (int k = 0; k < g.nz; ++k)
                x_values[(std::size_t(i) * std::size_t(g.ny) + std::size_t(j)) * std::size_t(g.nz) + std::size_t(k)] =
                    float(g.node(i, j, k).x());
    FieldRenderOptions o = small("cpu");
    o.view_from = {0, 0, 1};
    o.color_grid = &g;
    o.color_values = &x_values;
    const RenderedField r = render_field(g, phi, o);
    double blue_minus_red[2] = {0, 0};  // left, right halves of the hit pixels
    for (int y = 0; y < r.image.height; ++y)
        for (int x = 0; x < r.image.width; ++x) {
            if (r.depth[std::size_t(y) * std::size_t(r.image.width) + std::size_t(x)] < 0) continue;
            const std::uint8_t* c = &r.image.rgb[3 * (std::size_t(y) * std::size_t(r.image.width) + std::size_t(x))];
            blue_minus_red[x < r.image.width / 2 ? 0 : 1] += double(c[2]) - double(c[0]);
        }
    CHECK(blue_minus_red[0] > 0);
    CHECK(blue_minus_red[1] < 0);
    // Uncolored: the lit side (the light sits up and to the left of the camera) is brighter.
    o.color_grid = nullptr;
    o.color_values = nullptr;
    const RenderedField plain = render_field(g, phi, o);
    auto brightness = [&](int x, int y) { return int(plain.image.rgb[3 * (std::size_t(y) * 64 + std::size_t(x)) + 1]); };
    CHECK(brightness(26, 18) > brightness(38, 30));
    CHECK(brightness(0, 0) == 255);  // background
}

TEST_CASE("render: an explicit camera position looks at the center from there") {
    const GridSpec g = GridSpec::cube(48, kBox);
    const std::vector<float> phi = sphere_grid(g);
    FieldRenderOptions o = small("cpu");
    o.width = 65;  // odd: the middle pixel's ray goes through the center
    o.height = 49;
    o.eye = Eigen::Vector3d(0, 0, 3);
    const RenderedField r = render_field(g, phi, o);
    CHECK((r.camera.eye - Eigen::Vector3d(0, 0, 3)).norm() < 1e-12);
    CHECK(r.depth[24 * 65 + 32] == doctest::Approx(3 - kRadius).epsilon(1e-3));
    const Agreement a = against_sphere(r);
    CHECK(a.mask_fraction() <= 0.01);
    o.eye = Eigen::Vector3d(0, 5, 0);  // straight above the center, along up
    CHECK_THROWS_AS(render_field(g, phi, o), Error);
}

TEST_CASE("render: supersampling averages the rays of each pixel") {
    const GridSpec g = GridSpec::cube(32, kBox);
    const std::vector<float> phi = sphere_grid(g);
    FieldRenderOptions o = small("cpu");
    o.supersample = 2;
    const RenderedField r = render_field(g, phi, o);
    CHECK(r.image.width == 64);
    CHECK(r.render_width == 128);
    CHECK(r.depth.size() == std::size_t(128 * 96));
    // Some pixels on the silhouette are partly covered: neither background nor surface.
    bool mixed = false;
    for (int y = 0; y < 48 && !mixed; ++y)
        for (int x = 0; x < 64 && !mixed; ++x) {
            int hits = 0;
            for (int dy = 0; dy < 2; ++dy)
                for (int dx = 0; dx < 2; ++dx) hits += r.depth[std::size_t(2 * y + dy) * 128 + std::size_t(2 * x + dx)] >= 0;
            mixed = hits == 2;
        }
    CHECK(mixed);
}

TEST_CASE("render: bad options and inputs name what is wrong") {
    const GridSpec g = GridSpec::cube(8, kBox);
    const std::vector<float> phi = sphere_grid(g);
    auto refused = [&](FieldRenderOptions o, const std::string& where) {
        o.device = "cpu";
        try {
            (void)render_field(g, phi, o);
            FAIL("accepted: " << where);
        } catch (const Error& e) {
            CHECK(e.where() == where);
        }
    };
    FieldRenderOptions o;
    o.width = 0;
    refused(o, "FieldRenderOptions::width");
    o = {};
    o.supersample = 9;
    refused(o, "FieldRenderOptions::supersample");
    o = {};
    o.view_from = {0, 1, 0};  // parallel to up
    refused(o, "FieldRenderOptions::up");
    o = {};
    o.step_scale = 1.5;
    refused(o, "FieldRenderOptions::step_scale");
    o = {};
    o.fov_degrees = std::nan("");
    refused(o, "FieldRenderOptions::fov_degrees");
    o = {};
    const std::vector<float> few(10, 0.0f);
    o.color_grid = &g;
    o.color_values = &few;
    refused(o, "FieldRenderOptions::color_values");
    std::vector<float> with_nan = phi;
    with_nan[3] = std::nanf("");
    CHECK_THROWS_AS(render_field(g, with_nan, small("cpu")), Error);
    CHECK_THROWS_AS(render_field(g, std::vector<float>(5, 0.0f), small("cpu")), Error);
    const TorusField field(fitted_sphere(500), BlendOptions{});
    CHECK_THROWS_AS(render_field(field, Box{{0, 0, 0}, {0, 1, 1}}, small("cpu")), Error);
}

#ifdef GSD_HAVE_VULKAN
namespace {

// Renders on the CPU and on the device (lavapipe in CI) and holds the device to the CPU: the
// hit masks, the depths (to `depth_tol` at the 99th percentile) and the pictures.
template <class Render>
void device_matches_cpu(const char* what, FieldRenderOptions o, double depth_tol, const Render& render) {
    o.device = "cpu";
    const RenderedField cpu = render(o);
    o.device = "gpu";
    const RenderedField gpu = render(o);
    CHECK(gpu.device != "cpu");
    const Agreement a = between(cpu, gpu);
    const double image_off = image_difference(cpu.image, gpu.image, 8);
    MESSAGE(std::string(what) << ": mask differs at " << a.mask_differs << " of " << a.pixels << " pixels; depth 99% "
                 << a.depth_quantile(0.99) << ", max " << a.depth_quantile(1.0) << "; image bytes off by > 8: " << image_off);
    REQUIRE(a.both_hit > 300);
    CHECK(a.mask_fraction() <= 0.01);
    CHECK(a.depth_quantile(0.99) <= depth_tol);
    CHECK(image_off <= 0.01);
    // Rays in chunks of 777 (not a divisor of the image) instead of one: the same picture.
    o.chunk_size = 777;
    const RenderedField chunked = render(o);
    // Rays are independent, but a subgroup's rays share its neighbor walks, so the sums' terms
    // (and the last bits of a normal) can come in another order, and on lavapipe the rays that
    // pass its loop limit with their subgroup are marched on the CPU instead: the same hits,
    // depths within the tolerance (most of them equal), and pixels that differ by more than 8
    // no more often than between the devices.
    const Agreement c = between(chunked, gpu);
    std::size_t equal = 0;
    for (std::size_t p = 0; p < gpu.depth.size(); ++p) equal += chunked.depth[p] == gpu.depth[p];
    MESSAGE(std::string(what) << ", rays in chunks of 777 against one chunk: depths equal at " << equal << " of "
                 << gpu.depth.size() << " pixels, max difference " << c.depth_quantile(1.0));
    CHECK(c.mask_differs == 0);
    CHECK(c.depth_quantile(1.0) <= depth_tol);
    CHECK(double(equal) >= 0.9 * double(gpu.depth.size()));
    const double chunk_off = image_difference(chunked.image, gpu.image, 8);
    MESSAGE(std::string(what) << ", rays in chunks of 777 against one chunk: image bytes off by > 8: " << chunk_off);
    CHECK(chunk_off <= 0.01);
}

}  // namespace

TEST_CASE("render on the device matches the CPU reference (PAT, a grid), validation clean") {
    const gpu::Selection sel = gpu::select("gpu");
    REQUIRE(sel.context);  // lavapipe in CI
    const std::uint64_t errors_before = gpu::validation_error_count();

    // A PAT torus on the device beside the CPU, with the environment variables `vars` (name,
    // value) set for the device's run. Software devices march a blend as a wavefront of
    // blend_eval dispatches, GPUs in render_pat (render_gpu.cpp); GSD_RENDER_MARCH=kernel runs
    // render_pat here too.
    auto torus_pat = [&](const char* label, std::vector<std::pair<const char*, const char*>> vars) {
        const ScopedEnv env(std::move(vars));
        const PointCloud cloud = shapes::torus({0, 0, 0}, 0.55, 0.2)->sample(2500, 5);
        const TorusField field(JetFitter().fit(cloud), BlendOptions{});
        FieldRenderOptions o = small("cpu");
        o.view_from = {0.2, 1.0, 0.7};
        device_matches_cpu(label, o, 1e-3, [&](const FieldRenderOptions& r) { return render_field(field, kBox, r); });
    };
    const std::pair<const char*, const char*> kernel{"GSD_RENDER_MARCH", "kernel"};
    SUBCASE("PAT of a torus, the wavefront march (as software devices run it)") {
        torus_pat("PAT, wavefront", {{"GSD_RENDER_MARCH", "wavefront"}});
    }
    SUBCASE("PAT, the render_pat kernel") { torus_pat("PAT, render_pat", {kernel}); }
    SUBCASE("PAT, the render_pat kernel without empty-space skipping") {
        // The kernel's own march through every cell, as before the skip.
        const PointCloud cloud = shapes::torus({0, 0, 0}, 0.55, 0.2)->sample(2500, 5);
        const TorusField field(JetFitter().fit(cloud), BlendOptions{});
        FieldRenderOptions o = small("cpu");
        o.view_from = {0.2, 1.0, 0.7};
        o.skip_empty_space = false;
        const ScopedEnv env({kernel});
        device_matches_cpu("PAT, render_pat, no skip", o, 1e-3, [&](const FieldRenderOptions& r) { return render_field(field, kBox, r); });
    }
    SUBCASE("PAT, four rays a lane: the compaction hardware GPUs run") {
        // A lane whose ray ends takes its tile's next one (render_march.glsl); lavapipe runs one
        // ray a lane unless told otherwise.
        torus_pat("PAT, 4 rays a lane", {kernel, {"GSD_RENDER_RAYS_PER_LANE", "4"}});
    }
    SUBCASE("PAT, the kernel as GPUs run it (storage buffers, the ball walked together)") {
        torus_pat("PAT, GPUs' kernel", {kernel, {"GSD_SOFTWARE_SHAPED", "0"}});
    }
    SUBCASE("PAT, the k-nearest fallback walked by the subgroup together") {
        torus_pat("PAT, fallback together", {kernel, {"GSD_SHARED_KNN", "1"}});
    }
    SUBCASE("PAT, a low loop cap: the subgroups cut short, their rays marched on the CPU") {
        // On a software device (render_march.glsl's past_loop_limit); elsewhere no cap applies.
        torus_pat("PAT, loop cap 3000", {kernel, {"GSD_LOOP_CAP", "3000"}});
    }
    SUBCASE("the project's demo cloud (holes, noise), as gsd render draws it") {
        const PointCloud cloud = io::read_point_cloud(std::string(GSD_SOURCE_DIR) + "/data/demo/torus-holey.ply");
        const TorusField field(JetFitter().fit(cloud), BlendOptions{});
        const Box box = padded_cube(bounding_box(cloud.points));
        device_matches_cpu("demo cloud", small("cpu"), 1e-3 * box.diagonal(),
                           [&](const FieldRenderOptions& r) { return render_field(field, box, r); });
        const ScopedEnv env({kernel});
        device_matches_cpu("demo cloud, render_pat", small("cpu"), 1e-3 * box.diagonal(),
                           [&](const FieldRenderOptions& r) { return render_field(field, box, r); });
    }
    SUBCASE("a grid, colored by a second grid") {
        const GridSpec g = GridSpec::cube(40, kBox);
        const std::vector<float> phi = sphere_grid(g);
        std::vector<float> color(g.node_count());
        for (std::size_t i = 0; i < color.size(); ++i) color[i] = float(std::sin(0.01 * double(i)));
        FieldRenderOptions o = small("cpu");
        o.color_grid = &g;
        o.color_values = &color;
        o.supersample = 2;
        device_matches_cpu("grid", o, 1e-4, [&](const FieldRenderOptions& r) { return render_field(g, phi, r); });
    }
    CHECK(gpu::validation_error_count() == errors_before);
}
#endif
