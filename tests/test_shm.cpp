// The grid Signed Heat Method: the Poisson solvers (multigrid convergence, agreement between
// multigrid, CG and CHOLMOD, GPU vs CPU), step 1 (device vs CPU, chunking, interpolation vs
// exact), accuracy on analytic clouds, and the sign on badly broken meshes vs the winding number.
#include <doctest/doctest.h>

#include <gsd/baselines.hpp>
#include <gsd/gpu.hpp>
#include <gsd/io.hpp>
#include <gsd/shapes.hpp>
#include <gsd/shm.hpp>
#include <gsd/spatial.hpp>
#include <gsd/sums.hpp>
#include <gsd/viz.hpp>
#include <gsd/vulkan.hpp>

#include "support.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <optional>
#include <random>

using namespace gsd;

namespace {

const Box kCube{{-1, -1, -1}, {1, 1, 1}};

// A smooth unit field with a non-trivial divergence: the gradient of a sphere's SDF, bent.
std::vector<float> test_field(const GridSpec& g) {
    const Points x = g.nodes();
    std::vector<float> y(3 * std::size_t(x.rows()));
    for (Eigen::Index i = 0; i < x.rows(); ++i) {
        Eigen::Vector3d v(x(i, 0) + 0.3 * std::sin(3 * x(i, 1)), x(i, 1) + 0.1, x(i, 2) - 0.2 * x(i, 0));
        v.normalize();
        for (int a = 0; a < 3; ++a) y[3 * std::size_t(i) + std::size_t(a)] = float(v[a]);
    }
    return y;
}

double max_abs(const std::vector<double>& v) {
    double m = 0;
    for (double x : v) m = std::max(m, std::abs(x));
    return m;
}

double mean_error(const std::vector<float>& phi, const GridSpec& g, const shapes::Shape& s) {
    const Points x = g.nodes();
    double e = 0;
    for (Eigen::Index i = 0; i < x.rows(); ++i) e += std::abs(phi[std::size_t(i)] - s.sdf(x.row(i).transpose()));
    return e / double(x.rows());
}

bool closed(const PolygonMesh& m) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed;
    for (std::size_t f = 0; f < m.face_count(); ++f)
        for (std::size_t k = 0; k < 3; ++k) directed[{m.indices[3 * f + k], m.indices[3 * f + (k + 1) % 3]}]++;
    for (const auto& [e, n] : directed)
        if (n != 1 || directed.count({e.second, e.first}) != 1) return false;
    return !directed.empty();
}

// Points on a mesh's faces at most `spacing` apart (for distances to the true surface).
Points surface_samples(const PolygonMesh& m, double spacing) {
    std::vector<Eigen::Vector3d> out;
    for (std::size_t f = 0; f < m.face_count(); ++f) {
        const Eigen::Vector3d a = m.vertices.row(m.indices[m.offsets[f]]).transpose();
        for (auto k = m.offsets[f] + 1; k + 1 < m.offsets[f + 1]; ++k) {
            const Eigen::Vector3d b = m.vertices.row(m.indices[k]).transpose(), c = m.vertices.row(m.indices[k + 1]).transpose();
            const int n = 1 + int(std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()}) / spacing);
            for (int i = 0; i <= n; ++i)
                for (int j = 0; i + j <= n; ++j) out.push_back(a + (b - a) * (double(i) / n) + (c - a) * (double(j) / n));
        }
    }
    Points p(Eigen::Index(out.size()), 3);
    for (std::size_t i = 0; i < out.size(); ++i) p.row(Eigen::Index(i)) = out[i].transpose();
    return p;
}

struct SignScore {
    double shm_inside = 0, shm_outside = 0, gwn_inside = 0, gwn_outside = 0;
    int inside = 0, outside = 0;
};

// Sign correctness at grid nodes more than two cells from the true surface, for SHM on the
// broken mesh and for thresholding the broken mesh's winding number at ½. Truth: the winding
// number of the intact closed mesh; distances to a dense sampling of it.
SignScore score_signs(const PolygonMesh& intact, const PolygonMesh& broken, const GridSpec& g, const std::vector<float>& phi) {
    const double cell = g.box.extent().maxCoeff() / (g.nx - 1);
    const Points samples = surface_samples(intact, cell / 8);
    const KdTree tree(samples);
    const Points nodes = g.nodes();
    std::vector<Eigen::Index> far;
    for (Eigen::Index i = 0; i < nodes.rows(); ++i)
        if (tree.knn(nodes.row(i).transpose(), 1)[0].distance > 2.125 * cell) far.push_back(i);
    // A fixed random subset keeps the exact winding-number sums quick.
    std::mt19937_64 rng(3);
    std::shuffle(far.begin(), far.end(), rng);
    far.resize(std::min<std::size_t>(far.size(), 12000));
    Points q(Eigen::Index(far.size()), 3);
    for (std::size_t i = 0; i < far.size(); ++i) q.row(Eigen::Index(i)) = nodes.row(far[i]);
    WindingOptions exact;
    exact.exact = true;
    const std::vector<double> truth = fast_winding_numbers(OrientedElements::from_mesh(intact), q, exact).w;
    const std::vector<double> gwn = fast_winding_numbers(OrientedElements::from_mesh(broken), q, exact).w;
    SignScore s;
    for (std::size_t i = 0; i < far.size(); ++i) {
        const bool in = truth[i] > 0.5;
        const double p = phi[std::size_t(far[i])];
        if (in) {
            ++s.inside;
            s.shm_inside += p < 0;
            s.gwn_inside += gwn[i] > 0.5;
        } else {
            ++s.outside;
            s.shm_outside += p > 0;
            s.gwn_outside += gwn[i] <= 0.5;
        }
    }
    s.shm_inside /= s.inside;
    s.gwn_inside /= s.inside;
    s.shm_outside /= s.outside;
    s.gwn_outside /= s.outside;
    return s;
}

}  // namespace

