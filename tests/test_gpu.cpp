// GPU-vs-CPU conformance: every kernel runs on a Vulkan device (lavapipe in CI) and is held to
// the double-precision CPU reference with a stated tolerance. Validation layers are on
// (GSD_VALIDATION=1 from CTest) and any validation error fails the test.
#include <doctest/doctest.h>

#include <gsd/baselines.hpp>
#include <gsd/gpu.hpp>
#include <gsd/io.hpp>
#include <gsd/pat.hpp>
#include <gsd/shapes.hpp>
#include <gsd/sums.hpp>

#include "blend/blend.hpp"
#include "gpu/device_choice.hpp"
#include "gpu/runtime.hpp"
#include "sums/sum_tree.hpp"
#include "support.hpp"

#include <array>
#include <filesystem>
#include <future>
#include <set>

#include <cmath>
#include <cstdlib>
#include <random>

using namespace gsd;

namespace {

std::shared_ptr<gpu::Context> device() {
    static const gpu::Selection sel = gpu::select("gpu");
    return sel.context;
}

struct Diff {
    double max_abs = 0;
    std::size_t over = 0;  // entries beyond the tolerance
};

Diff compare(const std::vector<float>& a, const std::vector<float>& b, double tol) {
    REQUIRE(a.size() == b.size());
    Diff d;
    for (std::size_t i = 0; i < a.size(); ++i) {
        const double e = std::abs(double(a[i]) - double(b[i]));
        d.max_abs = std::max(d.max_abs, e);
        d.over += e > tol;
    }
    return d;
}

// Queries: the 24³ grid over [−1,1]³ plus points scattered near the surface of the cloud.
Points mixed_queries(const PointCloud& c, std::uint64_t seed) {
    const GridSpec g = GridSpec::cube(24, Box{{-1, -1, -1}, {1, 1, 1}});
    const Points grid = g.nodes();
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> noise(0, 0.02);
    Points q(grid.rows() + 2000, 3);
    q.topRows(grid.rows()) = grid;
    for (Eigen::Index i = 0; i < 2000; ++i) {
        const Eigen::Index j = Eigen::Index(rng() % std::uint64_t(c.size()));
        for (int a = 0; a < 3; ++a) q(grid.rows() + i, a) = c.points(j, a) + noise(rng);
    }
    return q;
}

// Scales a cloud into [−1, 1]³ (centered, longest side 1.8), the thesis' evaluation frame.
[[maybe_unused]] PointCloud normalized(PointCloud c) {  // used by the real-data tests
    const Box b = bounding_box(c.points);
    const Eigen::RowVector3d center = (0.5 * (b.lo + b.hi)).transpose();
    const double scale = 1.8 / b.extent().maxCoeff();
    for (Eigen::Index i = 0; i < c.size(); ++i) c.points.row(i) = (c.points.row(i) - center) * scale;
    return c;
}

BlendOptions on(const std::string& device_choice, bool exact = false) {
    BlendOptions o;
    o.device = device_choice;
    o.exact = exact;
    return o;
}

}  // namespace

TEST_CASE("a Vulkan device is available (lavapipe in CI) and validation is on") {
    const gpu::Inventory inv = gpu::list_devices();
    INFO("problem: " << inv.problem);
    REQUIRE(inv.loader_found);
    REQUIRE(device() != nullptr);
    MESSAGE("conformance device: " << gpu::device_name(*device()));
    CHECK(gpu::validation_active());
}

TEST_CASE("a validation error is seen (the runner fails any test case that raises one unexpectedly)") {
    REQUIRE(device());
    REQUIRE(gpu::validation_active());
    // A buffer with no usage flags breaks VUID-VkBufferCreateInfo-usage-requiredbitmask; drivers
    // still create it, so nothing else happens.
    VkBufferCreateInfo info{};
    info.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
    info.size = 256;
    info.usage = 0;
    info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    const std::uint64_t before = gpu::validation_error_count();
    VkBuffer buffer = VK_NULL_HANDLE;
    if (device()->vk().vkCreateBuffer(device()->device(), &info, nullptr, &buffer) == VK_SUCCESS)
        device()->vk().vkDestroyBuffer(device()->device(), buffer, nullptr);
    const std::uint64_t raised = gpu::validation_error_count() - before;
    test::expect_validation_errors(raised);  // on purpose: not this suite's failure
    CHECK(raised >= 1);
}

