// gsd::mesh_sdf and `gsd sdf`: the distance against an independent brute force, the sign against
// analytic inside/outside on closed and broken meshes, bad input, the CLI.
#include <gsd/io.hpp>
#include <gsd/sdf.hpp>
#include <gsd/shapes.hpp>

#include "support.hpp"

#include <doctest/doctest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <sstream>

using namespace gsd;
using test::run_cli;
using test::ScratchDir;

namespace {

// Distance from x to segment pq.
double segment_distance(const Eigen::Vector3d& x, const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
    const Eigen::Vector3d e = q - p;
    const double t = e.squaredNorm() > 0 ? std::clamp((x - p).dot(e) / e.squaredNorm(), 0.0, 1.0) : 0.0;
    return (x - (p + t * e)).norm();
}

// Distance from x to triangle abc, written apart from the library's (Voronoi regions there):
// the foot of the perpendicular if it falls inside (barycentric coordinates), else the nearest
// side.
double triangle_distance(const Eigen::Vector3d& x, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                         const Eigen::Vector3d& c) {
    const Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.squaredNorm() > 0) {
        const Eigen::Vector3d f = x - n.dot(x - a) / n.squaredNorm() * n;  // foot on the plane
        const double u = (c - b).cross(f - b).dot(n), v = (a - c).cross(f - c).dot(n), w = (b - a).cross(f - a).dot(n);
        if (u >= 0 && v >= 0 && w >= 0) return (x - f).norm();
    }
    return std::min({segment_distance(x, a, b), segment_distance(x, b, c), segment_distance(x, c, a)});
}

double brute_force(const PolygonMesh& m, const Eigen::Vector3d& x) {
    double best = INFINITY;
    for_each_triangle(m, [&](std::size_t, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
        best = std::min(best, triangle_distance(x, m.vertices.row(a).transpose(), m.vertices.row(b).transpose(),
                                                m.vertices.row(c).transpose()));
    });
    return best;
}

Points uniform_queries(int n, double half, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(-half, half);
    Points q(n, 3);
    for (int i = 0; i < n; ++i) q.row(i) << u(rng), u(rng), u(rng);
    return q;
}

}  // namespace

TEST_CASE("mesh_sdf: |φ| is the exact distance to the triangles, the sign is the sphere's") {
    const PolygonMesh sphere = shapes::icosphere(3);  // 1280 triangles, radius 1
    const Points q = uniform_queries(test::sized(600, 150), 2.0, 7);
    MeshSdfOptions o;
    o.device = "cpu";
    const MeshSdfResult r = mesh_sdf(sphere, q, o);
    REQUIRE(r.phi.size() == std::size_t(q.rows()));
    CHECK(r.triangles == 1280);
    CHECK(r.degenerate == 0);
    CHECK(r.device == "cpu");
    double worst = 0;
    std::size_t wrong_sign = 0, checked = 0;
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
        const Eigen::Vector3d x = q.row(i).transpose();
        const double d = brute_force(sphere, x);
        worst = std::max(worst, std::abs(std::abs(r.phi[std::size_t(i)]) - d) / std::max(d, 1e-3));
        const double exact = x.norm() - 1;  // the sphere the mesh approximates (chords ~0.15 long)
        if (std::abs(exact) > 0.02) {
            ++checked;
            wrong_sign += (r.phi[std::size_t(i)] < 0) != (exact < 0);
            CHECK(std::abs(r.phi[std::size_t(i)] - exact) < 0.02);
        }
    }
    CHECK(worst < 1e-9);
    CHECK(checked > std::size_t(q.rows()) / 2);
    CHECK(wrong_sign == 0);

    o.sign = SdfSign::none;
    const MeshSdfResult u = mesh_sdf(sphere, q, o);
    CHECK(u.winding.empty());
    for (std::size_t i = 0; i < u.phi.size(); ++i) CHECK(u.phi[i] == std::abs(r.phi[i]));
}