TEST_CASE("multigrid: a grid-independent convergence factor per cycle, on any grid size") {
    for (const GridSpec& g : {GridSpec::cube(17, kCube), GridSpec::cube(33, kCube), GridSpec::cube(64, kCube),
                              GridSpec{40, 24, 33, Box{{0, 0, 0}, {2, 1, 1.5}}}}) {
        CAPTURE(g.nx);
        CAPTURE(g.ny);
        const GridPoissonSolver solver(g, PoissonSolver::Multigrid, "cpu");
        const std::vector<double> b = solver.divergence(test_field(g));
        std::vector<double> history;
        const std::vector<double> phi = solver.solve(b, {1e-8, 40}, &history);
        REQUIRE(history.size() >= 3);
        // Geometric mean of the per-cycle reduction.
        const double factor = std::pow(history.back() / history.front(), 1.0 / double(history.size() - 1));
        MESSAGE("grid " << g.nx << "×" << g.ny << "×" << g.nz << ": " << history.size() << " cycles, factor " << factor);
        CHECK(factor < 0.35);
        CHECK(history.back() <= 1e-8);
        // And the answer solves the system.
        const std::vector<double> Lphi = solver.apply(phi);
        double r = 0, bn = 0;
        for (std::size_t i = 0; i < b.size(); ++i) { r += (Lphi[i] - b[i]) * (Lphi[i] - b[i]); bn += b[i] * b[i]; }
        CHECK(std::sqrt(r / bn) <= 1e-8);
    }
}

TEST_CASE("multigrid, CG and CHOLMOD solve the same system") {
    const GridSpec g{20, 14, 17, Box{{-1, -0.5, 0}, {1, 0.5, 1.2}}};
    const std::vector<float> y = test_field(g);
    std::vector<std::vector<double>> sol;
    for (PoissonSolver s : {PoissonSolver::Multigrid, PoissonSolver::CG, PoissonSolver::Direct}) {
        const GridPoissonSolver solver(g, s, "cpu");
        sol.push_back(solver.solve(solver.divergence(y), {1e-10, 5000}));
    }
    const double scale = max_abs(sol[0]);
    for (std::size_t k = 1; k < sol.size(); ++k) {
        double d = 0;
        for (std::size_t i = 0; i < sol[0].size(); ++i) d = std::max(d, std::abs(sol[k][i] - sol[0][i]));
        CHECK(d <= 1e-7 * scale);
    }
    // φ of an exact gradient field is recovered: Y = ∇(x + 2y) gives φ = x + 2y + const.
    std::vector<float> lin(3 * g.node_count());
    const Eigen::Vector3d grad(1, 2, 0);
    const Eigen::Vector3d u = grad.normalized();
    for (std::size_t i = 0; i < g.node_count(); ++i)
        for (int a = 0; a < 3; ++a) lin[3 * i + std::size_t(a)] = float(u[a]);
    const GridPoissonSolver solver(g, PoissonSolver::Multigrid, "cpu");
    const std::vector<double> phi = solver.solve(solver.divergence(lin), {1e-10, 50});
    const Points x = g.nodes();
    double worst = 0;
    const double offset = phi[0] - u.dot(x.row(0).transpose());
    for (Eigen::Index i = 0; i < x.rows(); ++i) worst = std::max(worst, std::abs(phi[std::size_t(i)] - offset - u.dot(x.row(i).transpose())));
    CHECK(worst < 1e-5);
}

TEST_CASE("GPU multigrid: relative residual 1e-6 within 20 cycles at 128^3, φ matches the CPU" * doctest::test_suite("slow")) {
    const gpu::Selection sel = gpu::select("gpu");
    REQUIRE(sel.context);
    const GridSpec g = GridSpec::cube(128, kCube);
    const std::vector<float> y = test_field(g);
    const GridPoissonSolver gpu_solver(g, PoissonSolver::Multigrid, "gpu");
    CHECK(gpu_solver.device() != "cpu");
    const std::vector<double> b = gpu_solver.divergence(y);
    std::vector<double> history;
    const std::vector<double> phi_gpu = gpu_solver.solve(b, {1e-6, 20}, &history);
    MESSAGE("GPU multigrid 128^3: " << history.size() << " cycles to " << history.back());
    CHECK(history.back() <= 1e-6);
    CHECK(history.size() <= 20);
    const GridPoissonSolver cpu_solver(g, PoissonSolver::Multigrid, "cpu");
    const std::vector<double> phi_cpu = cpu_solver.solve(b, {1e-6, 20});
    double d = 0;
    for (std::size_t i = 0; i < phi_cpu.size(); ++i) d = std::max(d, std::abs(phi_gpu[i] - phi_cpu[i]));
    MESSAGE("max |φ_gpu − φ_cpu| = " << d << " (diagonal " << g.box.diagonal() << ")");
    CHECK(d <= 1e-4 * g.box.diagonal());
    CHECK(gpu::validation_error_count() == 0);
}

