// `gsd shm surface` and `gsd curve` as a user meets them: outputs and their shapes, the sign
// convention end to end, curves from .obj l lines, points, exit codes and messages on bad input,
// and no partial outputs.
#include <doctest/doctest.h>

#include <gsd/io.hpp>
#include <gsd/shapes.hpp>
#include <gsd/surface.hpp>

#include "support.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>

using namespace gsd;
using test::run_cli;
using test::ScratchDir;

namespace {

/// An icosphere and a circle of latitude on it, z = 0.3, written as files.
struct Files {
    std::string mesh, curves;
};

Files sphere_with_circle(const ScratchDir& dir) {
    const PolygonMesh m = shapes::icosphere(3);
    Files f{dir.file("sphere.obj"), dir.file("circle.txt")};
    io::write_mesh(f.mesh, m);
    const SurfaceMesh mesh(m);
    std::vector<double> z(mesh.vertex_count());
    for (std::size_t i = 0; i < z.size(); ++i) z[i] = 0.3 - m.vertices(Eigen::Index(i), 2);  // < 0 above: the cap inside
    SurfaceSources s;
    s.curves = level_set_curves(mesh, z, 0);
    write_surface_curves(f.curves, s);
    return f;
}

}  // namespace

TEST_CASE("shm surface: φ per vertex, negative on the curve's left, and every optional output") {
    ScratchDir dir("cli-surface");
    const Files f = sphere_with_circle(dir);
    const std::string out = dir.file("phi.npy");
    const auto r = run_cli("shm surface " + f.mesh + " --curves " + f.curves + " -o " + out + " --render " +
                           dir.file("pic.png") + " --isolines " + dir.file("iso.obj") + " --colored " + dir.file("c.ply"));
    REQUIRE_MESSAGE(r.exit_code == 0, r.output);
    const io::NpyArray phi = io::read_npy(out);
    const PolygonMesh m = io::read_mesh(f.mesh);
    REQUIRE(phi.shape == std::vector<std::size_t>{std::size_t(m.vertices.rows())});
    for (Eigen::Index i = 0; i < m.vertices.rows(); ++i) {
        const double z = m.vertices(i, 2);
        if (z > 0.45) CHECK(phi.data[std::size_t(i)] < 0);   // the cap above the circle is inside
        if (z < 0.15) CHECK(phi.data[std::size_t(i)] > 0);
    }
    CHECK(test::file_exists(dir.file("pic.png")));
    const PolygonMesh colored = io::read_mesh(dir.file("c.ply"));
    CHECK(colored.vertices.rows() == m.vertices.rows());
    std::ifstream iso(dir.file("iso.obj"));
    std::string text((std::istreambuf_iterator<char>(iso)), std::istreambuf_iterator<char>());
    CHECK(text.find("\nl ") != std::string::npos);
    CHECK(text.find("g level_0\n") != std::string::npos);
}

TEST_CASE("shm surface: the modes and options run from the command line") {
    ScratchDir dir("cli-surface-modes");
    const Files f = sphere_with_circle(dir);
    for (const std::string extra :
         {"--level-set none", "--level-set components", "--soft-weight 0", "--preserve-normals", "--t-coef 4",
          "--intrinsic-delaunay", "--intrinsic-delaunay --refine --min-angle 20", "--unsigned"}) {
        const auto r = run_cli("shm surface " + f.mesh + " --curves " + f.curves + " -o " + dir.file("p.npy") + " " + extra);
        CHECK_MESSAGE(r.exit_code == 0, extra << ": " << r.output);
    }
    // --unsigned: no negative side.
    run_cli("shm surface " + f.mesh + " --curves " + f.curves + " -o " + dir.file("u.npy") + " --unsigned");
    double lowest = INFINITY;
    for (double x : io::read_npy(dir.file("u.npy")).data) lowest = std::min(lowest, x);
    CHECK(lowest > -0.05);
}

