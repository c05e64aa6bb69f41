#include "support.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <random>
#include <sys/wait.h>

namespace gsd::test {

namespace {
std::uint64_t g_cli_validation_errors = 0;
std::uint64_t g_expected_validation_errors = 0;

// The runtime prints one line per validation error ("gsd: Vulkan validation error: ...").
std::uint64_t count_validation_errors(const std::string& output) {
    static const std::string tag = "Vulkan validation error:";
    std::uint64_t n = 0;
    for (std::size_t at = output.find(tag); at != std::string::npos; at = output.find(tag, at + tag.size())) ++n;
    return n;
}
}  // namespace

std::uint64_t cli_validation_errors() { return g_cli_validation_errors; }
std::uint64_t expected_validation_errors() { return g_expected_validation_errors; }
void expect_validation_errors(std::uint64_t n) { g_expected_validation_errors += n; }

ScratchDir::ScratchDir(const std::string& tag) {
    std::random_device rd;
    path_ = std::filesystem::temp_directory_path() /
            ("gsd-test-" + tag + "-" + std::to_string(rd()) + std::to_string(rd()));
    std::filesystem::create_directories(path_);
}

ScratchDir::~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
}

RunResult run_shell(const std::string& command) {
    RunResult r;
    FILE* pipe = popen((command + " 2>&1").c_str(), "r");
    if (!pipe) return r;
    std::array<char, 4096> buf{};
    std::size_t n;
    while ((n = fread(buf.data(), 1, buf.size(), pipe)) > 0) r.output.append(buf.data(), n);
    const int status = pclose(pipe);
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    g_cli_validation_errors += count_validation_errors(r.output);
    return r;
}

RunResult run_cli(const std::string& args) { return run_shell(std::string(GSD_CLI) + " " + args); }

std::string shared_data(const std::string& relative) { return std::string(GSD_SHARED_DATA) + "/" + relative; }

std::vector<double> polygon_sdf(const Points& x, const std::vector<Eigen::Vector2d>& P) {
    std::vector<double> d(std::size_t(x.rows()));
    for (Eigen::Index i = 0; i < x.rows(); ++i) {
        const Eigen::Vector2d p(x(i, 0), x(i, 1));
        double dist = INFINITY, winding = 0;
        for (std::size_t k = 0; k + 1 < P.size(); ++k) {
            const Eigen::Vector2d e = P[k + 1] - P[k];
            const double t = std::clamp((p - P[k]).dot(e) / e.squaredNorm(), 0.0, 1.0);
            dist = std::min(dist, (p - P[k] - t * e).norm());
            const Eigen::Vector2d a = P[k] - p, b = P[k + 1] - p;
            winding += std::atan2(a.x() * b.y() - a.y() * b.x(), a.dot(b));
        }
        d[std::size_t(i)] = std::abs(winding) > std::numbers::pi ? -dist : dist;
    }
    return d;
}

void write_bytes(const std::string& path, const std::string& bytes) {
    std::ofstream f(path, std::ios::binary);
    f.write(bytes.data(), std::streamsize(bytes.size()));
}

bool file_exists(const std::string& path) { return std::filesystem::exists(path); }

std::vector<double> brute_force_winding(const PolygonMesh& mesh, const Points& queries) {
    std::vector<double> w(std::size_t(queries.rows()), 0.0);
    for (Eigen::Index q = 0; q < queries.rows(); ++q) {
        const Eigen::Vector3d x = queries.row(q).transpose();
        double sum = 0;
        for (std::size_t f = 0; f < mesh.face_count(); ++f) {
            const auto* c = mesh.indices.data() + mesh.offsets[f];
            const std::size_t n = mesh.offsets[f + 1] - mesh.offsets[f];
            for (std::size_t k = 1; k + 1 < n; ++k) {
                const Eigen::Vector3d a = mesh.vertices.row(c[0]).transpose() - x;
                const Eigen::Vector3d b = mesh.vertices.row(c[k]).transpose() - x;
                const Eigen::Vector3d d = mesh.vertices.row(c[k + 1]).transpose() - x;
                const double la = a.norm(), lb = b.norm(), ld = d.norm();
                const double num = a.dot(b.cross(d));
                const double den = la * lb * ld + a.dot(b) * ld + b.dot(d) * la + d.dot(a) * lb;
                sum += 2 * std::atan2(num, den);
            }
        }
        w[std::size_t(q)] = sum / (4 * M_PI);
    }
    return w;
}

}  // namespace gsd::test
