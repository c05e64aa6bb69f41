// TorusNet on the CPU (docs/torusnet.md): the golden file from PyTorch, the weights loader on
// good and malformed files, neighborhoods and features in degenerate cases, the fitter API and
// the CLI's --fitter net / --model.
#include <doctest/doctest.h>

#include <gsd/pat.hpp>
#include <gsd/shapes.hpp>
#include <gsd/spatial.hpp>

#include "pat/safetensors.hpp"
#include "pat/torus_net.hpp"
#include "pat/torus_net_model.hpp"
#include "support.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <random>

using namespace gsd;
using pat::TorusNetModel;

namespace {

const std::string kModelPath = std::string(GSD_SOURCE_DIR) + "/models/torusnet.safetensors";
const std::string kGoldenPath = std::string(GSD_SOURCE_DIR) + "/tests/data/torusnet_golden.safetensors";

// The comparison every TorusNet check uses: the largest error relative to the reference value,
// with references below 1e-3 in magnitude compared absolutely against 1e-3:
//   max_i |ours_i − ref_i| / max(|ref_i|, 1e-3).
double relative_error(const std::vector<double>& ours, const std::vector<double>& ref) {
    REQUIRE(ours.size() == ref.size());
    double worst = 0;
    for (std::size_t i = 0; i < ours.size(); ++i)
        worst = std::max(worst, std::abs(ours[i] - ref[i]) / std::max(std::abs(ref[i]), 1e-3));
    return worst;
}

std::vector<double> as_vector(const Jet& j) { return {j.a00, j.a10, j.a01, j.a11, j.a20, j.a02}; }

// ---- hand-made weights files ----------------------------------------------------------------

struct Tensor {
    std::string dtype = "F32";
    std::vector<std::size_t> shape;
    std::string bytes;
};
using Tensors = std::map<std::string, Tensor>;

Tensor random_tensor(std::vector<std::size_t> shape, std::mt19937& rng, double scale) {
    std::normal_distribution<float> g(0.0f, float(scale));
    std::size_t n = 1;
    for (std::size_t d : shape) n *= d;
    std::vector<float> v(n);
    for (float& x : v) x = g(rng);
    Tensor t;
    t.shape = std::move(shape);
    t.bytes.assign(reinterpret_cast<const char*>(v.data()), 4 * n);
    return t;
}

struct Config {
    int k = 8, width = 8, blocks = 2, heads = 2, mlp = 16;
};

// A random model of the documented layout (small, so the tests stay fast).
Tensors random_model(const Config& c, unsigned seed = 5) {
    std::mt19937 rng(seed);
    const auto W = std::size_t(c.width), F = std::size_t(c.mlp);
    Tensors t;
    auto linear = [&](const std::string& name, std::size_t in, std::size_t out) {
        t[name + ".weight"] = random_tensor({out, in}, rng, 1.0 / std::sqrt(double(in)));
        t[name + ".bias"] = random_tensor({out}, rng, 0.1);
    };
    auto norm = [&](const std::string& name) {
        t[name + ".weight"] = random_tensor({W}, rng, 1.0);
        t[name + ".bias"] = random_tensor({W}, rng, 0.1);
    };
    linear("embed", 7, W);
    norm("embed_norm");
    for (int b = 0; b < c.blocks; ++b) {
        const std::string p = "blocks." + std::to_string(b) + ".";
        norm(p + "norm1");
        linear(p + "qkv", W, 3 * W);
        linear(p + "proj", W, W);
        norm(p + "norm2");
        linear(p + "fc1", W, F);
        linear(p + "fc2", F, W);
    }
    norm("final_norm");
    linear("head", W, 6);
    return t;
}

std::map<std::string, std::string> metadata_of(const Config& c) {
    return {{"format", "gsd-torusnet"}, {"version", "1"}, {"k", std::to_string(c.k)},
            {"width", std::to_string(c.width)}, {"blocks", std::to_string(c.blocks)},
            {"heads", std::to_string(c.heads)}, {"mlp", std::to_string(c.mlp)}, {"description", "test model"}};
}

nlohmann::json header_of(const Tensors& tensors, const std::map<std::string, std::string>& meta) {
    nlohmann::json h;
    std::size_t offset = 0;
    for (const auto& [name, t] : tensors) {
        h[name] = {{"dtype", t.dtype}, {"shape", t.shape}, {"data_offsets", {offset, offset + t.bytes.size()}}};
        offset += t.bytes.size();
    }
    h["__metadata__"] = meta;
    return h;
}

std::string file_of(const nlohmann::json& header, const Tensors& tensors) {
    const std::string text = header.dump();
    const std::uint64_t n = text.size();
    std::string out(reinterpret_cast<const char*>(&n), 8);
    out += text;
    for (const auto& [name, t] : tensors) out += t.bytes;
    return out;
}

std::string file_of(const Tensors& tensors, const std::map<std::string, std::string>& meta) {
    return file_of(header_of(tensors, meta), tensors);
}

TorusNetModel parse(const std::string& bytes) {
    return TorusNetModel::from_bytes({reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()}, "test.safetensors");
}

// from_bytes must throw gsd::Error, naming the source, with `needle` in the message.
void check_rejects(const std::string& bytes, const std::string& needle) {
    CAPTURE(needle);
    bool threw = false;
    try {
        parse(bytes);
    } catch (const Error& e) {
        threw = true;
        CHECK(e.where() == "test.safetensors");
        CHECK_MESSAGE(std::string(e.what()).find(needle) != std::string::npos, std::string(e.what()));
    }
    CHECK(threw);
}

// ---- golden file --------------------------------------------------------------------------

struct Golden {
    int count = 0, k = 0;
    std::vector<double> neighbors, normals, features, scale, coeffs;
};

Golden read_golden() {
    const std::vector<std::uint8_t> bytes = pat::read_binary_file(kGoldenPath);
    const pat::SafeTensors st = pat::parse_safetensors(bytes, kGoldenPath);
    auto get = [&](const char* name) {
        REQUIRE_MESSAGE(st.tensors.count(name), "golden file lacks " << name);
        return pat::tensor_as_double(st.tensors.at(name), kGoldenPath, name);
    };
    Golden g;
    const auto& shape = st.tensors.at("neighbors").shape;
    REQUIRE(shape.size() == 3);
    g.count = int(shape[0]);
    g.k = int(shape[1]);
    g.neighbors = get("neighbors");
    g.normals = get("neighbor_normals");
    g.features = get("features");
    g.scale = get("scale");
    g.coeffs = get("coeffs");
    REQUIRE(g.normals.size() == g.neighbors.size());
    REQUIRE(g.features.size() == std::size_t(g.count * g.k * 7));
    REQUIRE(g.scale.size() == std::size_t(g.count));
    REQUIRE(g.coeffs.size() == std::size_t(g.count * 6));
    return g;
}

std::vector<Eigen::Vector3d> rows3(const std::vector<double>& v, std::size_t first, int k) {
    std::vector<Eigen::Vector3d> out(static_cast<std::size_t>(k));
    for (int j = 0; j < k; ++j) out[std::size_t(j)] = Eigen::Vector3d(&v[first + 3 * std::size_t(j)]);
    return out;
}

}  // namespace