// Odd, unequal sizes give coarse levels with a lone last cell (unequal cell sizes) and rows that
// do not fill a workgroup or a quad (the software build pads them); a grid of at most 4 cells an
// axis is one level, the dense solve alone. Both builds of the kernels (GSD_SOFTWARE_SHAPED) run
// on them, the GPUs' build with its grids in device memory (GSD_GPU_HOST_GRIDS=0) as on a GPU.
// Their scratch buffers start as NaN (GSD_GPU_POISON) rather than as whatever the allocation
// held, so a kernel that reads a value before one is stored fails the solve. V-cycles and
// F-cycles (whose second V-cycle on a level starts from a residual whose other color is 0).
TEST_CASE("GPU multigrid on grids of any shape, both kernel builds: φ matches the CPU") {
    REQUIRE(gpu::select("gpu").context);
    for (const bool f_cycle : {false, true})
    for (const GridSpec& g : {GridSpec{37, 50, 23, Box{{0, 0, 0}, {1.8, 2.5, 1.1}}}, GridSpec{33, 40, 65, Box{{0, 0, 0}, {1, 1.2, 2}}},
                              GridSpec{3, 4, 2, Box{{0, 0, 0}, {1, 1, 0.5}}}}) {
        CAPTURE(g.nx);
        CAPTURE(f_cycle);
        const GridPoissonSolver cpu_solver(g, PoissonSolver::Multigrid, "cpu");
        const std::vector<double> b = cpu_solver.divergence(test_field(g));
        std::vector<double> cpu_history;
        const std::vector<double> phi_cpu = cpu_solver.solve(b, {1e-8, 40, f_cycle}, &cpu_history);
        for (const char* shaped : {"0", "1"}) {
            CAPTURE(shaped);
            setenv("GSD_SOFTWARE_SHAPED", shaped, 1);
            setenv("GSD_GPU_POISON", "1", 1);
            setenv("GSD_GPU_HOST_GRIDS", shaped, 1);
            const GridPoissonSolver gpu_solver(g, PoissonSolver::Multigrid, "gpu");
            gpu_solver.prepare(f_cycle);  // SignedHeatGrid's way: made ready first
            std::vector<double> history;
            const std::vector<double> phi = gpu_solver.solve(b, {1e-8, 40, f_cycle}, &history);
            // Solving with b moved in (φ may come back in b's memory) gives the same φ.
            std::vector<double> b_copy = b;
            const std::vector<double> phi_moved = gpu_solver.solve(std::move(b_copy), {1e-8, 40, f_cycle});
            CHECK(phi_moved == phi);
            // A second solve that runs no cycle (b = 0) gives φ = 0, not what the first left.
            const std::vector<double> none = gpu_solver.solve(std::vector<double>(b.size(), 0.0), {1e-8, 40});
            CHECK(std::all_of(none.begin(), none.end(), [](double v) { return v == 0.0; }));
            unsetenv("GSD_GPU_POISON");
            unsetenv("GSD_GPU_HOST_GRIDS");
            unsetenv("GSD_SOFTWARE_SHAPED");
            CHECK(std::all_of(phi.begin(), phi.end(), [](double v) { return std::isfinite(v); }));
            CHECK(gpu_solver.device() != "cpu");
            CHECK(history.back() <= 1e-8);
            CHECK(history.size() <= cpu_history.size() + 2);  // float32 cycles converge as the CPU's
            double d = 0;
            for (std::size_t i = 0; i < phi.size(); ++i) d = std::max(d, std::abs(phi[i] - phi_cpu[i]));
            MESSAGE(g.nx << "x" << g.ny << "x" << g.nz << ", shaped " << std::string(shaped) << ": " << history.size() << " cycles (CPU "
                          << cpu_history.size() << "), max |φ_gpu − φ_cpu| = " << d);
            CHECK(d <= 1e-6 * g.box.diagonal());
        }
    }
    CHECK(gpu::validation_error_count() == 0);
}

namespace {

// The direction at node i of a step-1 field (3 floats per node).
Eigen::Vector3f direction(const std::vector<float>& y, std::size_t i) { return {y[3 * i], y[3 * i + 1], y[3 * i + 2]}; }

// The largest |y − z| over the nodes of two step-1 fields.
double largest_gap(const std::vector<float>& y, const std::vector<float>& z) {
    double worst = 0;
    for (std::size_t i = 0; 3 * i < y.size(); ++i) worst = std::max(worst, double((direction(y, i) - direction(z, i)).norm()));
    return worst;
}

}  // namespace

TEST_CASE("step 1 on the device matches the CPU, whatever the chunk size") {
    REQUIRE(gpu::select("gpu").context);
    const PointCloud c = shapes::by_name("torus")->sample(2048, 4);
    const ShmSource src = shm_source(c);
    const GridSpec g = GridSpec::cube(28, kCube);
    ShmOptions cpu, gpu_one, gpu_many;
    cpu.device = "cpu";
    gpu_one.device = gpu_many.device = "gpu";
    gpu_many.chunk_size = 100;
    const std::vector<float> a = SignedHeatGrid(src, g, cpu).diffused_directions();
    const std::vector<float> b = SignedHeatGrid(src, g, gpu_one).diffused_directions();
    const std::vector<float> d = SignedHeatGrid(src, g, gpu_many).diffused_directions();
    CHECK(b == d);
    const double worst = largest_gap(a, b);
    MESSAGE("step 1, max |Y_gpu − Y_cpu| = " << worst);
    CHECK(worst < 1e-4);
    // On lavapipe a subgroup stops short of llvmpipe's loop limit and the host sums its queries
    // on the CPU. With a cap of one iteration every subgroup stops: the CPU's directions to the
    // bit. With a low one, some: the same directions within the tolerance.
    if (gpu::select("gpu").context->info().is_software()) {
        setenv("GSD_LOOP_CAP", "1", 1);
        const std::vector<float> every = SignedHeatGrid(src, g, gpu_one).diffused_directions();
        setenv("GSD_LOOP_CAP", "200", 1);
        const std::vector<float> some = SignedHeatGrid(src, g, gpu_one).diffused_directions();
        unsetenv("GSD_LOOP_CAP");
        CHECK(every == a);
        std::size_t redone = 0;
        for (std::size_t i = 0; i < g.node_count(); ++i)
            redone += direction(some, i) == direction(a, i) && direction(some, i) != direction(b, i);
        const double capped = largest_gap(a, some);
        MESSAGE("step 1 with a loop cap of 200: max |Y_gpu − Y_cpu| = " << capped << ", " << redone << " nodes the CPU's");
        CHECK(capped < 1e-4);
        CHECK(redone > 0);
        // Step 1 on the device with the environment variable `var` set to `value`.
        auto directions_with = [&](const char* var, const char* value) {
            setenv(var, value, 1);
            std::vector<float> y = SignedHeatGrid(src, g, gpu_one).diffused_directions();
            unsetenv(var);
            return y;
        };
        // Each lane walking alone, as on GPUs.
        const std::vector<float> alone = directions_with("GSD_SHM_WALK", "alone");
        const double apart = largest_gap(a, alone);
        MESSAGE("step 1, each lane walking alone: max |Y_gpu − Y_cpu| = " << apart);
        CHECK(apart < 1e-4);
        // The kernel as GPUs run it (storage buffers, the walk taken together), beside the one
        // shaped for software devices (gpu::software_shaped: texel buffers, each lane's walk
        // listing what it sums) that ran above.
        const std::vector<float> as_gpus = directions_with("GSD_SOFTWARE_SHAPED", "0");
        const double gpus = largest_gap(a, as_gpus);
        MESSAGE("step 1, the GPUs' kernel: max |Y_gpu − Y_cpu| = " << gpus);
        CHECK(gpus < 1e-4);
        CHECK(as_gpus != b);  // the two kernels did run: they sum in different orders
    }
    CHECK(gpu::validation_error_count() == 0);
}

