// gsd-winding-bench: `gsd winding` against the exact sum and, given its program, libigl's
// fast_winding_number — whole runs (load, build, evaluate, write), side by side in one run.
//
//   gsd-winding-bench [--resolution R | --mesh FILE] [--queries M] [--check K] [--repeat N]
//                     [--threads T] [--igl PROGRAM] [--gpu] [--gsd PROGRAM] [--work DIR]
//                     [--also "GSD ARGS"]...
//
// The mesh: the procedural double torus at resolution R (default 110: 91,514 faces) with 10 % of
// its area in 3 holes and 5 % of its faces flipped (`gsd mesh double-torus -r R`, then
// `gsd mesh --from … --holes 3 --hole-area 0.1 --flip 0.05`), or any mesh file (--mesh). Queries: M (default 10⁶) uniform
// in its bounding box, written as float32 .npy, which both programs read. Each program runs N
// times (default 3), in turn, with T threads (default 2). Errors against the exact sum at the
// first K queries (default 20000): the largest and the mean over those farther than one mean
// edge length from the surface (where `gsd winding` promises 1e-3), and the largest over all.
// --also adds a row: `gsd winding` with those arguments too (e.g. "--tolerance 2e-3"), on the CPU.
#include <gsd/io.hpp>
#include <gsd/shapes.hpp>
#include <gsd/sums.hpp>

#include "sums/sum_tree.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

using namespace gsd;

namespace {

struct Options {
    int resolution = 110;
    std::size_t queries = 1000000, check = 20000;
    int repeat = 3, threads = 2;
    std::string mesh, igl, gsd, work = "/tmp/gsd-winding-bench";
    std::vector<std::string> also;
    bool gpu = false;
};

struct Errors {
    double far_max = 0, far_mean = 0, all_max = 0;
};

double seconds(const std::string& command) {
    const auto t0 = std::chrono::steady_clock::now();
    const int rc = std::system((command + " >/dev/null 2>&1").c_str());
    if (rc != 0) {
        std::fprintf(stderr, "gsd-winding-bench: failed (%d): %s\n", rc, command.c_str());
        std::exit(1);
    }
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

Errors errors(const std::vector<double>& exact, const std::vector<bool>& far, const io::NpyArray& w) {
    Errors e;
    std::size_t n_far = 0;
    for (std::size_t i = 0; i < exact.size(); ++i) {
        const double d = std::abs(w.data[i] - exact[i]);
        e.all_max = std::max(e.all_max, d);
        if (!far[i]) continue;
        e.far_max = std::max(e.far_max, d);
        e.far_mean += d;
        ++n_far;
    }
    e.far_mean /= double(std::max<std::size_t>(n_far, 1));
    return e;
}

}  // namespace

int main(int argc, char** argv) {
    Options o;
    o.gsd = (std::filesystem::path(argv[0]).parent_path() / "gsd").string();
    CLI::App app{"Whole runs of gsd winding against the exact sum and other programs (scripts/bench.sh sums)"};
    app.add_option("--resolution", o.resolution, "double torus resolution (3 holes, 5 % of faces flipped)")
        ->check(CLI::Range(16, 100000))->capture_default_str();
    app.add_option("--mesh", o.mesh, "a mesh file instead of the double torus")->check(CLI::ExistingFile);
    app.add_option("--queries", o.queries, "uniform queries in the mesh's box")->check(CLI::PositiveNumber)->capture_default_str();
    app.add_option("--check", o.check, "queries held to the exact sum")->capture_default_str();
    app.add_option("--repeat", o.repeat, "runs per program (the fastest counts)")->check(CLI::PositiveNumber)->capture_default_str();
    app.add_option("--threads", o.threads, "threads per program")->check(CLI::PositiveNumber)->capture_default_str();
    app.add_option("--igl", o.igl, "libigl's fast winding number: PROGRAM mesh MESH Q.npy OUT.npy --threads T");
    app.add_flag("--gpu", o.gpu, "also gsd winding --device gpu");
    app.add_option("--gsd", o.gsd, "the gsd program")->capture_default_str();
    app.add_option("--work", o.work, "a folder for the inputs and outputs")->capture_default_str();
    app.add_option("--also", o.also, "another gsd winding run with these arguments (repeatable)");
    CLI11_PARSE(app, argc, argv);
    o.check = std::min(o.check, o.queries);
    std::filesystem::create_directories(o.work);
    const std::string mesh_path = o.work + "/mesh.obj", query_path = o.work + "/queries.npy";

    shapes::MeshCorruption damage;
    damage.holes = 3;
    damage.hole_area = 0.1;
    damage.flip_fraction = 0.05;
    PolygonMesh mesh;
    try {
        mesh = o.mesh.empty() ? shapes::corrupt(shapes::double_torus_mesh(o.resolution), damage, 1) : io::read_mesh(o.mesh);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "gsd-winding-bench: %s\n", e.what());
        return 1;
    }
    io::write_mesh(mesh_path, mesh);