TEST_CASE("shm surface --integrate l1: φ per corner and the jumps around a torus' tube") {
    ScratchDir dir("cli-surface-l1");
    const std::string mesh = dir.file("torus.obj"), curve = dir.file("meridian.txt");
    REQUIRE(run_cli("mesh torus -r 24 -o " + mesh).exit_code == 0);
    REQUIRE(run_cli("curve " + mesh + " --plane 0 1 0 0 --near 0.5 0 0 -o " + curve).exit_code == 0);
    const std::string base = "shm surface " + mesh + " --curves " + curve + " -o " + dir.file("phi.npy");
    const auto r = run_cli(base + " --integrate l1 --corners " + dir.file("c.npy") + " --jumps " + dir.file("j.obj") +
                           " --render " + dir.file("p.png") + " --isolines " + dir.file("i.obj") + " --colored " +
                           dir.file("c.ply") + " -v");
    REQUIRE_MESSAGE(r.exit_code == 0, r.output);
    CHECK(r.output.find("L1 integration: φ jumps along 1 polylines") != std::string::npos);
    const SurfaceMesh surface(io::read_mesh(mesh));
    const io::NpyArray corners = io::read_npy(dir.file("c.npy"));
    REQUIRE(corners.shape == std::vector<std::size_t>{surface.triangle_count(), 3});
    // The jump: one closed polyline on the far side of the tube (x < 0), φ higher on its left.
    std::ifstream obj(dir.file("j.obj"));
    std::string line;
    int points = 0, lines = 0;
    while (std::getline(obj, line)) {
        double x, y, z;
        if (std::sscanf(line.c_str(), "v %lf %lf %lf", &x, &y, &z) == 3) {
            ++points;
            CHECK(x < -0.2);
        }
        lines += line.rfind("l ", 0) == 0;
    }
    CHECK(points > 8);
    CHECK(lines == 1);
    // The colored mesh has a vertex per triangle corner, so the jump shows.
    CHECK(io::read_mesh(dir.file("c.ply")).vertices.rows() == Eigen::Index(3 * surface.triangle_count()));
    CHECK(test::file_exists(dir.file("p.png")));
    CHECK(test::file_exists(dir.file("i.obj")));
    // Options that need L1 integration, or that it excludes.
    for (const std::string& bad : std::vector<std::string>{" --corners " + dir.file("x.npy"), " --jumps " + dir.file("x.obj"),
                                  " --integrate l1 --sharpen", " --integrate l3"}) {
        const auto e = run_cli(base + bad);
        CHECK_MESSAGE(e.exit_code != 0, bad);
        CHECK_FALSE(test::file_exists(dir.file("x.npy")));
        CHECK_FALSE(test::file_exists(dir.file("x.obj")));
    }
}

TEST_CASE("shm surface --filter-nonbounding: the loop around the tube left out, the distance to the rest") {
    ScratchDir dir("cli-surface-filter");
    const std::string mesh = dir.file("torus.obj"), meridian = dir.file("m.txt"), loop = dir.file("loop.txt");
    REQUIRE(run_cli("mesh torus -r 24 -o " + mesh).exit_code == 0);
    REQUIRE(run_cli("curve " + mesh + " --plane 0 1 0 0 --near -0.5 0 0 -o " + meridian).exit_code == 0);
    REQUIRE(run_cli("curve " + mesh + " --sphere 0.7 0 0 0.15 -o " + loop).exit_code == 0);
    const auto r = run_cli("shm surface " + mesh + " --curves " + meridian + " " + loop + " --filter-nonbounding -o " +
                           dir.file("f.npy") + " --render " + dir.file("f.png"));
    REQUIRE_MESSAGE(r.exit_code == 0, r.output);
    CHECK(r.output.find("1 nonbounding polylines left out") != std::string::npos);
    REQUIRE(run_cli("shm surface " + mesh + " --curves " + loop + " -o " + dir.file("loop.npy")).exit_code == 0);
    const io::NpyArray filtered = io::read_npy(dir.file("f.npy")), direct = io::read_npy(dir.file("loop.npy"));
    REQUIRE(filtered.data.size() == direct.data.size());
    for (std::size_t i = 0; i < direct.data.size(); ++i) CHECK(filtered.data[i] == doctest::Approx(direct.data[i]).epsilon(1e-5).scale(1));
    // Only a loop around the tube: nothing bounds, a clear error and no output.
    const auto e = run_cli("shm surface " + mesh + " --curves " + meridian + " --filter-nonbounding -o " + dir.file("x.npy"));
    CHECK(e.exit_code != 0);
    CHECK(e.output.find("every curve bounds nothing") != std::string::npos);
    CHECK_FALSE(test::file_exists(dir.file("x.npy")));
    CHECK(run_cli("shm surface " + mesh + " --curves " + loop + " --filter-nonbounding --unsigned -o " + dir.file("x.npy")).exit_code != 0);
}