TEST_CASE("step 1 on the device: points, triangles and both together match the CPU") {
    // The kernel is specialized by the kinds of element the tree holds (shm_diffuse.comp's
    // ELEMENT_KINDS): a cloud's points alone, a mesh's triangles alone (refined), or a source
    // combining both, which takes the general code for each element.
    REQUIRE(gpu::select("gpu").context);
    const ShmSource cloud = shm_source(shapes::by_name("torus")->sample(1024, 8));
    const ShmSource mesh = shm_source(shapes::mesh(*shapes::by_name("capsule"), 10));
    const std::vector<std::pair<std::string, ShmSource>> cases{{"points", cloud}, {"triangles", mesh}, {"both", combine(cloud, mesh)}};
    for (const auto& entry : cases) {
        const std::string& name = entry.first;  // (no structured binding: clang 14 cannot capture one)
        const ShmSource& src = entry.second;
        CAPTURE(name);
        const GridSpec g = GridSpec::cube(24, shm_default_bounds(src));
        ShmOptions cpu, gpu_opt;
        cpu.device = "cpu";
        gpu_opt.device = "gpu";
        const std::vector<float> want = SignedHeatGrid(src, g, cpu).diffused_directions();
        const std::vector<float> got = SignedHeatGrid(src, g, gpu_opt).diffused_directions();
        const double worst = largest_gap(want, got);
        MESSAGE("step 1 on " << name << ": max |Y_gpu − Y_cpu| = " << worst);
        CHECK(worst < 1e-4);
        if (!gpu::select("gpu").context->info().is_software()) continue;
        // On a software device, also each lane walking alone and the GPUs' kernel (the same
        // element code), and the workgroups shared out between another count of threads (the
        // same directions to the bit).
        for (const auto& setting : {std::pair{"GSD_SHM_WALK", "alone"}, std::pair{"GSD_SOFTWARE_SHAPED", "0"},
                                    std::pair{"GSD_DISPATCH_THREADS", "3"}}) {
            const std::string var = setting.first;
            CAPTURE(var);
            ::setenv(setting.first, setting.second, 1);
            const std::vector<float> y = SignedHeatGrid(src, g, gpu_opt).diffused_directions();
            ::unsetenv(setting.first);
            CHECK(largest_gap(want, y) < 1e-4);
            if (var == "GSD_DISPATCH_THREADS") CHECK(y == got);
        }
    }
    CHECK(gpu::validation_error_count() == 0);
}

// Broken meshes with coarse faces: the case where GPU and CPU used to disagree (lavapipe ended
// long loops early and dropped half the sources). Whole solves, φ compared.
TEST_CASE("broken meshes (holes, flips, coarse faces): GPU and CPU SHM agree to 1e-4 of the diagonal") {
    REQUIRE(gpu::select("gpu").context);
    std::vector<std::pair<std::string, PolygonMesh>> cases;
    shapes::MeshCorruption d;
    d.holes = 3;
    d.hole_area = 0.15;
    d.flip_fraction = 0.05;
    cases.push_back({"coarse broken capsule", shapes::corrupt(shapes::mesh(*shapes::by_name("capsule"), 12), d, 3)});
#if GSD_HAVE_SHARED_DATA
    cases.push_back({"broken pat-block", shapes::corrupt(io::read_mesh(test::shared_data("meshes/pat-block.obj")), d, 5)});
#endif
    for (const auto& entry : cases) {
        const auto& name = entry.first;  // (no structured binding: clang 14 cannot capture one)
        const auto& mesh = entry.second;
        CAPTURE(name);
        const ShmSource src = shm_source(mesh);
        const GridSpec g = GridSpec::cube(32, shm_default_bounds(src));
        ShmOptions cpu, gpu_one, gpu_many;
        cpu.device = "cpu";
        gpu_one.device = gpu_many.device = "gpu";
        gpu_many.chunk_size = 777;
        const ShmResult a = SignedHeatGrid(src, g, cpu).solve();
        const ShmResult b = SignedHeatGrid(src, g, gpu_one).solve();
        const ShmResult c = SignedHeatGrid(src, g, gpu_many).solve();
        CHECK(b.phi == c.phi);
        CHECK(b.device != "cpu");
        double worst = 0;
        std::size_t flips = 0;
        for (std::size_t i = 0; i < a.phi.size(); ++i) {
            worst = std::max(worst, double(std::abs(a.phi[i] - b.phi[i])));
            flips += (a.phi[i] > 0) != (b.phi[i] > 0) && std::abs(a.phi[i]) > 1e-4 * g.box.diagonal();
        }
        MESSAGE(name << ": max |φ_gpu − φ_cpu| = " << worst / g.box.diagonal() << " of the diagonal; terms "
                     << b.kernel_terms << " vs " << a.kernel_terms);
        CHECK(worst <= 1e-4 * g.box.diagonal());
        CHECK(flips == 0);
        // The same sums on both: terms differ only where float and double decide a borderline
        // cluster differently.
        CHECK(double(b.kernel_terms) == doctest::Approx(double(a.kernel_terms)).epsilon(0.01));
    }
    CHECK(gpu::validation_error_count() == 0);
}

