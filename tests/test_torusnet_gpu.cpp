// TorusNet on the device (shaders/torus_net*.comp) against PyTorch's golden file and the
// double-precision CPU reference (docs/torusnet.md, "GPU kernels"). Runs on lavapipe in CI,
// with the validation layer on: any validation error fails the test.
#include <doctest/doctest.h>

#include <gsd/gpu.hpp>
#include <gsd/pat.hpp>
#include <gsd/shapes.hpp>
#include <gsd/spatial.hpp>

#include "gpu/runtime.hpp"
#include "pat/safetensors.hpp"
#include "pat/torus_net.hpp"
#include "pat/torus_net_gpu.hpp"
#include "pat/torus_net_gpu_check.hpp"
#include "pat/torus_net_model.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <random>

using namespace gsd;
using pat::TorusNetModel;

namespace {

const std::string kModelPath = std::string(GSD_SOURCE_DIR) + "/models/torusnet.safetensors";
const std::string kGoldenPath = std::string(GSD_SOURCE_DIR) + "/tests/data/torusnet_golden.safetensors";

std::shared_ptr<gpu::Context> device() {
    static const gpu::Selection sel = gpu::select("gpu");
    return sel.context;
}

// The dimensionless outputs of the network, r = (a00/m, a10, a01, a11·m, a20·m, a02·m): every
// coefficient in the unit the network works in (the neighborhood's median distance m).
std::array<double, 6> raw(const Jet& j, double m) {
    return {j.a00 / m, j.a10, j.a01, j.a11 * m, j.a20 * m, j.a02 * m};
}

// The tolerance measure of the GPU kernels (docs/torusnet.md, "GPU kernels"): per point, the
// largest error of the six dimensionless outputs relative to the largest of them,
//   max_c |r_gpu,c − r_ref,c| / max(max_c |r_ref,c|, 1e-3).
double point_error(const Jet& ours, const Jet& ref, double m) {
    const auto a = raw(ours, m), b = raw(ref, m);
    double err = 0, size = 1e-3;
    for (int c = 0; c < 6; ++c) {
        err = std::max(err, std::abs(a[std::size_t(c)] - b[std::size_t(c)]));
        size = std::max(size, std::abs(b[std::size_t(c)]));
    }
    return err / size;
}

// ---- models built in memory ---------------------------------------------------------------

struct Dims {
    int k, width, blocks, heads, mlp;
};

// A random model of the documented layout, built directly (weights ~ N(0, 1/in), LayerNorm γ
// around 1), so the kernels can be run on shapes the shipped model does not have.
TorusNetModel random_model(const Dims& d, unsigned seed) {
    std::mt19937 rng(seed);
    TorusNetModel m;
    m.k = d.k;
    m.width = d.width;
    m.blocks = d.blocks;
    m.heads = d.heads;
    m.mlp = d.mlp;
    auto take = [&](std::size_t n, double mean, double sd) {
        const std::size_t at = m.params.size();
        std::normal_distribution<float> g{float(mean), float(sd)};
        for (std::size_t i = 0; i < n; ++i) m.params.push_back(g(rng));
        m.params.resize((m.params.size() + 3) / 4 * 4, 0.0f);
        return at;
    };
    auto linear = [&](int in, int out) {
        pat::NetLinear l;
        l.in = in;
        l.out = out;
        l.weight = take(std::size_t(in) * std::size_t(out), 0, 1 / std::sqrt(double(in)));
        l.bias = take(std::size_t(out), 0, 0.1);
        return l;
    };
    auto norm = [&](int w) {
        pat::NetNorm n;
        n.width = w;
        n.weight = take(std::size_t(w), 1, 0.2);
        n.bias = take(std::size_t(w), 0, 0.1);
        return n;
    };
    m.embed = linear(7, d.width);
    m.embed_norm = norm(d.width);
    for (int b = 0; b < d.blocks; ++b) {
        pat::NetBlock blk;
        blk.norm1 = norm(d.width);
        blk.qkv = linear(d.width, 3 * d.width);
        blk.proj = linear(d.width, d.width);
        blk.norm2 = norm(d.width);
        blk.fc1 = linear(d.width, d.mlp);
        blk.fc2 = linear(d.mlp, d.width);
        m.block.push_back(blk);
    }
    m.final_norm = norm(d.width);
    m.head = linear(d.width, 6);
    return m;
}

// ---- neighborhoods ------------------------------------------------------------------------

struct Neighborhoods {
    Points positions, normals;  // k rows per neighborhood
    int count = 0;
};

// The CPU's neighborhoods (torusnet_neighbors) of every `stride`-th point of a cloud.
Neighborhoods neighborhoods_of(const PointCloud& c, int k, int stride) {
    const KdTree tree(c.points);
    std::vector<Neighbor> scratch;
    std::vector<std::uint32_t> tokens;
    Neighborhoods nb;
    nb.count = int((c.size() + stride - 1) / stride);
    nb.positions.resize(Eigen::Index(nb.count) * k, 3);
    nb.normals.resize(Eigen::Index(nb.count) * k, 3);
    for (int p = 0; p < nb.count; ++p) {
        pat::torusnet_neighbors(tree, std::uint32_t(p * stride), k, scratch, tokens);
        for (int j = 0; j < k; ++j) {
            nb.positions.row(Eigen::Index(p) * k + j) = c.points.row(tokens[std::size_t(j)]);
            nb.normals.row(Eigen::Index(p) * k + j) = c.normals.row(tokens[std::size_t(j)]);
        }
    }
    return nb;
}

// The CPU reference on neighborhood p: features [k][7], m, jet.
struct Reference {
    std::vector<double> features;
    double m = 0;
    Jet jet;
};

// The CPU features and m of neighborhood p.
Reference features_of(const TorusNetModel& model, const Neighborhoods& nb, int p) {
    const int k = model.k;
    const auto kk = std::size_t(k);
    std::vector<Eigen::Vector3d> P(kk), N(kk);
    for (int j = 0; j < k; ++j) {
        P[std::size_t(j)] = nb.positions.row(Eigen::Index(p) * k + j).transpose();
        N[std::size_t(j)] = nb.normals.row(Eigen::Index(p) * k + j).transpose();
    }
    Reference r;
    r.features.resize(kk * 7);
    pat::torusnet_features(model, P.data(), N.data(), tangent_of(N[0].normalized()), r.features.data(), r.m);
    return r;
}

Reference reference(const TorusNetModel& model, const pat::TorusNetCpu& net, const Neighborhoods& nb, int p) {
    Reference r = features_of(model, nb, p);
    r.jet = net.predict(r.features.data(), r.m);
    return r;
}

// The CPU's m of neighborhood p.
double scale_of(const TorusNetModel& model, const Neighborhoods& nb, int p) {
    return features_of(model, nb, p).m;
}

struct Errors {
    double features = 0, scale = 0, coeffs = 0;
};

// The kernel on given neighborhoods vs the CPU reference on the same ones; `global` forces the
// device-memory workspace (else the kernel's own choice, reported in `used_global`).
Errors kernel_vs_reference(const TorusNetModel& model, const Neighborhoods& nb, bool global, bool& used_global) {
    const pat::TorusNetGpuTrace t = pat::torusnet_gpu_neighborhoods(model, *device(), nb.positions, nb.normals, global);
    used_global = t.global_workspace;
    const pat::TorusNetCpu net(model);
    Errors e;
    const std::size_t k = std::size_t(model.k);
    for (int p = 0; p < nb.count; ++p) {
        const Reference r = reference(model, net, nb, p);
        for (std::size_t f = 0; f < 7 * k; ++f)
            e.features = std::max(e.features, std::abs(t.features[std::size_t(p) * 7 * k + f] - r.features[f]) /
                                                  std::max(std::abs(r.features[f]), 1.0));
        e.scale = std::max(e.scale, std::abs(t.scale[std::size_t(p)] - r.m) / r.m);
        e.coeffs = std::max(e.coeffs, point_error(t.jets[std::size_t(p)], r.jet, r.m));
    }
    return e;
}

// Points whose k-neighborhood is ambiguous at float32 precision: the (k−1)-th and k-th nearest
// other points (in double) are within a relative 1e-5, so a float32 search may take either,
// unless every point in that band is the same point (position and normal): exact copies
// make the same tokens whichever is taken.
std::vector<bool> knn_ties(const PointCloud& c, int k) {
    const KdTree tree(c.points);
    std::vector<Neighbor> nb;
    std::vector<bool> tie(std::size_t(c.size()), false);
    const std::size_t extra = 48;
    for (Eigen::Index i = 0; i < c.size(); ++i) {
        tree.knn(c.points.row(i).transpose(), std::size_t(k) + extra, nb);
        std::vector<Neighbor> others;
        for (const Neighbor& n : nb)
            if (n.index != std::uint32_t(i)) others.push_back(n);
        std::sort(others.begin(), others.end(), [](const Neighbor& a, const Neighbor& b) { return a.distance < b.distance; });
        const double last_in = others[std::size_t(k - 2)].distance, first_out = others[std::size_t(k - 1)].distance;
        if (first_out - last_in > 1e-5 * first_out) continue;
        // The band of distances a float32 search cannot order: all copies of one point?
        const double lo = last_in - 1e-5 * first_out, hi = first_out + 1e-5 * first_out;
        std::int64_t first = -1;
        bool same = others.back().distance > hi;  // else the band may go on past the query
        for (const Neighbor& n : others)
            if (n.distance >= lo && n.distance <= hi) {
                if (first < 0) first = n.index;
                same = same && c.points.row(n.index) == c.points.row(first) && c.normals.row(n.index) == c.normals.row(first);
            }
        tie[std::size_t(i)] = !same;
    }
    return tie;
}

// predict_jets_gpu vs predict_jets_cpu on a cloud: the worst point error (points with a kNN tie
// excluded, and counted).
double cloud_error(const TorusNetModel& model, const PointCloud& c, std::size_t& ties, std::size_t chunk = 0) {
    std::vector<Jet> gj, cj;
    Points gt, ct;
    pat::predict_jets_gpu(model, c, *device(), gj, gt, chunk, {});
    const KdTree tree(c.points);
    pat::predict_jets_cpu(model, c, tree, cj, ct, {});
    REQUIRE(gj.size() == cj.size());
    CHECK((gt - ct).cwiseAbs().maxCoeff() == 0.0);  // both tangent_of in double
    const std::vector<bool> tie = knn_ties(c, model.k);
    const Neighborhoods nb = neighborhoods_of(c, model.k, 1);
    double worst = 0;
    ties = 0;
    for (Eigen::Index i = 0; i < c.size(); ++i) {
        if (tie[std::size_t(i)]) {
            ++ties;
            continue;
        }
        const double m = scale_of(model, nb, int(i));
        worst = std::max(worst, point_error(gj[std::size_t(i)], cj[std::size_t(i)], m));
    }
    return worst;
}

PointCloud noisy_box(std::size_t n, std::uint64_t seed) {
    shapes::Corruption c;
    c.position_noise = 0.003;
    c.normal_noise = 0.1;
    return shapes::corrupt(shapes::by_name("rounded-box")->sample(n, seed), c, seed + 1);
}

}  // namespace

