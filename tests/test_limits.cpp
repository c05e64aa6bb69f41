// Work whose size depends on coordinate values is bounded, extreme coordinates are refused
// with the element named, outputs never replace special files: the hardening issue's findings
// (hangs, overflows, unbounded memory) as regression tests, at the API and at the CLI.
#include <doctest/doctest.h>

#include <gsd/io.hpp>
#include <gsd/pat.hpp>
#include <gsd/shapes.hpp>
#include <gsd/shm.hpp>

#include "support.hpp"

#include <sys/stat.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>

using namespace gsd;
using test::run_cli;
using test::run_shell;
using test::ScratchDir;

namespace {

PolygonMesh unit_triangle() {
    PolygonMesh m;
    m.vertices.resize(3, 3);
    m.vertices << 0, 0, 0, 1, 0, 0, 0, 1, 0;
    m.add_face({0, 1, 2});
    return m;
}

Eigen::Vector3d total_vector_area(const ShmSource& s) { return s.elements.vectors.colwise().sum().transpose(); }

std::string cloud_text(double far) {
    std::string s;
    for (int i = 0; i < 40; ++i) s += std::to_string(0.1 * (i % 7)) + " " + std::to_string(0.1 * (i / 7)) + " 0 0 0 1\n";
    s += std::to_string(far) + " 0 0 0 0 1\n";
    return s;
}

}  // namespace

TEST_CASE("mesh sources: a face far larger than a tight grid costs work near the grid only, and is signed right") {
    // The old sources split every face to the grid spacing: 4^10 (4^30) pieces for a unit
    // triangle under a 1e-3 (1e-9) box. Now the triangle is one element, refined adaptively
    // near each node only, so the work per node is bounded by the depth of that refinement.
    const PolygonMesh tri = unit_triangle();
    const ShmSource src = shm_source(tri);
    CHECK(src.size() == 1);
    CHECK((total_vector_area(src) - Eigen::Vector3d(0, 0, 0.5)).norm() < 1e-15);
    for (double side : {1e-3, 1e-9}) {
        CAPTURE(side);
        const GridSpec g = GridSpec::cube(12, Box{{0.2, 0.2, -side}, {0.2 + side, 0.2 + side, side}});
        ShmOptions o;
        o.device = "cpu";
        const ShmResult r = SignedHeatGrid(src, g, o).solve();
        // Refinement stops at r_floor (1e-3 h): ~10 levels of a few dozen pieces per node.
        CHECK(r.kernel_terms < g.node_count() * 2000);
        // The face's normal is +z: φ > 0 above it, < 0 below.
        for (int i = 0; i < g.nx; ++i)
            for (int k = 0; k < g.nz; ++k) {
                const float phi = r.phi[std::size_t((i * g.ny + 5) * g.nz + k)];
                if (k < 5) CHECK(phi < 0);
                if (k > 6) CHECK(phi > 0);
            }
    }
}

