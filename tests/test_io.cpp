// Tests of the io module: round trips for every writable format, hand-made files in every
// PLY encoding / npy variant with known values, every malformed case throwing gsd::Error, and
// the real files in ../shared/data. Long (~1000 lines) because every format and every malformed
// case has its own test, and they share the hand-made files' helpers below.
#include <doctest/doctest.h>

#include <gsd/io.hpp>

#include "support.hpp"

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>

using namespace gsd;
using gsd::test::ScratchDir;
using gsd::test::write_bytes;

namespace {

static_assert(std::endian::native == std::endian::little, "the byte builders below assume a little-endian host");

// ---- helpers ----------------------------------------------------------------------------

template <class T>
std::string le(T v) {
    std::string s(sizeof(T), '\0');
    std::memcpy(s.data(), &v, sizeof(T));
    return s;
}

template <class T>
std::string be(T v) {
    std::string s = le(v);
    return {s.rbegin(), s.rend()};
}

/// The message of the gsd::Error that `f` throws, or "<no error>".
template <class F>
std::string error_of(F&& f) {
    try {
        f();
    } catch (const Error& e) {
        return e.what();
    }
    return "<no error>";
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

/// Points on a sphere of radius 2 around (1, -1, 0.5), outward unit normals.
PointCloud sphere_cloud(int n) {
    PointCloud c;
    c.points.resize(n, 3);
    c.normals.resize(n, 3);
    for (int i = 0; i < n; ++i) {
        const double z = 1 - 2 * (i + 0.5) / n, r = std::sqrt(1 - z * z), a = i * 2.399963229728653;
        const Eigen::Vector3d d(r * std::cos(a), r * std::sin(a), z);
        c.normals.row(i) = d.transpose();
        c.points.row(i) = (Eigen::Vector3d(1, -1, 0.5) + 2 * d).transpose();
    }
    return c;
}

/// A unit cube of 6 quads plus one extra pentagon fan-able face: polygons of mixed size.
PolygonMesh polygon_mesh() {
    PolygonMesh m;
    m.vertices.resize(9, 3);
    m.vertices << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1, 0.5, 0.5, 1.5;
    m.add_face({0, 3, 2, 1});
    m.add_face({0, 1, 5, 4});
    m.add_face({1, 2, 6, 5});
    m.add_face({2, 3, 7, 6});
    m.add_face({3, 0, 4, 7});
    m.add_face({4, 5, 8});
    m.add_face({5, 6, 8});
    m.add_face({6, 7, 4, 8});  // a quad reusing the apex: polygons of size 3 and 4 mixed
    return m;
}

void check_same_cloud(const PointCloud& a, const PointCloud& b, double tol) {
    REQUIRE(a.size() == b.size());
    CHECK((a.points - b.points).cwiseAbs().maxCoeff() <= tol);
    CHECK((a.normals - b.normals).cwiseAbs().maxCoeff() <= tol);
}

void check_same_polygons(const PolygonMesh& a, const PolygonMesh& b) {
    CHECK(a.indices == b.indices);
    CHECK(a.offsets == b.offsets);
}

std::string npy_file(std::string_view descr, std::string_view shape, const std::string& data, int major = 1,
                     std::string_view fortran = "False") {
    std::string dict = "{'descr': '" + std::string(descr) + "', 'fortran_order': " + std::string(fortran) +
                       ", 'shape': " + std::string(shape) + ", }";
    const std::size_t pre = major == 1 ? 10 : 12;
    while ((pre + dict.size() + 1) % 64) dict += ' ';
    dict += '\n';
    std::string out = std::string("\x93NUMPY", 6) + char(major) + char(0);
    out += major == 1 ? le(std::uint16_t(dict.size())) : le(std::uint32_t(dict.size()));
    return out + dict + data;
}

/// Reads with the reader for `path`'s kind; any exception other than gsd::Error fails.
template <class F>
bool only_gsd_errors(F&& f) {
    try {
        f();
    } catch (const Error&) {
    } catch (const std::exception& e) {
        FAIL("a non-gsd exception escaped: " << e.what());
        return false;
    }
    return true;
}

std::size_t files_in(const std::filesystem::path& dir) {
    std::size_t n = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++n;
    return n;
}

}  // namespace

// ---- basics -----------------------------------------------------------------------------

TEST_CASE("extension is lower-cased, includes the dot, and looks at the file name only") {
    CHECK(io::extension("a/b/C.PLY") == ".ply");
    CHECK(io::extension("x.tar.gz") == ".gz");
    CHECK(io::extension("dir.d/noext") == "");
    CHECK(io::extension("") == "");
}

TEST_CASE("write_file_atomic writes, replaces, and leaves nothing behind on failure") {
    ScratchDir dir("io-atomic");
    const std::string p = dir.file("a.bin");
    io::write_file_atomic(p, std::string("one\0two", 7));
    io::write_file_atomic(p, "replaced");
    CHECK(files_in(dir.path()) == 1);
    CHECK(io::extension(p) == ".bin");
    CHECK_THROWS_AS(io::write_file_atomic(dir.file("missing/a.bin"), "x"), Error);
    std::filesystem::create_directory(dir.file("adir"));
    CHECK_THROWS_AS(io::write_file_atomic(dir.file("adir"), "x"), Error);  // rename onto a directory fails
    CHECK(files_in(dir.path()) == 2);  // a.bin and adir: no temp file left
    CHECK(error_of([&] { io::write_file_atomic(dir.file("missing/a.bin"), "x"); }).find("cannot create") !=
          std::string::npos);
}

// ---- round trips ------------------------------------------------------------------------

TEST_CASE("point clouds round-trip through every writable format") {
    ScratchDir dir("io-cloud-rt");
    const PointCloud cloud = sphere_cloud(500);
    for (const char* ext : {".ply", ".npy", ".xyz", ".xyzn", ".txt", ".pc", ".obj", ".PLY"}) {
        CAPTURE(ext);
        const std::string p = dir.file(std::string("cloud") + ext);
        io::write_point_cloud(p, cloud);
        const PointCloud back = io::read_point_cloud(p);
        const bool float32 = io::extension(p) == ".ply" || io::extension(p) == ".npy";
        // Text formats write the shortest exact decimal; binary ones store float32 (|x| ≤ 3).
        check_same_cloud(cloud, back, float32 ? 4e-7 : 1e-15);
        CHECK_FALSE(io::file_has_faces(p));
    }
}

TEST_CASE("polygon meshes round-trip through .obj, .ply, .off; .stl fan-triangulates and welds") {
    ScratchDir dir("io-mesh-rt");
    const PolygonMesh mesh = polygon_mesh();
    for (const char* ext : {".obj", ".ply", ".off"}) {
        CAPTURE(ext);
        const std::string p = dir.file(std::string("mesh") + ext);
        io::write_mesh(p, mesh);
        const PolygonMesh back = io::read_mesh(p);
        check_same_polygons(mesh, back);
        CHECK((back.vertices - mesh.vertices).cwiseAbs().maxCoeff() == 0.0);  // all values exact in float32
        CHECK(io::file_has_faces(p));
    }
    const std::string stl = dir.file("mesh.stl");
    io::write_mesh(stl, mesh);
    CHECK(std::filesystem::file_size(stl) == 84 + 50 * (5 * 2 + 2 + 2));
    const PolygonMesh tri = io::read_mesh(stl);
    CHECK(tri.vertices.rows() == 9);  // welded back to the shared corners
    REQUIRE(tri.face_count() == 14);
    for (std::size_t f = 0; f < tri.face_count(); ++f) CHECK(tri.face_size(f) == 3);
    // Every triangle's corners are corners of the original, by position.
    for (std::uint32_t i : tri.indices) {
        bool found = false;
        for (Eigen::Index v = 0; v < mesh.vertices.rows(); ++v) found |= tri.vertices.row(i) == mesh.vertices.row(v);
        CHECK(found);
    }
}

TEST_CASE("a PLY with a face over 255 corners gets a wide list count") {
    ScratchDir dir("io-wide");
    PolygonMesh m;
    const int n = 300;
    m.vertices.resize(n, 3);
    std::vector<std::uint32_t> ring(n);
    for (int i = 0; i < n; ++i) {
        m.vertices.row(i) << std::cos(2 * M_PI * i / n), std::sin(2 * M_PI * i / n), 0;
        ring[std::size_t(i)] = std::uint32_t(i);
    }
    m.add_face(ring.data(), ring.size());
    io::write_mesh(dir.file("ring.ply"), m);
    const PolygonMesh back = io::read_mesh(dir.file("ring.ply"));
    REQUIRE(back.face_count() == 1);
    CHECK(back.face_size(0) == 300);
}

// ---- PLY --------------------------------------------------------------------------------

TEST_CASE("ascii PLY: shuffled properties, colors skipped, a face element before the vertices") {
    ScratchDir dir("io-ply-ascii");
    const std::string p = dir.file("a.ply");
    write_bytes(p,
                "ply\r\nformat ascii 1.0\r\ncomment hand made\r\nobj_info none\r\n"
                "element face 2\r\nproperty list uchar int vertex_indices\r\nproperty uchar red\r\n"
                "element vertex 3\r\nproperty float nz\r\nproperty uchar red\r\nproperty double x\r\n"
                "property float y\r\nproperty float z\r\nproperty uchar green\r\nproperty float nx\r\n"
                "property float ny\r\nproperty uchar blue\r\nproperty uchar alpha\r\nproperty float quality\r\n"
                "element edge 1\r\nproperty int vertex1\r\nproperty int vertex2\r\n"
                "end_header\r\n"
                "3 0 1 2 255\r\n4 0 1 2 1 7\r\n"
                "1 10 1.5 -2.25 3 20 0 0 30 40 0.5\r\n"
                "0 11 -4 5e-1 +6 21 2 0 31 41 0.25\r\n"
                "0.8 12 7 8 9 22 0 0.6 32 42 1\r\n"
                "0 1\r\n");
    const PointCloud c = io::read_point_cloud(p);
    REQUIRE(c.size() == 3);
    CHECK(c.points.row(0) == Eigen::RowVector3d(1.5, -2.25, 3));
    CHECK(c.points.row(1) == Eigen::RowVector3d(-4, 0.5, 6));
    CHECK(c.points.row(2) == Eigen::RowVector3d(7, 8, 9));
    CHECK(c.normals.row(0) == Eigen::RowVector3d(0, 0, 1));
    CHECK(c.normals.row(1) == Eigen::RowVector3d(1, 0, 0));  // (2, 0, 0) normalized
    CHECK(c.normals(2, 1) == doctest::Approx(0.6));
    CHECK(c.normals(2, 2) == doctest::Approx(0.8));
    CHECK(io::file_has_faces(p));
    const PolygonMesh m = io::read_mesh(p);
    CHECK(m.face_count() == 2);
    CHECK(m.face_size(1) == 4);
}

TEST_CASE("big-endian binary PLY with mixed types, a face element first and an element after") {
    ScratchDir dir("io-ply-be");
    std::string body;
    // faces: uchar count, int indices, then a uchar red
    body += char(3) + be(std::int32_t(0)) + be(std::int32_t(1)) + be(std::int32_t(2)) + char(9);
    body += char(4) + be(std::int32_t(2)) + be(std::int32_t(1)) + be(std::int32_t(0)) + be(std::int32_t(1)) + char(9);
    const double xs[3] = {0.125, -3.5, 1e-3};
    for (int i = 0; i < 3; ++i) {
        body += be(xs[i]);                               // double x
        body += be(float(i + 0.5f));                     // float y
        body += be(std::int16_t(-7 * i));                // short z
        body += std::string("\x01\x02\x03", 3);          // uchar red green blue
        body += be(float(0)) + be(float(i == 1 ? -1.0f : 0.0f)) + be(float(i == 1 ? 0.0f : 1.0f));
    }
    // a trailing element with a list (skipped, must not disturb anything)
    body += be(std::uint16_t(2)) + be(1.0f) + be(2.0f);
    const std::string p = dir.file("be.ply");
    write_bytes(p,
                "ply\nformat binary_big_endian 1.0\n"
                "element face 2\nproperty list uchar int vertex_indices\nproperty uchar red\n"
                "element vertex 3\nproperty double x\nproperty float y\nproperty short z\n"
                "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                "property float nx\nproperty float ny\nproperty float nz\n"
                "element material 1\nproperty list ushort float weights\n"
                "end_header\n" + body);
    const PointCloud c = io::read_point_cloud(p);
    REQUIRE(c.size() == 3);
    for (int i = 0; i < 3; ++i) {
        CHECK(c.points(i, 0) == xs[i]);
        CHECK(c.points(i, 1) == i + 0.5);
        CHECK(c.points(i, 2) == -7 * i);
    }
    CHECK(c.normals.row(1) == Eigen::RowVector3d(0, -1, 0));
    CHECK(c.normals.row(2) == Eigen::RowVector3d(0, 0, 1));
    const PolygonMesh m = io::read_mesh(p);
    REQUIRE(m.face_count() == 2);
    CHECK(m.indices == std::vector<std::uint32_t>{0, 1, 2, 2, 1, 0, 1});
}

TEST_CASE("binary PLY: every scalar type name and alias, both byte orders") {
    ScratchDir dir("io-ply-types");
    struct Type {
        const char* name;
        std::string (*le)(double);
        std::string (*be)(double);
    };
    const Type types[] = {
        {"char", [](double v) { return le(std::int8_t(v)); }, [](double v) { return be(std::int8_t(v)); }},
        {"int8", [](double v) { return le(std::int8_t(v)); }, [](double v) { return be(std::int8_t(v)); }},
        {"uchar", [](double v) { return le(std::uint8_t(v)); }, [](double v) { return be(std::uint8_t(v)); }},
        {"uint8", [](double v) { return le(std::uint8_t(v)); }, [](double v) { return be(std::uint8_t(v)); }},
        {"short", [](double v) { return le(std::int16_t(v)); }, [](double v) { return be(std::int16_t(v)); }},
        {"int16", [](double v) { return le(std::int16_t(v)); }, [](double v) { return be(std::int16_t(v)); }},
        {"ushort", [](double v) { return le(std::uint16_t(v)); }, [](double v) { return be(std::uint16_t(v)); }},
        {"uint16", [](double v) { return le(std::uint16_t(v)); }, [](double v) { return be(std::uint16_t(v)); }},
        {"int", [](double v) { return le(std::int32_t(v)); }, [](double v) { return be(std::int32_t(v)); }},
        {"int32", [](double v) { return le(std::int32_t(v)); }, [](double v) { return be(std::int32_t(v)); }},
        {"uint", [](double v) { return le(std::uint32_t(v)); }, [](double v) { return be(std::uint32_t(v)); }},
        {"uint32", [](double v) { return le(std::uint32_t(v)); }, [](double v) { return be(std::uint32_t(v)); }},
        {"float", [](double v) { return le(float(v)); }, [](double v) { return be(float(v)); }},
        {"float32", [](double v) { return le(float(v)); }, [](double v) { return be(float(v)); }},
        {"double", [](double v) { return le(v); }, [](double v) { return be(v); }},
        {"float64", [](double v) { return le(v); }, [](double v) { return be(v); }},
    };
    const double rows[2][6] = {{1, 2, 3, 0, 0, 1}, {100, 120, 7, 0, 5, 0}};
    for (const Type& t : types) {
        for (bool big : {false, true}) {
            CAPTURE(t.name);
            CAPTURE(big);
            std::string header = std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") +
                                 " 1.0\nelement vertex 2\n";
            for (const char* prop : {"x", "y", "z", "nx", "ny", "nz"})
                header += std::string("property ") + t.name + " " + prop + "\n";
            std::string body;
            for (const auto& row : rows)
                for (double v : row) body += big ? t.be(v) : t.le(v);
            const std::string p = dir.file(std::string(t.name) + ".ply");
            write_bytes(p, header + "end_header\n" + body);
            const PointCloud c = io::read_point_cloud(p);
            REQUIRE(c.size() == 2);
            CHECK(c.points.row(0) == Eigen::RowVector3d(1, 2, 3));
            CHECK(c.points.row(1) == Eigen::RowVector3d(100, 120, 7));
            CHECK(c.normals.row(1) == Eigen::RowVector3d(0, 1, 0));
        }
    }
}

TEST_CASE("PLY meshes: vertex_index lists of any count/index type, other face properties skipped") {
    ScratchDir dir("io-ply-mesh");
    std::string body;
    for (int i = 0; i < 4; ++i) body += le(float(i & 1)) + le(float(i >> 1)) + le(0.0f) + char(200);
    // face: uchar flags, list int ushort vertex_index, list uchar float texcoord
    body += char(1) + le(std::int32_t(4)) + le(std::uint16_t(0)) + le(std::uint16_t(1)) + le(std::uint16_t(3)) +
            le(std::uint16_t(2)) + char(2) + le(0.5f) + le(0.5f);
    body += char(0) + le(std::int32_t(3)) + le(std::uint16_t(0)) + le(std::uint16_t(1)) + le(std::uint16_t(3)) +
            char(0);
    const std::string p = dir.file("m.ply");
    write_bytes(p,
                "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float32 x\nproperty float32 y\n"
                "property float32 z\nproperty uint8 red\nelement face 2\nproperty uchar flags\n"
                "property list int ushort vertex_index\nproperty list uchar float texcoord\nend_header\n" + body);
    const PolygonMesh m = io::read_mesh(p);
    CHECK(m.vertices.rows() == 4);
    CHECK(m.vertices.row(3) == Eigen::RowVector3d(1, 1, 0));
    CHECK(m.indices == std::vector<std::uint32_t>{0, 1, 3, 2, 0, 1, 3});
    CHECK(m.offsets == std::vector<std::uint32_t>{0, 4, 7});
    CHECK(io::file_has_faces(p));
    // Only x y z: a mesh is fine, a point cloud is not.
    CHECK(contains(error_of([&] { io::read_point_cloud(p); }), "point cloud has no normals (needs nx ny nz)"));
}

TEST_CASE("malformed PLY files throw gsd::Error naming the problem") {
    ScratchDir dir("io-ply-bad");
    const std::string good = dir.file("good.ply");
    io::write_point_cloud(good, sphere_cloud(100));
    std::string bytes;
    {
        std::ifstream f(good, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(f), {});
    }
    auto bad = [&](const std::string& name, const std::string& content) {
        const std::string p = dir.file(name);
        write_bytes(p, content);
        return error_of([&] { io::read_point_cloud(p); });
    };
    CHECK(contains(bad("trunc.ply", bytes.substr(0, bytes.size() - 10)), "too short"));
    CHECK(contains(bad("trunc2.ply", bytes.substr(0, bytes.find("end_header"))), "end_header"));
    std::string huge = bytes;
    huge.replace(huge.find("vertex 100"), 10, "vertex 1000000000000");
    CHECK(contains(bad("huge.ply", huge), "too short"));
    CHECK(contains(bad("magic.ply", "plx\nformat ascii 1.0\n"), "not a PLY file"));
    CHECK(contains(bad("fmt.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n"), "unknown PLY encoding"));
    CHECK(contains(bad("type.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n"),
                   "unknown PLY property type"));
    CHECK(contains(bad("nofmt.ply", "ply\nelement vertex 0\nend_header\n"), "format"));
    CHECK(contains(bad("noxyz.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                                    "end_header\n1 2\n3 4\n"),
                   "x, y and z"));
    CHECK(contains(bad("nonum.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                                    "property float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
                                    "end_header\n1 2 3 0 0 1\n4 five 6 0 0 1\n"),
                   "line 12"));
    CHECK(contains(bad("extra.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                                    "property float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
                                    "end_header\n1 2 3 0 0 1 7\n4 5 6 0 0 1\n"),
                   "line 11: PLY element 'vertex' row 0: more values on the line"));
    CHECK(contains(bad("nan.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                                  "property float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
                                  "end_header\n1 2 3 0 0 1\n4 nan 6 0 0 1\n"),
                   "non-finite"));
    CHECK(contains(bad("zeron.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                                    "property float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
                                    "end_header\n1 2 3 0 0 1\n4 5 6 0 0 0\n"),
                   "zero-length normal"));
    CHECK(contains(bad("one.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                                  "property float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
                                  "end_header\n1 2 3 0 0 1\n"),
                   "at least 2 points"));
    CHECK(contains(bad("noverts.ply", "ply\nformat ascii 1.0\nelement face 0\nend_header\n"), "no 'vertex' element"));
    // A face list that announces more items than the file holds.
    std::string face_body = le(0.f) + le(0.f) + le(0.f) + le(1.f) + le(0.f) + le(0.f) + le(0.f) + le(1.f) + le(0.f);
    face_body += char(200) + le(std::int32_t(0));
    const std::string mesh_header =
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    write_bytes(dir.file("list.ply"), mesh_header + face_body);
    CHECK(contains(error_of([&] { io::read_mesh(dir.file("list.ply")); }), "truncated"));
    write_bytes(dir.file("alist.ply"), "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                       "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                                       "end_header\n0 0 0\n1 0 0\n0 1 0\n1e300 0 1 2\n");
    CHECK(contains(error_of([&] { io::read_mesh(dir.file("alist.ply")); }), "line 13: PLY element 'face' row 0: list 'vertex_indices' announces"));
    // Out-of-range and too-short faces.
    std::string faces_oor = face_body.substr(0, 36) + char(3) + le(std::int32_t(0)) + le(std::int32_t(1)) +
                            le(std::int32_t(3));
    write_bytes(dir.file("oor.ply"), mesh_header + faces_oor);
    CHECK(contains(error_of([&] { io::read_mesh(dir.file("oor.ply")); }), "out of range"));
    std::string faces_two = face_body.substr(0, 36) + char(2) + le(std::int32_t(0)) + le(std::int32_t(1));
    write_bytes(dir.file("two.ply"), mesh_header + faces_two);
    CHECK(contains(error_of([&] { io::read_mesh(dir.file("two.ply")); }), "at least 3"));
    std::string faces_neg = face_body.substr(0, 36) + char(3) + le(std::int32_t(0)) + le(std::int32_t(-1)) +
                            le(std::int32_t(2));
    write_bytes(dir.file("neg.ply"), mesh_header + faces_neg);
    CHECK_THROWS_AS(io::read_mesh(dir.file("neg.ply")), Error);
    // A point cloud is not a mesh.
    CHECK(contains(error_of([&] { io::read_mesh(good); }), "no 'face' element"));
    // A NaN coordinate in binary.
    std::string nan_bytes = bytes;
    const float qnan = std::numeric_limits<float>::quiet_NaN();
    std::memcpy(nan_bytes.data() + bytes.find("end_header\n") + 11 + 24 * 5 + 4, &qnan, 4);
    CHECK(contains(bad("nanbin.ply", nan_bytes), "non-finite coordinate (element 5)"));
}

// ---- .npy -------------------------------------------------------------------------------

TEST_CASE("npy: hand-written float32/float64, both byte orders, v1/v2/v3 headers, read back exactly") {
    ScratchDir dir("io-npy");
    const std::vector<double> values = {0.5, -1.25, 3, 1e-3, 7, 8};
    auto data = [&](auto cast, bool big) {
        std::string s;
        for (double v : values) s += big ? be(cast(v)) : le(cast(v));
        return s;
    };
    const auto f32 = [](double v) { return float(v); };
    const auto f64 = [](double v) { return v; };
    const auto i32 = [](double v) { return std::int32_t(v * 4); };
    const auto i64 = [](double v) { return std::int64_t(v * 1000); };
    auto expect = [&](auto cast) {
        std::vector<double> e;
        for (double v : values) e.push_back(double(cast(v)));
        return e;
    };
    struct Case {
        const char* name;
        std::string bytes;
        std::vector<double> expected;  // the stored values, widened exactly
    };
    const Case cases[] = {
        {"f4le.npy", npy_file("<f4", "(2, 3)", data(f32, false)), expect(f32)},
        {"f4be.npy", npy_file(">f4", "(2, 3)", data(f32, true)), expect(f32)},
        {"f8le.npy", npy_file("<f8", "(2, 3)", data(f64, false)), values},
        {"f8be.npy", npy_file(">f8", "(2, 3)", data(f64, true)), values},
        {"v2.npy", npy_file("<f8", "(2, 3)", data(f64, false), 2), values},
        {"v3.npy", npy_file("<f4", "(2,3)", data(f32, false), 3), expect(f32)},
        {"i4.npy", npy_file("<i4", "(2, 3)", data(i32, false), 1), expect(i32)},
        {"i8be.npy", npy_file(">i8", "(2, 3)", data(i64, true), 1), expect(i64)},
    };
    CHECK(expect(f32)[3] != values[3]);  // the float32 cases really are float32
    for (const Case& c : cases) {
        CAPTURE(c.name);
        write_bytes(dir.file(c.name), c.bytes);
        const io::NpyArray a = io::read_npy(dir.file(c.name));
        CHECK(a.shape == std::vector<std::size_t>{2, 3});
        CHECK(a.data == c.expected);
        const Points q = io::read_queries(dir.file(c.name));
        REQUIRE(q.rows() == 2);
        CHECK(q(1, 0) == c.expected[3]);
        CHECK(q(0, 2) == c.expected[2]);
    }
    // Shapes (N,) and () parse.
    write_bytes(dir.file("vec.npy"), npy_file("<f8", "(6,)", data(f64, false)));
    CHECK(io::read_npy(dir.file("vec.npy")).shape == std::vector<std::size_t>{6});
    write_bytes(dir.file("scalar.npy"), npy_file("<f8", "()", le(2.5)));
    const io::NpyArray s = io::read_npy(dir.file("scalar.npy"));
    CHECK(s.shape.empty());
    REQUIRE(s.size() == 1);
    CHECK(s.data[0] == 2.5);
}

TEST_CASE("write_npy writes a padded version 1.0 '<f4' header that numpy's rules accept") {
    ScratchDir dir("io-npy-write");
    const std::vector<float> v = {1.5f, -2.f, 0.1f, 4.f, 5.f, 6.f, 7.f, 8.f};
    const std::string p = dir.file("w.npy");
    io::write_npy(p, {2, 2, 2}, v);
    std::ifstream f(p, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(f)), {});
    REQUIRE(bytes.size() > 10);
    CHECK(bytes.substr(0, 6) == std::string("\x93NUMPY", 6));
    CHECK(bytes[6] == 1);
    CHECK(bytes[7] == 0);
    std::uint16_t hlen = 0;
    std::memcpy(&hlen, bytes.data() + 8, 2);
    CHECK((10 + hlen) % 64 == 0);
    CHECK(bytes[9 + hlen] == '\n');
    const std::string header = bytes.substr(10, hlen);
    CHECK(contains(header, "'descr': '<f4'"));
    CHECK(contains(header, "'fortran_order': False"));
    CHECK(contains(header, "'shape': (2, 2, 2)"));
    CHECK(bytes.size() == 10 + hlen + 8 * 4);
    const io::NpyArray a = io::read_grid(p);
    for (std::size_t i = 0; i < v.size(); ++i) CHECK(a.data[i] == double(v[i]));
    io::write_npy(p, {3}, v.data(), 3);
    CHECK(io::read_npy(p).shape == std::vector<std::size_t>{3});
    std::ifstream g(p, std::ios::binary);
    const std::string one((std::istreambuf_iterator<char>(g)), {});
    CHECK(contains(one, "'shape': (3,)"));
    // A shape that does not match the count is refused, and nothing is written.
    CHECK_THROWS_AS(io::write_npy(dir.file("bad.npy"), {2, 2}, v), Error);
    CHECK_FALSE(test::file_exists(dir.file("bad.npy")));
    CHECK_THROWS_AS(io::write_npy(dir.file("nodir/x.npy"), {8}, v), Error);
    CHECK(files_in(dir.path()) == 1);
}

TEST_CASE("malformed or unsuitable .npy files throw gsd::Error") {
    ScratchDir dir("io-npy-bad");
    auto err = [&](const std::string& name, const std::string& bytes, auto reader) {
        write_bytes(dir.file(name), bytes);
        return error_of([&] { reader(dir.file(name)); });
    };
    const auto npy = [](const std::string& p) { io::read_npy(p); };
    const auto queries = [](const std::string& p) { io::read_queries(p); };
    const auto grid = [](const std::string& p) { io::read_grid(p); };
    const std::string six = le(1.0) + le(2.0) + le(3.0) + le(4.0) + le(5.0) + le(6.0);
    CHECK(contains(err("fortran.npy", npy_file("<f8", "(2, 3)", six, 1, "True"), npy), "Fortran"));
    CHECK(contains(err("magic.npy", "NUMPY not really", npy), "bad magic"));
    CHECK(contains(err("ver.npy", std::string("\x93NUMPY\x09\x00", 8) + "xx", npy), "version"));
    CHECK(contains(err("trunc.npy", npy_file("<f8", "(2, 3)", six.substr(0, 40)), npy), "truncated"));
    CHECK(contains(err("huge.npy", npy_file("<f8", "(1000000000000, 3)", six), npy), "truncated"));
    CHECK(contains(err("overflow.npy", npy_file("<f8", "(4294967296, 4294967296, 4294967296)", six), npy),
                   "truncated"));
    CHECK(contains(err("dtype.npy", npy_file("<i2", "(3,)", six), npy), "unsupported dtype '<i2'"));
    CHECK(contains(err("struct.npy", npy_file("<f8", "(2, 3)", six).replace(20, 5, "[('x'"), npy), "structured"));
    CHECK(contains(err("hdr.npy", std::string("\x93NUMPY\x01\x00\xff\x00", 10) + "{'descr'", npy), "truncated"));
    CHECK(contains(err("q4.npy", npy_file("<f8", "(3, 2)", six), queries), "(M, 3)"));
    CHECK(contains(err("q0.npy", npy_file("<f8", "(0, 3)", ""), queries), "empty"));
    CHECK(contains(err("qnan.npy", npy_file("<f8", "(2, 3)", le(1.0) + le(double(NAN)) + six.substr(16)), queries),
                   "non-finite"));
    CHECK(contains(err("g2.npy", npy_file("<f8", "(2, 3)", six), grid), "3-D"));
    CHECK(contains(err("g1.npy", npy_file("<f8", "(1, 2, 3)", six), grid), "at least 2"));
    CHECK(contains(err("cloud3.npy", npy_file("<f8", "(2, 3)", six), [](const std::string& p) { io::read_point_cloud(p); }),
                   "no normals"));
}

// ---- text formats ----------------------------------------------------------------------

TEST_CASE(".xyz/.txt: comments, blank lines, commas, CRLF; bad lines name their line") {
    ScratchDir dir("io-xyz");
    const std::string p = dir.file("a.xyz");
    write_bytes(p, "# header comment\r\n\r\n1,2,3,0,0,1\r\n  4 5 6   0 2 0 # trailing\n\n+7, 8e0 ,-9 1 0 0\n");
    const PointCloud c = io::read_point_cloud(p);
    REQUIRE(c.size() == 3);
    CHECK(c.points.row(2) == Eigen::RowVector3d(7, 8, -9));
    CHECK(c.normals.row(1) == Eigen::RowVector3d(0, 1, 0));
    auto err = [&](const std::string& content) {
        write_bytes(dir.file("b.txt"), content);
        return error_of([&] { io::read_point_cloud(dir.file("b.txt")); });
    };
    CHECK(contains(err("1 2 3\n4 5 6\n"), "point cloud has no normals (needs nx ny nz"));
    CHECK(contains(err("1 2 3 0 0 1\n1 2 3 0 1\n"), "line 2"));
    CHECK(contains(err("1 2 3 0 0 1\n1 2 x 0 1 0\n"), "line 2: expected a number, found 'x'"));
    CHECK(contains(err("1 2 3 0 0 1\n1 2 inf 0 1 0\n"), "non-finite"));
    CHECK(contains(err("1 2 3 0 0 1\n1 2 1e999 0 1 0\n"), "line 2"));
    CHECK(contains(err("1 2 3 0 0 1\n"), "at least 2 points"));
    CHECK(contains(err("1 2 3 0 0 1\n4 5 6 0 0 0\n"), "zero-length normal"));
    CHECK(contains(err("# only a comment\n\n"), "empty"));
}

TEST_CASE(".pc and .obj point clouds: v/vn pairs; counts must match") {
    ScratchDir dir("io-pc");
    write_bytes(dir.file("a.pc"), "# c\nv 1 2 3\nvn 0 0 1\nv 4 5 6\nvn 0 3 0\n");
    const PointCloud c = io::read_point_cloud(dir.file("a.pc"));
    CHECK(c.points.row(1) == Eigen::RowVector3d(4, 5, 6));
    CHECK(c.normals.row(1) == Eigen::RowVector3d(0, 1, 0));
    write_bytes(dir.file("a.obj"), "o x\nv 1 2 3\nv 4 5 6 1\nvt 0 0\nvn 0 0 1\nvn 0 3 0\nf 1//1 2//2 1//1\n");
    check_same_cloud(io::read_point_cloud(dir.file("a.obj")), c, 0);
    auto err = [&](const std::string& name, const std::string& content) {
        write_bytes(dir.file(name), content);
        return error_of([&] { io::read_point_cloud(dir.file(name)); });
    };
    CHECK(contains(err("b.pc", "v 1 2 3\nvn 0 0 1\nv 4 5 6\n"), "counts must match"));
    CHECK(contains(err("c.pc", "v 1 2 3\nv 4 5 6\n"), "no normals"));
    CHECK(contains(err("d.pc", "v 1 2 3\nvn 0 0 1\nq 1\n"), "line 3"));
    CHECK(contains(err("e.pc", "v 1 2\nvn 0 0 1\n"), "line 1"));
    CHECK(contains(err("b.obj", "v 1 2 3\nv 4 5 6\nvn 0 0 1\n"), "counts must match"));
    CHECK(contains(err("c.obj", "v 1 2 3\nv 4 5 6\nf 1 2 1\n"), "no normals"));
}

TEST_CASE("unoriented clouds: read_cloud_points reads every cloud format with or without normals") {
    ScratchDir dir("io-unoriented");
    Points expected(3, 3);
    expected << 1, 2, 3, 4, 5, 6, 7, 8, 10;
    const std::vector<std::pair<std::string, std::string>> files{
        {"a.xyz", "# x y z\n1 2 3\n4,5,6\n7 8 10\n"},
        {"a.pc", "v 1 2 3\nv 4 5 6\nv 7 8 10\n"},
        {"a.obj", "v 1 2 3\nv 4 5 6\nv 7 8 10\nf 1 2 3\n"},
        {"a.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                  "end_header\n1 2 3\n4 5 6\n7 8 10\n"}};
    for (const auto& file : files) {
        const std::string& name = file.first;
        CAPTURE(name);
        write_bytes(dir.file(name), file.second);
        const PointCloud c = io::read_cloud_points(dir.file(name));
        CHECK(c.normals.rows() == 0);
        CHECK(c.points == expected);
        CHECK(contains(error_of([&] { io::read_point_cloud(dir.file(name)); }), "no normals"));
    }
    std::string values;
    for (double v : {1, 2, 3, 4, 5, 6, 7, 8, 10}) values.append(reinterpret_cast<const char*>(&v), 8);
    write_bytes(dir.file("a.npy"), npy_file("<f8", "(3, 3)", values));
    CHECK(io::read_cloud_points(dir.file("a.npy")).points == expected);
    // With normals, exactly read_point_cloud's answer (normalized).
    write_bytes(dir.file("n.xyz"), "1 2 3 0 0 2\n4 5 6 0 3 0\n");
    CHECK(io::read_cloud_points(dir.file("n.xyz")).normals.row(1) == Eigen::RowVector3d(0, 1, 0));
    // Rows must agree on their width; coordinates must be finite.
    write_bytes(dir.file("mixed.xyz"), "1 2 3\n4 5 6 0 0 1\n");
    CHECK(contains(error_of([&] { io::read_cloud_points(dir.file("mixed.xyz")); }), "line 2: expected 3 numbers like the first row"));
    write_bytes(dir.file("nan.xyz"), "1 2 3\n4 nan 6\n");
    CHECK_THROWS_AS(io::read_cloud_points(dir.file("nan.xyz")), Error);
    write_bytes(dir.file("far.xyz"), "1 2 3\n4 5 6\n1e31 0 0\n");
    CHECK(contains(error_of([&] { io::read_cloud_points(dir.file("far.xyz")); }), "beyond"));
    write_bytes(dir.file("empty.xyz"), "# nothing\n");
    CHECK(contains(error_of([&] { io::read_cloud_points(dir.file("empty.xyz")); }), "empty"));
}

TEST_CASE(".obj meshes: polygons, v/vt/vn corners, negative indices, ignored statements") {
    ScratchDir dir("io-obj");
    const std::string p = dir.file("m.obj");
    write_bytes(p,
                "# comment\nmtllib x.mtl\no thing\ng group\n"
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1 1.0\n"
                "vt 0 0\nvn 0 0 1\ns off\nusemtl mat\n"
                "f 1/1/1 2/1/1 3/1/1 4/1/1\n"
                "f -5//1 -4//1 -1//1\n"
                "f 1/1 2 5\n"
                "l 1 2\n");
    const PolygonMesh m = io::read_mesh(p);
    CHECK(m.vertices.rows() == 5);
    CHECK(m.offsets == std::vector<std::uint32_t>{0, 4, 7, 10});
    CHECK(m.indices == std::vector<std::uint32_t>{0, 1, 2, 3, 0, 1, 4, 0, 1, 4});
    CHECK(io::file_has_faces(p));
    auto err = [&](const std::string& content) {
        write_bytes(dir.file("b.obj"), content);
        return error_of([&] { io::read_mesh(dir.file("b.obj")); });
    };
    const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    CHECK(contains(err(tri + "f 1 2 4\n"), "line 4: face vertex index 4 is out of range"));
    CHECK(contains(err(tri + "f 1 2\n"), "line 4: face has 2 vertices"));
    CHECK(contains(err(tri + "f 0 1 2\n"), "index 0"));
    CHECK(contains(err(tri + "f -4 1 2\n"), "before the first vertex"));
    CHECK(contains(err(tri + "f 1 2 x\n"), "bad face vertex 'x'"));
    CHECK(contains(err("v 0 0 zero\n"), "line 1"));
    CHECK(contains(err(tri), "no faces"));
    CHECK(contains(err(tri + "bogus 1 2 3\nf 1 2 3\n"), "unknown OBJ statement 'bogus'"));
    write_bytes(dir.file("c.obj"), tri + "vn 0 0 1\nvn 0 0 1\nvn 0 0 1\n");
    CHECK_FALSE(io::file_has_faces(dir.file("c.obj")));
    // A UTF-8 byte-order mark (Windows editors) is skipped; elsewhere it is still an error.
    write_bytes(dir.file("bom.obj"), "\xEF\xBB\xBF" + tri + "f 1 2 3\n");
    const PolygonMesh bom = io::read_mesh(dir.file("bom.obj"));
    CHECK(bom.vertices.rows() == 3);
    CHECK(bom.indices == std::vector<std::uint32_t>{0, 1, 2});
    CHECK(contains(err(tri + "\xEF\xBB\xBF" + "f 1 2 3\n"), "unknown OBJ statement"));
}

TEST_CASE("a UTF-8 byte-order mark is skipped by every line-based reader") {
    ScratchDir dir("io-bom");
    const std::string bom = "\xEF\xBB\xBF";
    const std::vector<std::pair<std::string, std::string>> meshes = {
        {"m.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"},
        {"m.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"},
        {"m.stl", "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\n"
                  "endfacet\nendsolid t\n"}};
    for (const auto& entry : meshes) {  // (no structured binding: clang 14 cannot capture one)
        const std::string& name = entry.first;
        CAPTURE(name);
        write_bytes(dir.file(name), bom + entry.second);
        const PolygonMesh m = io::read_mesh(dir.file(name));
        CHECK(m.vertices.rows() == 3);
        CHECK(m.face_count() == 1);
    }
    write_bytes(dir.file("c.xyz"), bom + "0 0 0 0 0 1\n1 0 0 0 0 1\n");
    CHECK(io::read_point_cloud(dir.file("c.xyz")).size() == 2);
}

TEST_CASE(".off meshes: comments, counts on the header line, colors after indices") {
    ScratchDir dir("io-off");
    const std::string p = dir.file("m.off");
    write_bytes(p, "OFF # a comment\n# another\n\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0.5 1\n"
                   "4 0 1 2 3 255 0 0\n3 0 1 4 0.1 0.2 0.3 1\n");
    const PolygonMesh m = io::read_mesh(p);
    CHECK(m.vertices.rows() == 5);
    CHECK(m.vertices.row(4) == Eigen::RowVector3d(0.5, 0.5, 1));
    CHECK(m.offsets == std::vector<std::uint32_t>{0, 4, 7});
    CHECK(io::file_has_faces(p));
    write_bytes(dir.file("c.off"), "COFF 3 1 0\n0 0 0 255 0 0 255\n1 0 0 255 0 0 255\n0 1 0 255 0 0 255\n3 0 1 2\n");
    CHECK(io::read_mesh(dir.file("c.off")).face_count() == 1);
    auto err = [&](const std::string& content) {
        write_bytes(dir.file("b.off"), content);
        return error_of([&] { io::read_mesh(dir.file("b.off")); });
    };
    CHECK(contains(err("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"), "line 6: face vertex index 3 is out of range"));
    CHECK(contains(err("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n"), "at least 3"));
    CHECK(contains(err("OFF\n3 1 0\n0 0 0\n1 0 0\n"), "truncated"));
    CHECK(contains(err("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n\n\n"), "ends after 1 of 2 faces"));
    CHECK(contains(err("OFF\n1000000000000 1 0\n0 0 0\n"), "truncated"));
    CHECK(contains(err("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 zz\n3 0 1 2\n"), "line 5"));
    CHECK(contains(err("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n"), "lists fewer"));
    CHECK(contains(err("PLY\n3 1 0\n"), "not an OFF file"));
    CHECK(contains(err("4OFF\n3 1 0\n"), "unsupported OFF variant"));
    CHECK(contains(err("OFF BINARY\n"), "binary OFF"));
    CHECK(contains(err("OFF\n-3 1 0\n"), "bad vertex count"));
}

TEST_CASE(".stl: ascii and binary (detected by size, even with a 'solid' header), welded exactly") {
    ScratchDir dir("io-stl");
    const std::string ascii =
        "solid test\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n   vertex 1 1 0\n"
        "  endloop\n endfacet\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 1 0\n"
        "   vertex 0 1 -0\n  endloop\n endfacet\nendsolid test\n";
    write_bytes(dir.file("a.stl"), ascii);
    const PolygonMesh a = io::read_mesh(dir.file("a.stl"));
    CHECK(a.vertices.rows() == 4);
    CHECK(a.indices == std::vector<std::uint32_t>{0, 1, 2, 0, 2, 3});
    CHECK(io::file_has_faces(dir.file("a.stl")));

    std::string bin = "solid but actually binary";
    bin.resize(80, ' ');
    bin += le(std::uint32_t(2));
    const float tris[2][9] = {{0, 0, 0, 1, 0, 0, 1, 1, 0}, {0, 0, 0, 1, 1, 0, 0, 1, 0}};
    for (const auto& t : tris) {
        bin += le(0.f) + le(0.f) + le(1.f);
        for (float v : t) bin += le(v);
        bin += le(std::uint16_t(0));
    }
    write_bytes(dir.file("b.stl"), bin);
    const PolygonMesh b = io::read_mesh(dir.file("b.stl"));
    CHECK(b.vertices.rows() == 4);
    CHECK(b.indices == a.indices);
    CHECK(b.vertices == a.vertices);

    auto err = [&](const std::string& content) {
        write_bytes(dir.file("c.stl"), content);
        return error_of([&] { io::read_mesh(dir.file("c.stl")); });
    };
    std::string trunc = bin.substr(0, bin.size() - 7);
    trunc.replace(0, 5, "xxxxx");
    CHECK(contains(err(trunc), "header says 2 triangles"));
    CHECK(contains(err("not an stl"), "not an STL file"));
    CHECK(contains(err(ascii.substr(0, ascii.find("endloop"))), "truncated"));
    CHECK(contains(err("solid x\n facet normal 0 0 1\n outer loop\n vertex 0 0\n"), "line 4"));
    CHECK(contains(err("solid x\n facet normal 0 0 1\n outer loop\n vertex 0 0 0\n vertex 1 0 0\n endloop\n"),
                   "needs 3"));
    CHECK(contains(err("solid x\n bananas\n"), "line 2"));
    std::string nan_bin = bin;
    const float qnan = std::numeric_limits<float>::quiet_NaN();
    std::memcpy(nan_bin.data() + 84 + 12 + 4, &qnan, 4);
    CHECK(contains(err(nan_bin), "non-finite"));
    std::string empty_bin = bin.substr(0, 80) + le(std::uint32_t(0));
    CHECK(contains(err(empty_bin), "no vertices"));
}

// ---- errors common to every format ----------------------------------------------------

TEST_CASE("every reader rejects missing files, directories, empty files and random bytes") {
    ScratchDir dir("io-common-bad");
    std::mt19937 rng(12345);
    std::string noise(4096, '\0');
    for (char& ch : noise) ch = char(rng() & 0xff);
    std::filesystem::create_directory(dir.file("folder.ply"));
    for (const char* ext : {".ply", ".xyz", ".xyzn", ".txt", ".pc", ".obj", ".npy"}) {
        CAPTURE(ext);
        CHECK(contains(error_of([&] { io::read_point_cloud(dir.file(std::string("missing") + ext)); }), "not found"));
        write_bytes(dir.file(std::string("empty") + ext), "");
        CHECK(contains(error_of([&] { io::read_point_cloud(dir.file(std::string("empty") + ext)); }), "empty"));
        write_bytes(dir.file(std::string("noise") + ext), noise);
        CHECK_THROWS_AS(io::read_point_cloud(dir.file(std::string("noise") + ext)), Error);
    }
    for (const char* ext : {".obj", ".ply", ".off", ".stl"}) {
        CAPTURE(ext);
        CHECK_THROWS_AS(io::read_mesh(dir.file(std::string("missing") + ext)), Error);
        write_bytes(dir.file(std::string("empty") + ext), "");
        CHECK_THROWS_AS(io::read_mesh(dir.file(std::string("empty") + ext)), Error);
        write_bytes(dir.file(std::string("noise") + ext), noise);
        CHECK_THROWS_AS(io::read_mesh(dir.file(std::string("noise") + ext)), Error);
    }
    CHECK(contains(error_of([&] { io::read_point_cloud(dir.file("folder.ply")); }), "is a directory"));
    CHECK(contains(error_of([&] { io::read_mesh(dir.file("folder.ply")); }), "is a directory"));
    CHECK_THROWS_AS(io::read_npy(dir.file("missing.npy")), Error);
    CHECK(contains(error_of([&] { io::read_point_cloud("/dev/null.ply"); }), "not found"));
    const std::string foo = error_of([&] { io::read_point_cloud(dir.file("a.foo")); });
    CHECK(contains(foo, "unsupported format '.foo' (supported: .ply"));
    CHECK(contains(error_of([&] { io::read_mesh(dir.file("a.xyz")); }), "unsupported format '.xyz'"));
    CHECK(contains(error_of([&] { io::read_mesh(dir.file("noext")); }), "no extension"));
    CHECK_THROWS_AS(io::file_has_faces(dir.file("a.foo")), Error);
    CHECK_THROWS_AS(io::file_has_faces(dir.file("missing.stl")), Error);
    const Error e = [&] {
        try {
            io::read_point_cloud(dir.file("missing.ply"));
        } catch (const Error& err) {
            return err;
        }
        return Error("");
    }();
    CHECK(e.where() == dir.file("missing.ply"));
}

TEST_CASE("corrupted and truncated copies of valid files only ever throw gsd::Error") {
    ScratchDir dir("io-fuzz");
    const PointCloud cloud = sphere_cloud(40);
    const PolygonMesh mesh = polygon_mesh();
    std::vector<std::string> files;
    for (const char* ext : {".ply", ".npy", ".xyz", ".pc", ".obj"}) {
        files.push_back(dir.file(std::string("c") + ext));
        io::write_point_cloud(files.back(), cloud);
    }
    for (const char* ext : {".obj", ".ply", ".off", ".stl"}) {
        files.push_back(dir.file(std::string("m") + ext));
        io::write_mesh(files.back(), mesh);
    }
    // An ascii PLY with lists too, so ascii list parsing meets corruption.
    files.push_back(dir.file("ma.ply"));
    write_bytes(files.back(),
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                "property float nx\nproperty float ny\nproperty float nz\nelement face 1\n"
                "property list uchar int vertex_indices\nend_header\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n");
    std::mt19937 rng(7);
    for (const std::string& f : files) {
        CAPTURE(f);
        std::ifstream in(f, std::ios::binary);
        const std::string original((std::istreambuf_iterator<char>(in)), {});
        const std::string p = dir.file("fuzz" + io::extension(f));
        const bool is_mesh = std::filesystem::path(f).filename().string()[0] == 'm';
        for (int trial = 0; trial < 300; ++trial) {
            std::string bytes = original;
            if (trial % 3 == 0) {
                bytes.resize(rng() % bytes.size());
            } else {
                for (int k = 0; k < 1 + trial % 5; ++k) {
                    const std::size_t at = rng() % bytes.size();
                    bytes[at] = (trial % 2) ? char(rng() & 0xff) : "0123456789 \n-.e#/"[rng() % 18];
                }
            }
            write_bytes(p, bytes);
            CHECK(only_gsd_errors([&] {
                if (is_mesh) io::read_mesh(p);
                else io::read_point_cloud(p);
            }));
            CHECK(only_gsd_errors([&] { io::file_has_faces(p); }));
        }
    }
}

TEST_CASE("writers refuse bad inputs and bad places, and leave no file behind") {
    ScratchDir dir("io-write-bad");
    const PointCloud good = sphere_cloud(10);
    CHECK_THROWS_AS(io::write_point_cloud(dir.file("nodir/a.ply"), good), Error);
    CHECK_THROWS_AS(io::write_mesh(dir.file("nodir/a.obj"), polygon_mesh()), Error);
    CHECK(contains(error_of([&] { io::write_point_cloud(dir.file("a.foo"), good); }), "unsupported format '.foo'"));
    PointCloud mismatched = good;
    mismatched.normals.conservativeResize(5, 3);
    CHECK_THROWS_AS(io::write_point_cloud(dir.file("a.ply"), mismatched), Error);
    CHECK_THROWS_AS(io::write_point_cloud(dir.file("b.ply"), PointCloud{}), Error);
    PointCloud nan = good;
    nan.points(3, 1) = NAN;
    CHECK_THROWS_AS(io::write_point_cloud(dir.file("c.xyz"), nan), Error);
    PolygonMesh broken = polygon_mesh();
    broken.indices[2] = 99;
    CHECK_THROWS_AS(io::write_mesh(dir.file("d.off"), broken), Error);
    CHECK(files_in(dir.path()) == 0);
    // An existing file is replaced whole.
    io::write_point_cloud(dir.file("e.xyz"), good);
    io::write_point_cloud(dir.file("e.xyz"), sphere_cloud(20));
    CHECK(io::read_point_cloud(dir.file("e.xyz")).size() == 20);
    CHECK(files_in(dir.path()) == 1);
}

TEST_CASE("file_has_faces") {
    ScratchDir dir("io-faces");
    io::write_point_cloud(dir.file("c.ply"), sphere_cloud(10));
    io::write_mesh(dir.file("m.ply"), polygon_mesh());
    write_bytes(dir.file("z.ply"), "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nelement face 0\n"
                                   "property list uchar int vertex_indices\nend_header\n");
    write_bytes(dir.file("x.off"), "anything");
    write_bytes(dir.file("x.xyz"), "1 2 3 0 0 1\n");
    CHECK_FALSE(io::file_has_faces(dir.file("c.ply")));
    CHECK(io::file_has_faces(dir.file("m.ply")));
    CHECK_FALSE(io::file_has_faces(dir.file("z.ply")));
    CHECK(io::file_has_faces(dir.file("x.off")));
    CHECK_FALSE(io::file_has_faces(dir.file("x.xyz")));
}

// ---- size ----------------------------------------------------------------------------

// Load time is measured by gsd-bench, not asserted here (tests check results, not speed).
TEST_CASE("a 1e6-point binary PLY round-trips") {
    ScratchDir dir("io-big");
    const PointCloud big = sphere_cloud(1000000);
    const std::string p = dir.file("big.ply");
    io::write_point_cloud(p, big);
    const PointCloud back = io::read_point_cloud(p);
    REQUIRE(back.size() == 1000000);
    for (Eigen::Index i : {Eigen::Index(0), Eigen::Index(123457), Eigen::Index(999999)}) {
        CHECK((back.points.row(i) - big.points.row(i)).norm() < 1e-6);
        CHECK((back.normals.row(i) - big.normals.row(i)).norm() < 1e-6);
    }
}

// ---- real data --------------------------------------------------------------------------

#if GSD_HAVE_SHARED_DATA
TEST_CASE("every real point cloud loads with plausible counts and unit normals") {
    int files = 0;
    for (const auto& entry : std::filesystem::directory_iterator(test::shared_data("pointclouds"))) {
        const std::string p = test::shared_data("pointclouds/" + entry.path().filename().string());
        CAPTURE(p);
        const PointCloud c = io::read_point_cloud(p);
        CHECK(c.size() > 100);
        CHECK((c.normals.rowwise().norm().array() - 1).abs().maxCoeff() < 1e-12);
        CHECK(c.points.allFinite());
        CHECK_FALSE(io::file_has_faces(p));
        ++files;
    }
    CHECK(files >= 7);
    CHECK(io::read_point_cloud(test::shared_data("pointclouds/holey-bunny.ply")).size() == 12917);
    CHECK(io::read_point_cloud(test::shared_data("pointclouds/bunny.pc")).size() == 1430);
}

TEST_CASE("every real mesh loads; polygon-bear keeps its polygons") {
    int files = 0;
    for (const auto& entry : std::filesystem::directory_iterator(test::shared_data("meshes"))) {
        const std::string p = test::shared_data("meshes/" + entry.path().filename().string());
        CAPTURE(p);
        const PolygonMesh m = io::read_mesh(p);
        CHECK(m.vertices.rows() > 100);
        CHECK(m.face_count() > 100);
        CHECK(io::file_has_faces(p));
        ++files;
    }
    CHECK(files >= 7);
    const PolygonMesh bear = io::read_mesh(test::shared_data("meshes/polygon-bear.obj"));
    CHECK(bear.face_count() == 1034);
    std::size_t largest = 0;
    for (std::size_t f = 0; f < bear.face_count(); ++f) largest = std::max(largest, bear.face_size(f));
    CHECK(largest > 4);
}
#endif

TEST_CASE("write_vdb: a VDB file from a valid scalar grid; bad grids and options are refused with no output") {
    ScratchDir dir("io-vdb");
    const std::string path = dir.file("g.vdb");
    GridSpec g = GridSpec::cube(6, Box{{-1, -2, 0}, {1, 0, 2}});
    std::vector<float> v(g.node_count());
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = float(i % 7) * 0.3f - 0.9f;
#ifdef GSD_EXPECT_VDB
    REQUIRE(io::vdb_available());  // the plugin was built: the search must find it
#endif
    if (!io::vdb_available()) {
        CHECK_THROWS_AS(io::write_vdb(path, g, v), Error);
        CHECK_FALSE(test::file_exists(path));
        return;
    }
    io::write_vdb(path, g, v);
    std::ifstream in(path, std::ios::binary);
    char magic[8] = {};
    in.read(magic, 8);
    CHECK(std::string(magic, 4) == " BDV");  // OpenVDB's magic number 0x56444220, little-endian
    auto refused = [&](const GridSpec& grid, const std::vector<float>& values, const io::VdbOptions& o, const char* why) {
        CAPTURE(why);
        const std::string out = dir.file("bad.vdb");
        CHECK_THROWS_AS(io::write_vdb(out, grid, values, o), Error);
        CHECK_FALSE(test::file_exists(out));
    };
    refused(g, std::vector<float>(v.size() - 1), {}, "a value short");
    std::vector<float> nan = v;
    nan[5] = std::nanf("");
    refused(g, nan, {}, "NaN");
    const GridSpec slab{6, 6, 3, Box{{0, 0, 0}, {1, 1, 1}}};  // spacing 0.2, 0.2, 0.5
    refused(slab, std::vector<float>(slab.node_count(), 0.5f), {}, "a level set on non-cubic voxels");
    io::VdbOptions plain;
    plain.level_set = false;
    CHECK_NOTHROW(io::write_vdb(dir.file("slab.vdb"), slab, std::vector<float>(slab.node_count(), 0.5f), plain));
    io::VdbOptions narrow;
    narrow.half_width = 0.5;
    refused(g, v, narrow, "a band under one voxel");
    io::VdbOptions nameless;
    nameless.name = "";
    refused(g, v, nameless, "no name");
}

TEST_CASE("read_vdb: what write_vdb wrote comes back on the same nodes") {
    if (!io::vdb_available()) {
        CHECK_THROWS_AS(io::read_vdb("missing.vdb"), Error);
        return;
    }
    ScratchDir dir("io-vdb-read");
    // Every node's value (not a level set): the same grid, every value.
    const GridSpec g{5, 6, 7, Box{{-1, -2, 0}, {1, 0.5, 3}}};
    std::vector<float> v(g.node_count());
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = float(i % 11) * 0.25f - 1.1f;
    io::VdbOptions plain;
    plain.level_set = false;
    io::write_vdb(dir.file("plain.vdb"), g, v, plain);
    const auto [pg, pv] = io::read_vdb(dir.file("plain.vdb"));
    CHECK(pg.nx == 5);
    CHECK(pg.ny == 6);
    CHECK(pg.nz == 7);
    for (int a = 0; a < 3; ++a) {
        CHECK(pg.box.lo[a] == doctest::Approx(g.box.lo[a]));
        CHECK(pg.box.hi[a] == doctest::Approx(g.box.hi[a]));
    }
    CHECK(pv == v);
    // A sphere's distance as a level set: the band's values as written, ± the band's half width
    // beyond it, on the nodes of the band's box grown by one.
    const GridSpec s = GridSpec::cube(33, Box{{-1, -1, -1}, {1, 1, 1}});
    const Points nodes = s.nodes();
    std::vector<float> phi(s.node_count());
    for (Eigen::Index i = 0; i < nodes.rows(); ++i) phi[std::size_t(i)] = float(nodes.row(i).norm() - 0.5);
    io::write_vdb(dir.file("sphere.vdb"), s, phi);
    const auto [lg, lv] = io::read_vdb(dir.file("sphere.vdb"));
    const double h = 2.0 / 32, band = 3 * h;
    std::size_t checked = 0;
    const Points back = lg.nodes();
    for (Eigen::Index i = 0; i < back.rows(); ++i) {
        const double exact = back.row(i).norm() - 0.5;
        if (std::abs(exact) < band - 1e-6) {
            CHECK(lv[std::size_t(i)] == doctest::Approx(exact).epsilon(1e-5));
            ++checked;
        } else {
            CHECK(std::abs(lv[std::size_t(i)]) <= band + 1e-5);
            CHECK((lv[std::size_t(i)] < 0) == (exact < 0));
        }
    }
    CHECK(checked > 1000);
    CHECK_THROWS_AS(io::read_vdb(dir.file("missing.vdb")), Error);
    test::write_bytes(dir.file("junk.vdb"), "not a vdb file at all");
    CHECK_THROWS_AS(io::read_vdb(dir.file("junk.vdb")), Error);
}

TEST_CASE("grid metadata round-trips exactly; absent is nullopt; bad options and grids are refused") {
    ScratchDir dir("io-grid-meta");
    const std::string grid = dir.file("g.npy");
    CHECK_FALSE(io::read_grid_metadata(grid).has_value());
    io::GridMetadata m;
    m.grid = GridSpec{5, 6, 7, Box{{-0.1, 1.0 / 3.0, -1e-9}, {2.0 / 7.0, 12345.678901234567, 1e-9}}};
    m.components = 3;
    m.method = "shm";
    m.options_json = R"({"t_coef": 1.5, "solver": "mg"})";
    m.command = {"gsd", "shm", "grid", "a b.obj"};
    io::write_grid_metadata(grid, m);
    const auto r = io::read_grid_metadata(grid);
    REQUIRE(r.has_value());
    CHECK(r->grid.nx == 5);
    CHECK(r->grid.ny == 6);
    CHECK(r->grid.nz == 7);
    CHECK(r->grid.box.lo == m.grid.box.lo);  // every bit of the doubles
    CHECK(r->grid.box.hi == m.grid.box.hi);
    CHECK(r->components == 3);
    CHECK(r->method == "shm");
    CHECK(r->command == m.command);
    CHECK(r->version == std::string(version()));
    CHECK(r->options_json.find("\"t_coef\":1.5") != std::string::npos);

    m.options_json = "[1, 2]";
    CHECK_THROWS_AS(io::write_grid_metadata(grid, m), Error);
    m.options_json = "{";
    CHECK_THROWS_AS(io::write_grid_metadata(grid, m), Error);
    m.options_json = "{}";
    m.components = 2;
    CHECK_THROWS_AS(io::write_grid_metadata(grid, m), Error);
    m.components = 1;
    m.grid.nx = 1;
    CHECK_THROWS_AS(io::write_grid_metadata(grid, m), Error);
    for (const char* bad : {"", "[]", R"({"shape": [4, 4], "bounds": {"lo": [0,0,0], "hi": [1,1,1]}})",
                            R"({"shape": [4, 4, 4], "bounds": {"lo": [0,0,0], "hi": [1,1,"x"]}})",
                            R"({"shape": [4, 4, 4.5], "bounds": {"lo": [0,0,0], "hi": [1,1,1]}})",
                            R"({"shape": [4, 4, 4], "bounds": {"lo": [0,0,0], "hi": [1,1,1e400]}})",
                            R"({"shape": [4, 4, 4]})",
                            // components: required, 1 or 3 (2 passed before fuzz/grid_metadata.cpp)
                            R"({"shape": [4, 4, 4], "bounds": {"lo": [0,0,0], "hi": [1,1,1]}})",
                            R"({"shape": [4, 4, 4], "components": 2, "bounds": {"lo": [0,0,0], "hi": [1,1,1]}})",
                            R"({"shape": [4, 4, 4], "components": 1.0, "bounds": {"lo": [0,0,0], "hi": [1,1,1]}})"}) {
        CAPTURE(bad);
        write_bytes(io::grid_metadata_path(grid), bad);
        try {
            (void)io::read_grid_metadata(grid);
            FAIL("accepted");
        } catch (const Error& e) {
            CHECK(std::string(e.where()) == io::grid_metadata_path(grid));
        }
    }
}