TEST_CASE("mesh_sdf on a broken mesh: holes and flipped faces keep the sign away from the surface") {
    const auto torus_shape = shapes::torus(Eigen::Vector3d::Zero(), 0.5, 0.2);
    const shapes::Shape& torus = *torus_shape;
    shapes::MeshCorruption c;
    c.holes = 3;
    c.hole_area = 0.1;
    c.flip_fraction = 0.1;
    const PolygonMesh broken = shapes::corrupt(shapes::mesh(torus, 48), c, 5);
    const Points q = uniform_queries(test::sized(4000, 800), 1.0, 11);
    MeshSdfOptions o;
    o.device = "cpu";
    const MeshSdfResult r = mesh_sdf(broken, q, o);
    std::size_t far = 0, right = 0;
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
        const double exact = torus.sdf(q.row(i).transpose());
        if (std::abs(exact) < 0.05) continue;
        ++far;
        right += (r.phi[std::size_t(i)] < 0) == (exact < 0);
        // the distance is to the damaged mesh, which still lies on the torus where it is left
        CHECK(std::abs(r.phi[std::size_t(i)]) >= std::abs(exact) - 0.02);
    }
    REQUIRE(far > std::size_t(q.rows()) / 3);
    MESSAGE("sign right at " << right << " of " << far << " queries farther than 0.05 from the torus");
    CHECK(double(right) >= 0.99 * double(far));
    // Outside the mesh's bounding box the automatic sign sums nothing: outside, w = 0; inside
    // it, the winding numbers of the repaired faces, deep in the tube ≈ 1.
    REQUIRE(r.winding.size() == std::size_t(q.rows()));
    const Box box = bounding_box(broken.vertices);
    std::size_t outside_box = 0;
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
        const Eigen::Vector3d x = q.row(i).transpose();
        if ((x.array() >= box.lo.array()).all() && (x.array() <= box.hi.array()).all()) {
            if (torus.sdf(x) < -0.15) CHECK(r.winding[std::size_t(i)] > 0.5);
            continue;
        }
        ++outside_box;
        CHECK(r.winding[std::size_t(i)] == 0.0);
        CHECK(r.phi[std::size_t(i)] > 0);
    }
    CHECK(outside_box > std::size_t(q.rows()) / 4);
}

namespace {

// A closed sphere with every fifth face reversed, and two faces duplicated reversed (each pair
// cancels in a winding number: a hole where the sign must still hold).
PolygonMesh misoriented_sphere() {
    PolygonMesh m = shapes::icosphere(3);
    PolygonMesh out;
    out.vertices = m.vertices;
    for (std::size_t f = 0; f < m.face_count(); ++f) {
        const std::uint32_t* c = m.indices.data() + m.offsets[f];
        if (f % 5 == 0) out.add_face({c[0], c[2], c[1]});
        else out.add_face({c[0], c[1], c[2]});
        if (f == 7 || f == 300) out.add_face({c[0], c[2], c[1]});
    }
    return out;
}

double sphere_sign_accuracy(const MeshSdfResult& r, const Points& q, double margin) {
    std::size_t far = 0, right = 0;
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
        const double exact = q.row(i).norm() - 1;
        if (std::abs(exact) < margin) continue;
        ++far;
        right += (r.phi[std::size_t(i)] < 0) == (exact < 0);
    }
    return double(right) / double(far);
}

}  // namespace

