#include <doctest/doctest.h>

#include <gsd/io.hpp>
#include <gsd/shapes.hpp>
#include <gsd/viz.hpp>

#include "support.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>

using namespace gsd;

namespace {

struct Pixel {
    int r, g, b;
    bool operator==(const Pixel&) const = default;
};

Pixel pixel(const Image& img, int x, int y) {
    const std::uint8_t* p = &img.rgb[(std::size_t(y) * img.width + x) * 3];
    return {p[0], p[1], p[2]};
}

double luminance(const Pixel& p) { return 0.3 * p.r + 0.59 * p.g + 0.11 * p.b; }
bool reddish(const Pixel& p) { return p.r > p.b + 40; }
bool bluish(const Pixel& p) { return p.b > p.r + 40; }
bool near_black(const Pixel& p) { return p.r < 50 && p.g < 50 && p.b < 50; }
bool gray(const Pixel& p) { return std::abs(p.r - p.g) <= 2 && std::abs(p.g - p.b) <= 2; }
bool is(const Pixel& p, const std::array<std::uint8_t, 3>& c) { return p == Pixel{c[0], c[1], c[2]}; }

// A sphere of radius 0.5 at the origin, as a closed outward triangle mesh.
PolygonMesh sphere_mesh(int n = 48) { return shapes::mesh(*shapes::sphere({0, 0, 0}, 0.5), n); }

std::vector<double> per_vertex(const PolygonMesh& m, double (*f)(const Eigen::Vector3d&)) {
    std::vector<double> v;
    for (Eigen::Index i = 0; i < m.vertices.rows(); ++i) v.push_back(f(m.vertices.row(i).transpose()));
    return v;
}

// A square options image looking at the origin from +z with y up: world x to the right.
SurfaceRenderOptions front_view(int size = 400) {
    SurfaceRenderOptions o;
    o.width = o.height = size;
    o.view_from = {0, 0, 1};
    o.up = {0, 1, 0};
    return o;
}

// Quads in the plane z = 0 from x = x[i] to x[i+1], y ∈ [−h, h].
PolygonMesh strip(const std::vector<double>& x, double h) {
    PolygonMesh m;
    m.vertices.resize(Eigen::Index(2 * x.size()), 3);
    for (std::size_t i = 0; i < x.size(); ++i) {
        m.vertices.row(Eigen::Index(2 * i)) << x[i], -h, 0;
        m.vertices.row(Eigen::Index(2 * i + 1)) << x[i], h, 0;
    }
    for (std::uint32_t i = 0; i + 1 < x.size(); ++i) m.add_face({2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1});
    return m;
}

Polyline arc_at_equator(double z_sign) {  // on the sphere, y = 0, facing ±z
    Polyline line;
    for (int i = 0; i <= 40; ++i) {
        const double t = -0.6 + 1.2 * i / 40;
        line.emplace_back(0.5 * std::sin(t), 0.0, z_sign * 0.5 * std::cos(t));
    }
    return line;
}

}  // namespace

TEST_CASE("render_surface: sphere colored by z, seen from the front and the back") {
    const PolygonMesh m = sphere_mesh();
    SurfacePicture pic;
    pic.mesh = &m;
    pic.vertex_values = per_vertex(m, [](const Eigen::Vector3d& p) { return p.z(); });

    const Image img = render_surface(pic);  // default three-quarter view, from z > 0
    REQUIRE(img.width == 1024);
    REQUIRE(img.height == 768);
    REQUIRE(img.rgb.size() == 1024u * 768u * 3u);
    CHECK(reddish(pixel(img, 512, 384)));  // the side facing the camera has z > 0
    for (auto [x, y] : {std::pair{0, 0}, {1023, 0}, {0, 767}, {1023, 767}})
        CHECK(is(pixel(img, x, y), {255, 255, 255}));  // background

    SurfaceRenderOptions back = front_view();
    back.view_from = {0.2, -0.1, -1};
    CHECK(bluish(pixel(render_surface(pic, back), 200, 200)));
}