// ---- the contract, against PyTorch --------------------------------------------------------

TEST_CASE("golden: features, scale and coefficients match PyTorch (float64) to 1e-5") {
    const TorusNetModel model = TorusNetModel::load(kModelPath);
    const Golden g = read_golden();
    REQUIRE_MESSAGE(g.k == model.k, "tests/data/torusnet_golden.safetensors was made for another model "
                                    "(regenerate it with tools/train/golden.py --model models/torusnet.safetensors)");
    const pat::TorusNetCpu net(model);
    const std::size_t k = std::size_t(g.k);
    std::vector<double> features, scale, coeffs;
    for (int p = 0; p < g.count; ++p) {
        const auto P = rows3(g.neighbors, std::size_t(p) * k * 3, g.k);
        const auto N = rows3(g.normals, std::size_t(p) * k * 3, g.k);
        std::vector<double> f(k * 7);
        double m = 0;
        pat::torusnet_features(model, P.data(), N.data(), tangent_of(N[0].normalized()), f.data(), m);
        features.insert(features.end(), f.begin(), f.end());
        scale.push_back(m);
        // The network runs on our features: the check covers features and network together.
        const auto c = as_vector(net.predict(f.data(), m));
        coeffs.insert(coeffs.end(), c.begin(), c.end());
    }
    const double ef = relative_error(features, g.features), es = relative_error(scale, g.scale),
                 ec = relative_error(coeffs, g.coeffs);
    MESSAGE("golden (" << g.count << " neighborhoods, k=" << g.k << "): max relative error features " << ef
                       << ", scale " << es << ", coefficients " << ec);
    CHECK(ef <= 1e-5);
    CHECK(es <= 1e-5);
    CHECK_MESSAGE(ec <= 1e-5, "if only the coefficients differ, the golden file may come from another model: "
                              "regenerate it with tools/train/golden.py --model models/torusnet.safetensors");
    // The one-pass helper is the same network.
    const auto P = rows3(g.neighbors, 0, g.k);
    const auto N = rows3(g.normals, 0, g.k);
    std::vector<double> f(k * 7);
    double m = 0;
    pat::torusnet_features(model, P.data(), N.data(), tangent_of(N[0].normalized()), f.data(), m);
    CHECK(as_vector(pat::torusnet_predict(model, f.data(), m)) == as_vector(net.predict(f.data(), m)));
}