TEST_CASE("TorusNet GPU: a Vulkan device is available (lavapipe in CI) and validation is on") {
    const gpu::Inventory inv = gpu::list_devices();
    INFO("problem: " << inv.problem);
    REQUIRE(inv.loader_found);
    REQUIRE(device() != nullptr);
    MESSAGE("device: " << gpu::device_name(*device()));
    CHECK(gpu::validation_active());
}

TEST_CASE("on a software device with 8-lane subgroups and shuffles, the shipped model runs the software build") {
    REQUIRE(device());
    const gpu::DeviceInfo& info = device()->info();
    const TorusNetModel model = TorusNetModel::load(kModelPath);
    const bool lanes = pat::runs_lanes_kernel(model, *device());
    MESSAGE(info.name << ": subgroup " << info.subgroup_size << std::string(info.subgroup_shuffle ? ", shuffle" : "")
                      << "; the shipped model on the " << std::string(lanes ? "software" : "GPU") << " build");
    if (info.is_software() && info.subgroup_shuffle && info.subgroup_size == 8 && gpu::software_shaped(*device())) {
        CHECK(lanes);  // lavapipe with AVX2: what CI measures and the cloud tests below compare
        CHECK_FALSE(pat::runs_lanes_kernel(random_model({20, 32, 1, 2, 64}, 1), *device()));  // k % 8 != 0
    }
    if (!info.is_software()) CHECK_FALSE(lanes);  // a GPU may run a workgroup as several subgroups
}