TEST_CASE("render_surface: framing and symmetry of a sphere seen head-on") {
    const PolygonMesh m = sphere_mesh(64);
    SurfacePicture pic;
    pic.mesh = &m;
    pic.vertex_values = per_vertex(m, [](const Eigen::Vector3d& p) { return p.x(); });
    SurfaceRenderOptions o = front_view();
    o.background = {10, 200, 30};
    const Image img = render_surface(pic, o);
    auto covered = [&](int x, int y) { return !is(pixel(img, x, y), o.background); };

    // The disk is centered and fills the image less the 4% margins: diameter ≈ 0.92 × 400.
    int x0 = 400, x1 = -1, y0 = 400, y1 = -1, mismatched = 0, inside = 0;
    for (int y = 0; y < 400; ++y)
        for (int x = 0; x < 400; ++x) {
            if (!covered(x, y)) continue;
            ++inside;
            x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
            mismatched += !covered(399 - x, y) + !covered(x, 399 - y);
        }
    CHECK(x1 - x0 + 1 == doctest::Approx(368).epsilon(0.02));
    CHECK(y1 - y0 + 1 == doctest::Approx(368).epsilon(0.02));
    CHECK(std::abs((x0 + x1) - 399) <= 2);
    CHECK(std::abs((y0 + y1) - 399) <= 2);
    CHECK(mismatched < inside / 200);  // mirror images of each other, up to edge pixels

    // φ = x: blue left, red right, the zero contour down the middle column.
    for (int d : {60, 100, 150}) {  // nearer the middle the colors are too pale to call
        CHECK(bluish(pixel(img, 199 - d, 200)));
        CHECK(reddish(pixel(img, 200 + d, 200)));
    }
    CHECK(near_black(pixel(img, 199, 200)));
    CHECK(near_black(pixel(img, 200, 200)));
    // Isolines ±k·spacing sit at mirrored columns: a darkened pixel on the right has one on the
    // left within a pixel.
    auto dark = [&](int x) {
        return luminance(pixel(img, x, 200)) < 0.85 * std::max(luminance(pixel(img, x - 3, 200)),
                                                                luminance(pixel(img, x + 3, 200)));
    };
    int found = 0;
    for (int x = 205; x < 370; ++x) {
        if (!dark(x)) continue;
        ++found;
        CHECK((dark(399 - x) || dark(398 - x) || dark(400 - x)));
    }
    CHECK(found >= 5);
}

TEST_CASE("render_surface: the zero contour lies on the zero level set, and only when asked") {
    const PolygonMesh m = sphere_mesh(64);
    SurfacePicture pic;
    pic.mesh = &m;
    pic.vertex_values = per_vertex(m, [](const Eigen::Vector3d& p) { return p.y(); });  // zero: the equator
    SurfaceRenderOptions o = front_view();
    o.isolines = 0;
    const Image img = render_surface(pic, o);
    for (int x : {80, 140, 200, 260, 320}) {  // the equator is the middle row seen from +z
        CAPTURE(x);
        CHECK(near_black(pixel(img, x, 199)));
        CHECK(near_black(pixel(img, x, 200)));
        CHECK(reddish(pixel(img, x, 120)));  // above: y > 0
        CHECK(bluish(pixel(img, x, 280)));
        CHECK(luminance(pixel(img, x, 194)) > 120);
        CHECK(luminance(pixel(img, x, 205)) > 120);
    }
    o.zero_contour = false;
    const Image plain = render_surface(pic, o);
    CHECK(luminance(pixel(plain, 200, 200)) > 150);  // white (zero), shaded
}