TEST_CASE("shm surface: curves from an .obj's own l lines, points from --points") {
    ScratchDir dir("cli-surface-obj");
    const PolygonMesh m = shapes::icosphere(2);
    std::string obj;
    for (Eigen::Index i = 0; i < m.vertices.rows(); ++i)
        obj += "v " + std::to_string(m.vertices(i, 0)) + " " + std::to_string(m.vertices(i, 1)) + " " +
               std::to_string(m.vertices(i, 2)) + "\n";
    for (std::size_t k = 0; k < m.face_count(); ++k)
        obj += "f " + std::to_string(m.indices[3 * k] + 1) + " " + std::to_string(m.indices[3 * k + 1] + 1) + " " +
               std::to_string(m.indices[3 * k + 2] + 1) + "\n";
    const std::string with_lines = dir.file("lines.obj");
    test::write_bytes(with_lines, obj + "l 1 2 3\n");
    const auto r = run_cli("shm surface " + with_lines + " -o " + dir.file("a.npy"));
    CHECK_MESSAGE(r.exit_code == 0, r.output);
    test::write_bytes(dir.file("pts.txt"), "v 1\nv 5\n");
    const auto p = run_cli("shm surface " + with_lines + " --points " + dir.file("pts.txt") + " -o " + dir.file("b.npy"));
    REQUIRE_MESSAGE(p.exit_code == 0, p.output);
    const io::NpyArray b = io::read_npy(dir.file("b.npy"));
    CHECK(b.data[0] == doctest::Approx(0).scale(1));  // distance 0 at the points themselves
    CHECK(b.data[4] == doctest::Approx(0).scale(1));
}