TEST_CASE("tangent_axis is the branch tangent_of takes") {
    std::mt19937_64 rng(3);
    std::normal_distribution<double> g;
    for (int i = 0; i < 20000; ++i) {
        Eigen::Vector3d n(g(rng), g(rng), g(rng));
        // Every third normal sits on a branch threshold (|n_x| or |n_y| ≈ 0.57735).
        if (i % 3 == 1) n = Eigen::Vector3d(0.57735 * (i % 2 ? 1 : -1), g(rng), g(rng));
        n.normalize();
        Eigen::Vector3d axis = Eigen::Vector3d::Zero();
        axis[pat::tangent_axis(n)] = 1;
        CHECK((n.cross(axis).normalized() - tangent_of(n)).norm() == 0.0);
    }
}

TEST_CASE("golden: GPU features, scale and coefficients match PyTorch (float64)") {
    REQUIRE(device());
    const TorusNetModel model = TorusNetModel::load(kModelPath);
    const std::vector<std::uint8_t> bytes = pat::read_binary_file(kGoldenPath);
    const pat::SafeTensors st = pat::parse_safetensors(bytes, kGoldenPath);
    auto get = [&](const char* name) {
        REQUIRE_MESSAGE(st.tensors.count(name), "golden file lacks " << name);
        return pat::tensor_as_double(st.tensors.at(name), kGoldenPath, name);
    };
    const auto& shape = st.tensors.at("neighbors").shape;
    REQUIRE(shape.size() == 3);
    const int count = int(shape[0]), k = int(shape[1]);
    REQUIRE_MESSAGE(k == model.k, "the golden file was made for another model (tools/train/golden.py)");
    const std::vector<double> pos = get("neighbors"), nrm = get("neighbor_normals"), features = get("features"),
                              scale = get("scale"), coeffs = get("coeffs");
    Points P(Eigen::Index(count) * k, 3), N(Eigen::Index(count) * k, 3);
    for (Eigen::Index r = 0; r < P.rows(); ++r)
        for (int a = 0; a < 3; ++a) {
            P(r, a) = pos[std::size_t(3 * r + a)];
            N(r, a) = nrm[std::size_t(3 * r + a)];
        }
    for (const bool global : {false, true}) {
        CAPTURE(global);
        const pat::TorusNetGpuTrace t = pat::torusnet_gpu_neighborhoods(model, *device(), P, N, global);
        double ef = 0, es = 0, ec = 0;
        for (std::size_t f = 0; f < features.size(); ++f)
            ef = std::max(ef, std::abs(t.features[f] - features[f]) / std::max(std::abs(features[f]), 1.0));
        for (int p = 0; p < count; ++p) {
            const double m = scale[std::size_t(p)];
            es = std::max(es, std::abs(t.scale[std::size_t(p)] - m) / m);
            const double* c = &coeffs[6 * std::size_t(p)];
            ec = std::max(ec, point_error(t.jets[std::size_t(p)], Jet{c[0], c[1], c[2], c[3], c[4], c[5]}, m));
        }
        MESSAGE("golden on the device (" << count << " neighborhoods, k=" << k << std::string(global ? ", device-memory" : ", shared")
                                         << " workspace): features " << ef << ", scale " << es << ", coefficients " << ec);
        CHECK(ef <= 1e-5);
        CHECK(es <= 1e-6);
        CHECK(ec <= 1e-4);
    }
    CHECK(gpu::validation_error_count() == 0);
}