TEST_CASE("a kernel asked for with the wrong number of bindings is an error, not a pipeline") {
    REQUIRE(device());
    // mg_add reads two buffers (e, s); asking for three, or one, must say so.
    const std::uint32_t push = sizeof(std::uint32_t);
    CHECK_THROWS_WITH_AS(device()->kernel("mg_add", 3, push), doctest::Contains("its shader declares 2"), Error);
    CHECK_THROWS_AS(device()->kernel("mg_add", 1, push), Error);
    CHECK(device()->kernel("mg_add", 2, push).bindings == 2);
    CHECK(gpu::validation_error_count() == test::expected_validation_errors());
}

TEST_CASE("the kernel table: every embedded shader has a row, with the bindings its SPIR-V declares") {
    // Read from the embedded SPIR-V, no device needed (building every pipeline would cost
    // lavapipe minutes of LLVM on a fresh machine; the conformance tests build them as used).
    std::set<std::string> listed;
    for (const gpu::KernelSpec* spec : gpu::kernel_table::all) {
        CAPTURE(spec->shader);
        CHECK(listed.insert(spec->shader).second);  // one row per shader
        CHECK(gpu::shader_binding_count(spec->shader) == spec->bindings);
        CHECK((spec->texels.all() >> spec->bindings_of(spec->has_software_build())) == 0);  // texel bindings the shader has
        if (spec->has_software_build()) {
            const std::string software = std::string(spec->shader) + "_software";
            listed.insert(software);
            CHECK(gpu::shader_binding_count(software) == spec->bindings_of(true));
        }
    }
    for (const std::string& name : gpu::embedded_shader_names()) {
        CAPTURE(name);
        CHECK(listed.count(name) == 1);
    }
    CHECK(listed.size() == gpu::embedded_shader_names().size());
}

TEST_CASE("a kernel of the table without a software build refuses to be asked for one") {
    REQUIRE(device());
    CHECK_THROWS_AS(gpu::kernel(*device(), gpu::kernel_table::mg_add, {}, 0, true), Error);
    CHECK(gpu::kernel(*device(), gpu::kernel_table::mg_add).bindings == 2);
    CHECK(gpu::validation_error_count() == test::expected_validation_errors());
}

TEST_CASE("torus_from_jet: device tori match the CPU's") {
    REQUIRE(device());
    std::mt19937_64 rng(1);
    std::normal_distribution<double> g;
    std::uniform_real_distribution<double> u(-1, 1);
    const int n = 4000;
    Points p(n, 3), nrm(n, 3), tan(n, 3);
    std::vector<Jet> jets(n);
    for (int i = 0; i < n; ++i) {
        const Eigen::Vector3d ni = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
        p.row(i) << u(rng), u(rng), u(rng);
        nrm.row(i) = ni.transpose();
        tan.row(i) = tangent_of(ni).transpose();
        Jet& j = jets[std::size_t(i)];
        j.a00 = 0.01 * g(rng);
        j.a10 = 0.3 * g(rng);
        j.a01 = 0.3 * g(rng);
        // Mix curved, umbilic, cylindrical and flat cases.
        const int kind = i % 4;
        j.a20 = kind == 3 ? 0 : 3 * g(rng);
        j.a02 = kind == 1 ? j.a20 : (kind == 3 ? 0 : 3 * g(rng));
        j.a11 = kind == 1 || kind == 3 ? 0 : 3 * g(rng);
        if (kind == 2) { j.a02 = 0; j.a11 = 0; j.a01 = 0; }
    }
    const std::vector<float> dev = blend::tori_on_device(*device(), p, nrm, tan, jets);
    double worst_q = 0, worst_k = 0, worst_n = 0, worst_e = 0;
    for (int i = 0; i < n; ++i) {
        const Torus t = torus_from_jet(p.row(i).transpose(), nrm.row(i).transpose(), tan.row(i).transpose(), jets[std::size_t(i)]);
        const float* d = &dev[12 * std::size_t(i)];
        const Eigen::Vector3d q(d[0], d[1], d[2]), e1(d[4], d[5], d[6]), nn(d[8], d[9], d[10]);
        worst_q = std::max(worst_q, (q - t.q).norm());
        const double kscale = 1 + std::abs(t.k1);
        worst_k = std::max({worst_k, std::abs(d[3] - t.k1) / kscale, std::abs(d[7] - t.k2) / kscale});
        worst_n = std::max(worst_n, (nn - t.n).norm());
        // The principal direction is defined up to sign, and not at all at an umbilic.
        if (std::abs(t.k1 - t.k2) > 1e-2 * kscale) worst_e = std::max(worst_e, 1 - std::abs(e1.dot(t.e1)));
    }
    CHECK(worst_q < 1e-6);
    CHECK(worst_k < 1e-5);
    CHECK(worst_n < 1e-6);
    CHECK(worst_e < 1e-4);
    CHECK(gpu::validation_error_count() == test::expected_validation_errors());
}