TEST_CASE("the shipped model is models/torusnet.safetensors, embedded") {
    const TorusNetModel& shipped = TorusNetModel::shipped();
    const TorusNetModel file = TorusNetModel::load(kModelPath);
    CHECK(&shipped == &TorusNetModel::shipped());
    CHECK(shipped.k == file.k);
    CHECK(shipped.width == file.width);
    CHECK(shipped.blocks == file.blocks);
    CHECK(shipped.description == file.description);
    CHECK(shipped.params == file.params);  // a stale embedding fails here
}

// ---- the loader -----------------------------------------------------------------------------

TEST_CASE("loader: a valid file gives every tensor at its offset") {
    const Config c;
    const Tensors t = random_model(c);
    const TorusNetModel m = parse(file_of(t, metadata_of(c)));
    CHECK(m.k == c.k);
    CHECK(m.width == c.width);
    CHECK(m.blocks == c.blocks);
    CHECK(m.heads == c.heads);
    CHECK(m.mlp == c.mlp);
    CHECK(m.description == "test model");
    REQUIRE(m.block.size() == std::size_t(c.blocks));
    auto same = [&](const std::string& name, std::size_t offset) {
        const Tensor& x = t.at(name);
        CAPTURE(name);
        REQUIRE(offset + x.bytes.size() / 4 <= m.params.size());
        CHECK(offset % 4 == 0);  // vec4-aligned for the GPU
        CHECK(std::memcmp(m.params.data() + offset, x.bytes.data(), x.bytes.size()) == 0);
    };
    same("embed.weight", m.embed.weight);
    same("embed_norm.bias", m.embed_norm.bias);
    same("blocks.1.qkv.weight", m.block[1].qkv.weight);
    same("blocks.0.fc2.bias", m.block[0].fc2.bias);
    same("blocks.1.norm2.weight", m.block[1].norm2.weight);
    same("final_norm.weight", m.final_norm.weight);
    same("head.weight", m.head.weight);
    CHECK(m.block[0].fc1.in == c.width);
    CHECK(m.block[0].fc1.out == c.mlp);
    CHECK(m.head.out == 6);
}