TEST_CASE("step 1: interpolating far from the source matches summing everywhere") {
    const PointCloud c = shapes::by_name("capsule")->sample(3000, 5);
    const ShmSource src = shm_source(c);
    const GridSpec g = GridSpec::cube(48, Box{{-1.5, -1.5, -1.5}, {1.5, 1.5, 1.5}});
    ShmOptions exact, fast;
    exact.device = fast.device = "cpu";
    exact.interpolation_cells = 0;
    const SignedHeatGrid a(src, g, exact), b(src, g, fast);
    const ShmResult ra = a.solve(), rb = b.solve();
    CHECK(rb.exact_nodes < ra.exact_nodes);
    double worst = 0, mean = 0;
    for (std::size_t i = 0; i < ra.phi.size(); ++i) {
        const double e = std::abs(ra.phi[i] - rb.phi[i]);
        worst = std::max(worst, e);
        mean += e;
    }
    mean /= double(ra.phi.size());
    MESSAGE("interpolated vs exact step 1: " << rb.exact_nodes << " vs " << ra.exact_nodes
                                             << " exact nodes; φ differs by mean " << mean << ", max " << worst);
    const double cell = 3.0 / 47;
    CHECK(mean < 0.01 * cell);
    CHECK(worst < 0.1 * cell);
}

TEST_CASE("analytic clouds: SHM is accurate on a sphere and a torus (2048 points, 64^3)") {
    // Measured (mean |φ − φ_true| over the 64³ grid on [−1,1]³): sphere 0.00094, torus 0.0032.
    // SHM converges linearly in the spacing (thesis §4.5); with h ≈ 0.02 and a grid cell of
    // 0.032 the bounds are 0.1 and 0.25 of a cell.
    const GridSpec g = GridSpec::cube(64, kCube);
    const double cell = 2.0 / 63;
    for (const auto& c : {std::pair{"sphere", 0.1 * cell}, std::pair{"torus", 0.25 * cell}}) {
        const char* name = c.first;  // (no structured binding: clang 14 cannot capture one)
        const double bound = c.second;
        CAPTURE(name);
        auto s = shapes::by_name(name);
        ShmOptions o;
        o.device = "cpu";
        const ShmResult r = SignedHeatGrid(shm_source(s->sample(2048, 1)), g, o).solve();
        const double err = mean_error(r.phi, g, *s);
        MESSAGE(name << ": mean |φ − φ_true| = " << err);
        CHECK(err < bound);
    }
}

TEST_CASE("--redistance: SHM's sign and zero set kept, |φ| the distance to that zero set") {
    // A capsule cloud with 3 holes: SHM's generalized distance strays from the Euclidean one away
    // from the surface; the distance to its own zero set does not.
    const GridSpec g = GridSpec::cube(test::sized(48, 32), kCube);
    auto s = shapes::by_name("capsule");
    shapes::Corruption k;
    k.holes = 3;
    const ShmSource src = shm_source(shapes::corrupt(s->sample(2048, 1), k, 2));
    ShmOptions o;
    o.device = "cpu";
    const ShmResult plain = SignedHeatGrid(src, g, o).solve();
    o.redistance = true;
    const ShmResult re = SignedHeatGrid(src, g, o).solve();
    std::size_t flipped = 0;
    for (std::size_t i = 0; i < plain.phi.size(); ++i) flipped += (plain.phi[i] < 0) != (re.phi[i] < 0);
    CHECK(flipped == 0);
    const double e_plain = mean_error(plain.phi, g, *s), e_re = mean_error(re.phi, g, *s);
    MESSAGE("mean |φ − φ_true|: SHM " << e_plain << ", redistanced " << e_re);
    CHECK(e_re < 0.8 * e_plain);
    CHECK(re.seconds_redistance > 0);
}

TEST_CASE("broken meshes: 20% of the area in 3 holes and 10% of faces flipped — the sign is right" * doctest::test_suite("slow")) {
    struct Case { std::string name; PolygonMesh mesh; };
    std::vector<Case> cases;
    cases.push_back({"torus (procedural)", shapes::mesh(*shapes::by_name("torus"), 48)});
    cases.push_back({"rounded box (procedural)", shapes::mesh(*shapes::by_name("rounded-box"), 48)});
#if GSD_HAVE_SHARED_DATA
    for (const char* m : {"bunny_small", "pat-block", "pat-femur"})
        cases.push_back({m, io::read_mesh(test::shared_data(std::string("meshes/") + m + ".obj"))});
#endif
    // And one more with Gaussian noise on the vertices (0.3% of the diagonal) on top.
    cases.push_back({"capsule (procedural) + noise", shapes::mesh(*shapes::by_name("capsule"), 48)});
    shapes::MeshCorruption damage;
    damage.holes = 3;
    damage.hole_area = 0.2;
    damage.flip_fraction = 0.1;
    for (const Case& c : cases) {
        CAPTURE(c.name);
        shapes::MeshCorruption d = damage;
        if (c.name.find("noise") != std::string::npos) d.vertex_noise = 0.003;
        const PolygonMesh broken = shapes::corrupt(c.mesh, d, 11);
        if (d.vertex_noise == 0) CHECK(shapes::area(broken) == doctest::Approx(0.8 * shapes::area(c.mesh)).epsilon(0.03));
        const GridSpec g = GridSpec::cube(48, shm_default_bounds(shm_source(c.mesh)));
        ShmOptions o;
        o.device = "cpu";
        const ShmResult r = SignedHeatGrid(shm_source(broken), g, o).solve();
        const SignScore s = score_signs(c.mesh, broken, g, r.phi);
        MESSAGE(c.name << ": SHM inside " << 100 * s.shm_inside << "% outside " << 100 * s.shm_outside << "% | GWN inside "
                       << 100 * s.gwn_inside << "% outside " << 100 * s.gwn_outside << "% (" << s.inside << " inside, "
                       << s.outside << " outside nodes)");
        CHECK(s.shm_inside >= 0.95);
        CHECK(s.shm_outside >= 0.99);
        CHECK(s.shm_inside > s.gwn_inside);
        // The zero level set is a closed surface.
        const PolygonMesh zero = contour(g, r.phi, 0.0);
        CHECK(closed(zero));
    }
}

