// gsd-broken-bench: inside/outside on broken closed meshes — the grid SHM's sign against the
// generalized winding number thresholded at ½ (the classic answer).
//
//   gsd-broken-bench [--grid N] [--seed S] [--t-coef T] [--cutoff C] [--fit-zero-set W] [--veto-winding T] [--veto-margin M] [--only-given] [--dump DIR] [MESH.obj ...]
//
// Each mesh (procedural shapes, plus any given) is scaled into [−0.9, 0.9]³ and damaged three
// ways: (a) 20 % of the area in 3 holes + 10 % of faces flipped; (b) the same plus duplicated
// faces (10 % of the faces again, half of them flipped); (c) holes + flips + vertex noise of 0.5 %
// of the diagonal, which makes the surface cross itself. Truth: the winding number of the intact
// mesh. Scored at the nodes of an N³ grid on [−1, 1]³ farther than two cells from the intact
// surface. Prints one row per mesh and damage: the share of inside and outside nodes signed
// right by SHM and by the GWN, and the SHM run time. --t-coef, --cutoff, --fit-zero-set,
// --veto-winding and --veto-margin set the ShmOptions of the same names.
//
// --dump DIR writes, per mesh and damage, the broken mesh (.obj), and on the grid (.npy of shape
// (nx, ny, nz), as `gsd shm grid` writes φ): φ, the truth (the intact mesh's winding number) and
// the broken mesh's winding number, the last two NaN within two cells of the surface — to see
// where and why a sign goes wrong.
#include <CLI/CLI.hpp>
#include "broken_meshes.hpp"
#include <gsd/io.hpp>
#include <gsd/shapes.hpp>
#include <gsd/shm.hpp>
#include <gsd/sums.hpp>

#include "sums/sum_tree.hpp"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <limits>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

using namespace gsd;
using bench::normalized;
using bench::with_duplicates;

namespace {



struct Score {
    double shm_in = 0, shm_out = 0, gwn_in = 0, gwn_out = 0;
    std::size_t in = 0, out = 0;
};

Score score(const PolygonMesh& intact, const PolygonMesh& broken, const GridSpec& g, const std::vector<float>& phi,
            std::vector<float>* truth_grid = nullptr, std::vector<float>* gwn_grid = nullptr) {
    const double cell = g.box.extent().maxCoeff() / (g.nx - 1);
    const OrientedElements truth_src = OrientedElements::from_mesh(intact);
    const sums::SumTree truth_tree(truth_src);
    const Points nodes = g.nodes();
    std::vector<Eigen::Index> far;
    for (Eigen::Index i = 0; i < nodes.rows(); ++i)
        if (truth_tree.nearest_distance(nodes.row(i).transpose()) > 2 * cell) far.push_back(i);
    Points q(Eigen::Index(far.size()), 3);
    for (std::size_t i = 0; i < far.size(); ++i) q.row(Eigen::Index(i)) = nodes.row(far[i]);
    WindingOptions o;
    o.device = "cpu";
    const std::vector<double> truth = fast_winding_numbers(truth_src, q, o).w;
    const std::vector<double> gwn = fast_winding_numbers(OrientedElements::from_mesh(broken), q, o).w;
    // Values at the scored nodes onto the whole grid, NaN elsewhere.
    auto to_grid = [&](const std::vector<double>& values, std::vector<float>* grid) {
        if (!grid) return;
        grid->assign(std::size_t(nodes.rows()), std::numeric_limits<float>::quiet_NaN());
        for (std::size_t i = 0; i < far.size(); ++i) (*grid)[std::size_t(far[i])] = float(values[i]);
    };
    to_grid(truth, truth_grid);
    to_grid(gwn, gwn_grid);
    Score s;
    for (std::size_t i = 0; i < far.size(); ++i) {
        const double p = phi[std::size_t(far[i])];
        if (truth[i] > 0.5) {
            ++s.in;
            s.shm_in += p < 0;
            s.gwn_in += gwn[i] > 0.5;
        } else {
            ++s.out;
            s.shm_out += p > 0;
            s.gwn_out += gwn[i] <= 0.5;
        }
    }
    s.shm_in /= double(s.in);
    s.gwn_in /= double(s.in);
    s.shm_out /= double(s.out);
    s.gwn_out /= double(s.out);
    return s;
}

}  // namespace