TEST_CASE("PAT on the device matches the CPU reference (sphere, accelerated and exact, with gradients)") {
    REQUIRE(device());
    auto s = shapes::by_name("sphere");
    const PointCloud c = s->sample(2048, 1);
    const FittedTori f = JetFitter().fit(c);
    const Points q = mixed_queries(c, 2);
    for (bool exact : {false, true}) {
        CAPTURE(exact);
        const FieldValues cpu = TorusField(f, on("cpu", exact)).evaluate(q, true);
        const FieldValues gpu = TorusField(f, on("gpu", exact)).evaluate(q, true);
        CHECK(gpu.device != "cpu");
        const Diff dphi = compare(gpu.phi, cpu.phi, 1e-4);
        MESSAGE("PAT " << std::string(exact ? "exact" : "accelerated") << " max |φ_gpu − φ_cpu| = " << dphi.max_abs);
        CHECK(dphi.max_abs < 1e-4);
        const Diff dgrad = compare(gpu.gradient, cpu.gradient, 1e-3);
        CHECK(dgrad.max_abs < 1e-3);
    }
    CHECK(gpu::validation_error_count() == test::expected_validation_errors());
}

TEST_CASE("PAT's k-nearest fallback walked per subgroup (the hardware GPUs' path) matches the CPU reference") {
    // Hardware GPUs walk the fallback together (blend_field.glsl, knn_together); lavapipe does
    // not by default, so GSD_SHARED_KNN=1 puts that path under test here. Queries far apart and
    // in random order too: a subgroup whose lanes want different subtrees.
    REQUIRE(device());
    auto s = shapes::by_name("torus");
    const PointCloud c = s->sample(4096, 5);
    const FittedTori f = JetFitter().fit(c);
    Points q = mixed_queries(c, 6);
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-1.5, 1.5);
    Points spread(512, 3);
    for (Eigen::Index i = 0; i < spread.rows(); ++i)
        for (int a = 0; a < 3; ++a) spread(i, a) = u(rng);
    const FieldValues cpu = TorusField(f, on("cpu", false)).evaluate(q, true);
    const FieldValues cpu_spread = TorusField(f, on("cpu", false)).evaluate(spread, true);
    // φ and ∇φ at x on the device, with the kernel build GSD_SOFTWARE_SHAPED and GSD_SHARED_KNN
    // choose; and the checks against the CPU's, within docs/gpu.md's tolerances.
    auto on_build = [&](const char* shaped, const char* shared, const BlendOptions& o, const Points& x) {
        ::setenv("GSD_SOFTWARE_SHAPED", shaped, 1);
        if (shared) ::setenv("GSD_SHARED_KNN", shared, 1);
        const FieldValues v = TorusField(f, o).evaluate(x, true);
        ::unsetenv("GSD_SOFTWARE_SHAPED");
        ::unsetenv("GSD_SHARED_KNN");
        return v;
    };
    auto agrees = [](const FieldValues& got, const FieldValues& want) {
        CHECK(compare(got.phi, want.phi, 1e-4).max_abs < 1e-4);
        CHECK(compare(got.gradient, want.gradient, 1e-3).max_abs < 1e-3);
    };
    // And blend_eval as GPUs run it (storage buffers, the ball walked together) beside the
    // kernel shaped for software devices (texel buffers, each lane's ball walk listing leaves).
    for (const auto& setting : {std::pair{"0", "1"}, std::pair{"1", "1"}, std::pair{"0", "0"}}) {
        const char* shared = setting.first;  // (not structured bindings: clang's CAPTURE cannot take them)
        const char* shaped = setting.second;
        CAPTURE(shared);
        CAPTURE(shaped);
        agrees(on_build(shaped, shared, on("gpu", false), q), cpu);
        agrees(on_build(shaped, shared, on("gpu", false), spread), cpu_spread);
    }
    // Every kernel build leaves out PAT terms past the nearest point + PRUNE/λ, λ = 2C/ρ, and
    // weighs from the nearest point (blend_field.glsl): at a small C the reach passes ρ and
    // nothing is left out, at the largest the most is, and e^C would overflow float32 sums (it
    // did before this check, at bf9e67e: ∇φ off by 0.06 at C = 80, φ by 0.02 at 87). Near the
    // cloud and far; the software build, the GPUs' build with each lane's k-nearest walk and
    // with the subgroup's.
    for (const double C : {4.0, 20.0, 64.0, 80.0, 87.0}) {
        for (const auto& setting : {std::pair{"1", "0"}, std::pair{"0", "0"}, std::pair{"0", "1"}}) {
            const char* shaped = setting.first;  // (not structured bindings: clang's CAPTURE cannot take them)
            const char* shared = setting.second;
            CAPTURE(C);
            CAPTURE(shaped);
            CAPTURE(shared);
            BlendOptions cpu_c = on("cpu", false), gpu_c = on("gpu", false);
            cpu_c.C = gpu_c.C = C;
            agrees(on_build(shaped, shared, gpu_c, q), TorusField(f, cpu_c).evaluate(q, true));
            agrees(on_build(shaped, shared, gpu_c, spread), TorusField(f, cpu_c).evaluate(spread, true));
        }
    }
    // A fallback of fewer than K_MAX points: the software kernel's list then holds its k in the
    // last slots of its registers (blend_field.glsl, knn_listed).
    for (const int k : {1, 7}) {
        CAPTURE(k);
        BlendOptions cpu_k = on("cpu", false), gpu_k = on("gpu", false);
        cpu_k.fallback_k = gpu_k.fallback_k = k;
        agrees(on_build("1", nullptr, gpu_k, spread), TorusField(f, cpu_k).evaluate(spread, true));
    }
    CHECK(gpu::validation_error_count() == test::expected_validation_errors());
}