TEST_CASE("the outside veto: no inside bulging out of a sphere's missing cap") {
    // A sphere of radius 0.7 without the cap within 55° of +z (a fifth of its area): SHM's
    // completion bulges out over the opening. Truth: |x| < 0.7, at nodes more than two cells
    // from the sphere.
    const double radius = 0.7;
    const PolygonMesh sphere = shapes::icosphere(4, radius);
    PolygonMesh open;
    open.vertices = sphere.vertices;
    for (std::size_t f = 0; f < sphere.face_count(); ++f) {
        const std::uint32_t* v = &sphere.indices[sphere.offsets[f]];
        const Eigen::Vector3d c = (sphere.vertices.row(v[0]) + sphere.vertices.row(v[1]) + sphere.vertices.row(v[2])).transpose() / 3;
        if (c.z() / c.norm() < std::cos(55 * M_PI / 180)) open.add_face(v, 3);
    }
    const GridSpec g = GridSpec::cube(test::sized(48, 32), kCube);
    const double cell = 2.0 / (g.nx - 1);
    ShmOptions off, on;
    off.device = on.device = "cpu";
    off.veto_winding = 0;
    const ShmResult a = SignedHeatGrid(shm_source(open), g, off).solve(), b = SignedHeatGrid(shm_source(open), g, on).solve();
    CHECK(a.vetoed_nodes == 0);
    const Points x = g.nodes();
    int inside = 0, outside = 0, wrong_out_off = 0, wrong_out_on = 0, wrong_in_on = 0, changed = 0;
    for (Eigen::Index i = 0; i < x.rows(); ++i) {
        const double r = x.row(i).norm();
        const std::size_t k = std::size_t(i);
        changed += (a.phi[k] < 0) != (b.phi[k] < 0);
        if (std::abs(r - radius) <= 2 * cell) continue;
        if (r < radius) {
            ++inside;
            wrong_in_on += !(b.phi[k] < 0);
        } else {
            ++outside;
            wrong_out_off += !(a.phi[k] > 0);
            wrong_out_on += !(b.phi[k] > 0);
        }
    }
    MESSAGE("outside nodes signed wrong: " << wrong_out_off << " without the veto, " << wrong_out_on << " with it (of " << outside
                                           << "); inside wrong with it: " << wrong_in_on << " of " << inside << "; "
                                           << b.vetoed_nodes << " nodes vetoed");
    REQUIRE(wrong_out_off > 0.005 * outside);  // the bulge the veto is for
    CHECK(2 * wrong_out_on < wrong_out_off);
    CHECK(wrong_out_on < 0.01 * outside);
    CHECK(wrong_in_on == 0);
    CHECK(std::size_t(changed) == b.vetoed_nodes);  // the veto only turns inside to outside
}

TEST_CASE("the outside veto leaves thin parts alone" * doctest::test_suite("slow")) {
    // A thin slab (a rounded box squashed to a fifth of its height: 0.14 thick, the margin 0.1)
    // with 20 % of its area in 3 holes: its inside has low winding numbers, but no node inside
    // is farther than 0.75 margins from the faces, where the veto's ramp starts. (Slow: the
    // slab needs 48³ to have nodes inside more than two cells from its faces.)
    ShmOptions off, on;
    off.device = on.device = "cpu";
    off.veto_winding = 0;
    PolygonMesh slab = shapes::mesh(*shapes::by_name("rounded-box"), 48);
    slab.vertices.col(2) *= 0.2;
    shapes::MeshCorruption holes;
    holes.holes = 3;
    holes.hole_area = 0.2;
    const PolygonMesh broken = shapes::corrupt(slab, holes, 5);
    const GridSpec gs = GridSpec::cube(48, shm_default_bounds(shm_source(slab)));
    const ShmResult c = SignedHeatGrid(shm_source(broken), gs, off).solve(), d = SignedHeatGrid(shm_source(broken), gs, on).solve();
    const SignScore sc = score_signs(slab, broken, gs, c.phi), sd = score_signs(slab, broken, gs, d.phi);
    MESSAGE("thin slab, inside / outside right: " << 100 * sc.shm_inside << " / " << 100 * sc.shm_outside << " % without the veto, "
                                                  << 100 * sd.shm_inside << " / " << 100 * sd.shm_outside << " % with it; GWN inside "
                                                  << 100 * sd.gwn_inside << " %");
    REQUIRE(sd.inside > 100);
    CHECK(sd.shm_inside == sc.shm_inside);
    CHECK(sd.shm_outside >= sc.shm_outside);
}

TEST_CASE("fitting the zero set softly pulls φ to zero on the source") {
    shapes::Corruption holes;
    holes.holes = 2;
    holes.hole_radius = 0.12;
    const PointCloud c = shapes::corrupt(shapes::by_name("rounded-box")->sample(2000, 6), holes, 7);
    const ShmSource src = shm_source(c);
    const GridSpec g = GridSpec::cube(40, kCube);
    ShmOptions shift, fit;
    shift.device = fit.device = "cpu";
    shift.fit_zero_set = 0;
    fit.fit_zero_set = 10;
    const ShmResult a = SignedHeatGrid(src, g, shift).solve(), b = SignedHeatGrid(src, g, fit).solve();
    CHECK(a.fit_history.empty());
    REQUIRE(!b.fit_history.empty());
    CHECK(b.fit_history.back() <= 1e-6);
    auto rms_on_source = [&](const std::vector<float>& phi) {
        // Trilinear φ at the samples, as the fit sees it.
        double s = 0;
        for (Eigen::Index i = 0; i < c.size(); ++i) {
            int b[3];
            double t[3];
            for (int a = 0; a < 3; ++a) {
                const double u = (c.points(i, a) + 1) / 2 * 39;
                b[a] = std::min(int(u), 38);
                t[a] = u - b[a];
            }
            double v = 0;
            for (int k = 0; k < 8; ++k) {
                const int o[3] = {k & 1, (k >> 1) & 1, (k >> 2) & 1};
                v += (o[0] ? t[0] : 1 - t[0]) * (o[1] ? t[1] : 1 - t[1]) * (o[2] ? t[2] : 1 - t[2]) *
                     phi[(std::size_t(b[0] + o[0]) * 40 + std::size_t(b[1] + o[1])) * 40 + std::size_t(b[2] + o[2])];
            }
            s += v * v;
        }
        return std::sqrt(s / double(c.size()));
    };
    MESSAGE("RMS φ on the source: shifted " << rms_on_source(a.phi) << ", fitted " << rms_on_source(b.phi));
    CHECK(rms_on_source(b.phi) < 0.5 * rms_on_source(a.phi));
}