TEST_CASE("mesh_sdf signs: pseudonormals on a clean mesh, repaired winding numbers on a broken one, the diagnosis") {
    const Points q = uniform_queries(3000, 1.6, 21);
    MeshSdfOptions o;
    o.device = "cpu";
    // Clean: auto takes pseudonormals, right at every query off the surface (the icosphere's
    // flattening is below 0.02 at level 3).
    const PolygonMesh sphere = shapes::icosphere(3);
    const MeshSdfResult clean = mesh_sdf(sphere, q, o);
    CHECK(clean.sign == SdfSign::pseudonormal);
    CHECK(clean.winding.empty());
    CHECK(sphere_sign_accuracy(clean, q, 0.02) == 1.0);
    // The same sphere as a soup (every face its own three vertices): welded, it is clean again.
    PolygonMesh soup;
    soup.vertices.resize(Eigen::Index(3 * sphere.face_count()), 3);
    for (std::size_t f = 0; f < sphere.face_count(); ++f) {
        for (int k = 0; k < 3; ++k)
            soup.vertices.row(Eigen::Index(3 * f + std::size_t(k))) = sphere.vertices.row(sphere.indices[sphere.offsets[f] + std::size_t(k)]);
        soup.add_face({std::uint32_t(3 * f), std::uint32_t(3 * f + 1), std::uint32_t(3 * f + 2)});
    }
    const MeshSdfResult welded = mesh_sdf(soup, q, o);
    CHECK(welded.sign == SdfSign::pseudonormal);
    CHECK(welded.diagnosis.find(std::to_string(3 * sphere.face_count() - std::size_t(sphere.vertices.rows())) +
                                " vertices at another's position") != std::string::npos);
    for (std::size_t i = 0; i < clean.phi.size(); ++i) CHECK(welded.phi[i] == clean.phi[i]);

    // Broken orientation: plain winding numbers go wrong, the repaired ones do not.
    const PolygonMesh bad = misoriented_sphere();
    const MeshSdfResult repaired = mesh_sdf(bad, q, o);
    CHECK(repaired.sign == SdfSign::winding);
    CHECK(repaired.reoriented == shapes::icosphere(3).face_count() / 5);  // the reversed fifth (duplicates are dropped)
    CHECK(repaired.diagnosis.find("2 duplicated triangles") != std::string::npos);
    CHECK(sphere_sign_accuracy(repaired, q, 0.02) == 1.0);
    o.sign = SdfSign::winding;
    const MeshSdfResult plain = mesh_sdf(bad, q, o);
    MESSAGE("winding numbers of the faces as given: sign right at " << sphere_sign_accuracy(plain, q, 0.02));
    CHECK(sphere_sign_accuracy(plain, q, 0.02) < 1.0);
    // Pseudonormals asked for on it: defined, but wrong near the reversed faces.
    o.sign = SdfSign::pseudonormal;
    CHECK(sphere_sign_accuracy(mesh_sdf(bad, q, o), q, 0.02) < 1.0);
    // Every sign gives the same distance.
    for (std::size_t i = 0; i < plain.phi.size(); ++i) CHECK(std::abs(plain.phi[i]) == doctest::Approx(std::abs(repaired.phi[i])).epsilon(1e-12));
}

TEST_CASE("mesh_sdf gradient: the unit vector from the nearest point, signed as φ (on a sphere: x/|x|)") {
    const PolygonMesh sphere = shapes::icosphere(4);
    const Points q = uniform_queries(2000, 1.6, 31);
    for (const SdfSign sign : {SdfSign::automatic, SdfSign::winding}) {
        MeshSdfOptions o;
        o.device = "cpu";
        o.sign = sign;
        o.gradient = true;
        const MeshSdfResult r = mesh_sdf(sphere, q, o);
        REQUIRE(r.gradient.size() == 3 * r.phi.size());
        for (Eigen::Index i = 0; i < q.rows(); ++i) {
            if (std::abs(r.phi[std::size_t(i)]) < 0.05) continue;
            const Eigen::Vector3d g(r.gradient[3 * std::size_t(i)], r.gradient[3 * std::size_t(i) + 1], r.gradient[3 * std::size_t(i) + 2]);
            CHECK(g.norm() == doctest::Approx(1.0).epsilon(1e-12));
            CHECK(g.dot(q.row(i).normalized().transpose()) > 0.99);
        }
    }
    MeshSdfOptions plain;
    plain.device = "cpu";
    CHECK(mesh_sdf(sphere, q, plain).gradient.empty());
}

