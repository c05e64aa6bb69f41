// gsd-gpu-bench: one table of every query-heavy stage, the CPU path against a device, measured
// side by side in one run — PAT evaluation, fast winding numbers, a sphere-traced picture of a
// PAT field, the volumetric Signed Heat Method (step 1 and step 3) and the TorusNet fit.
// Each device figure excludes a first, small run of the same stage (pipeline compile, driver
// start), and each figure is the median of --rounds runs (default 3 at the small sizes, 1 at
// the full ones: a shared machine's noise moves single runs by a third); where a CPU-path run at full size would take minutes, the CPU runs a stated share of
// the work and its rate (items per second) is what the ratio compares. `scripts/bench.sh gpu`
// runs it; docs/gpu.md says how to run it on a machine without gsd's build dependencies.
//
//   gsd-gpu-bench [--full] [--device D] [--rounds N] [--stages pat,winding,sdf,render,shm,net]
//
// Sizes: small ones by default (a software device such as lavapipe), the full ones with
// --full (a real GPU: PAT of 10⁵ and 10⁶ points, winding numbers of 10⁶ queries on 10⁵ faces, a
// 1920×1080 picture of a 10⁶-point PAT field, SHM on a 256³ grid, TorusNet on 10⁶ points).
#include <CLI/CLI.hpp>
#include <gsd/gpu.hpp>
#include <gsd/pat.hpp>
#include <gsd/render.hpp>
#include <gsd/sdf.hpp>
#include <gsd/shapes.hpp>

#include "bench_queries.hpp"
#include <gsd/shm.hpp>
#include <gsd/sums.hpp>

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <random>
#include <set>
#include <string>

using namespace gsd;

namespace {

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

int g_rounds = 3;  // --rounds

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const std::size_t m = v.size() / 2;
    return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

// The median wall time of g_rounds runs of f (the last run's results are what f leaves).
double seconds(const std::function<void()>& f) {
    std::vector<double> t;
    for (int i = 0; i < g_rounds; ++i) {
        const double t0 = now();
        f();
        t.push_back(now() - t0);
    }
    return median(t);
}

struct Row {
    std::string stage, size, unit;
    double cpu_rate = 0, device_rate = 0, device_seconds = 0;
    double difference = -1;  ///< largest |device − CPU| over what both computed (−1: not compared)
};

void print_row(const Row& r) {
    char diff[32] = "";
    if (r.difference >= 0) std::snprintf(diff, sizeof(diff), "%9.2g", r.difference);
    std::printf("%-24s %-34s %11.3g %11.3g %8.2fx %9.3f s %9s  (%s)\n", r.stage.c_str(), r.size.c_str(), r.cpu_rate,
                r.device_rate, r.device_rate / r.cpu_rate, r.device_seconds, diff, r.unit.c_str());
    std::fflush(stdout);
}

double max_difference(const std::vector<float>& a, const std::vector<float>& b) {
    double m = 0;
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) m = std::max(m, double(std::abs(a[i] - b[i])));
    return m;
}
double max_difference(const std::vector<double>& a, const std::vector<double>& b) {
    double m = 0;
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) m = std::max(m, std::abs(a[i] - b[i]));
    return m;
}


std::string count(double n) {
    char b[32];
    std::snprintf(b, sizeof(b), "%.0e", n);
    std::string s = b;  // 1e+06 → 1e6
    const auto plus = s.find("e+0");
    if (plus != std::string::npos) s.replace(plus, 3, "e");
    return s;
}

Row bench_pat(const shapes::Shape& torus, std::size_t points, std::size_t queries, double cpu_share, const std::string& device) {
    const FittedTori tori = JetFitter().fit(torus.sample(points, 1));
    const Points q = bench::queries_near(torus, queries, 7);
    const Points q_cpu = q.topRows(Eigen::Index(double(queries) * cpu_share));
    Row r{"PAT evaluation", count(double(points)) + " pts, " + count(double(queries)) + " queries", "queries/s"};
    std::vector<float> ref;
    for (const std::string& d : {std::string("cpu"), device}) {
        BlendOptions o;
        o.device = d;
        const TorusField field(tori, o);
        field.evaluate(q.topRows(256));  // setup: tree, upload, pipelines
        const Points& use = d == "cpu" ? q_cpu : q;
        FieldValues v;
        const double t = seconds([&] { v = field.evaluate(use); });
        if (d == "cpu") ref = v.phi;
        else r.difference = max_difference(ref, v.phi);
        (d == "cpu" ? r.cpu_rate : r.device_rate) = double(use.rows()) / t;
        if (d != "cpu") r.device_seconds = t;
    }
    return r;
}