TEST_CASE("degenerate input gets a clear error") {
    PolygonMesh flat;
    flat.vertices.resize(3, 3);
    flat.vertices << 0, 0, 0, 1, 0, 0, 2, 0, 0;  // collinear: zero area
    flat.add_face({0, 1, 2});
    CHECK_THROWS_AS(shm_source(flat), Error);
    PointCloud one;
    one.points = Points::Zero(1, 3);
    one.normals = Points::Zero(1, 3);
    one.normals(0, 2) = 1;
    CHECK_THROWS_AS(shm_source(one), Error);
    const ShmSource ok = shm_source(shapes::by_name("sphere")->sample(200, 1));
    // The library names the option field at fault (the CLI reports the flag that sets it).
    auto field_at_fault = [&](ShmOptions bad, GridSpec grid = GridSpec::cube(8, kCube)) {
        try {
            SignedHeatGrid g(ok, grid, bad);
        } catch (const Error& e) {
            return e.where();
        }
        return std::string("no error");
    };
    ShmOptions bad;
    bad.t_coef = 0;
    CHECK(field_at_fault(bad) == "ShmOptions::t_coef");
    bad = {};
    bad.fit_zero_set = -1;
    CHECK(field_at_fault(bad) == "ShmOptions::fit_zero_set");
    bad.fit_zero_set = std::nan("");  // NaN and infinity fail every test, not just the sign
    CHECK(field_at_fault(bad) == "ShmOptions::fit_zero_set");
    bad = {};
    bad.t_coef = std::numeric_limits<double>::infinity();
    CHECK(field_at_fault(bad) == "ShmOptions::t_coef");
    bad = {};
    bad.cutoff = std::nan("");
    CHECK(field_at_fault(bad) == "ShmOptions::cutoff");
    bad = {};
    bad.interpolation_cells = std::nan("");
    CHECK(field_at_fault(bad) == "ShmOptions::interpolation_cells");
    bad = {};
    bad.sum_tolerance = 2;
    CHECK(field_at_fault(bad) == "ShmOptions::sum_tolerance");
    bad = {};
    bad.veto_winding = 1;
    CHECK(field_at_fault(bad) == "ShmOptions::veto_winding");
    bad = {};
    bad.veto_margin = 0;
    CHECK(field_at_fault(bad) == "ShmOptions::veto_margin");
    bad = {};
    bad.veto_slope = std::nan("");
    CHECK(field_at_fault(bad) == "ShmOptions::veto_slope");
    CHECK(field_at_fault({}, GridSpec::cube(1, kCube)) == "GridSpec");
    CHECK(field_at_fault({}, GridSpec::cube(8, Box{{0, 0, 0}, {1e31, 1, 1}})) == "GridSpec::box");
    // A grid that does not contain the source cannot be shifted to it.
    ShmOptions o;
    o.device = "cpu";
    CHECK_THROWS_AS(SignedHeatGrid(ok, GridSpec::cube(8, Box{{5, 5, 5}, {6, 6, 6}}), o).solve(), Error);
}

TEST_CASE("CLI: gsd shm grid on a broken mesh, a cloud, and both; bad input exits 1") {
    test::ScratchDir dir("cli-shm");
    REQUIRE(test::run_cli("mesh capsule -r 40 --holes 2 --hole-area 0.15 --flip 0.1 -o " + dir.file("m.obj")).exit_code == 0);
    REQUIRE(test::run_cli("sample sphere -n 800 -o " + dir.file("c.ply")).exit_code == 0);
    const auto r = test::run_cli("shm grid " + dir.file("m.obj") + " --grid 24 -o " + dir.file("m.npy") + " --device cpu");
    CHECK(r.exit_code == 0);
    CHECK(r.output.find("--bounds") != std::string::npos);  // the default bounds are reported
    CHECK(io::read_npy(dir.file("m.npy")).shape == std::vector<std::size_t>{24, 24, 24});
    // With room around the shape, the zero level set is closed.
    CHECK(test::run_cli("shm grid " + dir.file("m.obj") + " --grid 32 --bounds -1 -1 -1 1 1 1 -o " + dir.file("m2.npy") +
                        " --contour " + dir.file("z.obj"))
              .exit_code == 0);
    CHECK(closed(io::read_mesh(dir.file("z.obj"))));
    CHECK(test::run_cli("shm grid " + dir.file("m.obj") + " " + dir.file("c.ply") + " --grid 20 --solver cg -o " + dir.file("mc.npy"))
              .exit_code == 0);
    CHECK(test::run_cli("shm grid " + dir.file("c.ply") + " --grid 16 --solver direct --bounds -1 -1 -1 1 1 1 -o " + dir.file("d.npy"))
              .exit_code == 0);
    test::write_bytes(dir.file("flat.obj"), "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n");
    const auto bad = test::run_cli("shm grid " + dir.file("flat.obj") + " --grid 16 -o " + dir.file("f.npy"));
    CHECK(bad.exit_code == 1);
    CHECK(bad.output.find("flat.obj") != std::string::npos);
    CHECK_FALSE(test::file_exists(dir.file("f.npy")));
    CHECK(test::run_cli("shm grid " + dir.file("c.ply") + " --grid 16 --solver magic -o " + dir.file("x.npy")).exit_code == 2);
    // Errors the library raises about an option field name the flag here.
    const auto t0 = test::run_cli("shm grid " + dir.file("c.ply") + " --grid 16 --bounds 0 0 0 1e31 1 1 -o " + dir.file("t.npy"));
    CHECK(t0.exit_code == 1);
    CHECK(t0.output.find("error: --bounds:") != std::string::npos);
    CHECK_FALSE(test::file_exists(dir.file("t.npy")));
}