TEST_CASE("render_surface: isolines at every multiple of 2·range/isolines") {
    const PolygonMesh m = strip({-1, 1}, 1);  // one quad facing the camera, φ = x
    SurfacePicture pic;
    pic.mesh = &m;
    pic.vertex_values = per_vertex(m, [](const Eigen::Vector3d& p) { return p.x(); });
    SurfaceRenderOptions o = front_view();
    o.range = 1;
    o.isolines = 20;  // spacing 0.1
    const Image img = render_surface(pic, o);
    // The quad spans 0.92 of the image: world x maps to pixel 200 + 184·x.
    auto column = [](double x) { return int(std::floor(200 + 184 * x)); };
    auto darkest_near = [&](double x) {
        double l = 255;
        for (int c = column(x) - 1; c <= column(x) + 1; ++c) l = std::min(l, luminance(pixel(img, c, 100)));
        return l;
    };
    // Away from saturation (where the map itself is dark), each level is clearly darker than
    // the colors half a spacing to either side.
    for (int k = -4; k <= 4; ++k) {
        if (k == 0) continue;
        CAPTURE(k);
        const double around = 0.5 * (luminance(pixel(img, column((k - 0.5) * 0.1), 100)) +
                                     luminance(pixel(img, column((k + 0.5) * 0.1), 100)));
        CHECK(darkest_near(k * 0.1) < around - 40);
        CHECK(luminance(pixel(img, column((k + 0.5) * 0.1), 100)) > darkest_near((k + 0.5) * 0.1) - 5);
    }
    CHECK(near_black(pixel(img, column(0), 100)));
}

TEST_CASE("render_surface: curves on the front show, the same curves on the back are hidden") {
    const PolygonMesh m = sphere_mesh();
    SurfacePicture pic;
    pic.mesh = &m;
    const SurfaceRenderOptions o = front_view();
    const Image bare = render_surface(pic, o);

    SurfacePicture::Curves front;
    front.lines = {arc_at_equator(+1)};
    front.color = {0, 255, 0};
    front.width = 5;
    pic.curves = {front};
    const Image with_front = render_surface(pic, o);
    for (int x : {120, 200, 280}) {
        const Pixel p = pixel(with_front, x, 200);
        CHECK((p.g > 230 && p.r < 30 && p.b < 30));
        CHECK(pixel(bare, x, 200) != p);
    }
    CHECK(pixel(with_front, 200, 185) == pixel(bare, 200, 185));  // 5 px wide, not more

    SurfacePicture::Curves back = front;
    back.lines = {arc_at_equator(-1)};
    pic.curves = {back};
    CHECK(render_surface(pic, o).rgb == bare.rgb);

    // A segment that passes behind the camera is clipped, not projected through the eye.
    back.lines = {{Eigen::Vector3d(0.1, 0.1, 0.6), Eigen::Vector3d(0.1, 0.1, 50)}, {Eigen::Vector3d(0, 0, 0.55)}};
    pic.curves = {back};
    const Image clipped = render_surface(pic, o);
    CHECK(clipped.rgb != bare.rgb);
    CHECK(pixel(clipped, 200, 200).g > 200);  // the single point is drawn as a dot
}

