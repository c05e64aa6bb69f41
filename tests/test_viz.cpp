#include <doctest/doctest.h>

#include <gsd/viz.hpp>

#include "support.hpp"

#include <Eigen/Geometry>

#include <stb/stb_image.h>  // the implementation is in libstb

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <numbers>
#include <numeric>
#include <random>
#include <set>

using namespace gsd;

namespace {

const Box kCube{{-1, -1, -1}, {1, 1, 1}};

std::vector<float> sample(const GridSpec& g, const std::function<double(const Eigen::Vector3d&)>& f) {
    std::vector<float> v;
    v.reserve(g.node_count());
    for (int i = 0; i < g.nx; ++i)
        for (int j = 0; j < g.ny; ++j)
            for (int k = 0; k < g.nz; ++k) v.push_back(float(f(g.node(i, j, k))));
    return v;
}

double sphere_sdf(const Eigen::Vector3d& p) { return p.norm() - 0.5; }

double torus_sdf(const Eigen::Vector3d& p) {  // major radius 0.5, minor 0.2, around z
    const double q = std::hypot(p.x(), p.y()) - 0.5;
    return std::hypot(q, p.z()) - 0.2;
}

Eigen::Vector3d vertex(const PolygonMesh& m, std::uint32_t v) { return m.vertices.row(v).transpose(); }

Eigen::Vector3d corner(const PolygonMesh& m, std::size_t f, int c) {
    return vertex(m, m.indices[m.offsets[f] + c]);
}

// Topology of a triangle mesh: how often each directed and undirected edge is used.
struct EdgeUse {
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed, undirected;
};

EdgeUse edge_use(const PolygonMesh& m) {
    EdgeUse e;
    for (std::size_t f = 0; f < m.face_count(); ++f) {
        REQUIRE(m.face_size(f) == 3);
        for (int c = 0; c < 3; ++c) {
            const std::uint32_t a = m.indices[m.offsets[f] + c], b = m.indices[m.offsets[f] + (c + 1) % 3];
            ++e.directed[{a, b}];
            ++e.undirected[{std::min(a, b), std::max(a, b)}];
        }
    }
    return e;
}

bool is_closed(const EdgeUse& e) {
    return std::all_of(e.undirected.begin(), e.undirected.end(), [](auto& kv) { return kv.second == 2; });
}

bool is_consistently_oriented(const EdgeUse& e) {
    return std::all_of(e.directed.begin(), e.directed.end(), [](auto& kv) { return kv.second == 1; });
}

long euler_characteristic(const PolygonMesh& m, const EdgeUse& e) {
    return long(m.vertices.rows()) - long(e.undirected.size()) + long(m.face_count());
}

int component_count(const PolygonMesh& m) {
    std::vector<std::uint32_t> parent(m.vertices.rows());
    std::iota(parent.begin(), parent.end(), 0u);
    std::function<std::uint32_t(std::uint32_t)> root = [&](std::uint32_t v) {
        return parent[v] == v ? v : parent[v] = root(parent[v]);
    };
    for (std::size_t f = 0; f < m.face_count(); ++f)
        for (int c = 1; c < 3; ++c) parent[root(m.indices[m.offsets[f] + c])] = root(m.indices[m.offsets[f]]);
    std::set<std::uint32_t> roots;
    for (std::uint32_t v = 0; v < parent.size(); ++v) roots.insert(root(v));
    return int(roots.size());
}

// Every vertex's triangles form a single fan (the surface is a manifold there, not two cones
// touching at a point). Needs a closed, consistently oriented mesh.
bool vertices_are_manifold(const PolygonMesh& m) {
    std::vector<std::map<std::uint32_t, std::uint32_t>> ring(m.vertices.rows());  // next around v
    for (std::size_t f = 0; f < m.face_count(); ++f)
        for (int c = 0; c < 3; ++c) {
            const std::uint32_t* t = &m.indices[m.offsets[f]];
            ring[t[c]][t[(c + 1) % 3]] = t[(c + 2) % 3];
        }
    for (const auto& r : ring) {
        if (r.empty()) return false;  // unused vertex
        std::uint32_t v = r.begin()->first;
        std::size_t steps = 0;
        do {
            const auto it = r.find(v);
            if (it == r.end()) return false;
            v = it->second;
            ++steps;
        } while (v != r.begin()->first && steps <= r.size());
        if (steps != r.size()) return false;
    }
    return true;
}

Eigen::Vector3d area_normal(const PolygonMesh& m, std::size_t f) {  // length = 2 · area
    return (corner(m, f, 1) - corner(m, f, 0)).cross(corner(m, f, 2) - corner(m, f, 0));
}

double smallest_triangle_area(const PolygonMesh& m) {
    double a = INFINITY;
    for (std::size_t f = 0; f < m.face_count(); ++f) a = std::min(a, 0.5 * area_normal(m, f).norm());
    return a;
}

// Volume enclosed by a closed, outward-oriented mesh (divergence theorem).
double signed_volume(const PolygonMesh& m) {
    double v = 0;
    for (std::size_t f = 0; f < m.face_count(); ++f)
        v += corner(m, f, 0).dot(corner(m, f, 1).cross(corner(m, f, 2))) / 6;
    return v;
}

void check_closed_sphere(int n, double radius_tolerance) {
    CAPTURE(n);
    const GridSpec g = GridSpec::cube(n, kCube);
    const PolygonMesh m = contour(g, sample(g, sphere_sdf));
    REQUIRE(m.face_count() > 100);
    const EdgeUse e = edge_use(m);
    CHECK(is_closed(e));
    CHECK(is_consistently_oriented(e));
    CHECK(euler_characteristic(m, e) == 2);
    CHECK(component_count(m) == 1);
    CHECK(vertices_are_manifold(m));
    double worst = 0;
    for (Eigen::Index v = 0; v < m.vertices.rows(); ++v)
        worst = std::max(worst, std::abs(m.vertices.row(v).norm() - 0.5));
    CHECK(worst < radius_tolerance);
    const double exact = 4.0 / 3.0 * std::numbers::pi * 0.125;
    const double volume = signed_volume(m);
    CHECK(volume > 0);  // outward normals
    CHECK(std::abs(volume - exact) < 0.02 * exact);
    CHECK(smallest_triangle_area(m) > 0);
}

}  // namespace