TEST_CASE("far geometry: a face with a corner at 1e30, or a stray vertex 10^9 edges away, costs what the grid sees") {
    // Issue 32: the zero-set fit sampled a face by its own extent (one triangle reaching 1e30
    // spun for ever under a [-1, 1]³ crop), step 1 refined a 4·10⁹-long needle near every node,
    // and one stray vertex set the mean edge length — the diffusion time — 10⁴× too large.
    ScratchDir dir("far");
    const std::string d = dir.path().string() + "/";
    test::write_bytes(d + "needle.obj", "v 0 0 0\nv 1 0 0\nv 0 1 1e30\nf 1 2 3\n");
    auto r = run_cli("shm grid " + d + "needle.obj --grid 8 --bounds -1 -1 -1 1 1 1 -o " + d + "needle.npy");
    CHECK(r.exit_code == 0);
    const io::NpyArray phi = io::read_grid(d + "needle.npy");
    for (double v : phi.data) CHECK(std::isfinite(v));
    // The same on both device paths where one is there (GPU φ within its tolerance of the CPU's).
    for (const char* device : {"cpu", "gpu"}) {
        CAPTURE(device);
        ShmOptions o;
        o.device = device;
        const PolygonMesh m = io::read_mesh(d + "needle.obj");
        const ShmResult res = SignedHeatGrid(shm_source(m), GridSpec::cube(8, Box{{-1, -1, -1}, {1, 1, 1}}), o).solve();
        for (float v : res.phi) CHECK(std::isfinite(v));
    }

    // A 24×24 grid of triangles in z = 0 with one corner moved 4·10⁹ away: the scale stays the
    // typical edge's (each length counts at most 100 medians), and φ under a crop is what the
    // intact plane gives, sign for sign.
    constexpr int n = 24;
    PolygonMesh plane;
    plane.vertices.resize((n + 1) * (n + 1), 3);
    for (int i = 0; i <= n; ++i)
        for (int j = 0; j <= n; ++j) plane.vertices.row((n + 1) * i + j) << 2.0 * i / n - 1, 2.0 * j / n - 1, 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            const auto a = std::uint32_t((n + 1) * i + j), row = std::uint32_t(n + 1);
            plane.add_face({a, a + row, a + row + 1});
            plane.add_face({a, a + row + 1, a + 1});
        }
    PolygonMesh stray = plane;
    stray.vertices((n + 1) * (n + 1) - 1, 1) = 4294967295.0;
    CHECK(shm_source(stray).spacing == doctest::Approx(shm_source(plane).spacing).epsilon(0.25));
    ShmOptions o;
    o.device = "cpu";
    const GridSpec g = GridSpec::cube(16, Box{{-0.6, -0.6, -0.6}, {0.6, 0.6, 0.6}});
    const ShmResult intact = SignedHeatGrid(shm_source(plane), g, o).solve();
    const ShmResult broken = SignedHeatGrid(shm_source(stray), g, o).solve();
    std::size_t same = 0;
    for (std::size_t i = 0; i < intact.phi.size(); ++i) same += (intact.phi[i] > 0) == (broken.phi[i] > 0);
    CHECK(double(same) / double(intact.phi.size()) > 0.98);
}

TEST_CASE("far geometry on surfaces: a stray vertex 10^9 edges away leaves the rest of the mesh solvable") {
    // The surface operators took their scale from a plain mean of the edges (one far vertex made
    // every ordinary face "degenerate"), and kept the stray faces, whose stiffness against the
    // others' cannot be factored in double. Now: a robust scale, and faces spanning more than
    // 10⁶ typical edges count as degenerate (docs/io.md, "Work bounds").
    ScratchDir dir("far-surface");
    const std::string d = dir.path().string() + "/";
    PolygonMesh m = shapes::icosphere(2);
    m.vertices(7, 1) *= 4294967295.0;
    io::write_mesh(d + "far.obj", m);
    auto r = run_cli("curve " + d + "far.obj --plane 0 0 1 0 -o " + d + "loop.txt");
    REQUIRE(r.exit_code == 0);
    r = run_cli("shm surface " + d + "far.obj --curves " + d + "loop.txt -o " + d + "phi.npy");
    CHECK(r.exit_code == 0);
    const io::NpyArray phi = io::read_npy(d + "phi.npy");
    std::size_t finite = 0;
    for (double v : phi.data) finite += std::isfinite(v);
    CHECK(finite + 1 >= phi.data.size());  // every vertex but, at most, the stray one
    r = run_cli("swn " + d + "far.obj --curves " + d + "loop.txt -o " + d + "labels.npy");
    CHECK(r.exit_code == 0);
}

TEST_CASE("tiny cells: a grid whose cells double precision cannot resolve at its coordinates is refused") {
    CHECK_THROWS_WITH_AS(GridSpec::cube(8, Box{{1e6, 1e6, 1e6}, {1e6 + 1e-9, 1e6 + 1e-9, 1e6 + 1e-9}}).validate(),
                         doctest::Contains("too small"), Error);
    CHECK_THROWS_AS(GridSpec::cube(8, Box{{0, 0, 0}, {1e-120, 1e-120, 1e-120}}).validate(), Error);
    CHECK_NOTHROW(GridSpec::cube(8, Box{{0, 0, 0}, {1e-3, 1e-3, 1e-3}}).validate());
}

TEST_CASE("memory budget: GSD_MEMORY_LIMIT is read, and work past it is refused before allocating") {
    ::setenv("GSD_MEMORY_LIMIT", "1M", 1);
    CHECK(memory_budget() == (std::size_t(1) << 20));
    CHECK_THROWS_WITH_AS(check_memory(2e6, "x", "a test"), doctest::Contains("memory budget"), Error);
    CHECK_NOTHROW(check_memory(1e5, "x", "a test"));
    ::setenv("GSD_MEMORY_LIMIT", "lots", 1);
    CHECK_THROWS_AS(memory_budget(), Error);
    ::unsetenv("GSD_MEMORY_LIMIT");
    CHECK(memory_budget() > (std::size_t(1) << 26));
}