TEST_CASE("render_surface: face labels in their label colors, polygons fanned") {
    const PolygonMesh m = strip({-1, 0, 1}, 0.5);  // two quads
    SurfacePicture pic;
    pic.mesh = &m;
    pic.face_labels = {1, -1};
    SurfaceRenderOptions o = front_view();
    o.height = 300;
    const Image img = render_surface(pic, o);
    // A face turned to the camera is lit by one common factor: the color is a scaled label color.
    auto scaled = [](const Pixel& p, const std::array<std::uint8_t, 3>& c) {
        const double k = double(p.r * c[0] + p.g * c[1] + p.b * c[2]) / (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        return k > 0.6 && k <= 1.0 && std::abs(p.r - k * c[0]) < 3 && std::abs(p.g - k * c[1]) < 3 &&
               std::abs(p.b - k * c[2]) < 3;
    };
    CHECK(scaled(pixel(img, 108, 150), label_color(1)));
    CHECK(scaled(pixel(img, 292, 150), label_color(-1)));
    CHECK_FALSE(scaled(pixel(img, 292, 150), label_color(1)));

    // Labels are distinct from each other and from the gray of missing values; 0 is light.
    std::vector<std::array<std::uint8_t, 3>> colors;
    for (int l = -12; l <= 12; ++l) colors.push_back(label_color(l));
    std::sort(colors.begin(), colors.end());
    CHECK(std::adjacent_find(colors.begin(), colors.end()) == colors.end());
    for (std::uint8_t c : label_color(0)) CHECK(c > 220);
    CHECK(label_color(1) != diverging_color(NAN, 1));
    CHECK_NOTHROW(label_color(std::numeric_limits<int>::min()));
    CHECK_NOTHROW(label_color(std::numeric_limits<int>::max()));
}

TEST_CASE("render_surface: the same color map as render_slice, NaN and plain meshes gray") {
    CHECK(diverging_color(0, 1) == std::array<std::uint8_t, 3>{255, 255, 255});
    CHECK(diverging_color(2, 2) == std::array<std::uint8_t, 3>{103, 0, 31});
    CHECK(diverging_color(-7, 2) == std::array<std::uint8_t, 3>{5, 48, 97});
    CHECK(diverging_color(0.5, 1) != diverging_color(-0.5, 1));
    const auto missing = diverging_color(NAN, 1);
    CHECK((missing[0] == missing[1] && missing[1] == missing[2]));
    CHECK_THROWS_AS(diverging_color(0.5, 0), Error);
    CHECK_THROWS_AS(diverging_color(0.5, NAN), Error);

    // A flat quad of constant value: the plain gray picture gives the lighting factor, and the
    // colored one must be the diverging color under that same factor.
    const PolygonMesh m = strip({-1, 1}, 1);
    SurfacePicture pic;
    pic.mesh = &m;
    SurfaceRenderOptions o = front_view(100);
    const Pixel plain = pixel(render_surface(pic, o), 50, 50);
    CHECK(gray(plain));
    const double light = plain.r / double(missing[0]);
    pic.vertex_values.assign(4, 0.45);  // between isolines (a field flat on a level is all line)
    o.range = 1;
    const Pixel colored = pixel(render_surface(pic, o), 50, 50);
    const auto expected = diverging_color(0.45, 1);
    CHECK(std::abs(colored.r - light * expected[0]) < 3);
    CHECK(std::abs(colored.g - light * expected[1]) < 3);
    CHECK(std::abs(colored.b - light * expected[2]) < 3);

    // NaN on the left half of a sphere: gray there, colored on the right.
    const PolygonMesh s = sphere_mesh();
    pic.mesh = &s;
    pic.vertex_values = per_vertex(s, [](const Eigen::Vector3d& p) { return p.x() < 0 ? NAN : p.z(); });
    const Image img = render_surface(pic, front_view());
    CHECK(gray(pixel(img, 120, 200)));
    CHECK(reddish(pixel(img, 280, 200)));
}

TEST_CASE("render_surface: back faces are tinted, or not, as asked") {
    PolygonMesh m = strip({-1, 1}, 1);
    std::reverse(m.indices.begin(), m.indices.end());  // normal now points away from the camera
    SurfacePicture pic;
    pic.mesh = &m;
    SurfaceRenderOptions o = front_view(100);
    const Pixel tinted = pixel(render_surface(pic, o), 50, 50);
    CHECK(tinted.r > tinted.b + 20);  // yellow-brown
    o.mark_back_faces = false;
    const Pixel two_sided = pixel(render_surface(pic, o), 50, 50);
    CHECK(gray(two_sided));
    std::reverse(m.indices.begin(), m.indices.end());
    CHECK(pixel(render_surface(pic, o), 50, 50) == two_sided);  // lit as if it faced the camera
}

TEST_CASE("render_surface: deterministic, sizes and supersampling as asked") {
    const PolygonMesh m = shapes::mesh(*shapes::torus({0, 0, 0}, 0.5, 0.2), 40);
    SurfacePicture pic;
    pic.mesh = &m;
    pic.vertex_values = per_vertex(m, [](const Eigen::Vector3d& p) { return p.x() - 0.2; });
    pic.curves.push_back({{{Eigen::Vector3d(-0.7, 0, 0.2), Eigen::Vector3d(0.7, 0, 0.2)}}, {200, 0, 0}, 2.0});
    SurfaceRenderOptions o;
    o.width = 321;
    o.height = 123;
    o.supersample = 3;
    const Image a = render_surface(pic, o), b = render_surface(pic, o);
    CHECK(a.width == 321);
    CHECK(a.height == 123);
    CHECK(a.rgb == b.rgb);
    o.supersample = 1;
    const Image c = render_surface(pic, o);
    CHECK(c.width == 321);
    CHECK(c.rgb != a.rgb);
}

TEST_CASE("render_surface: rejects bad input") {
    const PolygonMesh m = sphere_mesh(16);
    SurfacePicture pic;
    pic.mesh = &m;
    CHECK_NOTHROW(render_surface(pic, front_view(32)));

    CHECK_THROWS_AS(render_surface(SurfacePicture{}), Error);  // no mesh
    const PolygonMesh empty;
    SurfacePicture bad = pic;
    bad.mesh = &empty;
    CHECK_THROWS_AS(render_surface(bad), Error);
    bad = pic;
    bad.vertex_values.assign(std::size_t(m.vertices.rows()) - 1, 0.0);
    CHECK_THROWS_AS(render_surface(bad), Error);
    bad = pic;
    bad.face_labels.assign(m.face_count() + 1, 0);
    CHECK_THROWS_AS(render_surface(bad), Error);
    bad = pic;
    bad.vertex_values.assign(std::size_t(m.vertices.rows()), 0.0);
    bad.face_labels.assign(m.face_count(), 0);
    CHECK_THROWS_AS(render_surface(bad), Error);  // both
    bad = pic;
    bad.curves.push_back({{{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(NAN, 0, 0)}}, {0, 0, 0}, 3.0});
    CHECK_THROWS_AS(render_surface(bad), Error);
    bad = pic;
    bad.curves.push_back({{{Eigen::Vector3d(0, 0, 0)}}, {0, 0, 0}, 0.0});
    CHECK_THROWS_AS(render_surface(bad), Error);

    auto rejects = [&](auto change) {
        SurfaceRenderOptions o = front_view(32);
        change(o);
        CHECK_THROWS_AS(render_surface(pic, o), Error);
    };
    rejects([](SurfaceRenderOptions& o) { o.width = 0; });
    rejects([](SurfaceRenderOptions& o) { o.height = -5; });
    rejects([](SurfaceRenderOptions& o) { o.width = 20000; });
    rejects([](SurfaceRenderOptions& o) { o.width = o.height = 10001, o.supersample = 1; });  // > 10^8 pixels
    rejects([](SurfaceRenderOptions& o) { o.width = o.height = 6000, o.supersample = 2; });
    rejects([](SurfaceRenderOptions& o) { o.supersample = 0; });
    rejects([](SurfaceRenderOptions& o) { o.supersample = 9; });
    rejects([](SurfaceRenderOptions& o) { o.range = -1; });
    rejects([](SurfaceRenderOptions& o) { o.range = NAN; });
    rejects([](SurfaceRenderOptions& o) { o.isolines = -1; });
    rejects([](SurfaceRenderOptions& o) { o.view_from = {0, 0, 0}; });
    rejects([](SurfaceRenderOptions& o) { o.view_from = {0, INFINITY, 0}; });
    rejects([](SurfaceRenderOptions& o) { o.up = o.view_from * -2; });
}

// ---- colored meshes ------------------------------------------------------------------------

namespace {

std::string read_all(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

}  // namespace

TEST_CASE("write_colored_mesh: binary PLY with colors and values that read_mesh reads back") {
    test::ScratchDir dir("viz_surface");
    const PolygonMesh m = sphere_mesh(16);
    const auto n = std::size_t(m.vertices.rows());
    std::vector<double> phi = per_vertex(m, [](const Eigen::Vector3d& p) { return p.z(); });
    phi[1] = NAN;
    std::vector<std::array<std::uint8_t, 3>> colors;
    for (double v : phi) colors.push_back(diverging_color(v, 0.5));

    const std::string path = dir.file("phi.ply");
    io::write_colored_mesh(path, m, colors, phi, "phi");
    const std::string bytes = read_all(path);
    const std::string header_end = "end_header\n";
    const std::size_t body = bytes.find(header_end) + header_end.size();
    REQUIRE(body > header_end.size());
    const std::string header = bytes.substr(0, body);
    CHECK(header.find("format binary_little_endian 1.0") != std::string::npos);
    CHECK(header.find("property uchar red\nproperty uchar green\nproperty uchar blue\nproperty float phi\n") !=
          std::string::npos);
    CHECK(bytes.size() == body + n * (12 + 3 + 4) + m.face_count() * (1 + 12));
    // Vertex 0's color sits after its three floats; vertex 1's value is the NaN.
    CHECK(std::uint8_t(bytes[body + 12]) == colors[0][0]);
    CHECK(std::uint8_t(bytes[body + 14]) == colors[0][2]);
    float stored = 0;
    std::memcpy(&stored, &bytes[body + 19 + 15], 4);
    CHECK(std::isnan(stored));

    const PolygonMesh back = io::read_mesh(path);
    REQUIRE(back.vertices.rows() == m.vertices.rows());
    CHECK((back.vertices - m.vertices).cwiseAbs().maxCoeff() < 1e-6);  // float32
    CHECK(back.indices == m.indices);
    CHECK(back.offsets == m.offsets);

    // Without values: colors only; polygons keep their sizes.
    const PolygonMesh quads = strip({-1, 0, 1, 2}, 1);
    const std::string qpath = dir.file("quads.ply");
    io::write_colored_mesh(qpath, quads, std::vector<std::array<std::uint8_t, 3>>(8, {1, 2, 3}));
    CHECK(read_all(qpath).find("property float") == read_all(qpath).find("property float x"));
    CHECK(read_all(qpath).find("property float value") == std::string::npos);
    const PolygonMesh qback = io::read_mesh(qpath);
    CHECK(qback.offsets == quads.offsets);
    CHECK(qback.indices == quads.indices);
}

TEST_CASE("write_colored_mesh: rejects bad input and leaves no file") {
    test::ScratchDir dir("viz_surface");
    const PolygonMesh m = sphere_mesh(16);
    const auto n = std::size_t(m.vertices.rows());
    const std::vector<std::array<std::uint8_t, 3>> colors(n, {9, 9, 9});
    CHECK_THROWS_AS(io::write_colored_mesh(dir.file("a.obj"), m, colors), Error);
    CHECK_THROWS_AS(io::write_colored_mesh(dir.file("a.ply"), m, {colors.begin(), colors.end() - 1}), Error);
    CHECK_THROWS_AS(io::write_colored_mesh(dir.file("a.ply"), m, colors, std::vector<double>(n + 1)), Error);
    CHECK_THROWS_AS(io::write_colored_mesh(dir.file("a.ply"), m, colors, std::vector<double>(n), "red"), Error);
    CHECK_THROWS_AS(io::write_colored_mesh(dir.file("a.ply"), m, colors, std::vector<double>(n), "two words"), Error);
    CHECK_THROWS_AS(io::write_colored_mesh(dir.file("a.ply"), m, colors, std::vector<double>(n), ""), Error);
    CHECK_THROWS_AS(io::write_colored_mesh(dir.file("a.ply"), PolygonMesh{}, {}), Error);
    CHECK(std::distance(std::filesystem::directory_iterator(dir.path()), {}) == 0);
}