TEST_CASE("predict_jets_gpu matches the CPU reference on clouds") {
    REQUIRE(device());
    const TorusNetModel model = TorusNetModel::load(kModelPath);
    struct Case {
        std::string name;
        PointCloud cloud;
    };
    PointCloud dup = shapes::by_name("torus")->sample(2500, 9);
    // Duplicates: point 7 four times more (token 0 must still be the point itself), and more
    // copies of point 11 than k, so its neighborhood is nothing but copies.
    for (const auto& [src, copies] : {std::pair{7, 4}, std::pair{11, model.k + 3}})
        for (int c = 0; c < copies; ++c) {
            dup.points.conservativeResize(dup.points.rows() + 1, 3);
            dup.normals.conservativeResize(dup.normals.rows() + 1, 3);
            dup.points.row(dup.points.rows() - 1) = dup.points.row(src);
            dup.normals.row(dup.normals.rows() - 1) = dup.normals.row(src);
        }
    const Case cases[] = {{"sphere", shapes::by_name("sphere")->sample(3000, 2)},
                          {"noisy rounded box", noisy_box(4000, 5)},
                          {"torus with duplicates", dup}};
    for (const Case& c : cases) {
        CAPTURE(c.name);
        std::size_t ties = 0;
        const double err = cloud_error(model, c.cloud, ties);
        MESSAGE(c.name << " (" << c.cloud.size() << " points): max relative error " << err << ", " << ties
                       << " points with a kNN tie excluded");
        CHECK(err <= 1e-3);
        CHECK(ties * 100 <= std::size_t(c.cloud.size()));
    }
    CHECK(gpu::validation_error_count() == 0);
}