TEST_CASE("shm surface: bad input is a clear error naming the file and line, and leaves no output") {
    ScratchDir dir("cli-surface-bad");
    const Files f = sphere_with_circle(dir);
    const std::string out = dir.file("phi.npy");
    test::write_bytes(dir.file("bad.txt"), "#offset 0\nv 0\nv 100000\nl 0 1\n");
    auto r = run_cli("shm surface " + f.mesh + " --curves " + dir.file("bad.txt") + " -o " + out);
    CHECK(r.exit_code == 1);
    CHECK(r.output.find("bad.txt: line 3: vertex index 100000 is out of range") != std::string::npos);
    CHECK_FALSE(test::file_exists(out));

    // Isolines so dense they would fill the disk, and options that are not finite numbers.
    r = run_cli("shm surface " + f.mesh + " --curves " + f.curves + " -o " + out + " --isolines " + dir.file("i.obj") +
                " --isoline-spacing 1e-9");
    CHECK(r.exit_code == 1);
    CHECK(r.output.find("--isoline-spacing: 1e-09 gives") != std::string::npos);
    CHECK_FALSE(test::file_exists(out));
    CHECK_FALSE(test::file_exists(dir.file("i.obj")));
    r = run_cli("shm surface " + f.mesh + " --curves " + f.curves + " -o " + out + " --t-coef inf");
    CHECK(r.exit_code == 2);
    CHECK(r.output.find("'inf' is not a finite number") != std::string::npos);
    CHECK_FALSE(test::file_exists(out));

    // A strip a billionth as high as it is long: the operator cannot be factored, and the error
    // names the mesh and why.
    std::string strip;
    for (int i = 0; i < 30; ++i) strip += "v " + std::to_string(i) + " 0 0\nv " + std::to_string(i) + " 1e-9 0\n";
    for (int i = 0; i < 29; ++i)
        strip += "f " + std::to_string(2 * i + 1) + " " + std::to_string(2 * i + 3) + " " + std::to_string(2 * i + 4) + "\nf " +
                 std::to_string(2 * i + 1) + " " + std::to_string(2 * i + 4) + " " + std::to_string(2 * i + 2) + "\n";
    strip += "l 1 60\n";
    test::write_bytes(dir.file("strip.obj"), strip);
    r = run_cli("shm surface " + dir.file("strip.obj") + " -o " + out);
    CHECK(r.exit_code == 1);
    CHECK_MESSAGE(r.output.find("strip.obj: its surface operator") != std::string::npos, r.output);
    CHECK_FALSE(test::file_exists(out));

    test::write_bytes(dir.file("nan.txt"), "v 1\ne 2 nan\nl 1 2\n");
    r = run_cli("shm surface " + f.mesh + " --curves " + dir.file("nan.txt") + " -o " + out);
    CHECK(r.exit_code == 1);
    CHECK(r.output.find("nan.txt: line 2") != std::string::npos);

    // Outputs go all or none: a render into a missing folder fails after φ was computed.
    r = run_cli("shm surface " + f.mesh + " --curves " + f.curves + " -o " + out + " --render " + dir.file("no/such/dir.png"));
    CHECK(r.exit_code == 1);
    CHECK_FALSE(test::file_exists(out));

    // Usage errors exit 2.
    io::write_mesh(dir.file("m.ply"), io::read_mesh(f.mesh));
    CHECK(run_cli("shm surface " + dir.file("m.ply") + " -o " + out).exit_code == 2);  // no curves anywhere
    CHECK(run_cli("shm surface " + f.mesh + " --curves " + f.curves + " -o " + out + " --refine").exit_code == 2);
    CHECK(run_cli("shm surface " + f.mesh + " --curves " + f.curves + " -o " + dir.file("phi.txt")).exit_code == 2);
    CHECK(run_cli("shm surface " + f.mesh + " --curves " + f.curves + " -o " + out + " --level-set sometimes").exit_code == 2);
    CHECK_FALSE(test::file_exists(out));
}

TEST_CASE("curve: the intersection with a plane or sphere, whole or broken, as a curve file") {
    ScratchDir dir("cli-curve");
    const std::string mesh = dir.file("s.obj");
    io::write_mesh(mesh, shapes::icosphere(3));
    auto r = run_cli("curve " + mesh + " --plane 0 0 1 0.2 -o " + dir.file("whole.txt"));
    REQUIRE_MESSAGE(r.exit_code == 0, r.output);
    const SurfaceMesh m(io::read_mesh(mesh));
    const SurfaceSources whole = read_surface_curves(dir.file("whole.txt"), m);
    REQUIRE(whole.curves.size() == 1);
    for (const SurfacePoint& p : whole.curves[0].nodes) CHECK(position(m, p).z() == doctest::Approx(0.2));
    r = run_cli("curve " + mesh + " --sphere 0 0 1 0.8 --break 0.4 --gaps 2 --seed 3 -o " + dir.file("broken.txt"));
    REQUIRE_MESSAGE(r.exit_code == 0, r.output);
    const SurfaceSources broken = read_surface_curves(dir.file("broken.txt"), m);
    CHECK(broken.curves.size() >= 1);
    CHECK(run_cli("curve " + mesh + " --plane 0 0 1 5 -o " + dir.file("x.txt")).exit_code == 1);  // misses the mesh
    CHECK(run_cli("curve " + mesh + " -o " + dir.file("x.txt")).exit_code == 2);
}