TEST_CASE("memory budget: fitting, blending and the surface commands estimate their memory from the input first") {
    test::ScratchDir dir("limits-memory");
    const std::string d = dir.file("");
    REQUIRE(test::run_cli("sample torus -n 3000 -o " + d + "c.ply").exit_code == 0);
    REQUIRE(test::run_cli("mesh torus -r 24 -o " + d + "t.obj").exit_code == 0);
    REQUIRE(test::run_cli("curve " + d + "t.obj --plane 0 1 0 0 --near 0.5 0 0 -o " + d + "loop.txt").exit_code == 0);
    // 3000 points need ~1.5 MiB for the jet fit, ~6 MiB for TorusNet; the torus mesh (a few
    // thousand vertices) tens of MiB for the surface methods. A 1 MiB budget refuses each, by
    // name, with no output; the default budget runs them.
    // Fitting turns flipped normals back first, which needs its own ~2.2 MiB (--keep-normals skips it).
    const std::vector<std::pair<std::string, std::string>> runs = {
        {"pat fit " + d + "c.ply --fitter jet -o " + d + "j.tori", "voting on the normals of 3000 points"},
        {"pat fit " + d + "c.ply --fitter jet --keep-normals -o " + d + "jk.tori", "fitting jets to 3000 points"},
        {"pat fit " + d + "c.ply --fitter net --keep-normals --device cpu -o " + d + "n.tori", "fitting TorusNet to 3000 points"},
        {"shm surface " + d + "t.obj --curves " + d + "loop.txt -o " + d + "s.npy", "Signed Heat Method on"},
        {"swn " + d + "t.obj --curves " + d + "loop.txt -o " + d + "w.npy", "Surface Winding Numbers on"},
    };
    for (const auto& run : runs) {
        const std::string& args = run.first;  // (clang 14 cannot CAPTURE a structured binding)
        const std::string& what = run.second;
        CAPTURE(args);
        const auto refused = test::run_shell("GSD_MEMORY_LIMIT=1M " GSD_CLI " " + args);
        CHECK(refused.exit_code == 1);
        CHECK(refused.output.find(what) != std::string::npos);
        CHECK(refused.output.find("memory budget") != std::string::npos);
        CHECK_FALSE(test::file_exists(args.substr(args.rfind(' ') + 1)));
        CHECK(test::run_cli(args).exit_code == 0);
    }
    // The fast sums' tree over a mesh's faces (gsd winding, gsd shm grid).
    for (const std::string cmd : {"winding ", "shm grid "}) {
        CAPTURE(cmd);
        const auto tree = test::run_shell("GSD_MEMORY_LIMIT=1M " GSD_CLI " " + cmd + d + "t.obj --grid 4 -o " + d + "tree.npy");
        CHECK(tree.exit_code == 1);
        CHECK(tree.output.find("a summation tree over") != std::string::npos);
        CHECK_FALSE(test::file_exists(d + "tree.npy"));
    }
    // The blend of already fitted tori (pat eval --tori) is estimated too.
    io::write_npy(d + "q.npy", {1, 3}, std::vector<float>{0, 0, 0});
    const auto blend = test::run_shell("GSD_MEMORY_LIMIT=1M " GSD_CLI " pat eval --tori " + d + "j.tori --queries " + d +
                                       "q.npy -o " + d + "e.npy");
    CHECK(blend.exit_code == 1);
    CHECK(blend.output.find("a torus field of 3000 points") != std::string::npos);
}

TEST_CASE("coordinates: beyond ±1e30, or one element 1e12× the bulk's size away, are refused with the element named") {
    PointCloud c;
    c.points = Points::Random(50, 3);
    c.normals = Points::Constant(50, 3, 1.0);
    PointCloud huge = c;
    huge.points(7, 1) = 1e200;
    CHECK_THROWS_WITH_AS(validate(huge, "f.ply"), doctest::Contains("element 7"), Error);
    PointCloud stray = c;
    stray.points(11, 0) = 1e15;
    CHECK_THROWS_WITH_AS(validate(stray, "f.ply"), doctest::Contains("point 11"), Error);
    PointCloud fine = c;
    fine.points(11, 0) = 1e9;  // far, but a grid over it still resolves the bulk in double
    CHECK_NOTHROW(validate(fine, "f.ply"));
    PolygonMesh m = unit_triangle();
    m.vertices(2, 2) = -1e31;
    CHECK_THROWS_WITH_AS(validate(m, "m.obj"), doctest::Contains("element 2"), Error);
    // Bounds: finite numbers whose difference overflows, or beyond the limit.
    CHECK_THROWS_AS(validate_box(Box{{-1e308, -1, -1}, {1e308, 1, 1}}, "--bounds"), Error);
    CHECK_THROWS_AS(validate_box(Box{{0, 0, 0}, {1e31, 1, 1}}, "--bounds"), Error);
    CHECK_NOTHROW(validate_box(Box{{-1e29, -1, -1}, {1e29, 1, 1}}, "--bounds"));
}