int main(int argc, char** argv) {
    int n = 64;
    std::uint64_t seed = 21;
    ShmOptions shm;
    shm.device = "cpu";
    std::vector<std::pair<std::string, PolygonMesh>> meshes;
    bool only_given = false;
    std::string dump;
    std::vector<std::string> given;
    CLI::App app{"SHM's sign on broken meshes (holes, flips, coarse faces) against the intact meshes' (docs/shm.md)"};
    app.add_option("meshes", given, "meshes to break besides the analytic ones")->check(CLI::ExistingFile);
    app.add_option("--grid", n, "grid nodes per axis")->check(CLI::Range(4, 1024));
    app.add_option("--seed", seed, "damage seed");
    app.add_option("--t-coef", shm.t_coef, "ShmOptions::t_coef");
    app.add_option("--cutoff", shm.cutoff, "ShmOptions::cutoff");
    app.add_option("--fit-zero-set", shm.fit_zero_set, "ShmOptions::fit_zero_set");
    app.add_option("--veto-winding", shm.veto_winding, "ShmOptions::veto_winding");
    app.add_option("--veto-margin", shm.veto_margin, "ShmOptions::veto_margin");
    app.add_flag("--only-given", only_given, "only the meshes given");
    app.add_option("--dump", dump, "folder for each case's grids");
    CLI11_PARSE(app, argc, argv);
    for (const std::string& a : given) {
        const auto slash = a.find_last_of('/');
        meshes.push_back({a.substr(slash == std::string::npos ? 0 : slash + 1), io::read_mesh(a)});
    }
    if (!only_given) {
        for (const char* s : {"sphere", "torus", "capsule", "rounded-box"}) meshes.insert(meshes.begin(), {s, shapes::mesh(*shapes::by_name(s), 64)});
        meshes.insert(meshes.begin(), {"double-torus", shapes::double_torus_mesh(64)});
    }
    const GridSpec g = GridSpec::cube(n, Box{{-1, -1, -1}, {1, 1, 1}});
    std::printf("%d^3 on [-1,1]^3, nodes > 2 cells from the intact surface; %% signed right (inside / outside)\n", n);
    std::printf("%-22s %-14s %8s %8s | %8s %8s | %8s %8s\n", "mesh", "damage", "SHM in", "SHM out", "GWN in", "GWN out", "inside", "SHM s");
    for (const auto& [name, raw] : meshes) {
        const PolygonMesh intact = normalized(raw);
        shapes::MeshCorruption holes;
        holes.holes = 3;
        holes.hole_area = 0.2;
        holes.flip_fraction = 0.1;
        shapes::MeshCorruption noisy = holes;
        noisy.vertex_noise = 0.005;
        const PolygonMesh a = shapes::corrupt(intact, holes, seed);
        const std::vector<std::pair<const char*, PolygonMesh>> damaged{
            {"holes+flips", a}, {"+duplicates", with_duplicates(a, 10, seed + 1)}, {"+self-crossing", shapes::corrupt(intact, noisy, seed)}};
        for (const auto& [what, broken] : damaged) {
            const ShmOptions o = shm;
            const auto t0 = std::chrono::steady_clock::now();
            const ShmResult r = SignedHeatGrid(shm_source(broken), g, o).solve();
            const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
            std::vector<float> truth, gwn;
            const Score s = score(intact, broken, g, r.phi, dump.empty() ? nullptr : &truth, dump.empty() ? nullptr : &gwn);
            if (!dump.empty()) {
                std::filesystem::create_directories(dump);
                std::string stem = dump + "/" + name.substr(0, name.rfind('.')) + "_" + what;
                std::replace(stem.begin(), stem.end(), '+', 'p');
                io::write_mesh(stem + ".obj", broken);
                const std::vector<std::size_t> shape{std::size_t(g.nx), std::size_t(g.ny), std::size_t(g.nz)};
                io::write_npy(stem + ".phi.npy", shape, r.phi);
                io::write_npy(stem + ".truth.npy", shape, truth);
                io::write_npy(stem + ".gwn.npy", shape, gwn);
            }
            std::printf("%-22s %-14s %7.2f%% %7.2f%% | %7.2f%% %7.2f%% | %8zu %8.2f\n", name.c_str(), what, 100 * s.shm_in, 100 * s.shm_out,
                        100 * s.gwn_in, 100 * s.gwn_out, s.in, dt);
            std::fflush(stdout);
        }
    }
    return 0;
}
