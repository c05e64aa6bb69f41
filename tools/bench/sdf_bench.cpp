// gsd-sdf-bench: the signs of `gsd sdf` on broken closed meshes, beside ray parity.
//
//   gsd-sdf-bench [--queries Q] [--margin M] [--seed S] [--shm-grid N] [--device D] [--only-given] [MESH ...]
//
// Each mesh (procedural closed shapes, plus any given; meant to be closed) is scaled into
// [−0.9, 0.9]³ and damaged several ways: holes (a share of the area cut out around random faces),
// flipped faces, duplicated faces (half of them reversed), vertex noise that makes the surface
// cross itself, and all of them together. Q queries uniform in [−1, 1]³ are scored where they lie
// farther than M × the intact mesh's box diagonal from the intact surface; the truth is the intact
// mesh's exact winding number. One row per mesh and damage: the share signed right by each sign
// of mesh_sdf (auto, winding of the faces as given, pseudonormals, the grid SHM) and by ray
// parity (a crossing count along one ray, and the majority of three), and each sign's time.
#include <CLI/CLI.hpp>
#include "broken_meshes.hpp"
#include <gsd/io.hpp>
#include <gsd/sdf.hpp>
#include <gsd/shapes.hpp>
#include <gsd/sums.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

using namespace gsd;
using bench::normalized;
using bench::with_duplicates;

namespace {



// Ray parity along +x after a rotation R (so that the rays meet the mesh in general position):
// the mesh's triangles bucketed by their (y, z) extent in a G × G grid; a query counts the
// triangles its ray crosses beyond it.
class RayParity {
public:
    RayParity(const PolygonMesh& mesh, const Eigen::Matrix3d& R) : R_(R) {
        for_each_triangle(mesh, [&](std::size_t, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
            tri_.push_back({R * Eigen::Vector3d(mesh.vertices.row(a)), R * Eigen::Vector3d(mesh.vertices.row(b)),
                            R * Eigen::Vector3d(mesh.vertices.row(c))});
        });
        lo_ = {1e300, 1e300};
        hi_ = {-1e300, -1e300};
        for (const auto& t : tri_)
            for (const auto& p : t) {
                lo_ = lo_.cwiseMin(p.tail<2>());
                hi_ = hi_.cwiseMax(p.tail<2>());
            }
        g_ = std::max(1, int(std::sqrt(double(tri_.size()) / 4)));
        cells_.assign(std::size_t(g_) * std::size_t(g_), {});
        for (std::uint32_t i = 0; i < tri_.size(); ++i) {
            Eigen::Vector2d l = tri_[i][0].tail<2>(), h = l;
            for (const auto& p : tri_[i]) {
                l = l.cwiseMin(p.tail<2>());
                h = h.cwiseMax(p.tail<2>());
            }
            const auto [i0, j0] = cell(l);
            const auto [i1, j1] = cell(h);
            for (int u = i0; u <= i1; ++u)
                for (int v = j0; v <= j1; ++v) cells_[std::size_t(u) * std::size_t(g_) + std::size_t(v)].push_back(i);
        }
    }
    bool inside(const Eigen::Vector3d& x0) const {
        const Eigen::Vector3d x = R_ * x0;
        const Eigen::Vector2d p = x.tail<2>();
        if ((p.array() < lo_.array()).any() || (p.array() > hi_.array()).any()) return false;
        const auto [u, v] = cell(p);
        int crossings = 0;
        for (std::uint32_t i : cells_[std::size_t(u) * std::size_t(g_) + std::size_t(v)]) {
            const auto& t = tri_[i];
            // (y, z) in the projected triangle: barycentric by 2D cross products.
            auto cross2 = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); };
            const Eigen::Vector2d a = t[0].tail<2>(), b = t[1].tail<2>(), c = t[2].tail<2>();
            const double area = cross2(b - a, c - a);
            if (area == 0) continue;
            const double wa = cross2(b - p, c - p) / area, wb = cross2(c - p, a - p) / area, wc = 1 - wa - wb;
            if (wa < 0 || wb < 0 || wc < 0) continue;
            const double hit = wa * t[0].x() + wb * t[1].x() + wc * t[2].x();
            crossings += hit > x.x();
        }
        return crossings % 2 == 1;
    }

private:
    std::pair<int, int> cell(const Eigen::Vector2d& p) const {
        const Eigen::Vector2d s = (p - lo_).cwiseQuotient((hi_ - lo_).cwiseMax(1e-300)) * g_;
        return {std::clamp(int(s.x()), 0, g_ - 1), std::clamp(int(s.y()), 0, g_ - 1)};
    }
    Eigen::Matrix3d R_;
    std::vector<std::array<Eigen::Vector3d, 3>> tri_;
    Eigen::Vector2d lo_, hi_;
    int g_ = 1;
    std::vector<std::vector<std::uint32_t>> cells_;
};

