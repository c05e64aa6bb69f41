// gsd-accuracy: mean |φ − φ_true| of PAT-jet, SSPD and SHC on the analytic shapes, on a grid
// over [−1, 1]³ (thesis §5.3 protocol). Prints a table; used for the closing notes and for
// choosing defaults. Not a test: tests assert fixed bounds, this measures.
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
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto next = [&] { return std::string(argv[++i]); };
        if (a == "--points") n_points = std::stoi(next());
        else if (a == "--grid") grid_n = std::stoi(next());
        else if (a == "--r-spacings") r_spacings = std::stod(next());
        else if (a == "--device") device = next();
        else if (a == "--k") k = std::stoi(next());
        else if (a == "--sigma") sigma = std::stod(next());
        else if (a == "--normal-weight") nw = std::stod(next());
        else if (a == "--exact") exact = true;
        else if (a == "--noise") bad.position_noise = std::stod(next());
        else if (a == "--normal-noise") bad.normal_noise = std::stod(next());
        else if (a == "--flip") bad.flip_fraction = std::stod(next());
        else if (a == "--holes") bad.holes = std::stoi(next());
        else { std::fprintf(stderr, "usage: gsd-accuracy [--points N] [--grid N] [--r-spacings S] [--k K] [--sigma F] [--normal-weight W] [--exact] [--device D] [--noise S] [--normal-noise S] [--flip F] [--holes H]\n"); return 2; }
    }
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