TEST_CASE("far from the origin: fixed-point positions keep float32 features accurate") {
    REQUIRE(device());
    const TorusNetModel model = TorusNetModel::load(kModelPath);
    PointCloud c = shapes::by_name("sphere")->sample(1500, 4);
    c.points.rowwise() += Eigen::RowVector3d(1000, -2000, 500);
    std::size_t ties = 0;
    const double err = cloud_error(model, c, ties);
    MESSAGE("sphere at (1000, -2000, 500): max relative error " << err << ", " << ties << " ties excluded");
    CHECK(err <= 1e-3);
    CHECK(gpu::validation_error_count() == 0);
}

TEST_CASE("results do not depend on the chunk size" * doctest::test_suite("slow")) {
    REQUIRE(device());
    const TorusNetModel model = TorusNetModel::load(kModelPath);
    const PointCloud c = noisy_box(2000, 8);
    std::vector<Jet> a, b, d;
    Points ta, tb, td;
    pat::predict_jets_gpu(model, c, *device(), a, ta, 0, {});
    pat::predict_jets_gpu(model, c, *device(), b, tb, 77, {});  // 26 chunks, not a workgroup multiple
    pat::predict_jets_gpu(model, c, *device(), d, td, 1, {});
    auto same = [](const std::vector<Jet>& x, const std::vector<Jet>& y) {
        for (std::size_t i = 0; i < x.size(); ++i)
            if (x[i].a00 != y[i].a00 || x[i].a10 != y[i].a10 || x[i].a01 != y[i].a01 || x[i].a11 != y[i].a11 ||
                x[i].a20 != y[i].a20 || x[i].a02 != y[i].a02)
                return false;
        return x.size() == y.size();
    };
    CHECK(same(a, b));
    CHECK(same(a, d));
    // Progress: once per chunk, ending at 1.
    int reports = 0;
    double last = 0;
    pat::predict_jets_gpu(model, c, *device(), b, tb, 500, [&](std::string_view stage, double f) {
        CHECK(stage == "fit");
        CHECK(f >= last);
        last = f;
        ++reports;
    });
    CHECK(reports == 4);
    CHECK(last == 1.0);
    CHECK(gpu::validation_error_count() == 0);
}

TEST_CASE("the public API runs TorusNet on the device") {
    REQUIRE(device());
    TorusNetOptions o;
    o.device = "gpu";
    const PointCloud c = shapes::by_name("sphere")->sample(600, 3);
    const FittedTori g = TorusNet(o).fit(c);
    o.device = "cpu";
    const FittedTori r = TorusNet(o).fit(c);
    REQUIRE(g.size() == r.size());
    CHECK(g.fitter == "net");
    double worst = 0;
    for (Eigen::Index i = 0; i < g.size(); ++i)
        worst = std::max(worst, std::abs(g.jets[std::size_t(i)].a20 - r.jets[std::size_t(i)].a20) /
                                    std::max(std::abs(r.jets[std::size_t(i)].a20), 1.0));
    CHECK(worst < 1e-3);
    CHECK(gpu::validation_error_count() == 0);
}