TEST_CASE("contour: sphere SDF gives a closed, oriented genus-0 mesh on the sphere") {
    check_closed_sphere(32, 0.01);
    check_closed_sphere(64, 0.005);
}

TEST_CASE("contour: normals point toward increasing value") {
    const GridSpec g = GridSpec::cube(24, kCube);
    // Negated SDF: the inside is "above", so the mesh must face inward (negative volume).
    std::vector<float> v = sample(g, sphere_sdf);
    for (float& x : v) x = -x;
    const PolygonMesh m = contour(g, v);
    CHECK(signed_volume(m) < 0);
    // Per triangle: the normal agrees with the SDF gradient (radial) of the plain sphere.
    const PolygonMesh out = contour(g, sample(g, sphere_sdf));
    for (std::size_t f = 0; f < out.face_count(); ++f) {
        const Eigen::Vector3d c = (corner(out, f, 0) + corner(out, f, 1) + corner(out, f, 2)) / 3;
        REQUIRE(area_normal(out, f).dot(c) > 0);
    }
}

TEST_CASE("contour: torus has Euler characteristic 0, two spheres are two closed components") {
    const GridSpec g = GridSpec::cube(48, kCube);
    const PolygonMesh torus = contour(g, sample(g, torus_sdf));
    const EdgeUse te = edge_use(torus);
    CHECK(is_closed(te));
    CHECK(is_consistently_oriented(te));
    CHECK(euler_characteristic(torus, te) == 0);
    CHECK(component_count(torus) == 1);

    const PolygonMesh two = contour(g, sample(g, [](const Eigen::Vector3d& p) {
        const Eigen::Vector3d a(-0.5, 0, 0), b(0.5, 0.1, 0);
        return std::min((p - a).norm(), (p - b).norm()) - 0.3;
    }));
    const EdgeUse e2 = edge_use(two);
    CHECK(is_closed(e2));
    CHECK(is_consistently_oriented(e2));
    CHECK(component_count(two) == 2);
    CHECK(euler_characteristic(two, e2) == 4);
}

TEST_CASE("contour: iso other than zero, and a saddle-rich field, stay closed and oriented") {
    // Gyroid-like field on a non-cubic grid: many cells with alternating face signs, the
    // ambiguous cases of classic marching cubes. Restricted to a ball so the surface is closed.
    const GridSpec g{40, 33, 27, Box{{-1, -1, -0.8}, {1, 1, 0.8}}};
    const PolygonMesh m = contour(g, sample(g, [](const Eigen::Vector3d& p) {
        const Eigen::Vector3d q = 9 * p;
        const double gyroid = std::sin(q.x()) * std::cos(q.y()) + std::sin(q.y()) * std::cos(q.z()) +
                              std::sin(q.z()) * std::cos(q.x());
        return std::max(gyroid, p.norm() - 0.7);
    }), 0.1);
    REQUIRE(m.face_count() > 1000);
    const EdgeUse e = edge_use(m);
    CHECK(is_closed(e));
    CHECK(is_consistently_oriented(e));
    CHECK(smallest_triangle_area(m) > 0);
    CHECK(signed_volume(m) > 0);
}