TEST_CASE("mesh_sdf --sign shm: the grid SHM's sign on a broken mesh") {
    const auto torus_shape = shapes::torus(Eigen::Vector3d::Zero(), 0.5, 0.2);
    shapes::MeshCorruption c;
    c.holes = 3;
    c.hole_area = 0.1;
    c.flip_fraction = 0.1;
    const PolygonMesh broken = shapes::corrupt(shapes::mesh(*torus_shape, 48), c, 5);
    const Points q = uniform_queries(test::sized(3000, 600), 1.0, 13);
    MeshSdfOptions o;
    o.device = "cpu";
    o.sign = SdfSign::shm;
    o.shm_grid = 48;
    const MeshSdfResult r = mesh_sdf(broken, q, o);
    CHECK(r.sign == SdfSign::shm);
    std::size_t far = 0, right = 0;
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
        const double exact = torus_shape->sdf(q.row(i).transpose());
        if (std::abs(exact) < 0.05) continue;
        ++far;
        right += (r.phi[std::size_t(i)] < 0) == (exact < 0);
    }
    MESSAGE("shm sign right at " << right << " of " << far);
    CHECK(double(right) >= 0.97 * double(far));
    o.shm_grid = 4;
    CHECK_THROWS_AS(mesh_sdf(broken, q, o), Error);
}

TEST_CASE("mesh_sdf on the device (nearest triangles, winding numbers, SHM): the result is the CPU's") {
    const PolygonMesh sphere = shapes::icosphere(2);
    const Points q = uniform_queries(300, 1.5, 3);
    MeshSdfOptions cpu, gpu;
    cpu.device = "cpu";
    gpu.device = "gpu";
    cpu.sign = gpu.sign = SdfSign::winding;  // (auto would take pseudonormals on this clean sphere)
    const MeshSdfResult a = mesh_sdf(sphere, q, cpu), b = mesh_sdf(sphere, q, gpu);
    REQUIRE(a.winding.size() == std::size_t(q.rows()));
    REQUIRE(b.winding.size() == std::size_t(q.rows()));
    for (std::size_t i = 0; i < a.phi.size(); ++i) {
        // The device finds the nearest triangle in float32 (a near tie may go to another one);
        // its distance is computed in double.
        CHECK(std::abs(std::abs(a.phi[i]) - std::abs(b.phi[i])) <= 1e-6 * (1 + std::abs(a.phi[i])));
        CHECK(std::abs(a.winding[i] - b.winding[i]) < 1e-4);
    }
    // A broken torus, every sign: the same distances to float32 precision, and the same signs
    // away from where w or SHM's φ is near its threshold.
    const auto torus_shape = shapes::torus(Eigen::Vector3d::Zero(), 0.5, 0.2);
    shapes::MeshCorruption c;
    c.holes = 3;
    c.hole_area = 0.1;
    c.flip_fraction = 0.1;
    const PolygonMesh broken = shapes::corrupt(shapes::mesh(*torus_shape, 40), c, 9);
    const Points t = uniform_queries(test::sized(4000, 1000), 1.0, 17);
    for (const SdfSign sign : {SdfSign::automatic, SdfSign::pseudonormal, SdfSign::shm}) {
        cpu.sign = gpu.sign = sign;
        const MeshSdfResult x = mesh_sdf(broken, t, cpu), y = mesh_sdf(broken, t, gpu);
        std::size_t differ = 0;
        for (std::size_t i = 0; i < x.phi.size(); ++i) {
            CHECK(std::abs(std::abs(x.phi[i]) - std::abs(y.phi[i])) <= 1e-6 * (1 + std::abs(x.phi[i])));
            differ += (x.phi[i] < 0) != (y.phi[i] < 0);
        }
        CAPTURE(sdf_sign_name(sign));
        CHECK(differ <= x.phi.size() / 200);
    }
}