TEST_CASE("CLI: extreme inputs are clear errors with no output; thin grids give bounded pictures") {
    ScratchDir dir("limits");
    const std::string d = dir.path().string() + "/";
    // A mesh at 1e200: an error naming the file and vertex, not a hang.
    test::write_bytes(d + "big.obj", "v 0 0 0\nv 1e200 0 0\nv 0 1e200 0\nf 1 2 3\n");
    auto r = run_cli("shm grid " + d + "big.obj --grid 8 -o " + d + "big.npy");
    CHECK(r.exit_code == 1);
    CHECK(r.output.find("big.obj") != std::string::npos);
    CHECK_FALSE(test::file_exists(d + "big.npy"));
    // A unit triangle on a grid of 1e-3: quick, finite.
    test::write_bytes(d + "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    r = run_cli("shm grid " + d + "tri.obj --grid 8 --bounds 0 0 0 1e-3 1e-3 1e-3 -o " + d + "tri.npy");
    CHECK(r.exit_code == 0);
    const io::NpyArray phi = io::read_grid(d + "tri.npy");
    for (double v : phi.data) CHECK(std::isfinite(v));
    // A cloud near 1e200 (the TorusNet overflow) and one stray point: errors, no output.
    std::string cloud;
    for (int i = 0; i < 40; ++i) cloud += "1e200 " + std::to_string(1e198 * i) + " 0 0 0 1\n";
    test::write_bytes(d + "far.xyz", cloud);
    r = run_cli("pat fit " + d + "far.xyz -o " + d + "far.tori");
    CHECK(r.exit_code == 1);
    CHECK_FALSE(test::file_exists(d + "far.tori"));
    test::write_bytes(d + "stray.xyz", cloud_text(1e14));
    r = run_cli("pat fit " + d + "stray.xyz -o " + d + "stray.tori");
    CHECK(r.exit_code == 1);
    CHECK(r.output.find("point 40") != std::string::npos);
    // Queries at 1e200: an error, not NaN with exit 0.
    test::write_bytes(d + "ok.xyz", cloud_text(0.3));
    io::write_npy(d + "q.npy", {1, 3}, std::vector<float>{0, 0, 0});
    REQUIRE(run_cli("pat eval " + d + "ok.xyz --fitter jet --queries " + d + "q.npy -o " + d + "q-phi.npy").exit_code == 0);
    io::write_npy(d + "qbig.npy", {1, 3}, std::vector<float>{0, 1e30f * 100, 0});
    r = run_cli("pat eval " + d + "ok.xyz --fitter jet --queries " + d + "qbig.npy -o " + d + "qbig-phi.npy");
    CHECK(r.exit_code == 1);
    CHECK_FALSE(test::file_exists(d + "qbig-phi.npy"));
    // Bounds whose difference overflows: errors in every command, no output.
    const std::string wide = " --bounds -1e308 -1 -1 1e308 1 1 ";
    r = run_cli("slice " + d + "tri.npy" + wide + "--at 0 -o " + d + "s.png");
    CHECK(r.exit_code == 1);
    CHECK(r.output.find("--bounds") != std::string::npos);
    CHECK_FALSE(test::file_exists(d + "s.png"));
    CHECK(run_cli("pat eval " + d + "ok.xyz --fitter jet --grid 8" + wide + "-o " + d + "w.npy").exit_code == 1);
    CHECK(run_cli("baseline sspd " + d + "ok.xyz --grid 8" + wide + "-o " + d + "w.npy").exit_code == 1);
    CHECK_FALSE(test::file_exists(d + "w.npy"));
    // A thin (100000, 2, 2) grid: the default picture is capped, not 18 GB.
    io::write_npy(d + "thin.npy", {100000, 2, 2}, std::vector<float>(400000, 0.5f));
    r = run_cli("slice " + d + "thin.npy --bounds 0 0 0 1 1 1 --axis z --at 0.5 -o " + d + "thin.png");
    CHECK(r.exit_code == 0);
    std::ifstream png(d + "thin.png", std::ios::binary);
    std::string head(24, '\0');
    png.read(head.data(), 24);
    const auto be32 = [&](int at) {
        return (unsigned(std::uint8_t(head[at])) << 24) | (unsigned(std::uint8_t(head[at + 1])) << 16) |
               (unsigned(std::uint8_t(head[at + 2])) << 8) | unsigned(std::uint8_t(head[at + 3]));
    };
    CHECK(be32(16) <= 4096);
    CHECK(be32(20) <= 4096);
    // A grid past the memory budget is refused up front.
    r = run_shell("GSD_MEMORY_LIMIT=1M " GSD_CLI " pat eval " + d + "ok.xyz --fitter jet --grid 64 --bounds -1 -1 -1 1 1 1 -o " +
                  d + "m.npy");
    CHECK(r.exit_code == 1);
    CHECK(r.output.find("memory budget") != std::string::npos);
    CHECK_FALSE(test::file_exists(d + "m.npy"));
    // The smallest shape mesh the option accepts.
    r = run_cli("mesh sphere -r 8 -o " + d + "s8.obj");
    CHECK(r.exit_code == 0);
    CHECK(io::read_mesh(d + "s8.obj").face_count() > 0);
}

TEST_CASE("CLI: .tori from a FIFO or /dev/zero is refused; outputs go into FIFOs without replacing them; "
          "a wrong output extension is a usage error") {
    ScratchDir dir("special");
    const std::string d = dir.path().string() + "/";
    std::string cloud;
    for (int i = 0; i < 60; ++i)
        cloud += std::to_string(std::cos(0.1 * i)) + " " + std::to_string(std::sin(0.1 * i)) + " " + std::to_string(0.01 * (i % 5)) +
                 " " + std::to_string(std::cos(0.1 * i)) + " " + std::to_string(std::sin(0.1 * i)) + " 0\n";
    test::write_bytes(d + "c.xyz", cloud);
    REQUIRE(::mkfifo((d + "in.tori").c_str(), 0600) == 0);
    auto r = run_cli("pat eval --tori " + d + "in.tori --grid 8 --bounds -1 -1 -1 1 1 1 -o " + d + "e.npy");
    CHECK(r.exit_code == 1);
    CHECK(r.output.find("not a regular file") != std::string::npos);
    std::filesystem::create_symlink("/dev/zero", d + "zero.tori");
    r = run_cli("pat eval --tori " + d + "zero.tori --grid 8 --bounds -1 -1 -1 1 1 1 -o " + d + "e.npy");
    CHECK(r.exit_code == 1);
    CHECK_FALSE(test::file_exists(d + "e.npy"));
    // -o into a FIFO: the bytes arrive through it, and it is still a FIFO afterwards.
    REQUIRE(::mkfifo((d + "out.tori").c_str(), 0600) == 0);
    std::string received;
    std::thread reader([&] {
        std::ifstream f(d + "out.tori", std::ios::binary);
        received.assign(std::istreambuf_iterator<char>(f), {});
    });
    r = run_cli("pat fit " + d + "c.xyz --fitter jet -o " + d + "out.tori");
    reader.join();
    CHECK(r.exit_code == 0);
    struct stat st {};
    REQUIRE(::stat((d + "out.tori").c_str(), &st) == 0);
    CHECK(S_ISFIFO(st.st_mode));
    CHECK(received.size() > 64);
    CHECK(received.compare(0, 8, "GSDTORI1") == 0);
    test::write_bytes(d + "copy.tori", received);
    CHECK(load_tori(d + "copy.tori").size() == 60);
    // A wrong extension: exit 2 before any work, nothing written.
    r = run_cli("pat fit " + d + "c.xyz --fitter jet -o " + d + "out.txt");
    CHECK(r.exit_code == 2);
    CHECK_FALSE(test::file_exists(d + "out.txt"));
    r = run_cli("pat eval " + d + "c.xyz --fitter jet --grid 8 -o " + d + "phi.txt");
    CHECK(r.exit_code == 2);
    CHECK_FALSE(test::file_exists(d + "phi.txt"));
}