Eigen::Matrix3d random_rotation(std::mt19937_64& rng) {
    std::normal_distribution<double> g;
    Eigen::Quaterniond q(g(rng), g(rng), g(rng), g(rng));
    return q.normalized().toRotationMatrix();
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
    int queries = 20000, shm_grid = MeshSdfOptions{}.shm_grid;
    double margin = 0.01;
    std::uint64_t seed = 21;
    std::string device = "cpu";
    bool only_given = false;
    std::vector<std::string> given;
    CLI::App app{"gsd sdf's signs on broken closed meshes, beside ray parity (docs/sdf.md)"};
    app.add_option("meshes", given, "closed meshes to break besides the analytic ones")->check(CLI::ExistingFile);
    app.add_option("--queries", queries, "uniform queries in [-1,1]^3 per case")->check(CLI::Range(100, 10000000));
    app.add_option("--margin", margin, "score queries farther than this × the box diagonal from the intact surface")
        ->check(CLI::Range(0.0, 0.5));
    app.add_option("--seed", seed, "damage and query seed");
    app.add_option("--shm-grid", shm_grid, "MeshSdfOptions::shm_grid")->check(CLI::Range(8, 512));
    app.add_option("--device", device, "device for the winding numbers and SHM");
    app.add_flag("--only-given", only_given, "only the meshes given");
    CLI11_PARSE(app, argc, argv);
    std::vector<std::pair<std::string, PolygonMesh>> meshes;
    if (!only_given) {
        meshes.push_back({"double-torus", shapes::double_torus_mesh(64)});
        for (const char* s : {"sphere", "torus", "capsule", "rounded-box"}) meshes.push_back({s, shapes::mesh(*shapes::by_name(s), 64)});
    }
    for (const std::string& a : given) meshes.push_back({a.substr(a.find_last_of('/') + 1), io::read_mesh(a)});

    std::printf("%d uniform queries in [-1,1]^3 per case, scored > %.3g x the box diagonal from the intact surface; "
                "%% signed right\n", queries, margin);
    std::printf("%-16s %-16s %7s | %8s %8s %8s %8s | %8s %8s | %s\n", "mesh", "damage", "scored", "auto", "winding", "pseudo",
                "shm", "ray", "ray x3", "seconds: auto winding shm");
    for (const auto& [name, raw] : meshes) {
        const PolygonMesh intact = normalized(raw);
        const double diagonal = bounding_box(intact.vertices).diagonal();
        auto holes = [&](double area, double flips, double noise) {
            shapes::MeshCorruption c;
            c.holes = 3;
            c.hole_area = area;
            c.flip_fraction = flips;
            c.vertex_noise = noise;
            return c;
        };
        const std::vector<std::pair<std::string, PolygonMesh>> damaged{
            {"holes10+flips5", shapes::corrupt(intact, holes(0.1, 0.05, 0), seed)},
            {"holes20+flips10", shapes::corrupt(intact, holes(0.2, 0.1, 0), seed)},
            {"+duplicates", with_duplicates(shapes::corrupt(intact, holes(0.15, 0.07, 0), seed), 10, seed + 1)},
            {"+self-crossing", shapes::corrupt(intact, holes(0.15, 0.07, 0.005), seed)},
            {"all", with_duplicates(shapes::corrupt(intact, holes(0.15, 0.07, 0.005), seed), 10, seed + 1)}};
        // The scored queries and their truth, once per mesh.
        std::mt19937_64 rng(seed);
        std::uniform_real_distribution<double> u(-1, 1);
        Points all(queries, 3);
        for (int i = 0; i < queries; ++i) all.row(i) << u(rng), u(rng), u(rng);
        MeshSdfOptions unsigned_options;
        unsigned_options.sign = SdfSign::none;
        const std::vector<double> d = mesh_sdf(intact, all, unsigned_options).phi;
        std::vector<Eigen::Index> kept;
        for (Eigen::Index i = 0; i < all.rows(); ++i)
            if (d[std::size_t(i)] > margin * diagonal) kept.push_back(i);
        Points q(Eigen::Index(kept.size()), 3);
        for (std::size_t i = 0; i < kept.size(); ++i) q.row(Eigen::Index(i)) = all.row(kept[i]);
        WindingOptions exact;
        exact.exact = true;
        exact.device = "cpu";
        const std::vector<double> truth = fast_winding_numbers(OrientedElements::from_mesh(intact), q, exact).w;
        for (const auto& [what, broken] : damaged) {
            auto right = [&](auto&& inside_at) {
                std::size_t n = 0;
                for (std::size_t i = 0; i < truth.size(); ++i) n += inside_at(i) == (truth[i] > 0.5);
                return 100.0 * double(n) / double(truth.size());
            };
            double pct[4], sec[4];
            const SdfSign signs[4] = {SdfSign::automatic, SdfSign::winding, SdfSign::pseudonormal, SdfSign::shm};
            for (int s = 0; s < 4; ++s) {
                MeshSdfOptions o;
                o.sign = signs[s];
                o.device = device;
                o.shm_grid = shm_grid;
                const auto t0 = std::chrono::steady_clock::now();
                const MeshSdfResult r = mesh_sdf(broken, q, o);
                sec[s] = seconds_since(t0);
                pct[s] = right([&](std::size_t i) { return r.phi[i] < 0; });
            }
            std::mt19937_64 rot(seed + 7);
            std::vector<RayParity> rays;
            for (int k = 0; k < 3; ++k) rays.emplace_back(broken, random_rotation(rot));
            std::vector<std::uint8_t> votes(truth.size()), first(truth.size());
#pragma omp parallel for schedule(dynamic, 256)
            for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(truth.size()); ++i) {
                int v = 0;
                for (int k = 0; k < 3; ++k) {
                    const bool in = rays[std::size_t(k)].inside(q.row(i).transpose());
                    if (k == 0) first[std::size_t(i)] = in;
                    v += in;
                }
                votes[std::size_t(i)] = v >= 2;
            }
            const double ray1 = right([&](std::size_t i) { return first[i] != 0; });
            const double ray3 = right([&](std::size_t i) { return votes[i] != 0; });
            std::printf("%-16s %-16s %7zu | %7.2f%% %7.2f%% %7.2f%% %7.2f%% | %7.2f%% %7.2f%% | %.3f %.3f %.3f\n", name.c_str(),
                        what.c_str(), truth.size(), pct[0], pct[1], pct[2], pct[3], ray1, ray3, sec[0], sec[1], sec[3]);
            std::fflush(stdout);
        }
    }
    return 0;
}