TEST_CASE("SSPD and signed Hopf-Cole on the device match the CPU reference") {
    REQUIRE(device());
    auto s = shapes::by_name("torus");
    const PointCloud c = s->sample(2048, 3);
    const Points q = mixed_queries(c, 4);
    for (Baseline kind : {Baseline::Sspd, Baseline::Shc})
        for (bool exact : {false, true}) {
            CAPTURE(int(kind));
            CAPTURE(exact);
            const FieldValues cpu = BaselineField(kind, c, on("cpu", exact)).evaluate(q);
            const FieldValues gpu = BaselineField(kind, c, on("gpu", exact)).evaluate(q);
            const Diff d = compare(gpu.phi, cpu.phi, 1e-4);
            MESSAGE(std::string(kind == Baseline::Sspd ? "SSPD" : "SHC") << std::string(exact ? " exact" : " accelerated")
                                                             << " max |Δφ| = " << d.max_abs << ", over 1e-4: " << d.over);
            // SHC's sign flips where the dipole sum crosses zero, a discontinuity of φ far from
            // the cloud; float32 may put a node on the other side. Allow 1 in 2000 such nodes.
            if (kind == Baseline::Shc) CHECK(d.over * 2000 <= q.rows());
            else CHECK(d.max_abs < 1e-4);
        }
    // SSPD's sums, accelerated and exact, are taken from the nearest summed point on the device:
    // the largest C is within float32 too (blend_field.glsl, weight_ref).
    for (bool exact : {false, true}) {
        CAPTURE(exact);
        BlendOptions cpu_c = on("cpu", exact), gpu_c = on("gpu", exact);
        cpu_c.C = gpu_c.C = 87;
        const FieldValues cpu = BaselineField(Baseline::Sspd, c, cpu_c).evaluate(q);
        const FieldValues gpu = BaselineField(Baseline::Sspd, c, gpu_c).evaluate(q);
        CHECK(compare(gpu.phi, cpu.phi, 1e-4).max_abs < 1e-4);
    }
    CHECK(gpu::validation_error_count() == test::expected_validation_errors());
}