TEST_CASE("loader: malformed files are rejected with a clear error") {
    const Config c;
    const Tensors good = random_model(c);
    const auto meta = metadata_of(c);
    const std::string bytes = file_of(good, meta);

    SUBCASE("truncated") {
        check_rejects(bytes.substr(0, 5), "shorter than");
        check_rejects(bytes.substr(0, 40), "truncated");
        check_rejects(bytes.substr(0, bytes.size() - 4), "out of range");
    }
    SUBCASE("header length past the end, or absurd") {
        std::string b = bytes;
        const std::uint64_t huge = 1ull << 62;
        std::memcpy(b.data(), &huge, 8);
        check_rejects(b, "header length");
    }
    SUBCASE("bad JSON") {
        std::string b = bytes;
        b[8] = '#';  // the opening brace
        check_rejects(b, "JSON");
        const std::string text = "[1, 2]";
        const std::uint64_t n = text.size();
        check_rejects(std::string(reinterpret_cast<const char*>(&n), 8) + text, "not an object");
    }
    SUBCASE("trailing bytes no tensor covers") { check_rejects(bytes + "xxxx", "no tensor covers"); }
    SUBCASE("wrong dtype") {
        nlohmann::json h = header_of(good, meta);
        h["blocks.0.proj.bias"]["dtype"] = "I32";
        check_rejects(file_of(h, good), "expected F32");
        h["blocks.0.proj.bias"]["dtype"] = "Q4";
        check_rejects(file_of(h, good), "unknown dtype");
    }
    SUBCASE("wrong shape") {
        Tensors t = good;
        t["blocks.1.fc1.weight"].shape = {std::size_t(c.width), std::size_t(c.mlp)};  // transposed
        check_rejects(file_of(t, meta), "blocks.1.fc1.weight' has shape [8, 16], expected [16, 8]");
        t = good;
        t["head.bias"].shape = {2, 3};
        check_rejects(file_of(t, meta), "head.bias");
    }
    SUBCASE("shape does not match the bytes") {
        nlohmann::json h = header_of(good, meta);
        h["embed.bias"]["shape"] = nlohmann::json::array({c.width + 1});
        check_rejects(file_of(h, good), "need");
        h["embed.bias"]["shape"] = nlohmann::json::array({-1});
        check_rejects(file_of(h, good), "non-negative");
    }
    SUBCASE("missing or unexpected tensor") {
        Tensors t = good;
        t.erase("blocks.1.norm1.bias");
        check_rejects(file_of(t, meta), "missing tensor 'blocks.1.norm1.bias'");
        t = good;
        t["blocks.2.norm1.bias"] = good.at("blocks.1.norm1.bias");
        check_rejects(file_of(t, meta), "unexpected tensor 'blocks.2.norm1.bias'");
    }
    SUBCASE("offsets out of range, reversed or overlapping") {
        nlohmann::json h = header_of(good, meta);
        auto off = h["head.weight"]["data_offsets"];
        h["head.weight"]["data_offsets"] = nlohmann::json::array({off[0], 1u << 30});
        check_rejects(file_of(h, good), "out of range");
        h["head.weight"]["data_offsets"] = nlohmann::json::array({off[1], off[0]});
        check_rejects(file_of(h, good), "out of range");
        h = header_of(good, meta);
        const auto a = h["head.bias"]["data_offsets"];
        h["head.bias"]["data_offsets"] = nlohmann::json::array({0, a[1].get<std::size_t>() - a[0].get<std::size_t>()});
        check_rejects(file_of(h, good), "overlap");
    }
    SUBCASE("non-finite weights") {
        for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
            Tensors t = good;
            std::memcpy(t["blocks.0.qkv.weight"].bytes.data() + 4 * 17, &bad, 4);
            check_rejects(file_of(t, meta), "non-finite value at element 17");
        }
    }
    SUBCASE("bad metadata") {
        auto with = [&](const std::string& key, const std::string& value) {
            auto m = meta;
            if (value == "(erase)") m.erase(key);
            else m[key] = value;
            return file_of(good, m);
        };
        check_rejects(with("format", "pytorch"), "not a TorusNet weights file");
        check_rejects(with("format", "(erase)"), "not a TorusNet weights file");
        check_rejects(with("version", "2"), "version");
        check_rejects(with("k", "(erase)"), "lacks 'k'");
        check_rejects(with("k", "eight"), "not a positive integer");
        check_rejects(with("k", "8.0"), "not a positive integer");
        check_rejects(with("k", "-8"), "not a positive integer");
        check_rejects(with("k", "1"), "out of range");
        check_rejects(with("k", "100000"), "out of range");
        check_rejects(with("width", "4096"), "out of range");
        check_rejects(with("heads", "3"), "not a multiple of heads");
        check_rejects(with("mlp", "0"), "out of range");
        nlohmann::json h = header_of(good, meta);
        h["__metadata__"]["k"] = 8;  // a number, not a string
        check_rejects(file_of(h, good), "not a string");
    }
    SUBCASE("a missing file names the path") {
        try {
            TorusNetModel::load("/nonexistent/missing.safetensors");
            FAIL("no error");
        } catch (const Error& e) {
            CHECK(e.where() == "/nonexistent/missing.safetensors");
        }
    }
}

// ---- neighborhoods and features -------------------------------------------------------------