TEST_CASE("contour: random noise (every ambiguous case) gives a closed oriented manifold") {
    // Independent random values per node: saddles on faces and inside cubes everywhere, the
    // configurations where classic marching cubes leaves holes. Boundary nodes are above iso,
    // so the level set is closed inside the grid.
    const GridSpec g{14, 12, 10, kCube};
    std::mt19937 rng(12345);
    std::uniform_real_distribution<float> noise(-1, 1);
    std::vector<float> v(g.node_count());
    for (int i = 0; i < g.nx; ++i)
        for (int j = 0; j < g.ny; ++j)
            for (int k = 0; k < g.nz; ++k) {
                const bool boundary =
                    i == 0 || j == 0 || k == 0 || i == g.nx - 1 || j == g.ny - 1 || k == g.nz - 1;
                v[(std::size_t(i) * g.ny + j) * g.nz + k] = boundary ? 1.0f : noise(rng);
            }
    const PolygonMesh m = contour(g, v);
    REQUIRE(m.face_count() > 1000);
    const EdgeUse e = edge_use(m);
    CHECK(is_closed(e));
    CHECK(is_consistently_oriented(e));
    CHECK(vertices_are_manifold(m));
    CHECK(euler_characteristic(m, e) % 2 == 0);  // closed orientable surfaces
    CHECK(signed_volume(m) > 0);  // encloses the "below" blobs, normals pointing out of them
    CHECK(smallest_triangle_area(m) > 0);
}

TEST_CASE("contour: a level set leaving the grid gives a valid open mesh") {
    const GridSpec g = GridSpec::cube(20, kCube);
    const PolygonMesh m = contour(g, sample(g, [](const Eigen::Vector3d& p) { return p.norm() - 1.2; }));
    REQUIRE(m.face_count() > 0);
    const EdgeUse e = edge_use(m);
    CHECK(is_consistently_oriented(e));
    CHECK_FALSE(is_closed(e));
    for (const auto& [edge, uses] : e.undirected) REQUIRE((uses == 1 || uses == 2));
    CHECK(smallest_triangle_area(m) > 0);
}

TEST_CASE("contour: values exactly at iso on nodes give no degenerate or duplicate geometry") {
    // Plane x = 0 with a layer of nodes exactly on it (odd node count on [-1, 1]).
    const GridSpec g{17, 9, 11, kCube};
    const PolygonMesh m = contour(g, sample(g, [](const Eigen::Vector3d& p) { return p.x(); }));
    REQUIRE(m.face_count() > 0);
    CHECK(m.vertices.rows() == 9 * 11);  // one vertex per node of the plane, nothing else
    CHECK(m.vertices.col(0).cwiseAbs().maxCoeff() == 0.0);
    CHECK(smallest_triangle_area(m) > 1e-6);
    double area = 0;
    for (std::size_t f = 0; f < m.face_count(); ++f) {
        REQUIRE(area_normal(m, f).x() > 0);  // facing +x, toward increasing value
        area += 0.5 * area_normal(m, f).norm();
    }
    CHECK(area == doctest::Approx(4.0));  // covered once: no double layer
    const EdgeUse e = edge_use(m);
    CHECK(is_consistently_oriented(e));
    CHECK(euler_characteristic(m, e) == 1);  // a disk

    // A sphere whose SDF is exactly 0 at some nodes (the six axis points at radius 0.5).
    const GridSpec s = GridSpec::cube(33, kCube);
    std::vector<float> v = sample(s, sphere_sdf);
    const PolygonMesh ms = contour(s, v);
    const EdgeUse es = edge_use(ms);
    CHECK(is_closed(es));
    CHECK(is_consistently_oriented(es));
    CHECK(euler_characteristic(ms, es) == 2);
    CHECK(vertices_are_manifold(ms));
    CHECK(smallest_triangle_area(ms) > 0);
    std::set<std::array<double, 3>> distinct;
    for (Eigen::Index r = 0; r < ms.vertices.rows(); ++r)
        distinct.insert({ms.vertices(r, 0), ms.vertices(r, 1), ms.vertices(r, 2)});
    CHECK(distinct.size() == std::size_t(ms.vertices.rows()));
}