TEST_CASE("results do not depend on the chunk size (one chunk vs many)") {
    REQUIRE(device());
    auto s = shapes::by_name("capsule");
    const PointCloud c = s->sample(3000, 5);
    const FittedTori f = JetFitter().fit(c);
    const Points q = mixed_queries(c, 6);
    BlendOptions one = on("gpu"), many = on("gpu");
    one.chunk_size = std::size_t(q.rows());
    many.chunk_size = 64;
    const FieldValues a = TorusField(f, one).evaluate(q, true);
    const FieldValues b = TorusField(f, many).evaluate(q, true);
    CHECK(a.phi == b.phi);
    CHECK(a.gradient == b.gradient);
    const GridSpec g = GridSpec::cube(20, Box{{-1, -1, -1}, {1, 1, 1}});
    many.chunk_size = 333;  // not a multiple of the workgroup
    CHECK(TorusField(f, one).evaluate(g).phi == TorusField(f, many).evaluate(g).phi);
    // A grid goes to the device in bricks (odd sides: copies of edge nodes, dropped): each
    // node's φ as when the nodes come as a list, and as the CPU's.
    const GridSpec odd{13, 6, 9, Box{{-1, -0.9, -1.1}, {1, 0.8, 1}}};
    const FieldValues by_grid = TorusField(f, many).evaluate(odd, true);
    const FieldValues by_list = TorusField(f, one).evaluate(odd.nodes(), true);
    const FieldValues on_cpu = TorusField(f, on("cpu")).evaluate(odd, true);
    const Diff dl = compare(by_grid.phi, by_list.phi, 1e-6), dc = compare(by_grid.phi, on_cpu.phi, 2e-4);
    MESSAGE("odd grid on the device: max |Δφ| to the listed nodes " << dl.max_abs << ", to the CPU " << dc.max_abs);
    CHECK(dl.max_abs < 1e-6);
    CHECK(dc.max_abs < 2e-4);
    CHECK(compare(by_grid.gradient, by_list.gradient, 1e-5).max_abs < 1e-5);
    CHECK(gpu::validation_error_count() == test::expected_validation_errors());
}

#if GSD_HAVE_SHARED_DATA
TEST_CASE("real, sparse and corrupted clouds: device agrees with the CPU to 2e-4" * doctest::test_suite("slow")) {
    REQUIRE(device());
    for (const char* name : {"pointclouds/holey-bunny.ply", "pointclouds/tooth.ply", "pointclouds/chair.pc",
                             "pointclouds/snail.ply"}) {
        CAPTURE(name);
        const PointCloud c = normalized(io::read_point_cloud(test::shared_data(name)));
        const FittedTori f = JetFitter().fit(c);
        const GridSpec g = GridSpec::cube(32, Box{{-1, -1, -1}, {1, 1, 1}});
        const FieldValues cpu = TorusField(f, on("cpu")).evaluate(g);
        const FieldValues gpu = TorusField(f, on("gpu")).evaluate(g);
        const Diff d = compare(gpu.phi, cpu.phi, 2e-4);
        MESSAGE(std::string(name) << ": max |Δφ| = " << d.max_abs);
        CHECK(d.max_abs < 2e-4);
    }
    // A sparse, corrupted sampling: 512 points, noise, 10% flipped normals, holes.
    shapes::Corruption bad;
    bad.position_noise = 0.005;
    bad.normal_noise = 0.1;
    bad.flip_fraction = 0.1;
    bad.holes = 2;
    bad.hole_radius = 0.08;
    const PointCloud c = shapes::corrupt(shapes::by_name("rounded-box")->sample(512, 7), bad, 8);
    const FittedTori f = JetFitter().fit(c);
    const Points q = mixed_queries(c, 9);
    const Diff d = compare(TorusField(f, on("gpu")).evaluate(q).phi, TorusField(f, on("cpu")).evaluate(q).phi, 2e-4);
    MESSAGE("corrupted 512-point box: max |Δφ| = " << d.max_abs);
    CHECK(d.max_abs < 2e-4);
    // Outliers (5 % uniform in the box): both paths blend the same trusted points.
    shapes::Corruption strays;
    strays.outlier_fraction = 0.05;
    const PointCloud o = shapes::corrupt(shapes::by_name("torus")->sample(2048, 3), strays, 4);
    const FittedTori fo = JetFitter().fit(o);
    const TorusField on_gpu(fo, on("gpu")), on_cpu(fo, on("cpu"));
    REQUIRE(on_cpu.blended_count() < fo.size());
    CHECK(on_gpu.blended_count() == on_cpu.blended_count());
    const Points qo = mixed_queries(o, 10);
    const Diff dout = compare(on_gpu.evaluate(qo).phi, on_cpu.evaluate(qo).phi, 2e-4);
    MESSAGE("torus with 5 % outliers (" << fo.size() - on_cpu.blended_count() << " left out): max |Δφ| = " << dout.max_abs);
    CHECK(dout.max_abs < 2e-4);
    CHECK(gpu::validation_error_count() == test::expected_validation_errors());
}
#endif

