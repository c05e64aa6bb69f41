// `gsd swn` as a user meets it: labels per input face (int32) with the sign convention end to end,
// w per corner, the curve decomposition as OBJ groups, the picture, the SHM-sign alternative,
// curves from an .obj's own l lines, exit codes and messages on bad input, no partial outputs.
#include <doctest/doctest.h>

#include <gsd/io.hpp>
#include <gsd/shapes.hpp>
#include <gsd/surface.hpp>

#include "support.hpp"

#include <filesystem>

#include <fstream>
#include <iterator>
#include <vector>

using namespace gsd;
using test::run_cli;
using test::ScratchDir;

namespace {

std::string slurp(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/// A torus with a small loop on its outer side (counter-clockwise seen from outside) and a loop
/// around its tube along mesh edges.
struct Files {
    std::string mesh, curves;
    PolygonMesh m;
};

Files torus_with_loops(const ScratchDir& dir) {
    Files f{dir.file("torus.obj"), dir.file("loops.txt"), shapes::torus_mesh(48, 16)};
    io::write_mesh(f.mesh, f.m);
    const SurfaceMesh mesh(f.m);
    std::vector<double> d(mesh.vertex_count());
    for (std::size_t i = 0; i < d.size(); ++i)
        d[i] = (f.m.vertices.row(Eigen::Index(i)).transpose() - Eigen::Vector3d(0.7, 0, 0)).norm() - 0.25;
    SurfaceSources s;
    s.curves = level_set_curves(mesh, d, 0);  // d < 0 (near (0.7, 0, 0)) on the left
    SurfaceCurve around;
    for (int j = 0; j <= 16; ++j) around.nodes.push_back(SurfacePoint::at_vertex(std::uint32_t(24 * 16 + j % 16)));
    s.curves.push_back(around);
    write_surface_curves(f.curves, s);
    return f;
}

}  // namespace

TEST_CASE("swn: int32 labels per face (+1 inside the loop), w per corner, loops and a picture") {
    ScratchDir dir("cli-swn");
    const Files f = torus_with_loops(dir);
    const auto r = run_cli("-v swn " + f.mesh + " --curves " + f.curves + " -o " + dir.file("labels.npy") + " --w " +
                           dir.file("w.npy") + " --loops " + dir.file("loops.obj") + " --render " + dir.file("pic.png"));
    REQUIRE_MESSAGE(r.exit_code == 0, r.output);
    CHECK(r.output.find("nonbounding") != std::string::npos);
    const std::string bytes = slurp(dir.file("labels.npy"));
    CHECK(bytes.find("'descr': '<i4'") != std::string::npos);
    const io::NpyArray labels = io::read_npy(dir.file("labels.npy"));
    REQUIRE(labels.shape == std::vector<std::size_t>{f.m.face_count()});
    for (std::size_t t = 0; t < f.m.face_count(); ++t) {
        const std::uint32_t* v = f.m.indices.data() + f.m.offsets[t];
        const Eigen::Vector3d c = (f.m.vertices.row(v[0]) + f.m.vertices.row(v[1]) + f.m.vertices.row(v[2])).transpose() / 3;
        const double d = (c - Eigen::Vector3d(0.7, 0, 0)).norm();
        if (d < 0.2) CHECK(labels.data[t] == 1);  // inside the loop
        if (d > 0.3) CHECK(labels.data[t] == 0);  // outside: the loop around the tube changes nothing
    }
    const io::NpyArray w = io::read_npy(dir.file("w.npy"));
    CHECK(w.shape == std::vector<std::size_t>{f.m.face_count(), 3});
    const std::string loops = slurp(dir.file("loops.obj"));
    for (const char* g : {"g bounding\n", "g nonbounding\n", "g completed\n"}) CHECK(loops.find(g) != std::string::npos);
    CHECK(loops.find("\nl ") != std::string::npos);
    CHECK(test::file_exists(dir.file("pic.png")));
}

TEST_CASE("swn: the options run; --method shm labels by the sign of the surface SHM") {
    ScratchDir dir("cli-swn-options");
    const Files f = torus_with_loops(dir);
    const std::vector<std::string> options = {"--lp full",        "--lp none",    "--lp-solver clp",
                                              "--curve-weight 0.01", "--boundary-aware", "--no-close-gaps",
                                              "--close-gaps",     "--method shm",
                                              std::string("--method shm --render ").append(dir.file("s.png"))};
    for (const std::string& extra : options) {
        const auto r = run_cli("swn " + f.mesh + " --curves " + f.curves + " -o " + dir.file("l.npy") + " " + extra);
        CHECK_MESSAGE(r.exit_code == 0, extra << ": " << r.output);
    }
    // SHM's sign on the small loop alone: 1 inside, 0 outside.
    const SurfaceMesh mesh(f.m);
    SurfaceSources loop = read_surface_curves(f.curves, mesh);
    loop.curves.pop_back();
    write_surface_curves(dir.file("loop.txt"), loop);
    REQUIRE(run_cli("swn " + f.mesh + " --curves " + dir.file("loop.txt") + " -o " + dir.file("s.npy") + " --method shm").exit_code == 0);
    const io::NpyArray s = io::read_npy(dir.file("s.npy"));
    double inside = 0;
    for (double x : s.data) inside += x;
    CHECK(inside > 0);
    CHECK(inside < 0.2 * double(s.data.size()));
}

TEST_CASE("swn: curves from the mesh's own l lines") {
    ScratchDir dir("cli-swn-obj");
    const Files f = torus_with_loops(dir);
    // Append the loop around the tube as an l line (1-based) to a copy of the mesh.
    std::string obj = slurp(f.mesh);
    obj += "l";
    for (int j = 0; j <= 16; ++j) obj.append(" ").append(std::to_string(24 * 16 + j % 16 + 1));
    obj += "\n";
    test::write_bytes(dir.file("with_lines.obj"), obj);
    const auto r = run_cli("-v swn " + dir.file("with_lines.obj") + " -o " + dir.file("l.npy"));
    REQUIRE_MESSAGE(r.exit_code == 0, r.output);
    for (double x : io::read_npy(dir.file("l.npy")).data) CHECK(x == 0);  // bounds nothing
}

TEST_CASE("swn: bad input is a clear error and leaves no output") {
    ScratchDir dir("cli-swn-bad");
    const Files f = torus_with_loops(dir);
    const std::string out = dir.file("l.npy");
    auto fails = [&](const std::string& args, const std::string& message, int code) {
        const auto r = run_cli(args);
        CHECK_MESSAGE(r.exit_code == code, args << ": " << r.output);
        CHECK_MESSAGE(r.output.find(message) != std::string::npos, args << ": " << r.output);
        CHECK_FALSE(test::file_exists(out));
    };
    fails("swn " + f.mesh + " --curves " + f.curves + " -o " + dir.file("l.txt"), ".npy", 2);
    fails("swn " + f.mesh + " --curves " + f.curves + " -o " + out + " --loops " + dir.file("x.ply"), ".obj", 2);
    fails("swn " + f.mesh + " --curves " + f.curves + " -o " + out + " --lp simplex", "--lp", 2);
    fails("swn " + f.mesh + " --curves " + f.curves + " -o " + out + " --method shm --w " + dir.file("w.npy"), "--method shm", 2);
    fails("swn " + f.mesh + " --curves " + f.curves + " -o " + out + " --curve-weight nan", "not a finite number", 2);
    fails("swn " + f.mesh + " --curves " + f.curves + " -o " + out + " --w " + out, "named by two outputs", 1);
    test::write_bytes(dir.file("bad.txt"), "#offset 0\nv 0\nv 999999\nl 0 1\n");
    fails("swn " + f.mesh + " --curves " + dir.file("bad.txt") + " -o " + out, "bad.txt", 1);
    // Out-of-range indices are reported as the file wrote them: from 1 unless it says #offset 0.
    test::write_bytes(dir.file("one.txt"), "v 1\nv 999999\nl 1 2\n");
    fails("swn " + f.mesh + " --curves " + dir.file("one.txt") + " -o " + out,
          "line 2: vertex index 999999 is out of range (the mesh has 768 vertices, numbered from 1 here)", 1);
    test::write_bytes(dir.file("empty.txt"), "#offset 0\nv 0\n");
    fails("swn " + f.mesh + " --curves " + dir.file("empty.txt") + " -o " + out, "no curves", 1);
    fails("swn " + dir.file("missing.obj") + " --curves " + f.curves + " -o " + out, "missing.obj", 1);
    // A curve file as the mesh: .txt is a point-cloud format, so it needs --curves, and with them
    // it does not read as a cloud.
    fails("swn " + f.curves + " -o " + out, "--curves", 2);
    fails("swn " + f.curves + " --curves " + f.curves + " -o " + out, f.curves + ": line", 1);
    // MESH after the --curves list: the list takes it, and the error says so.
    fails("swn --curves " + f.curves + " " + f.mesh + " -o " + out, "--curves took '" + f.mesh + "'", 2);
    CHECK(run_cli("swn --curves " + f.curves + " -- " + f.mesh + " -o " + out + " -q").exit_code == 0);
    std::filesystem::remove(out);
    // Three faces on one edge: SWN refuses with the reason, SHM's sign still works.
    test::write_bytes(dir.file("fan.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\nl 3 1\n");
    fails("swn " + dir.file("fan.obj") + " -o " + out, "manifold", 1);
    CHECK(run_cli("swn " + dir.file("fan.obj") + " -o " + out + " --method shm").exit_code == 0);
}