// The winding and sdf stages' mesh: a double torus with 3 holes (10 % of its area) and 5 % of
// its faces flipped.
PolygonMesh broken_double_torus(int resolution) {
    shapes::MeshCorruption c;
    c.holes = 3;
    c.hole_area = 0.1;
    c.flip_fraction = 0.05;
    return shapes::corrupt(shapes::double_torus_mesh(resolution), c, 3);
}

// n queries uniform in the box enlarged by 0.1 on every side (seeded).
Points queries_around(const Box& b, std::size_t n, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    Points q(Eigen::Index(n), 3);
    for (Eigen::Index i = 0; i < q.rows(); ++i)
        for (int a = 0; a < 3; ++a) q(i, a) = std::uniform_real_distribution<double>(b.lo[a] - 0.1, b.hi[a] + 0.1)(rng);
    return q;
}

Row bench_winding(int resolution, std::size_t queries, double cpu_share, const std::string& device) {
    const PolygonMesh mesh = broken_double_torus(resolution);
    const OrientedElements elements = OrientedElements::from_mesh(mesh);
    const Points q = queries_around(bounding_box(elements.corners), queries, 5);
    const Points q_cpu = q.topRows(Eigen::Index(double(queries) * cpu_share));
    Row r{"winding numbers", count(double(elements.size())) + " faces (broken), " + count(double(queries)) + " queries", "queries/s"};
    std::vector<double> ref;
    for (const std::string& d : {std::string("cpu"), device}) {
        WindingOptions o;
        o.device = d;
        const WindingField field(elements, o);
        field.winding_numbers(q.topRows(256));  // setup: tree, pipelines
        const Points& use = d == "cpu" ? q_cpu : q;
        WindingResult w;
        const double t = seconds([&] { w = field.winding_numbers(use); });
        if (d == "cpu") ref = w.w;
        else r.difference = max_difference(ref, w.w);
        (d == "cpu" ? r.cpu_rate : r.device_rate) = double(use.rows()) / t;
        if (d != "cpu") r.device_seconds = t;
    }
    return r;
}

// The signed distance's nearest-triangle search alone (--sign none: the device's stage; the
// exact distance to the triangle found is computed on the host either way), whole mesh_sdf calls.
Row bench_sdf(int resolution, std::size_t queries, double cpu_share, const std::string& device) {
    const PolygonMesh mesh = broken_double_torus(resolution);
    const Points q = queries_around(bounding_box(mesh.vertices), queries, 7);
    const Points q_cpu = q.topRows(Eigen::Index(double(queries) * cpu_share));
    Row r{"sdf distance", count(double(mesh.face_count())) + " faces (broken), " + count(double(queries)) + " queries", "queries/s"};
    std::vector<double> ref;
    for (const std::string& d : {std::string("cpu"), device}) {
        MeshSdfOptions o;
        o.device = d;
        o.sign = SdfSign::none;
        mesh_sdf(mesh, q.topRows(256), o);  // setup: pipelines
        const Points& use = d == "cpu" ? q_cpu : q;
        MeshSdfResult s;
        const double t = seconds([&] { s = mesh_sdf(mesh, use, o); });
        if (d == "cpu") ref = s.phi;
        else r.difference = max_difference(ref, s.phi);
        (d == "cpu" ? r.cpu_rate : r.device_rate) = double(use.rows()) / t;
        if (d != "cpu") r.device_seconds = t;
    }
    return r;
}