TEST_CASE("results do not depend on how many threads a dispatch's workgroups are shared between") {
    // On llvmpipe each thread takes one block of a dispatch's workgroups, and the kernels that
    // walk trees take their work in the order of workgroup_order.glsl, which depends on the
    // thread count (gpu::dispatch_threads; GSD_DISPATCH_THREADS sets it): a permutation of the
    // workgroups, whatever the count — more threads than workgroups too —, so the same results
    // to the bit. (Elsewhere the variable changes nothing, and the check holds trivially.)
    REQUIRE(device());
    shapes::MeshCorruption d;
    d.holes = 2;
    d.flip_fraction = 0.1;
    const OrientedElements mesh = OrientedElements::from_mesh(shapes::corrupt(shapes::mesh(*shapes::by_name("torus"), 24), d, 3));
    const PointCloud c = shapes::by_name("capsule")->sample(1500, 5);
    const FittedTori f = JetFitter().fit(c);
    const Points q = mixed_queries(c, 11);
    WindingOptions w;
    w.device = "gpu";
    w.chunk_size = 1000;  // chunks of many workgroups, and a last one of few
    auto run = [&](const char* threads) {
        if (threads) ::setenv("GSD_DISPATCH_THREADS", threads, 1);
        auto r = std::make_pair(fast_winding_numbers(mesh, q, w).w, TorusField(f, on("gpu")).evaluate(q).phi);
        ::unsetenv("GSD_DISPATCH_THREADS");
        return r;
    };
    const auto base = run(nullptr);
    for (const char* threads : {"1", "3", "7", "1000"}) {
        CAPTURE(std::string(threads));
        const auto other = run(threads);
        CHECK(other.first == base.first);
        CHECK(other.second == base.second);
    }
    CHECK(gpu::validation_error_count() == test::expected_validation_errors());
}