// ---- distance sharpening (thesis §4.4, eq. 4.13) ------------------------------------------------

namespace {

struct SharpenCase {
    std::unique_ptr<shapes::Shape> shape;
    GridSpec grid;
    ShmResult shm;
    std::optional<SignedHeatGrid> solver;
};

// The SHM distance of a closed mesh of an analytic shape with a long diffusion time (t = 100h²,
// thesis fig. 4.13's setting), on an n³ grid over [−1, 1]³.
SharpenCase blurred_shm(const char* name, int n) {
    SharpenCase c;
    c.shape = shapes::by_name(name);
    c.grid = GridSpec::cube(n, kCube);
    ShmOptions o;
    o.t_coef = 100;
    o.device = Device::cpu();
    c.solver.emplace(shm_source(shapes::mesh(*c.shape, 40)), c.grid, o);
    c.shm = c.solver->solve();
    return c;
}

std::size_t label_changes(const std::vector<float>& a, const std::vector<float>& b) {
    std::size_t n = 0;
    for (std::size_t i = 0; i < a.size(); ++i) n += (a[i] < 0) != (b[i] < 0);
    return n;
}

}  // namespace

TEST_CASE("sharpening a blurred SHM distance (t = 100h²) halves its error against the exact SDF, every label kept" *
          doctest::test_suite("slow")) {
    for (const char* name : {"capsule", "rounded-box"}) {
        CAPTURE(name);
        const SharpenCase c = blurred_shm(name, 48);
        SharpenOptions o;
        o.device = Device::cpu();
        const SharpenResult s = c.solver->sharpen(c.shm.phi, o);
        const double before = mean_error(c.shm.phi, c.grid, *c.shape), after = mean_error(s.phi, c.grid, *c.shape);
        MESSAGE(std::string(name) << ": mean |φ − sdf| " << before << " → " << after << " in " << s.iterations << " iterations, largest slope "
                     << s.max_slope);
        CHECK(after <= 0.5 * before);
        CHECK(s.sign_changes == 0);
        CHECK(label_changes(c.shm.phi, s.phi) == 0);
        CHECK(s.max_slope < 1.3);  // |∇φ| ≤ 1 up to what is left of the iteration
        // Eq. 4.13 as written (no bound on the side): the zero set moves onto the source, so the
        // labels it changes are ones the blurred φ₀ had wrong: agreement with the exact sign grows.
        o.keep_sign = false;
        const SharpenResult free = c.solver->sharpen(c.shm.phi, o);
        const Points x = c.grid.nodes();
        std::size_t right_before = 0, right_after = 0;
        for (Eigen::Index i = 0; i < x.rows(); ++i) {
            const bool inside = c.shape->sdf(x.row(i).transpose()) < 0;
            right_before += (c.shm.phi[std::size_t(i)] < 0) == inside;
            right_after += (free.phi[std::size_t(i)] < 0) == inside;
        }
        MESSAGE("without the bound: " << label_changes(c.shm.phi, free.phi) << " labels changed; exact sign at " << right_before
                                      << " → " << right_after << " of " << x.rows() << " nodes");
        CHECK(right_after >= right_before);
        CHECK(mean_error(free.phi, c.grid, *c.shape) <= 0.5 * before);
    }
}

TEST_CASE("sharpening on the device equals the CPU (both run the same float32 PDHG) to 1e-4 of the diagonal" *
          doctest::test_suite("slow")) {
    REQUIRE(gpu::select("gpu").context);
    const SharpenCase c = blurred_shm("torus", 28);
    for (int iterations : {100, 300}) {  // 300 passes a restart (every 6 · 28 = 168)
        SharpenOptions o;
        o.iterations = iterations;
        o.device = Device::cpu();
        const SharpenResult cpu = c.solver->sharpen(c.shm.phi, o);
        o.device = Device("gpu");
        const SharpenResult gpu = c.solver->sharpen(c.shm.phi, o);
        CHECK(gpu.device != "cpu");
        double d = 0;
        for (std::size_t i = 0; i < cpu.phi.size(); ++i) d = std::max(d, double(std::abs(cpu.phi[i] - gpu.phi[i])));
        MESSAGE(iterations << " iterations: max |φ_gpu − φ_cpu| = " << d);
        CHECK(d <= 1e-4 * c.grid.box.diagonal());
    }
}

TEST_CASE("sharpening refuses bad input with a clear error") {
    const GridSpec g = GridSpec::cube(8, kCube);
    const ShmSource src = shm_source(shapes::mesh(*shapes::by_name("sphere"), 12));
    std::vector<float> phi(g.node_count(), 0.5f);
    CHECK_THROWS_WITH_AS(sharpen_distance(g, std::span<const float>(phi.data(), phi.size() - 1), src), doctest::Contains("values for a grid of"), Error);
    phi[3] = std::numeric_limits<float>::quiet_NaN();
    CHECK_THROWS_WITH_AS(sharpen_distance(g, phi, src), doctest::Contains("not finite at node 3"), Error);
    phi[3] = 0.5f;
    SharpenOptions bad;
    bad.iterations = -1;
    CHECK_THROWS_WITH_AS(sharpen_distance(g, phi, src, bad), doctest::Contains("iterations"), Error);
    const GridSpec away = GridSpec::cube(8, Box{{5, 5, 5}, {6, 6, 6}});
    CHECK_THROWS_WITH_AS(sharpen_distance(away, phi, src), doctest::Contains("outside the grid"), Error);
}