Row bench_render(const shapes::Shape& torus, std::size_t points, int width, int height, int cpu_divisor, const std::string& device) {
    const FittedTori tori = JetFitter().fit(torus.sample(points, 1));
    const Box box{{-1, -1, -1}, {1, 1, 1}};
    Row r{"render (PAT)", count(double(points)) + " pts, " + std::to_string(width) + "x" + std::to_string(height), "pixels/s"};
    std::vector<float> ref;  // the CPU's depths, compared when both rendered the same pixels
    for (const std::string& d : {std::string("cpu"), device}) {
        BlendOptions bo;
        bo.device = d;
        const TorusField field(tori, bo);
        FieldRenderOptions o;
        o.device = d;
        o.width = 64, o.height = 36;
        render_field(field, box, o);  // setup
        const int div = d == "cpu" ? cpu_divisor : 1;
        o.width = width / div, o.height = height / div;
        RenderedField picture;
        const double t = seconds([&] { picture = render_field(field, box, o); });
        if (d == "cpu" && div == 1) ref = picture.depth;
        if (d != "cpu" && ref.size() == picture.depth.size()) {
            // The share of pixels where one hit and the other missed (the test holds it to 0).
            std::size_t differ = 0;
            for (std::size_t i = 0; i < ref.size(); ++i) differ += (ref[i] < 0) != (picture.depth[i] < 0);
            r.difference = double(differ) / double(ref.size());
        }
        (d == "cpu" ? r.cpu_rate : r.device_rate) = double(o.width) * o.height / t;
        if (d != "cpu") r.device_seconds = t;
    }
    return r;
}

// Step 1 and step 3 as two rows (their own times, from ShmResult), in nodes per second. The
// rounds take the CPU path and the device in turn (the other stages run a device's rounds one
// after the other), as step 3 on lavapipe is within the noise of the CPU path's rate.
void bench_shm(const shapes::Shape& torus, std::size_t points, int n, const std::string& device) {
    const ShmSource src = shm_source(torus.sample(points, 1));
    const GridSpec grid = GridSpec::cube(n, Box{{-1, -1, -1}, {1, 1, 1}});
    Row s1{"SHM step 1 (diffuse)", count(double(points)) + " pts, " + std::to_string(n) + "^3", "nodes/s"};
    Row s3{"SHM step 3 (solve)", count(double(points)) + " pts, " + std::to_string(n) + "^3", "nodes/s"};
    const double nodes = double(grid.node_count());
    std::vector<float> ref;
    {  // setup: step 1's kernels, and one cycle of step 3's at this grid's sizes (a software
       // device compiles a pipeline per workgroup shape on first use)
        ShmOptions o;
        o.device = device;
        SignedHeatGrid(src, GridSpec::cube(17, grid.box), o).solve();
        std::vector<double> b(grid.node_count());
        for (std::size_t i = 0; i < b.size(); ++i) b[i] = double(i % 2) - 0.5;  // sums to 0 on even counts
        if (b.size() % 2) b.back() = 0.0;
        GridPoissonSolver(grid, o.solver, o.device).solve(b, {1e-30, 1});
    }
    std::vector<double> t1[2], t3[2];  // [0] the CPU path, [1] the device
    for (int round = 0; round < g_rounds; ++round)
        for (int which = 0; which < 2; ++which) {
            ShmOptions o;
            o.device = which == 0 ? std::string("cpu") : device;
            const ShmResult res = SignedHeatGrid(src, grid, o).solve();
            if (which == 0 && ref.empty()) ref = res.phi;
            if (which == 1 && s3.difference < 0) s3.difference = max_difference(ref, res.phi) / grid.box.diagonal();  // φ, relative to the diagonal
            t1[which].push_back(res.seconds_diffuse);
            t3[which].push_back(res.seconds_solve);
        }
    s1.cpu_rate = nodes / median(t1[0]), s1.device_rate = nodes / median(t1[1]), s1.device_seconds = median(t1[1]);
    s3.cpu_rate = nodes / median(t3[0]), s3.device_rate = nodes / median(t3[1]), s3.device_seconds = median(t3[1]);
    print_row(s1);
    print_row(s3);
}