TEST_CASE("fast winding numbers on the device match the CPU (broken mesh, cloud), whatever the chunk size") {
    REQUIRE(device());
    // Both kernels, the GPUs' and the one shaped for software devices (gpu::software_shaped),
    // and on a software device the loop guard's cut at every round (cap 1) and within the walk.
    // The software-shaped kernel sums groups of 16 queries on these trees; 12 and 8 are what it
    // takes on larger ones (GSD_WINDING_GROUP asks for them here).
    const char* setting = nullptr;
    const char* cap = nullptr;
    const char* group = nullptr;
    SUBCASE("the device's own kernel") {}
    SUBCASE("the GPUs' kernel") { setting = "0"; }
    SUBCASE("the software-shaped kernel") { setting = "1"; }
    SUBCASE("the software-shaped kernel, groups of 12") { setting = "1", group = "12"; }
    SUBCASE("the software-shaped kernel, groups of 8") { setting = "1", group = "8"; }
    SUBCASE("the software-shaped kernel, cut at once") { setting = "1", cap = "1"; }
    SUBCASE("the software-shaped kernel, cut on the way") { setting = "1", cap = "2400"; }
    SUBCASE("the software-shaped kernel, groups of 8, cut on the way") { setting = "1", cap = "2400", group = "8"; }
    if (setting) ::setenv("GSD_SOFTWARE_SHAPED", setting, 1);
    if (cap) ::setenv("GSD_LOOP_CAP", cap, 1);
    if (group) ::setenv("GSD_WINDING_GROUP", group, 1);
    struct Unset {
        ~Unset() {
            ::unsetenv("GSD_SOFTWARE_SHAPED");
            ::unsetenv("GSD_LOOP_CAP");
            ::unsetenv("GSD_WINDING_GROUP");
        }
    } unset;
    shapes::MeshCorruption d;
    d.holes = 3;
    d.hole_area = 0.2;
    d.flip_fraction = 0.1;
    const PolygonMesh m = shapes::corrupt(shapes::mesh(*shapes::by_name("torus"), 40), d, 4);
    const PointCloud c = shapes::by_name("capsule")->sample(3000, 5);
    // A tree too shallow for the software kernel's start over its top four levels (it starts
    // from the root there).
    PolygonMesh octahedron;  // 8 faces, one flipped
    octahedron.vertices.resize(6, 3);
    octahedron.vertices << 0.5, 0, 0, -0.5, 0, 0, 0, 0.5, 0, 0, -0.5, 0, 0, 0, 0.5, 0, 0, -0.5;
    for (const auto& f : {std::array{0u, 2u, 4u}, {2u, 1u, 4u}, {1u, 3u, 4u}, {3u, 0u, 4u}, {2u, 0u, 5u}, {1u, 2u, 5u}, {3u, 1u, 5u}, {5u, 3u, 0u}})
        octahedron.add_face({f[0], f[1], f[2]});
    const OrientedElements tiny = OrientedElements::from_mesh(octahedron);
    REQUIRE(sums::SumTree(tiny).first_leaf() <= 14);
    // And the shallowest tree that takes the start over the top four levels: every child of
    // the depth-3 nodes is a leaf.
    OrientedElements shallow;
    for (int n = 16; n <= 64 && shallow.size() == 0; ++n) {
        PointCloud part;
        part.points = c.points.topRows(n);
        part.normals = c.normals.topRows(n);
        const OrientedElements e = OrientedElements::from_cloud(part);
        if (sums::SumTree(e).first_leaf() == 15) shallow = e;
    }
    REQUIRE(shallow.size() > 0);
    // Point dipoles grow as 1/r² next to a point, and some queries are within 0.02 of one, where
    // |w| reaches tens: errors are relative to max(1, |w|), and the cloud gets a looser float32
    // tolerance than the mesh's solid angles.
    for (const auto& [e, tol] : {std::pair{OrientedElements::from_mesh(m), 1e-4}, std::pair{OrientedElements::from_cloud(c), 5e-4},
                                 std::pair{tiny, 1e-4}, std::pair{shallow, 5e-4}}) {
        const Points q = mixed_queries(c, 7);
        WindingOptions cpu, one, many;
        cpu.device = "cpu";
        one.device = many.device = "gpu";
        one.chunk_size = std::size_t(q.rows());
        many.chunk_size = 333;
        const WindingResult a = fast_winding_numbers(e, q, cpu);
        const WindingResult b = fast_winding_numbers(e, q, one);
        const WindingResult bb = fast_winding_numbers(e, q, many);
        CHECK(b.device != "cpu");
        // Which queries a cut hands to the CPU depends on their subgroup's other lanes.
        if (!cap) CHECK(b.w == bb.w);
        CHECK(b.terms == a.terms);  // the same walk: every lane sums the CPU's float walk's terms
        double worst = 0;
        for (std::size_t i = 0; i < a.w.size(); ++i)
            worst = std::max(worst, std::abs(a.w[i] - b.w[i]) / std::max(1.0, std::abs(a.w[i])));
        MESSAGE("winding: max |w_gpu − w_cpu| / max(1, |w_cpu|) = " << worst);
        CHECK(worst < tol);
    }
    CHECK(gpu::validation_error_count() == test::expected_validation_errors());
}