TEST_CASE("sdf_nearest, both builds (the GPUs' and the software devices'): the CPU's distances") {
    const auto torus_shape = shapes::torus(Eigen::Vector3d::Zero(), 0.5, 0.2);
    shapes::MeshCorruption c;
    c.holes = 3;
    c.hole_area = 0.1;
    const PolygonMesh broken = shapes::corrupt(shapes::mesh(*torus_shape, 40), c, 4);
    const Points q = uniform_queries(test::sized(3000, 800), 1.0, 19);
    MeshSdfOptions cpu;
    cpu.device = "cpu";
    cpu.sign = SdfSign::none;
    const MeshSdfResult ref = mesh_sdf(broken, q, cpu);
    for (const char* shaped : {"0", "1"}) {
        CAPTURE(shaped);
        ::setenv("GSD_SOFTWARE_SHAPED", shaped, 1);
        MeshSdfOptions gpu = cpu;
        gpu.device = "gpu";
        const MeshSdfResult r = mesh_sdf(broken, q, gpu);
        ::unsetenv("GSD_SOFTWARE_SHAPED");
        CHECK(r.device != "cpu");  // the suites run with a device (lavapipe at least)
        REQUIRE(r.phi.size() == ref.phi.size());
        for (std::size_t i = 0; i < r.phi.size(); ++i) CHECK(std::abs(r.phi[i] - ref.phi[i]) <= 1e-6 * (1 + ref.phi[i]));
    }
}

TEST_CASE("mesh_sdf: degenerate faces are counted and left out; bad input is an error") {
    PolygonMesh m = shapes::icosphere(1);
    // A zero-area triangle: three corners on one line.
    const auto v = Eigen::Index(m.vertices.rows());
    m.vertices.conservativeResize(v + 3, 3);
    m.vertices.row(v) << 2, 0, 0;
    m.vertices.row(v + 1) << 3, 0, 0;
    m.vertices.row(v + 2) << 4, 0, 0;
    for (Eigen::Index k = 0; k < 3; ++k) m.indices.push_back(std::uint32_t(v + k));
    m.offsets.push_back(std::uint32_t(m.indices.size()));
    Points q(2, 3);
    q << 0, 0, 0, 3, 0, 0.5;
    MeshSdfOptions o;
    o.device = "cpu";
    const MeshSdfResult r = mesh_sdf(m, q, o);
    CHECK(r.degenerate == 1);
    CHECK(r.triangles == 80);
    CHECK(r.phi[0] < 0);
    CHECK(r.phi[1] > 1.5);  // the sliver is not there: the sphere is the nearest

    Points bad = q;
    bad(1, 2) = std::nan("");
    CHECK_THROWS_AS(mesh_sdf(m, bad, o), Error);
    o.inside_threshold = 1.5;
    CHECK_THROWS_AS(mesh_sdf(m, q, o), Error);
    o.inside_threshold = 0.5;
    CHECK(mesh_sdf(m, Points(0, 3), o).phi.empty());
    PolygonMesh empty;
    CHECK_THROWS_AS(mesh_sdf(empty, q, o), Error);
}