namespace {

struct Shape {
    Dims dims;
    int stride;  // every stride-th point's neighborhood
};

/// Each shape through the kernel against the reference: in shared memory where it fits, and
/// forced into the device-memory workspace. With the kernel hardware GPUs get (the GPU build:
/// weights in a storage buffer, the matrix-product tile 4 rows × 1 vec4 column; the golden and
/// cloud cases run lavapipe's own), so that both are tested, and each pipeline compiles in half
/// the time on a machine that has not cached it.
/// With `gpus_kernel` false, the device's own kernel instead (on lavapipe the software build: a
/// subgroup a point, rows through shuffles, where the shape fits it).
void check_shapes(const PointCloud& c, std::initializer_list<Shape> shapes, bool gpus_kernel = true) {
    if (gpus_kernel) {
        ::setenv("GSD_TORUSNET_TILE", "4,1", 1);
        ::setenv("GSD_SOFTWARE_SHAPED", "0", 1);
    }
    struct Unset {
        ~Unset() {
            ::unsetenv("GSD_TORUSNET_TILE");
            ::unsetenv("GSD_SOFTWARE_SHAPED");
        }
    } unset;
    for (const Shape& s : shapes) {
        const Dims& d = s.dims;
        CAPTURE(d.k);
        CAPTURE(d.width);
        const TorusNetModel model = random_model(d, unsigned(d.k + d.width));
        const Neighborhoods nb = neighborhoods_of(c, d.k, s.stride);
        bool used_global = false;
        for (const bool force : {false, true}) {
            if (force && used_global) break;  // the model needed device memory anyway
            CAPTURE(force);
            const Errors e = kernel_vs_reference(model, nb, force, used_global);
            MESSAGE("k=" << d.k << " width " << d.width << " " << d.blocks << " blocks (" << nb.count
                         << " neighborhoods, " << std::string(used_global ? "device-memory" : "shared")
                         << " workspace): features " << e.features << ", scale " << e.scale << ", coefficients " << e.coeffs);
            CHECK(e.features <= 1e-5);
            CHECK(e.scale <= 1e-6);
            CHECK(e.coeffs <= 1e-3);
        }
    }
}

}  // namespace

TEST_CASE("models of other shapes: a small one in shared and in device memory, and clear errors") {
    REQUIRE(device());
    const PointCloud c = noisy_box(3000, 12);
    check_shapes(c, {Shape{{16, 32, 1, 2, 64}, 7}});
    // The device's own kernel (lavapipe: a subgroup a point, products through shuffles) on a
    // shape other than the shipped model's: one block, the MLP in a pass wider than the width.
    check_shapes(c, {Shape{{16, 32, 1, 2, 64}, 7}}, false);
    std::vector<Jet> jets;
    Points tangents;
    CHECK_THROWS_WITH_AS(pat::predict_jets_gpu(random_model({65, 32, 1, 2, 32}, 1), c, *device(), jets, tangents, 0, {}),
                         doctest::Contains("k ≤ 64"), Error);
    CHECK_THROWS_WITH_AS(pat::predict_jets_gpu(random_model({16, 30, 1, 2, 32}, 1), c, *device(), jets, tangents, 0, {}),
                         doctest::Contains("multiples of 4"), Error);
    CHECK(gpu::validation_error_count() == 0);
}

// Slow: each shape is a pipeline of its own, which lavapipe compiles with LLVM on a machine that
// has not seen it (about 150 s for these; docs/testing.md).
TEST_CASE("models of other shapes: the published one and odd sizes, a whole cloud in device memory" *
          doctest::test_suite("slow")) {
    REQUIRE(device());
    const PointCloud c = noisy_box(3000, 12);
    // k = 64, width 128, 4 blocks, 4 heads, MLP 256 (the published network's shape) does not
    // fit 32 KiB of shared memory: its activations go to device memory.
    check_shapes(c, {Shape{{64, 128, 4, 4, 256}, 97}, Shape{{24, 48, 3, 3, 96}, 13}});
    check_shapes(c, {Shape{{64, 128, 4, 4, 256}, 97}, Shape{{24, 48, 3, 3, 96}, 13}}, false);
    // A whole cloud through the device-memory workspace (the device's own kernel).
    const TorusNetModel big = random_model({64, 128, 2, 4, 256}, 3);
    std::size_t ties = 0;
    const PointCloud small = noisy_box(400, 3);
    CHECK(cloud_error(big, small, ties, 150) <= 1e-3);
    CHECK(gpu::validation_error_count() == 0);
}