    const Box box = bounding_box(mesh.vertices);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<float> q(3 * o.queries);
    for (std::size_t i = 0; i < o.queries; ++i)
        for (int a = 0; a < 3; ++a) q[3 * i + std::size_t(a)] = float(box.lo[a] + u(rng) * (box.hi[a] - box.lo[a]));
    io::write_npy(query_path, {o.queries, 3}, q);

    // The reference: the exact sum at the first K queries (as stored: float32), and which of
    // them lie farther than one mean edge length from the surface.
    const OrientedElements elements = OrientedElements::from_mesh(mesh);
    const sums::SumTree tree(elements);
    Points check(Eigen::Index(o.check), 3);
    for (std::size_t i = 0; i < o.check; ++i)
        for (int a = 0; a < 3; ++a) check(Eigen::Index(i), a) = q[3 * i + std::size_t(a)];
    WindingOptions exact_options;
    exact_options.exact = true;
    exact_options.device = "cpu";
    const std::vector<double> exact = fast_winding_numbers(elements, check, exact_options).w;
    const double edge = mean_edge_length(mesh);
    std::vector<bool> far(o.check);
    std::size_t n_far = 0;
    for (std::size_t i = 0; i < o.check; ++i) n_far += far[i] = tree.nearest_distance(check.row(Eigen::Index(i)).transpose()) > edge;

    struct Run {
        std::string label, command, output;
        std::vector<double> times;
    };
    const std::string threads = std::to_string(o.threads);
    std::vector<Run> runs;
    const std::string gsd_cmd = "OMP_NUM_THREADS=" + threads + " " + o.gsd + " winding " + mesh_path + " --queries " + query_path;
    runs.push_back({"gsd, defaults (CPU)", gsd_cmd + " --device cpu -o " + o.work + "/gsd.npy", o.work + "/gsd.npy", {}});
    runs.push_back({"gsd, beta 2 alone (CPU)", gsd_cmd + " --device cpu --beta 2 --tolerance 0 -o " + o.work + "/gsd_b2.npy",
                    o.work + "/gsd_b2.npy", {}});
    for (std::size_t a = 0; a < o.also.size(); ++a) {
        const std::string out = o.work + "/gsd_also" + std::to_string(a) + ".npy";
        runs.push_back({"gsd " + o.also[a], gsd_cmd + " --device cpu " + o.also[a] + " -o " + out, out, {}});
    }
    if (o.gpu) runs.push_back({"gsd, defaults (GPU)", gsd_cmd + " --device gpu -o " + o.work + "/gsd_gpu.npy", o.work + "/gsd_gpu.npy", {}});
    if (!o.igl.empty())
        runs.push_back({"libigl, beta 2", o.igl + " mesh " + mesh_path + " " + query_path + " " + o.work + "/igl.npy --threads " + threads,
                        o.work + "/igl.npy", {}});
    for (int r = 0; r < o.repeat; ++r)
        for (Run& run : runs) run.times.push_back(seconds(run.command));

    if (o.mesh.empty())
        std::printf("Broken double torus: %zu faces (10 %% of the area in 3 holes, 5 %% flipped); %zu queries uniform in its box;\n",
                    mesh.face_count(), o.queries);
    else
        std::printf("%s: %zu faces; %zu queries uniform in its box;\n", o.mesh.c_str(), mesh.face_count(), o.queries);
    std::printf("%d threads; whole runs, %d each in turn. Errors against the exact sum at %zu queries (%zu farther than\n",
                o.threads, o.repeat, o.check, n_far);
    std::printf("one mean edge length, %.4f, from the surface).\n\n", edge);
    std::printf("| %-24s | %-15s | %-9s | %-9s | %-11s | %-9s |\n", "run", "whole run (s)", "median", "max error", "mean error",
                "max (all)");
    std::printf("|--------------------------|-----------------|-----------|-----------|-------------|-----------|\n");
    double gsd_median = 0, igl_median = 0;
    for (Run& run : runs) {
        std::sort(run.times.begin(), run.times.end());
        const double median = run.times[run.times.size() / 2];
        if (run.label == "gsd, defaults (CPU)") gsd_median = median;
        if (run.label == "libigl, beta 2") igl_median = median;
        const Errors e = errors(exact, far, io::read_npy(run.output));
        char range[32];
        std::snprintf(range, sizeof(range), "%.2f-%.2f", run.times.front(), run.times.back());
        std::printf("| %-24s | %-15s | %9.3f | %9.2e | %11.2e | %9.2e |\n", run.label.c_str(), range, median, e.far_max, e.far_mean,
                    e.all_max);
    }
    if (igl_median > 0) std::printf("\ngsd defaults / libigl (medians): %.2f\n", gsd_median / igl_median);
    return 0;
}