TEST_CASE("contour: a level set that only touches a layer of nodes leaves no double layer") {
    // φ = −|x| reaches iso only on the nodes of x = 0: "above" is a sheet of zero thickness.
    // Both of its sides collapse onto the same nodes; the opposite copies cancel.
    const GridSpec g{9, 6, 7, kCube};
    const PolygonMesh m = contour(g, sample(g, [](const Eigen::Vector3d& p) { return -std::abs(p.x()); }));
    CHECK(m.face_count() == 0);
    CHECK(m.vertices.rows() == 0);
}

TEST_CASE("contour: level set missing the grid gives an empty mesh") {
    const GridSpec g = GridSpec::cube(8, kCube);
    const PolygonMesh m = contour(g, std::vector<float>(g.node_count(), 1.0f));
    CHECK(m.face_count() == 0);
    CHECK(m.vertices.rows() == 0);
}

TEST_CASE("contour: rejects non-finite values and size mismatches") {
    const GridSpec g = GridSpec::cube(8, kCube);
    std::vector<float> v = sample(g, sphere_sdf);
    v[123] = NAN;
    CHECK_THROWS_AS(contour(g, v), Error);
    v[123] = INFINITY;
    CHECK_THROWS_AS(contour(g, v), Error);
    v.pop_back();
    CHECK_THROWS_AS(contour(g, v), Error);
    CHECK_THROWS_AS(contour(g, sample(g, sphere_sdf), NAN), Error);
}

// ---- slices --------------------------------------------------------------------------------

namespace {

struct Pixel {
    int r, g, b;
};

Pixel pixel(const Image& img, int x, int y) {
    const std::uint8_t* p = &img.rgb[(std::size_t(y) * img.width + x) * 3];
    return {p[0], p[1], p[2]};
}

// The pixel whose center is nearest to image-plane point (u, v) of a slice spanning the box face.
Pixel pixel_at(const Image& img, double u, double v, double ulo, double uhi, double vlo, double vhi) {
    const int x = std::clamp(int((u - ulo) / (uhi - ulo) * img.width), 0, img.width - 1);
    const int y = std::clamp(int((vhi - v) / (vhi - vlo) * img.height), 0, img.height - 1);
    return pixel(img, x, y);
}

bool reddish(const Pixel& p) { return p.r > p.b + 40; }
bool bluish(const Pixel& p) { return p.b > p.r + 40; }
bool near_black(const Pixel& p) { return p.r < 60 && p.g < 60 && p.b < 60; }
bool near_white(const Pixel& p) { return p.r > 235 && p.g > 235 && p.b > 235; }

}  // namespace

TEST_CASE("render_slice: colors, zero contour and default size") {
    const GridSpec g = GridSpec::cube(64, kCube);
    const Image img = render_slice(g, sample(g, sphere_sdf), SliceOptions{});
    CHECK(img.width == 512);
    CHECK(img.height == 512);
    REQUIRE(img.rgb.size() == 512u * 512u * 3u);
    auto at = [&](double x, double y) { return pixel_at(img, x, y, -1, 1, -1, 1); };
    CHECK(bluish(at(0.0, 0.03)));    // inside: negative
    CHECK(reddish(at(0.93, 0.93)));  // far corner: positive
    const Pixel zero = at(0.5, 0.0);  // on the sphere
    CHECK((near_black(zero) || near_white(zero)));
    CHECK(near_black(at(0.0, -0.5)));
    // Colors saturate toward the ends: the corner is much more saturated than near the surface.
    CHECK(at(0.93, 0.93).b < at(0.62, 0.0).b);
}

TEST_CASE("render_slice: image axes and aspect ratio follow the box face") {
    const GridSpec g{9, 17, 5, Box{{0, -1, 0}, {1, 1, 0.5}}};
    // φ = y − 0.3·z + 0.2·x : positive to the right on Z slices and X slices.
    const std::vector<float> v =
        sample(g, [](const Eigen::Vector3d& p) { return p.y() - 0.3 * p.z() + 0.2 * p.x(); });

    SliceOptions z;  // x right (extent 1), y up (extent 2)
    z.at = 0.25;
    z.width = 100;
    const Image iz = render_slice(g, v, z);
    CHECK(iz.width == 100);
    CHECK(iz.height == 200);
    CHECK(reddish(pixel(iz, 50, 5)));      // top: large y
    CHECK(bluish(pixel(iz, 50, 194)));     // bottom: small y

    SliceOptions x;  // y right (extent 2), z up (extent 0.5)
    x.axis = Axis::X;
    x.at = 0.5;
    x.width = 400;
    const Image ix = render_slice(g, v, x);
    CHECK(ix.width == 400);
    CHECK(ix.height == 100);
    CHECK(reddish(pixel(ix, 395, 50)));
    CHECK(bluish(pixel(ix, 4, 50)));

    // Y slice: x right, z up; use a field that grows with z to check "up".
    const std::vector<float> vz = sample(g, [](const Eigen::Vector3d& p) { return p.z() - 0.25; });
    SliceOptions y;
    y.axis = Axis::Y;
    y.at = -0.2;
    const Image iy = render_slice(g, vz, y);
    CHECK(iy.width == 512);
    CHECK(iy.height == 256);
    CHECK(reddish(pixel(iy, 256, 3)));
    CHECK(bluish(pixel(iy, 256, 252)));
    CHECK(near_black(pixel(iy, 256, 128)));  // z = 0.25 is the middle row: zero contour
}