TEST_CASE("neighborhoods: the point itself is token 0, even among duplicates") {
    const int k = 8;
    PointCloud c = shapes::by_name("sphere")->sample(64, 2);
    // Ten copies of point 5 (more than k): the search may return any k of them.
    for (int d = 0; d < 10; ++d) {
        c.points.conservativeResize(c.points.rows() + 1, 3);
        c.points.row(c.points.rows() - 1) = c.points.row(5);
    }
    const KdTree tree(c.points);
    std::vector<Neighbor> scratch;
    std::vector<std::uint32_t> tokens;
    for (std::uint32_t i = 0; i < std::uint32_t(c.points.rows()); ++i) {
        pat::torusnet_neighbors(tree, i, k, scratch, tokens);
        REQUIRE(tokens.size() == std::size_t(k));
        CHECK(tokens[0] == i);
        std::vector<std::uint32_t> sorted = tokens;
        std::sort(sorted.begin(), sorted.end());
        CHECK(std::adjacent_find(sorted.begin(), sorted.end()) == sorted.end());
        // The k − 1 others are the nearest: none closer than the farthest token is left out.
        const double farthest = (c.points.row(tokens.back()) - c.points.row(i)).norm();
        int closer = 0;
        for (Eigen::Index j = 0; j < c.points.rows(); ++j)
            closer += j != i && (c.points.row(j) - c.points.row(i)).norm() < farthest;
        CHECK(closer <= k - 1);
    }
}

TEST_CASE("features: lower median, the 1e-3 floor, coincident points") {
    const Config cfg;
    const TorusNetModel model = parse(file_of(random_model(cfg), metadata_of(cfg)));
    const int k = model.k;
    const Eigen::Vector3d n(0, 0, 2);  // not unit: normalized by the features
    const Eigen::Vector3d s = tangent_of(n.normalized());
    std::vector<Eigen::Vector3d> P(std::size_t(k), Eigen::Vector3d(1, 2, 3)), N(std::size_t(k), n);
    std::vector<double> f(std::size_t(k) * 7);
    double m = 0;

    // Distances 0.01·j for j = 1 … k−1, shuffled: m is the element at (k−2)/2 when sorted.
    for (int j = 1; j < k; ++j) P[std::size_t(j)] += Eigen::Vector3d(0.01 * ((j * 5) % (k - 1) + 1), 0, 0);
    pat::torusnet_features(model, P.data(), N.data(), s, f.data(), m);
    CHECK(m == doctest::Approx(0.01 * ((k - 2) / 2 + 1)));
    CHECK(f[6] == 1);
    CHECK(f[7 + 6] == 0);
    CHECK(f[5] == doctest::Approx(1));  // n·n after normalizing
    CHECK(f[0] == 0);

    // Mostly duplicates of the center: the median is 0, so m = 1e-3 · d_max.
    for (int j = 1; j < k; ++j) P[std::size_t(j)] = P[0];
    P.back() += Eigen::Vector3d(0, 0, 4);
    pat::torusnet_features(model, P.data(), N.data(), s, f.data(), m);
    CHECK(m == doctest::Approx(4e-3));
    CHECK(f[std::size_t(k - 1) * 7 + 2] == doctest::Approx(1000));  // (d·n)/m

    // All coincide: m = 1 and every offset is 0.
    P.back() = P[0];
    pat::torusnet_features(model, P.data(), N.data(), s, f.data(), m);
    CHECK(m == 1);
    for (int j = 0; j < k; ++j) CHECK(f[std::size_t(j) * 7 + 2] == 0);
    const Jet jet = pat::torusnet_predict(model, f.data(), m);
    for (double a : as_vector(jet)) CHECK(std::isfinite(a));
}

// ---- the fitter -----------------------------------------------------------------------------

TEST_CASE("TorusNet::fit on the CPU: finite jets, tangent_of frames, fitter \"net\"") {
    TorusNetOptions o;
    o.device = "cpu";
    const TorusNet net(o);
    CHECK(net.k() == TorusNetModel::shipped().k);
    CHECK(net.description().find("TorusNet k=" + std::to_string(net.k())) == 0);
    const PointCloud cloud = shapes::by_name("sphere")->sample(400, 4);
    int reports = 0;
    const FittedTori t = net.fit(cloud, [&](std::string_view stage, double f) {
        CHECK(stage == "fit");
        CHECK(f > 0);
        CHECK(f <= 1);
        ++reports;
    });
    CHECK(reports >= 1);
    CHECK(t.fitter == "net");
    REQUIRE(t.size() == cloud.size());
    REQUIRE(t.jets.size() == std::size_t(cloud.size()));
    CHECK(t.spacing > 0);
    for (Eigen::Index i = 0; i < t.size(); ++i) {
        for (double a : as_vector(t.jets[std::size_t(i)])) REQUIRE(std::isfinite(a));
        const Eigen::Vector3d n = t.normals.row(i).transpose();
        CHECK((t.tangents.row(i).transpose() - tangent_of(n)).norm() < 1e-12);
    }
    // The same model from its file gives the same jets; so does the reference, point by point.
    o.model = kModelPath;
    const FittedTori u = TorusNet(o).fit(cloud);
    CHECK(as_vector(u.jets[17]) == as_vector(t.jets[17]));
    const KdTree tree(cloud.points);
    std::vector<Neighbor> scratch;
    std::vector<std::uint32_t> tokens;
    pat::torusnet_neighbors(tree, 17, net.k(), scratch, tokens);
    std::vector<Eigen::Vector3d> P, N;
    for (std::uint32_t j : tokens) {
        P.push_back(cloud.points.row(j).transpose());
        N.push_back(cloud.normals.row(j).transpose());
    }
    std::vector<double> f(tokens.size() * 7);
    double m = 0;
    pat::torusnet_features(TorusNetModel::shipped(), P.data(), N.data(), tangent_of(N[0]), f.data(), m);
    CHECK(relative_error(as_vector(pat::torusnet_predict(TorusNetModel::shipped(), f.data(), m)),
                         as_vector(t.jets[17])) < 1e-12);
}