Row bench_net(const shapes::Shape& torus, std::size_t points, double cpu_share, const std::string& device) {
    const PointCloud cloud = torus.sample(points, 1);
    PointCloud part;
    const auto m = Eigen::Index(std::max(256.0, double(points) * cpu_share));
    part.points = cloud.points.topRows(m);
    part.normals = cloud.normals.topRows(m);
    Row r{"TorusNet fit", count(double(points)) + " pts", "points/s"};
    for (const std::string& d : {std::string("cpu"), device}) {
        TorusNetOptions o;
        o.device = d;
        const TorusNet net(o);
        net.fit(torus.sample(256, 2));  // setup: weights, pipelines
        const PointCloud& use = d == "cpu" ? part : cloud;
        const double t = seconds([&] { net.fit(use); });
        (d == "cpu" ? r.cpu_rate : r.device_rate) = double(use.size()) / t;
        if (d != "cpu") r.device_seconds = t;
    }
    return r;
}

}  // namespace

int main(int argc, char** argv) {
    bool full = false;
    std::string device = "gpu";
    std::set<std::string> stages{"pat", "winding", "sdf", "render", "shm", "net"};
    CLI::App app{"Every GPU stage beside the CPU path, in one table (scripts/bench.sh gpu; docs/gpu.md)"};
    app.add_flag("--full", full, "the large sizes (for a GPU)");
    app.add_option("--device", device, "the device to time against the CPU path");
    int rounds = 0;
    app.add_option("--rounds", rounds, "runs of each timing, the median reported (default: 3, with --full 1)")->check(CLI::Range(1, 100));
    app.add_option("--stages", stages, "stages to run")->delimiter(',')->check(CLI::IsMember({"pat", "winding", "sdf", "render", "shm", "net"}));
    CLI11_PARSE(app, argc, argv);
    g_rounds = rounds > 0 ? rounds : full ? 1 : 3;
    set_log_sink([](std::string_view m) { std::fprintf(stderr, "note: %.*s\n", int(m.size()), m.data()); });
    const gpu::Selection sel = gpu::select(device);
    if (!sel.context) {
        std::fprintf(stderr, "gsd-gpu-bench: no device for '%s' (%s)\n", device.c_str(), sel.note.c_str());
        return 1;
    }
    std::printf("gsd-gpu-bench (%s sizes): device = %s; CPU path = %d threads; medians of %d rounds\n", full ? "full" : "small",
                sel.device_name.c_str(), omp_get_max_threads(), g_rounds);
    std::printf("%-24s %-34s %11s %11s %9s %11s %9s\n", "stage", "size", "CPU path", "device", "ratio", "device time", "max |Δ|");
    const auto torus = shapes::by_name("torus");
    try {
        if (stages.count("pat")) {
            if (full) {
                print_row(bench_pat(*torus, 100000, 10000000, 0.1, device));
                print_row(bench_pat(*torus, 1000000, 10000000, 0.1, device));
            } else {
                print_row(bench_pat(*torus, 100000, 200000, 1.0, device));
            }
        }
        if (stages.count("winding")) {
            // double_torus_mesh(n): about 8.4 n² triangles (n 110: 10⁵).
            if (full) print_row(bench_winding(110, 10000000, 0.1, device));
            else print_row(bench_winding(72, 300000, 1.0, device));
        }
        if (stages.count("sdf")) {
            if (full) print_row(bench_sdf(110, 10000000, 0.1, device));
            else print_row(bench_sdf(72, 300000, 1.0, device));
        }
        if (stages.count("render")) {
            if (full) print_row(bench_render(*torus, 1000000, 1920, 1080, 4, device));
            else print_row(bench_render(*torus, 20000, 320, 240, 1, device));
        }
        if (stages.count("shm")) bench_shm(*torus, full ? 100000 : 20000, full ? 256 : 128, device);
        if (stages.count("net")) {
            if (full) print_row(bench_net(*torus, 1000000, 0.05, device));
            else print_row(bench_net(*torus, 10000, 1.0, device));
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "gsd-gpu-bench: %s\n", e.what());
        return 1;
    }
    return 0;
}
