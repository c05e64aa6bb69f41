// gsd-accuracy: mean |φ − φ_true| of PAT-jet, SSPD and SHC on the analytic shapes, on a grid
// over [−1, 1]³ (thesis §5.3 protocol). Prints a table; used for the closing notes and for
// choosing defaults. Not a test: tests assert fixed bounds, this measures.
#include <CLI/CLI.hpp>
#include <gsd/baselines.hpp>
#include <gsd/pat.hpp>
#include <gsd/shapes.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

using namespace gsd;

namespace {

double mean_error(const shapes::Shape& s, const GridSpec& g, const std::vector<float>& phi) {
    const Points nodes = g.nodes();
    double sum = 0;
    for (Eigen::Index i = 0; i < nodes.rows(); ++i) sum += std::abs(double(phi[std::size_t(i)]) - s.sdf(nodes.row(i).transpose()));
    return sum / double(nodes.rows());
}

}  // namespace

int main(int argc, char** argv) {
    int n_points = 2048, grid_n = 64;
    double r_spacings = 8;
    std::string device = "cpu";
    int k = 24;
    double sigma = 1.0, nw = 1.0;
    bool exact = false;
    shapes::Corruption bad;
    CLI::App app{"PAT accuracy on analytic shapes against their exact SDFs (scripts/bench.sh)"};
    app.add_option("--points", n_points, "points sampled per shape")->check(CLI::Range(16, 100000000));
    app.add_option("--grid", grid_n, "grid nodes per axis over [-1,1]^3")->check(CLI::Range(2, 1024));
    app.add_option("--r-spacings", r_spacings, "blend radius in point spacings");
    app.add_option("--device", device, "cpu | gpu | auto | index | name");
    app.add_option("--k", k, "jet fit neighbors")->check(CLI::Range(6, 1024));
    app.add_option("--sigma", sigma, "jet fit weight width (× spacing)");
    app.add_option("--normal-weight", nw, "jet fit weight of the normals");
    app.add_flag("--exact", exact, "the exact sum instead of the accelerated one");
    app.add_option("--noise", bad.position_noise, "position noise (× spacing)");
    app.add_option("--normal-noise", bad.normal_noise, "normal noise");
    app.add_option("--flip", bad.flip_fraction, "share of flipped normals");
    app.add_option("--holes", bad.holes, "holes cut");
    CLI11_PARSE(app, argc, argv);
    const GridSpec g = GridSpec::cube(grid_n, Box{{-1, -1, -1}, {1, 1, 1}});
    BlendOptions opt;
    opt.device = device;
    opt.exact = exact;
    opt.r_eval_spacings = r_spacings;
    JetFitterOptions jo;
    jo.k = k;
    jo.sigma_factor = sigma;
    jo.normal_weight = nw;
    std::printf("mean |phi - phi_true| on %d^3 over [-1,1]^3, %d points, %s sum%s\n", grid_n, n_points,
                exact ? "exact" : "accelerated", exact ? "" : (" (r_eval = " + std::to_string(r_spacings) + " h)").c_str());
    std::printf("%-12s %10s %10s %10s\n", "shape", "PAT-jet", "SSPD", "SHC");
    for (const char* name : {"sphere", "torus", "capsule", "rounded-box"}) {
        auto s = shapes::by_name(name);
        PointCloud c = shapes::corrupt(s->sample(std::size_t(n_points), 1), bad, 2);
        const TorusField pat(JetFitter(jo).fit(c), opt);
        const double e_pat = mean_error(*s, g, pat.evaluate(g).phi);
        const double e_sspd = mean_error(*s, g, BaselineField(Baseline::Sspd, c, opt).evaluate(g).phi);
        const double e_shc = mean_error(*s, g, BaselineField(Baseline::Shc, c, opt).evaluate(g).phi);
        std::printf("%-12s %10.5f %10.5f %10.5f\n", name, e_pat, e_sspd, e_shc);
    }
    return 0;
}