TEST_CASE("gsd sdf: a grid around a closed mesh, negative inside; usage errors exit 2, bad input 1") {
    ScratchDir dir("cli-sdf");
    const std::string mesh = dir.file("sphere.obj");
    io::write_mesh(mesh, shapes::icosphere(3));
    const std::string out = dir.file("sdf.npy");
    REQUIRE(run_cli("sdf " + mesh + " --grid 17 --bounds -1.5 -1.5 -1.5 1.5 1.5 1.5 --device cpu -o " + out).exit_code == 0);
    const io::NpyArray a = io::read_npy(out);
    REQUIRE(a.data.size() == 17u * 17 * 17);
    const GridSpec g = GridSpec::cube(17, Box{{-1.5, -1.5, -1.5}, {1.5, 1.5, 1.5}});
    const Points nodes = g.nodes();
    for (Eigen::Index i = 0; i < nodes.rows(); ++i) {
        const double exact = nodes.row(i).norm() - 1;
        if (std::abs(exact) > 0.02) CHECK(std::abs(a.data[std::size_t(i)] - exact) < 0.02);
    }
    CHECK(run_cli("sdf " + mesh + " -o " + dir.file("x.npy")).exit_code == 2);  // no --grid or --queries
    CHECK(run_cli("sdf " + mesh + " --grid 8 --sign maybe -o " + dir.file("x.npy")).exit_code == 2);
    CHECK(run_cli("sdf " + dir.file("missing.obj") + " --grid 8 -o " + dir.file("x.npy")).exit_code == 1);
}

TEST_CASE("sample_sdf: near samples spread by σ about the surface, uniform ones fill the cube, the frame and seed hold") {
    const PolygonMesh m = shapes::icosphere(5);  // radius 1 about the origin
    SdfSampleOptions o;
    o.device = "cpu";
    o.near_sigma = {0.05, 0.01};
    o.uniform_fraction = 0.2;
    o.seed = 7;
    const std::size_t n = 20000;
    const SdfSamples s = sample_sdf(m, n, o);
    REQUIRE(s.points.rows() == Eigen::Index(n));
    REQUIRE(s.phi.size() == n);
    CHECK(s.radius == doctest::Approx(1.0).epsilon(1e-12));  // the farthest vertex: all are on the sphere
    CHECK(s.center.norm() < 1e-12);
    // Rows: 8000 of each σ, then 4000 uniform.
    const std::size_t per = 8000, uniform = 4000;
    for (int k = 0; k < 2; ++k) {
        double sum2 = 0;
        for (std::size_t i = k * per; i < (k + 1) * per; ++i) {
            const double radial = s.points.row(Eigen::Index(i)).norm() - 1;  // the offset along the normal
            sum2 += radial * radial;
            // The exact SDF of the unit sphere, within the icosphere's flattening (≤ 2e-3 at level 5).
            CHECK(std::abs(s.phi[i] - radial) < 3e-3);
        }
        const double sigma = std::sqrt(sum2 / double(per));
        CHECK(sigma == doctest::Approx(o.near_sigma[std::size_t(k)]).epsilon(0.06));
    }
    for (std::size_t i = 2 * per; i < 2 * per + uniform; ++i) {
        CHECK(s.points.row(Eigen::Index(i)).cwiseAbs().maxCoeff() <= 1.0);
        CHECK(std::abs(s.phi[i] - (s.points.row(Eigen::Index(i)).norm() - 1)) < 3e-3);
    }
    // The same seed, the same samples; normalize only changes the frame (here the identity up to
    // rounding); another seed, other samples.
    SdfSampleOptions o2 = o;
    o2.normalize = true;
    const SdfSamples t = sample_sdf(m, n, o2);
    CHECK((t.points - s.points).cwiseAbs().maxCoeff() < 1e-12);
    o2.seed = 8;
    CHECK((sample_sdf(m, n, o2).points - s.points).cwiseAbs().maxCoeff() > 0.1);
    // A shifted, scaled sphere normalizes back onto the unit one.
    PolygonMesh big = m;
    big.vertices = ((3.0 * big.vertices).rowwise() + Eigen::RowVector3d(10, -4, 2)).eval();
    const SdfSamples b = sample_sdf(big, n, o2);
    CHECK(b.radius == doctest::Approx(3.0).epsilon(1e-12));
    for (std::size_t i = 0; i < n; i += 97) CHECK(std::abs(b.phi[i] - (b.points.row(Eigen::Index(i)).norm() - 1)) < 3e-3);
    // Bad options.
    CHECK_THROWS_AS(sample_sdf(m, 0, o), Error);
    SdfSampleOptions bad = o;
    bad.near_sigma = {0.01, -1};
    CHECK_THROWS_AS(sample_sdf(m, 10, bad), Error);
    bad = o;
    bad.uniform_fraction = 1.5;
    CHECK_THROWS_AS(sample_sdf(m, 10, bad), Error);
    bad = o;
    bad.near_sigma.clear();
    CHECK_THROWS_AS(sample_sdf(m, 10, bad), Error);
    bad.uniform_fraction = 1;  // all uniform: no σ needed
    CHECK(sample_sdf(m, 10, bad).phi.size() == 10);
}