TEST_CASE("TorusNet: too few points, a missing model") {
    TorusNetOptions o;
    o.device = "cpu";
    const TorusNet net(o);
    const PointCloud small = shapes::by_name("sphere")->sample(std::size_t(net.k() - 1), 1);
    try {
        net.fit(small);
        FAIL("no error");
    } catch (const Error& e) {
        CHECK(std::string(e.what()).find("at least k = " + std::to_string(net.k())) != std::string::npos);
    }
    o.model = "/nonexistent/net.safetensors";
    CHECK_THROWS_AS(TorusNet{o}, Error);
}

// ---- the CLI --------------------------------------------------------------------------------

TEST_CASE("CLI: --fitter net, --model, and their usage errors") {
    test::ScratchDir dir("torusnet-cli");
    const std::string cloud = dir.file("sphere.ply");
    REQUIRE(test::run_cli("sample sphere -n 500 -o " + cloud).exit_code == 0);

    const auto fit = test::run_cli("pat fit " + cloud + " --fitter net --device cpu -o " + dir.file("net.tori"));
    CHECK_MESSAGE(fit.exit_code == 0, fit.output);
    const FittedTori t = load_tori(dir.file("net.tori"));
    CHECK(t.fitter == "net");
    CHECK(t.size() == 500);

    const auto with_model = test::run_cli("pat fit " + cloud + " --fitter net --device cpu --model " + kModelPath +
                                          " -o " + dir.file("net2.tori"));
    CHECK_MESSAGE(with_model.exit_code == 0, with_model.output);

    const auto eval = test::run_cli("pat eval " + cloud + " --fitter net --device cpu --grid 8 --bounds -1 -1 -1 1 1 1 -o " +
                                    dir.file("phi.npy"));
    CHECK_MESSAGE(eval.exit_code == 0, eval.output);
    CHECK(test::file_exists(dir.file("phi.npy")));

    const auto usage = test::run_cli("pat fit " + cloud + " --fitter jet --model x.safetensors -o " + dir.file("a.tori"));
    CHECK(usage.exit_code == 2);
    CHECK(usage.output.find("--model") != std::string::npos);
    // The default fitter is the network, so --model alone is valid; a missing file is an error.
    CHECK(test::run_cli("pat fit " + cloud + " --model x.safetensors -o " + dir.file("a.tori")).exit_code == 1);
    CHECK(test::run_cli("pat fit " + cloud + " --fitter net --k 12 -o " + dir.file("a.tori")).exit_code == 2);
    CHECK(test::run_cli("pat fit " + cloud + " --fitter lsq -o " + dir.file("a.tori")).exit_code == 2);

    const auto missing = test::run_cli("pat fit " + cloud + " --fitter net --model " + dir.file("missing.safetensors") +
                                       " -o " + dir.file("b.tori"));
    CHECK(missing.exit_code == 1);
    CHECK(missing.output.find("gsd: error: " + dir.file("missing.safetensors") + ": file not found") != std::string::npos);
    CHECK_FALSE(test::file_exists(dir.file("b.tori")));

    const std::string tiny = dir.file("tiny.xyz");
    REQUIRE(test::run_cli("sample sphere -n 10 -o " + tiny).exit_code == 0);
    const auto few = test::run_cli("pat fit " + tiny + " --fitter net --device cpu -o " + dir.file("c.tori"));
    CHECK(few.exit_code == 1);
    CHECK(few.output.find("TorusNet needs at least") != std::string::npos);
}