TEST_CASE("WindingField::prepare on another thread, beside evaluations: the same winding numbers") {
    REQUIRE(device());
    shapes::MeshCorruption d;
    d.holes = 2;
    d.flip_fraction = 0.1;
    const PolygonMesh m = shapes::corrupt(shapes::mesh(*shapes::by_name("torus"), 30), d, 6);
    const Points q = mixed_queries(shapes::by_name("torus")->sample(1000, 2), 3);
    WindingOptions gpu_opt;
    gpu_opt.device = "gpu";
    const WindingResult want = fast_winding_numbers(OrientedElements::from_mesh(m), q, gpu_opt);
    CHECK(want.device != "cpu");
    // prepare() first, then an evaluation; and one racing a prepare() and another evaluation.
    const WindingField first(OrientedElements::from_mesh(m), gpu_opt);
    first.prepare();
    CHECK(first.winding_numbers(q).w == want.w);
    const WindingField raced(OrientedElements::from_mesh(m), gpu_opt);
    auto first_call = std::async(std::launch::async, [&] {
        raced.prepare();
        return raced.winding_numbers(q);
    });
    auto second_call = std::async(std::launch::async, [&] { return raced.winding_numbers(q); });
    const WindingResult a = first_call.get(), b = second_call.get();
    CHECK(a.w == want.w);
    CHECK(b.w == want.w);
    // On the CPU path it does nothing, and the field is the same.
    WindingOptions cpu_opt;
    cpu_opt.device = "cpu";
    const WindingField on_cpu(OrientedElements::from_mesh(m), cpu_opt);
    on_cpu.prepare();
    CHECK(on_cpu.winding_numbers(q).w == fast_winding_numbers(OrientedElements::from_mesh(m), q, cpu_opt).w);
    CHECK(gpu::validation_error_count() == test::expected_validation_errors());
}

TEST_CASE("auto looks for Vulkan devices only where a GPU device node exists") {
    test::ScratchDir dev("dev");
    auto touch = [&](const std::string& name) { test::write_bytes(dev.file(name), ""); };
    CHECK_FALSE(gpu::has_gpu_device_node(dev.path().string()));
    std::filesystem::create_directories(dev.file("dri"));
    touch("null");
    touch("dri/by-path");
    CHECK_FALSE(gpu::has_gpu_device_node(dev.path().string()));
    touch("dri/renderD128");
    CHECK(gpu::has_gpu_device_node(dev.path().string()));
    for (const char* node : {"dri/card0", "nvidiactl", "dxg", "mali0"}) {
        test::ScratchDir other("dev");
        std::filesystem::create_directories(other.file("dri"));
        test::write_bytes(other.file(node), "");
        CHECK_MESSAGE(gpu::has_gpu_device_node(other.path().string()), node);
    }
    // A folder that cannot be read says nothing: the devices are looked for.
    CHECK(gpu::has_gpu_device_node(dev.file("missing")));
    // Here: with no node, auto runs on the CPU and says why; with one, the choice is the
    // inventory's (a real GPU, or the CPU with the device list in the note).
    const gpu::Selection sel = gpu::select("auto");
    if (!gpu::has_gpu_device_node()) {
        CHECK(sel.context == nullptr);
        CHECK(sel.note.find("no GPU device node") != std::string::npos);
    } else if (!sel.context) {
        CHECK(sel.note.find("no GPU device node") == std::string::npos);
    }
}

TEST_CASE("device choice: cpu, names, and fallback without a device") {
    CHECK(gpu::select("cpu").context == nullptr);
    CHECK_THROWS_AS(gpu::select("no-such-device-xyz"), Error);
    CHECK_THROWS_AS(gpu::select("99"), Error);
    const gpu::Selection by_index = gpu::select("0");
    CHECK(by_index.context != nullptr);
    try {
        (void)gpu::select("no-such-device-xyz");
    } catch (const Error& e) {
        CHECK(e.where() == "device");
    }
    // One value for every options struct: a context in hand runs there, choice strings resolve
    // to the same shared context.
    const Device held = by_index.context;
    CHECK(held.choice().empty());
    CHECK(held.describe() == gpu::device_name(*by_index.context));
    CHECK(gpu::select(held).context == by_index.context);
    CHECK(gpu::select(held).note.empty());
    CHECK(gpu::select(Device("gpu")).context == gpu::select("0").context);
    BlendOptions o;
    o.device = by_index.context;
    const PointCloud cloud = shapes::sphere({0, 0, 0}, 0.5)->sample(600, 2);
    const TorusField field(JetFitter().fit(cloud), o);
    Points q(3, 3);
    q << 0, 0, 0, 0.9, 0, 0, 0.5, 0, 0;
    const FieldValues v = field.evaluate(q);
    CHECK(v.device == gpu::device_name(*by_index.context));
    CHECK(v.phi[0] < 0);
    CHECK(v.phi[1] > 0);
    // Without a loader or a driver the CLI falls back to the CPU path with one line (see
    // test_cli for the process-level check with GSD_VULKAN_LOADER / VK_ICD_FILENAMES).
}