TEST_CASE("gsd sdf --samples: (S,4) rows x y z sdf and a sidecar with the frame") {
    ScratchDir dir("cli-sdf-samples");
    const std::string mesh = dir.file("sphere.obj");
    PolygonMesh m = shapes::icosphere(4);
    m.vertices = (2.0 * m.vertices).eval();
    io::write_mesh(mesh, m);
    const std::string out = dir.file("s.npy");
    REQUIRE(run_cli("sdf " + mesh + " --samples 3000 --near-sigma 0.02 --uniform 0.5 --normalize --device cpu -o " + out)
                .exit_code == 0);
    const io::NpyArray a = io::read_npy(out);
    REQUIRE(a.shape == std::vector<std::size_t>{3000, 4});
    for (std::size_t i = 0; i < 3000; ++i) {
        const double r = std::sqrt(a.data[4 * i] * a.data[4 * i] + a.data[4 * i + 1] * a.data[4 * i + 1] +
                                   a.data[4 * i + 2] * a.data[4 * i + 2]);
        CHECK(std::abs(a.data[4 * i + 3] - (r - 1)) < 1e-2);  // normalized: the unit sphere
    }
    CHECK(test::file_exists(out + ".json"));
    // --gradient beside --queries: (M,3) rows, unit vectors.
    const Points q = uniform_queries(50, 3.0, 4);
    io::write_npy(dir.file("q.npy"), {50, 3}, std::vector<float>(q.data(), q.data() + q.size()));
    REQUIRE(run_cli("sdf " + mesh + " --queries " + dir.file("q.npy") + " --gradient " + dir.file("g.npy") +
                    " --device cpu -o " + dir.file("p.npy")).exit_code == 0);
    const io::NpyArray g = io::read_npy(dir.file("g.npy"));
    REQUIRE(g.shape == std::vector<std::size_t>{50, 3});
    for (std::size_t i = 0; i < 50; ++i)
        CHECK(std::hypot(g.data[3 * i], g.data[3 * i + 1], g.data[3 * i + 2]) == doctest::Approx(1.0).epsilon(1e-6));
    CHECK(run_cli("sdf " + mesh + " --samples 10 --gradient " + dir.file("g2.npy") + " -o " + dir.file("x.npy")).exit_code == 2);
    CHECK(run_cli("sdf " + mesh + " --samples 10 --grid 8 -o " + dir.file("x.npy")).exit_code == 2);   // two domains
    CHECK(run_cli("sdf " + mesh + " --samples 10 -o " + dir.file("x.vdb")).exit_code == 2);            // not .npy
    CHECK(run_cli("sdf " + mesh + " --samples 10 --near-sigma 0 -o " + dir.file("x.npy")).exit_code == 2);
    CHECK(!test::file_exists(dir.file("x.npy")));
}

