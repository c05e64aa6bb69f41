// gsd-bench: throughput of Points as Tori. For clouds of several sizes: torus fitting
// (points/s) and evaluation (queries/s) on each device, measured side by side in one run, with
// the GPU/CPU ratio. The first evaluation on a device (tree build, upload, pipeline compile) is
// timed separately as "setup" and not counted in queries/s.
// `--net`: TorusNet fitting instead (points/s on each device, the shipped model); a first
// 256-point fit per device (pipeline compile) is timed as setup.
#include <CLI/CLI.hpp>
#include <gsd/gpu.hpp>
#include <gsd/io.hpp>
#include <gsd/pat.hpp>
#include <gsd/shapes.hpp>

#include "bench_queries.hpp"

#include <chrono>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

using namespace gsd;

namespace {

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }


// TorusNet fit throughput (points/s) on each device, side by side, with the GPU/CPU ratio.
int bench_net(const shapes::Shape& shape, const std::vector<std::string>& sizes, const std::vector<std::string>& devices) {
    std::printf("TorusNet fit throughput: torus shape, shipped model (%s)\n", TorusNet().description().c_str());
    for (const auto& d : devices) std::printf("  device '%s' = %s\n", d.c_str(), gpu::select(d).device_name.c_str());
    std::printf("\n%10s", "points");
    for (const auto& d : devices) std::printf(" %14s %9s", (d + " pts/s").c_str(), (d + " setup").c_str());
    if (devices.size() == 2) std::printf(" %10s", "ratio");
    std::printf("\n");
    for (const auto& s : sizes) {
        const std::size_t n = std::stoul(s);
        const PointCloud cloud = shape.sample(n, 1);
        std::printf("%10zu", n);
        std::vector<double> rates;
        for (const auto& d : devices) {
            TorusNetOptions o;
            o.device = d;
            const TorusNet fitter(o);
            double t0 = now();
            fitter.fit(shape.sample(256, 2));  // setup: pipelines, weights
            const double setup = now() - t0;
            t0 = now();
            const FittedTori t = fitter.fit(cloud);
            rates.push_back(double(n) / (now() - t0));
            std::printf(" %14.3g %8.2fs", rates.back(), setup);
            std::fflush(stdout);
        }
        if (rates.size() == 2) std::printf(" %9.2fx", rates[1] / rates[0]);
        std::printf("\n");
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    std::vector<std::string> sizes{"10000", "100000", "1000000"}, devices{"cpu", "gpu"};
    std::size_t queries = 1000000;
    bool exact = false, net = false;
    CLI::App app{"PAT throughput, CPU beside GPU: fit and evaluation rates per cloud size (scripts/bench.sh)"};
    app.add_option("--sizes", sizes, "cloud sizes")->delimiter(',');
    app.add_option("--devices", devices, "devices, side by side")->delimiter(',');
    app.add_option("--queries", queries, "queries per evaluation")->check(CLI::PositiveNumber);
    app.add_flag("--exact", exact, "the exact sum instead of the accelerated one");
    app.add_flag("--net", net, "TorusNet fitting instead of evaluation");
    CLI11_PARSE(app, argc, argv);
    set_log_sink([](std::string_view m) { std::fprintf(stderr, "note: %.*s\n", int(m.size()), m.data()); });
    auto shape = shapes::by_name("torus");
    if (net) return bench_net(*shape, sizes, devices);
    const Points q = bench::queries_near(*shape, queries, 99);
    std::printf("PAT throughput: torus shape, %zu queries (half near the surface), %s sum\n", queries, exact ? "exact" : "accelerated");
    for (const auto& d : devices) {
        const gpu::Selection s = gpu::select(d);
        std::printf("  device '%s' = %s\n", d.c_str(), s.device_name.c_str());
    }
    std::printf("\n%10s %12s", "points", "fit pts/s");
    for (const auto& d : devices) std::printf(" %12s %9s", (d + " q/s").c_str(), (d + " setup").c_str());
    if (devices.size() == 2) std::printf(" %10s", "ratio");
    std::printf("\n");
    std::vector<double> load_rates;
    for (const auto& s : sizes) {
        const std::size_t n = std::stoul(s);
        const PointCloud cloud = [&] {
            // Through a binary PLY, as a user's cloud arrives: also measures load speed.
            const std::string path = "/tmp/gsd-bench-" + std::to_string(n) + ".ply";
            io::write_point_cloud(path, shape->sample(n, 1));
            const double t = now();
            PointCloud c = io::read_point_cloud(path);
            load_rates.push_back(double(n) / (now() - t));
            std::remove(path.c_str());
            return c;
        }();
        double t0 = now();
        const FittedTori tori = JetFitter().fit(cloud);
        const double fit_rate = double(n) / (now() - t0);
        std::printf("%10zu %12.3g", n, fit_rate);
        std::fflush(stdout);
        std::vector<double> rates;
        for (const auto& d : devices) {
            BlendOptions opt;
            opt.device = d;
            opt.exact = exact;
            const TorusField field(tori, opt);
            t0 = now();
            field.evaluate(q.topRows(std::min<Eigen::Index>(256, q.rows())));  // setup: tree, upload, pipeline
            const double setup = now() - t0;
            t0 = now();
            const FieldValues v = field.evaluate(q);
            const double rate = double(queries) / (now() - t0);
            rates.push_back(rate);
            std::printf(" %12.3g %8.2fs", rate, setup);
            std::fflush(stdout);
        }
        if (rates.size() == 2) std::printf(" %9.2fx", rates[1] / rates[0]);
        std::printf("\n");
    }
    std::printf("\nbinary PLY load (read + validate), points/s:");
    for (double r : load_rates) std::printf(" %.3g", r);
    std::printf("\n");
    return 0;
}