TEST_CASE("point clouds: gsd curve, shm surface and swn on a cloud without faces, values per point") {
    ScratchDir dir("cli-cloud");
    // An unoriented cloud (.xyz, 3 numbers per line) sampled from the unit sphere.
    const std::string cloud = dir.file("sphere.xyz");
    REQUIRE(run_cli("sample sphere -n 3000 --seed 4 -o " + dir.file("s.ply")).exit_code == 0);
    const PointCloud sampled = io::read_point_cloud(dir.file("s.ply"));
    {
        std::ofstream out(cloud);
        for (Eigen::Index i = 0; i < sampled.points.rows(); ++i)
            out << sampled.points(i, 0) << ' ' << sampled.points(i, 1) << ' ' << sampled.points(i, 2) << '\n';
    }
    const PointCloud x = io::read_cloud_points(cloud);
    const Eigen::Vector3d center = x.points.colwise().mean().transpose();
    const std::string curve = dir.file("c.txt");
    // n·x < d on the curve's left: below the plane is inside.
    auto r = run_cli("curve " + cloud + " --plane 0 0 1 " + std::to_string(center.z() + 0.1) + " -o " + curve);
    REQUIRE_MESSAGE(r.exit_code == 0, r.output);
    std::ifstream in(curve);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    CHECK(text.find("\ne ") == std::string::npos);  // points only: v records
    CHECK(text.find("\nv ") != std::string::npos);

    const std::string phi = dir.file("phi.npy");
    r = run_cli("shm surface " + cloud + " --curves " + curve + " -o " + phi + " --render " + dir.file("p.png") +
                " --isolines " + dir.file("iso.obj"));
    REQUIRE_MESSAGE(r.exit_code == 0, r.output);
    CHECK(r.output.find("per point") != std::string::npos);
    const io::NpyArray values = io::read_npy(phi);
    REQUIRE(values.shape == std::vector<std::size_t>{std::size_t(x.points.rows())});
    const double radius = (x.points.rowwise() - center.transpose()).rowwise().norm().mean();
    int wrong = 0;
    for (Eigen::Index i = 0; i < x.points.rows(); ++i) {
        const double h = x.points(i, 2) - center.z() - 0.1;  // height above the plane
        if (std::abs(h) > 0.15 * radius) wrong += (values.data[std::size_t(i)] < 0) != (h < 0);
    }
    CHECK(wrong == 0);
    CHECK(test::file_exists(dir.file("p.png")));
    CHECK(test::file_exists(dir.file("iso.obj")));

    // SWN on the cloud: labels per point, 1 below the plane.
    const std::string labels = dir.file("l.npy");
    r = run_cli("swn " + cloud + " --curves " + curve + " -o " + labels + " --render " + dir.file("l.png"));
    REQUIRE_MESSAGE(r.exit_code == 0, r.output);
    const io::NpyArray l = io::read_npy(labels);
    REQUIRE(l.shape == std::vector<std::size_t>{std::size_t(x.points.rows())});
    wrong = 0;
    for (Eigen::Index i = 0; i < x.points.rows(); ++i) {
        const double h = x.points(i, 2) - center.z() - 0.1;
        if (std::abs(h) > 0.15 * radius) wrong += (l.data[std::size_t(i)] == 1) != (h < 0);
    }
    CHECK(wrong == 0);

    // Records that name a mesh's edges or faces mean nothing on a cloud.
    test::write_bytes(dir.file("e.txt"), "e 1 0.5\ne 2 0.5\ne 3 0.5\nl 1 2 3\n");
    r = run_cli("shm surface " + cloud + " --curves " + dir.file("e.txt") + " -o " + dir.file("bad.npy"));
    CHECK(r.exit_code == 1);
    CHECK(r.output.find("name cloud points") != std::string::npos);
    CHECK_FALSE(test::file_exists(dir.file("bad.npy")));
    r = run_cli("shm surface " + cloud + " --curves " + curve + " --neighbors 2 -o " + dir.file("bad.npy"));
    CHECK(r.exit_code == 2);
}