TEST_CASE("render_slice: fine grids get one pixel per node, explicit range saturates") {
    const GridSpec g{700, 2, 2, Box{{0, 0, 0}, {7, 1, 1}}};
    const std::vector<float> v = sample(g, [](const Eigen::Vector3d& p) { return p.x() - 3.5; });
    const Image img = render_slice(g, v, SliceOptions{});
    CHECK(img.width == 700);
    CHECK(img.height == 100);

    SliceOptions opt;
    opt.range = 0.5;
    opt.isolines = 0;
    opt.width = 70;
    const Image sat = render_slice(g, v, opt);
    // Beyond ±range every pixel has the same (saturated) color.
    CHECK(pixel(sat, 2, 5).r == pixel(sat, 20, 5).r);
    CHECK(pixel(sat, 2, 5).b == pixel(sat, 20, 5).b);
    CHECK(pixel(sat, 67, 5).r == pixel(sat, 50, 5).r);
}

TEST_CASE("render_slice: rejects bad input") {
    const GridSpec g = GridSpec::cube(8, kCube);
    std::vector<float> v = sample(g, sphere_sdf);
    SliceOptions opt;
    opt.at = 1.5;
    CHECK_THROWS_AS(render_slice(g, v, opt), Error);
    opt.at = 0;
    opt.width = -3;
    CHECK_THROWS_AS(render_slice(g, v, opt), Error);
    opt.width = 0;
    v.pop_back();
    CHECK_THROWS_AS(render_slice(g, v, opt), Error);
    v = sample(g, sphere_sdf);
    v[(4 * 8 + 4) * 8 + 3] = NAN;  // in the cells around z = 0
    CHECK_THROWS_AS(render_slice(g, v, opt), Error);
}

// ---- PNG -----------------------------------------------------------------------------------

namespace {

std::string read_all(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

}  // namespace

TEST_CASE("write_png: PNG signature, pixels read back, atomic") {
    test::ScratchDir dir("viz");
    Image img{5, 3, {}};
    for (int n = 0; n < 5 * 3 * 3; ++n) img.rgb.push_back(std::uint8_t(n * 17 % 256));
    const std::string path = dir.file("tiny.png");
    write_png(path, img);
    const std::string bytes = read_all(path);
    REQUIRE(bytes.size() > 8);
    CHECK(bytes.substr(0, 8) == std::string("\x89PNG\r\n\x1a\n", 8));

    int w = 0, h = 0, channels = 0;
    unsigned char* back = stbi_load(path.c_str(), &w, &h, &channels, 3);
    REQUIRE(back != nullptr);
    CHECK(w == 5);
    CHECK(h == 3);
    CHECK(std::equal(img.rgb.begin(), img.rgb.end(), back));
    stbi_image_free(back);

    // A rendered slice round-trips too.
    const GridSpec g = GridSpec::cube(16, kCube);
    const Image slice = render_slice(g, sample(g, torus_sdf), SliceOptions{});
    write_png(dir.file("slice.png"), slice);
    back = stbi_load(dir.file("slice.png").c_str(), &w, &h, &channels, 3);
    REQUIRE(back != nullptr);
    CHECK(w == slice.width);
    CHECK(h == slice.height);
    CHECK(std::equal(slice.rgb.begin(), slice.rgb.end(), back));
    stbi_image_free(back);

    // Only the two outputs are in the folder: no temporary files left behind.
    CHECK(std::distance(std::filesystem::directory_iterator(dir.path()), {}) == 2);

    const std::string missing = dir.file("no-such-folder/out.png");
    CHECK_THROWS_AS(write_png(missing, img), Error);
    CHECK_FALSE(std::filesystem::exists(dir.path() / "no-such-folder"));
    CHECK(std::distance(std::filesystem::directory_iterator(dir.path()), {}) == 2);

    CHECK_THROWS_AS(write_png(dir.file("bad.png"), Image{4, 4, std::vector<std::uint8_t>(10)}), Error);
    CHECK_FALSE(test::file_exists(dir.file("bad.png")));
}