TEST_CASE("gsd sdf --batch: good inputs written, bad ones listed, finished ones skipped, shards partition the list") {
    ScratchDir dir("cli-sdf-batch");
    std::string list;
    for (int i = 0; i < 7; ++i) {
        std::string name = "m";  // (not "m" + to_string(i): GCC 12's -Wrestrict misfires on it)
        name += std::to_string(i);
        const std::string mesh = dir.file(name + ".obj");
        io::write_mesh(mesh, shapes::icosphere(1 + i % 2));
        list += mesh + "\n";
        if (i == 2) list += "# a comment, then a blank line\n\n";
    }
    test::write_bytes(dir.file("broken.obj"), "v 0 0 0\nf 1 2 3\n");  // an index out of range
    list += dir.file("broken.obj") + "\n" + dir.file("missing.ply") + "\n";
    test::write_bytes(dir.file("list.txt"), list);
    const std::string out_dir = dir.file("out");
    const std::string base = "sdf --batch " + dir.file("list.txt") + " --out-dir " + out_dir + " --samples 200 --device cpu";

    // Two shards' dry runs: every input exactly once.
    std::string seen;
    std::size_t lines = 0;
    for (int s = 0; s < 2; ++s) {
        const test::RunResult r = run_cli(base + " --shard " + std::to_string(s) + "/2 --dry-run");
        REQUIRE(r.exit_code == 0);
        std::istringstream in(r.output);
        std::string line;
        std::getline(in, line);  // "K of 9 inputs (shard s/2)"
        CHECK(line.find("of 9 inputs") != std::string::npos);
        while (std::getline(in, line)) {
            if (line.find(" -> ") == std::string::npos) continue;
            seen += line.substr(0, line.find(" -> ")) + "\n";
            ++lines;
        }
    }
    CHECK(lines == 9);
    for (const std::string name : {"m0.obj", "m3.obj", "m6.obj", "broken.obj", "missing.ply"})
        CHECK(seen.find(dir.file(name)) != std::string::npos);
    CHECK(!test::file_exists(out_dir));  // a dry run writes nothing

    // Shard 1 of 2 from a Slurm array task's environment.
    const test::RunResult slurm =
        test::run_shell("SLURM_ARRAY_TASK_ID=5 SLURM_ARRAY_TASK_MIN=4 SLURM_ARRAY_TASK_COUNT=2 " +
                        std::string(GSD_CLI) + " " + base + " --shard auto --dry-run");
    CHECK(slurm.exit_code == 0);
    CHECK(slurm.output.find("4 of 9 inputs (shard 1/2)") != std::string::npos);

    // The whole list: 7 written, the 2 bad ones reported; exit 1 at the end.
    const test::RunResult all = run_cli(base);
    CHECK(all.exit_code == 1);
    CHECK(all.output.find("broken.obj") != std::string::npos);
    CHECK(all.output.find("missing.ply") != std::string::npos);
    CHECK(all.output.find("2 of 9 inputs failed") != std::string::npos);
    for (int i = 0; i < 7; ++i) CHECK(io::read_npy(out_dir + "/m" + std::to_string(i) + ".npy").shape[0] == 200);
    // As after a kill: one output gone. Run again: only that one is made.
    std::filesystem::remove(out_dir + "/m4.npy");
    test::write_bytes(out_dir + "/m4.npy.tmp-1-2-3", "half an array");  // what the kill left
    const test::RunResult again = run_cli(base);
    CHECK(!test::file_exists(out_dir + "/m4.npy.tmp-1-2-3"));
    CHECK(again.output.find("1 written, 6 already there, 2 failed") != std::string::npos);
    CHECK(test::file_exists(out_dir + "/m4.npy"));

    // Two inputs with one stem, and usage errors.
    test::write_bytes(dir.file("dup.txt"), dir.file("m0.obj") + "\n" + dir.file("out") + "/../m0.obj\n");
    CHECK(run_cli("sdf --batch " + dir.file("dup.txt") + " --out-dir " + out_dir + " --samples 10").exit_code == 1);
    CHECK(run_cli(base + " --shard 2/2").exit_code == 1);
    CHECK(run_cli(base + " --shard x").exit_code == 1);
    CHECK(run_cli("sdf --batch " + dir.file("list.txt") + " --samples 10").exit_code == 2);  // no --out-dir
}
