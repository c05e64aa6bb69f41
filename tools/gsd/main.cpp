// gsd — generalized signed distance from imperfect geometry, on the command line.
// The volumetric commands (the surface ones are in surface.cpp and swn.cpp): each a CLI11
// subcommand, its options and its run function, over ~800 lines because they share the option
// helpers and the output contract below.
//
// Exit status: 0 success, 1 a data error (message "gsd: error: <file>: <what>"), 2 a usage
// error. Outputs are written only when everything succeeded (atomically), so a failed run
// never leaves a partial file.
#include "cli.hpp"

#include <gsd/baselines.hpp>
#include <gsd/gpu.hpp>
#include <gsd/io.hpp>
#include <gsd/pat.hpp>
#include <gsd/render.hpp>
#include <gsd/shapes.hpp>
#include <gsd/shm.hpp>
#include <gsd/sdf.hpp>
#include <gsd/sums.hpp>
#include <gsd/viz.hpp>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <cstdio>
#include <filesystem>
#include <optional>

using namespace gsd;
using namespace gsd::cli;

namespace {

// ---- shared options ----------------------------------------------------------------------

// The fitter `pat fit` and `pat eval` use unless --fitter says otherwise: TorusNet, which beats
// the jet fit, SSPD and SHC on every row of the validation set (models/MODEL.md).
constexpr const char* kDefaultFitter = "net";

struct FitArgs {
    std::string fitter = kDefaultFitter;
    int k = JetFitterOptions{}.k;
    std::string model;
    std::string device;  // TorusNet's device: `pat fit --device`, or eval's shared --device
    bool keep_normals = false;
    CLI::Option* k_option = nullptr;
    CLI::Option* model_option = nullptr;

    void add_to(CLI::App& app, bool with_device) {
        app.add_option("--fitter", fitter, "Torus fitter: jet (weighted least squares) or net (TorusNet)")
            ->check(CLI::IsMember({"jet", "net"}))->capture_default_str();
        k_option = app.add_option("--k", k, "Neighbors per jet fit, the point itself included (net: fixed by the model)")
                       ->check(CLI::Range(6, 1024))->capture_default_str();
        model_option = app.add_option("--model", model, "TorusNet weights (.safetensors) for --fitter net (default: the shipped model)");
        app.add_flag("--keep-normals", keep_normals,
                     "Fit to the normals as given (by default normals that their neighbours contradict are turned back first: "
                     "a flipped normal's torus has the wrong sign)");
        if (with_device)
            app.add_option("--device", device,
                           "TorusNet's device: auto | gpu | cpu | device index | name substring (default: $GSD_DEVICE or auto)");
    }
    // --keep-normals where no cloud is fitted (a .tori keeps the normals it was fitted with; a
    // grid has none; --expr's clouds are fitted with the defaults) is a usage error, not ignored.
    void check_fits_a_cloud(bool fits) const {
        if (keep_normals && !fits)
            throw CLI::ValidationError("--keep-normals", "only a point cloud INPUT is fitted (a .tori keeps the normals it was fitted with)");
    }
    // Options that belong to the other fitter are usage errors, not silently ignored.
    void check() const {
        if (fitter != "net" && model_option->count() > 0)
            throw CLI::ValidationError("--model", "only --fitter net reads a model");
        if (fitter == "net" && k_option->count() > 0)
            throw CLI::ValidationError("--k", "TorusNet's k is fixed by its model");
    }
    FittedTori fit(PointCloud cloud, const std::string& path) const {
        if (!keep_normals) turn_back_normals(cloud);
        Progress progress("fit " + std::filesystem::path(path).filename().string());
        const auto t0 = std::chrono::steady_clock::now();
        FittedTori t;
        std::string what;
        if (fitter == "net") {
            TorusNetOptions o;
            o.model = model;
            o.device = device;
            const TorusNet net(o);
            what = "net, k=" + std::to_string(net.k());
            if (globals().verbose) note(net.description());
            if (cloud.size() < net.k())  // TorusNet::fit says so too, without naming the file
                throw Error(path, "TorusNet needs at least k = " + std::to_string(net.k()) + " points; the cloud has " +
                                      std::to_string(cloud.size()));
            t = net.fit(cloud, progress.fn());
        } else {
            JetFitterOptions o;
            o.k = k;
            what = "jet, k=" + std::to_string(k);
            t = JetFitter(o).fit(cloud, progress.fn());
        }
        progress.finish();
        if (globals().verbose)
            note("fitted " + std::to_string(t.size()) + " tori (" + what + ") in " + fmt("%.2f s", seconds_since(t0)));
        return t;
    }
};

struct BlendArgs {
    bool exact = false;
    std::string device;
    double r_eval = 0;
    double r_eval_spacings = BlendOptions{}.r_eval_spacings;
    void add_to(CLI::App& app) {
        app.add_flag("--exact", exact, "Sum over every point (eq. 5.6 as written) instead of the accelerated sum");
        app.add_option("--device", device, "auto | gpu | cpu | device index | name substring (default: $GSD_DEVICE or auto)");
        app.add_option("--r-eval", r_eval, "Radius of the accelerated sum (default: --r-eval-spacings × mean spacing)")
            ->check(finite_number())->check(CLI::PositiveNumber);
        app.add_option("--r-eval-spacings", r_eval_spacings, "Radius of the accelerated sum in mean spacings")
            ->check(finite_number())->check(CLI::PositiveNumber)->capture_default_str();
    }
    BlendOptions options() const {
        BlendOptions o;
        o.exact = exact;
        o.device = device;
        o.r_eval = r_eval;
        o.r_eval_spacings = r_eval_spacings;
        return o;
    }
};

bool is_tori_file(const std::string& path) { return io::extension(path) == ".tori"; }

// PAT's outlier defence (OutlierOptions): on by default; --keep-outliers blends every point as
// the thesis does, for comparison. --confidence writes each input point's confidence.
struct OutlierArgs {
    bool keep = false;
    std::string confidence;
    void add_to(CLI::App& app, bool with_keep) {
        if (with_keep)
            app.add_flag("--keep-outliers", keep,
                         "Blend every point, outliers included (disables PAT's outlier defence, for comparison)");
        app.add_option("--confidence", confidence,
                       "Also write each point's confidence: (N,) float32 .npy; 1 trusted, below 0.5 an outlier left out of the blend")
            ->check(output_file({".npy"}));
    }
    OutlierOptions options() const {
        OutlierOptions o;
        o.enabled = !keep;
        return o;
    }
    // The note every PAT command prints, so a user sees what the defence did.
    static void report(const PointConfidence& c, Eigen::Index total) {
        if (c.score.empty()) return;
        note(std::to_string(c.outliers) + " of " + std::to_string(total) +
             " points are outliers (off their neighbors' tori, or isolated) and are not blended" + (c.outliers ? "; --keep-outliers blends them" : ""));
    }
    static void write(const std::string& path, const PointConfidence& c) {
        io::write_npy(path, {c.confidence.size()}, c.confidence);
    }
};

// ---- commands ----------------------------------------------------------------------------

void add_pat(CLI::App& app) {
    auto* pat = app.add_subcommand("pat", "Points as Tori (thesis ch. 5): signed distance from an oriented point cloud");
    pat->require_subcommand(1);

    {
        auto* fit = pat->add_subcommand("fit", "Fit a torus at every point and save them (.tori) so a cloud is fitted once");
        auto input = std::make_shared<std::string>();
        auto output = std::make_shared<std::string>();
        auto args = std::make_shared<FitArgs>();
        auto outliers = std::make_shared<OutlierArgs>();
        fit->add_option("INPUT", *input, "Point cloud with normals (.ply .xyz .xyzn .txt .pc .obj .npy)")->required();
        fit->add_option("-o,--output", *output, "Output .tori file")->required()->check(output_file({".tori"}));
        args->add_to(*fit, true);
        outliers->add_to(*fit, false);
        fit->callback([=] {
            args->check();
            // TorusNet runs on a device: find it while the cloud is read (jets fit on the CPU).
            std::optional<DevicePrefetch> prefetch;
            if (args->fitter == "net") prefetch.emplace(args->device);
            const FittedTori t = args->fit(io::read_point_cloud(*input), *input);
            // The .tori file keeps every point; TorusField scores them again when it loads them.
            std::optional<PointConfidence> conf;
            if (!outliers->confidence.empty()) {
                conf = point_confidence(t);
                OutlierArgs::report(*conf, t.size());
            }
            write_all({{*output, [&] { save_tori(*output, t); }},
                       {outliers->confidence, [&] { OutlierArgs::write(outliers->confidence, *conf); }}});
            note("wrote " + std::to_string(t.size()) + " tori to " + *output +
                 (conf ? " and confidences to " + outliers->confidence : ""));
        });
    }
    {
        auto* eval = pat->add_subcommand("eval", "Evaluate the PAT signed distance on a grid or at query points");
        auto input = std::make_shared<std::string>();
        auto tori = std::make_shared<std::string>();
        auto output = std::make_shared<std::string>();
        auto gradient = std::make_shared<std::string>();
        auto domain = std::make_shared<Domain>();
        auto fit = std::make_shared<FitArgs>();
        auto blend = std::make_shared<BlendArgs>();
        auto outliers = std::make_shared<OutlierArgs>();
        auto* in = eval->add_option("INPUT", *input, "Point cloud with normals (or a .tori file)");
        auto* tin = eval->add_option("--tori", *tori, "Fitted tori from `gsd pat fit`");
        in->excludes(tin);
        eval->add_option("-o,--output", *output, "Output .npy: (N,N,N) for a grid, (M,) for queries; or .vdb (a grid: φ as an OpenVDB level set)")->required()->check(output_file({".npy", ".vdb"}));
        eval->add_option("--gradient", *gradient, "Also write ∇φ: (N,N,N,3) or (M,3) .npy")->check(output_file({".npy"}));
        domain->add_to(*eval, true);
        fit->add_to(*eval, false);
        blend->add_to(*eval);
        outliers->add_to(*eval, true);
        eval->callback([=] {
            if (input->empty() && tori->empty()) throw CLI::RequiredError("INPUT or --tori");
            if (outliers->keep && !outliers->confidence.empty())
                throw CLI::ValidationError("--confidence", "--keep-outliers scores no points");
            fit->check();
            fit->device = blend->device;  // one --device for the fit and the blend
            if (!domain->is_grid() && domain->queries.empty()) throw CLI::RequiredError("--grid or --queries");
            if (!domain->bounds.empty()) bounds_from(domain->bounds, "--bounds");  // before the costly fit
            const DevicePrefetch prefetch(blend->device);  // while the tori are read or fitted
            std::string source = !tori->empty() ? *tori : *input;
            fit->check_fits_a_cloud(!is_tori_file(source));
            FittedTori fitted = is_tori_file(source) ? load_tori(source) : fit->fit(io::read_point_cloud(source), source);
            const std::optional<Box> box = bounding_box(fitted.points);
            const Eigen::Index total = fitted.size();
            const TorusField field(std::move(fitted), blend->options(), outliers->options());
            OutlierArgs::report(field.confidence(), total);
            const bool want_gradient = !gradient->empty();
            evaluate_and_write(
                *domain, box, *output, *gradient,
                [&](const Points& q, const ProgressFn& p) { return field.evaluate(q, want_gradient, p); },
                [&](const GridSpec& g, const ProgressFn& p) { return field.evaluate(g, want_gradient, p); },
                "pat eval", "pat", kBlendGridBytesPerNode + (want_gradient ? kBlendGradientBytesPerNode : 0));
            if (!outliers->confidence.empty()) {
                try {
                    OutlierArgs::write(outliers->confidence, field.confidence());
                } catch (...) {  // all outputs or none
                    remove_output(*output);
                    if (!gradient->empty()) remove_output(*gradient);
                    throw;
                }
                note("wrote " + outliers->confidence);
            }
        });
    }
}

void add_baseline(CLI::App& app) {
    auto* base = app.add_subcommand("baseline", "Classic convolutional signed distances: sspd (eq. 5.9), shc (signed Hopf–Cole, eq. 5.8)");
    auto kind = std::make_shared<std::string>();
    auto input = std::make_shared<std::string>();
    auto output = std::make_shared<std::string>();
    auto domain = std::make_shared<Domain>();
    auto blend = std::make_shared<BlendArgs>();
    base->add_option("METHOD", *kind, "sspd | shc")->required()->check(CLI::IsMember({"sspd", "shc"}));
    base->add_option("INPUT", *input, "Point cloud with normals")->required();
    base->add_option("-o,--output", *output, "Output .npy, or .vdb for a grid (an OpenVDB level set)")->required()->check(output_file({".npy", ".vdb"}));
    domain->add_to(*base, true);
    blend->add_to(*base);
    base->callback([=] {
        if (!domain->is_grid() && domain->queries.empty()) throw CLI::RequiredError("--grid or --queries");
        const DevicePrefetch prefetch(blend->device);
        const PointCloud cloud = io::read_point_cloud(*input);
        const BaselineField field(baseline_from_name(*kind), cloud, blend->options());
        evaluate_and_write(
            *domain, bounding_box(cloud.points), *output, "",
            [&](const Points& q, const ProgressFn& p) { return field.evaluate(q, false, p); },
            [&](const GridSpec& g, const ProgressFn& p) { return field.evaluate(g, false, p); }, "baseline " + *kind, *kind,
            kBlendGridBytesPerNode);
    });
}

std::vector<float> as_float(const io::NpyArray& a) { return std::vector<float>(a.data.begin(), a.data.end()); }

void add_contour(CLI::App& app) {
    auto* c = app.add_subcommand("contour", "Extract a level set of a grid as a closed, oriented triangle mesh");
    auto input = std::make_shared<std::string>();
    auto output = std::make_shared<std::string>();
    auto bounds = std::make_shared<std::vector<double>>();
    auto iso = std::make_shared<double>(0.0);
    c->add_option("GRID", *input, "(N,N,N) float .npy grid")->required();
    c->add_option("--bounds", *bounds, "Grid box x0 y0 z0 x1 y1 z1 (default: from GRID.npy.json, written beside every grid)")->expected(6);
    c->add_option("--iso", *iso, "Level to extract")->capture_default_str();
    c->add_option("-o,--output", *output, "Output mesh (.obj .ply .off .stl)")->required()->check(output_file({".obj", ".ply", ".off", ".stl"}));
    c->callback([=] {
        const io::NpyArray a = io::read_grid(*input);
        const GridSpec g = grid_of(a.shape, *input, *bounds);
        PolygonMesh mesh;
        naming_file(*input, "values", [&] { mesh = contour(g, as_float(a), *iso); });
        if (mesh.face_count() == 0) throw Error(*input, "the level " + fmt("%g", *iso) + " does not cross the grid");
        io::write_mesh(*output, mesh);
        note("wrote " + std::to_string(mesh.face_count()) + " triangles to " + *output);
    });
}

void add_slice(CLI::App& app) {
    auto* s = app.add_subcommand("slice", "Render a planar slice of a grid as a PNG (diverging colors, isolines, zero contour)");
    auto input = std::make_shared<std::string>();
    auto output = std::make_shared<std::string>();
    auto bounds = std::make_shared<std::vector<double>>();
    auto axis = std::make_shared<std::string>("z");
    auto opt = std::make_shared<SliceOptions>();
    s->add_option("GRID", *input, "(N,N,N) float .npy grid")->required();
    s->add_option("--bounds", *bounds, "Grid box x0 y0 z0 x1 y1 z1 (default: from GRID.npy.json, written beside every grid)")->expected(6);
    s->add_option("--axis", *axis, "Slice perpendicular to x, y or z")->check(CLI::IsMember({"x", "y", "z"}))->capture_default_str();
    s->add_option("--at", opt->at, "World coordinate of the slice plane")->required();
    s->add_option("--width", opt->width, "Image width in pixels (default 512, or the grid size if larger)")->check(CLI::Range(0, 16384));
    s->add_option("--range", opt->range, "Colors saturate at ±range (default: max |value| on the slice)")->check(finite_number())->check(CLI::NonNegativeNumber);
    s->add_option("--isolines", opt->isolines, "Isolines on each side of zero")->check(CLI::Range(0, 1000))->capture_default_str();
    auto level = std::make_shared<double>(0.0);
    s->add_option("--level", *level, "Center the colors and the contour on this value instead of 0 (0.5 for winding numbers)")
        ->capture_default_str();
    s->add_option("-o,--output", *output, "Output .png")->required()->check(output_file({".png"}));
    s->callback([=] {
        if (!std::isfinite(*level)) throw Error("--level", "must be finite");
        const io::NpyArray a = io::read_grid(*input);
        const GridSpec g = grid_of(a.shape, *input, *bounds);
        SliceOptions o = *opt;
        o.axis = *axis == "x" ? Axis::X : (*axis == "y" ? Axis::Y : Axis::Z);
        std::vector<float> values = as_float(a);
        for (float& v : values) v = float(double(v) - *level);
        Image image;
        naming_file(*input, "values", [&] { image = render_slice(g, values, o); });
        write_png(*output, image);
        note("wrote " + *output);
    });
}

void add_sample(CLI::App& app) {
    auto* s = app.add_subcommand("sample", "Sample an analytic shape into an oriented point cloud (demo and test data)");
    auto shape = std::make_shared<std::string>();
    auto output = std::make_shared<std::string>();
    auto n = std::make_shared<std::size_t>(2048);
    auto seed = std::make_shared<std::uint64_t>(1);
    auto c = std::make_shared<shapes::Corruption>();
    s->add_option("SHAPE", *shape, "sphere | torus | capsule | rounded-box")
        ->required()->check(CLI::IsMember({"sphere", "torus", "capsule", "rounded-box"}));
    s->add_option("-n,--points", *n, "Number of points")->check(CLI::Range(std::size_t(2), std::size_t(100000000)))->capture_default_str();
    s->add_option("--seed", *seed, "Random seed")->capture_default_str();
    s->add_option("--noise", c->position_noise, "Gaussian noise on positions (× bounding-box diagonal)")->check(finite_number())->check(CLI::Range(0.0, 1.0));
    s->add_option("--normal-noise", c->normal_noise, "Gaussian noise on normals")->check(finite_number())->check(CLI::Range(0.0, 10.0));
    s->add_option("--flip", c->flip_fraction, "Fraction of normals flipped")->check(finite_number())->check(CLI::Range(0.0, 1.0));
    s->add_option("--outliers", c->outlier_fraction, "Fraction of points replaced by outliers")->check(finite_number())->check(CLI::Range(0.0, 1.0));
    s->add_option("--holes", c->holes, "Number of holes cut out")->check(CLI::Range(0, 1000));
    s->add_option("--hole-radius", c->hole_radius, "Hole radius (× bounding-box diagonal)")->check(finite_number())->check(CLI::Range(0.0, 1.0))->capture_default_str();
    s->add_option("-o,--output", *output, "Output point cloud (.ply .xyz .pc .obj .npy)")
        ->required()
        ->check(output_file({".ply", ".xyz", ".xyzn", ".txt", ".pc", ".obj", ".npy"}));
    s->callback([=] {
        const PointCloud clean = shapes::by_name(*shape)->sample(*n, *seed);
        const PointCloud cloud = shapes::corrupt(clean, *c, *seed + 1);
        io::write_point_cloud(*output, cloud);
        note("wrote " + std::to_string(cloud.size()) + " points of a " + *shape + " to " + *output);
    });
}

void add_shm(CLI::App& app) {
    auto* shm = app.add_subcommand("shm", "Signed Heat Method (thesis ch. 4): signed distance from broken meshes and clouds");
    shm->require_subcommand(1);
    auto* grid = shm->add_subcommand("grid", "Solve on a regular grid: INPUT is a mesh (a file with faces) or a point cloud with normals");
    auto inputs = std::make_shared<std::vector<std::string>>();
    auto output = std::make_shared<std::string>();
    auto contour_out = std::make_shared<std::string>();
    auto n = std::make_shared<int>(0);
    auto bounds = std::make_shared<std::vector<double>>();
    auto solver = std::make_shared<std::string>("mg");
    auto opt = std::make_shared<ShmOptions>();
    grid->add_option("INPUT", *inputs, "Mesh(es) and/or point cloud(s); several are combined into one source")->required();
    grid->add_option("--grid", *n, "Grid nodes per axis (N ≤ 1290: 2^31 nodes)")->required()->check(CLI::Range(4, 1290));
    grid->add_option("--bounds", *bounds, "Grid box x0 y0 z0 x1 y1 z1 (default: the input's bounding cube + 10%)")->expected(6);
    grid->add_option("-o,--output", *output, "Output (N,N,N) float32 .npy, or .vdb (φ as an OpenVDB level set)")->required()->check(output_file({".npy", ".vdb"}));
    grid->add_option("--t-coef", opt->t_coef, "Diffusion time t = t_coef · h² (h: mean spacing or edge length)")
        ->check(finite_number())->check(CLI::Range(1e-6, 1e6))->capture_default_str();
    grid->add_option("--sum-tolerance", opt->sum_tolerance, "Step 1 accuracy: error bound of each expansion, as a fraction of a sheet's field (smaller: slower, closer to the exact integral)")
        ->check(CLI::Range(1e-9, 1.0))->capture_default_str();
    grid->add_option("--solver", *solver, "Poisson solver: mg (multigrid), cg, direct (CHOLMOD, small grids)")
        ->check(CLI::IsMember({"mg", "cg", "direct"}))->capture_default_str();
    grid->add_flag("--f-cycle", opt->f_cycle, "Multigrid F-cycles instead of V-cycles");
    grid->add_option("--tolerance", opt->tolerance, "Relative residual to stop at")->check(finite_number())->check(CLI::PositiveNumber)->capture_default_str();
    grid->add_option("--fit-zero-set", opt->fit_zero_set, "Fit φ = 0 on the source softly with this weight (0: shift by the mean)")
        ->check(finite_number())->check(CLI::NonNegativeNumber)->capture_default_str();
    grid->add_option("--veto-winding", opt->veto_winding,
                     "Outside veto: turn outside the inside nodes far from the input (see --veto-margin) where its winding number is below this (0: no veto)")
        ->check(CLI::Range(0.0, 0.999))->capture_default_str();
    grid->add_option("--veto-margin", opt->veto_margin,
                     "Outside veto: a node is far when its distance to the input exceeds 3|φ| + this × the input's largest extent")
        ->check(finite_number())->check(CLI::PositiveNumber)->capture_default_str();
    grid->add_flag("--redistance", opt->redistance,
                   "Keep SHM's sign and zero set, and make |φ| the exact distance to that zero set (a true SDF)");
    auto keep_normals = std::make_shared<bool>(false);
    grid->add_flag("--keep-normals", *keep_normals,
                   "Keep a cloud's normals as they are (by default normals that their neighbours contradict are turned back first)");
    auto keep_outliers = std::make_shared<bool>(false);
    grid->add_flag("--keep-outliers", *keep_outliers,
                   "Keep every point of a cloud (by default points that PAT's outlier scores reject are left out before step 1)");
    grid->add_option("--device", opt->device, "auto | gpu | cpu | device index | name substring");
    grid->add_option("--contour", *contour_out, "Also write the zero level set as a mesh (.obj .ply .off .stl)")->check(output_file({".obj", ".ply", ".off", ".stl"}));
    auto sharpen = std::make_shared<bool>(false);
    auto sharpen_opt = std::make_shared<SharpenOptions>();
    grid->add_flag("--sharpen", *sharpen,
                   "Distance sharpening (thesis eq. 4.13): the sharpest φ with |∇φ| ≤ 1, zero on the input and φ's sign, by PDHG from the solve's φ");
    grid->add_option("--iterations", sharpen_opt->iterations, "With --sharpen: PDHG iterations (0: 24 × N)")
        ->check(CLI::Range(0, 1000000))->capture_default_str();
    grid->callback([=] {
        check_grid_output(*output, true);
        const DevicePrefetch prefetch(opt->device);
        GridSpec g;
        // The grid's size is checked before the source's cost; its default box is the source's
        // (as Python's and shm adaptive's), once a cloud's outliers are left out.
        const LoadedShmSource loaded = load_shm_source(*inputs, [&](const Box& box0) {
            g = bounds->empty() ? GridSpec::cube(*n, default_bounds(box0)) : GridSpec::cube(*n, bounds_from(*bounds, "--bounds"));
            g.validate();
            check_grid_memory(g, kShmGridBytesPerNode);
        }, !*keep_outliers, !*keep_normals);
        const ShmSource& src = loaded.source;
        if (bounds->empty()) {
            g = GridSpec::cube(*n, shm_default_bounds(src));
            g.validate();
            note("grid bounds (saved in the grid's .json sidecar, which contour and slice read): " + bounds_text(g.box));
        }
        opt->solver = poisson_solver_from_name(*solver);
        Progress progress("shm grid");
        const SignedHeatGrid shm(src, g, *opt);
        ShmResult r = shm.solve(progress.fn());
        progress.finish();
        if (*sharpen) {
            Progress sharpening("shm grid --sharpen");
            sharpen_opt->device = opt->device;
            SharpenResult sr = shm.sharpen(r.phi, *sharpen_opt, sharpening.fn());
            sharpening.finish();
            note("sharpened: " + std::to_string(sr.iterations) + " PDHG iterations on " + sr.device + " in " +
                 fmt("%.2f s", sr.seconds) + ", largest slope " + fmt("%.3f", sr.max_slope) + ", " +
                 std::to_string(sr.zero_set_rows) + " cells on the input");
            r.phi = std::move(sr.phi);
        }
        if (globals().verbose) {
            note("source: " + std::to_string(src.size()) + " elements, h = " + fmt("%.4g", src.spacing) + "; grid " +
                 std::to_string(*n) + "^3 on " + r.device);
            note("step 1 (diffuse): " + fmt("%.2f s", r.seconds_diffuse) + ", " + std::to_string(r.exact_nodes) + " of " +
                 std::to_string(g.node_count()) + " nodes summed exactly, " + std::to_string(r.kernel_terms) + " kernel terms");
            note("step 1's parts: setup " + fmt("%.2f s", r.seconds_setup) + ", sums " + fmt("%.2f s", r.seconds_sums) +
                 ", interpolation " + fmt("%.2f s", r.seconds_diffuse - r.seconds_setup - r.seconds_sums));
            std::string fit;
            if (!r.fit_history.empty())
                fit = "; zero-set fit " + std::to_string(r.fit_history.size()) + " iterations, relative residual " +
                      fmt("%.2e", r.fit_history.back());
            note("step 3 (solve): " + fmt("%.2f s", r.seconds_solve) + ", " + std::to_string(r.residual_history.size()) +
                 " iterations, relative residual " + fmt("%.2e", r.residual_history.empty() ? 0.0 : r.residual_history.back()) + fit);
            note("step 3's parts: Poisson " + fmt("%.2f s", r.seconds_poisson) + ", zero-set fit " + fmt("%.2f s", r.seconds_fit) +
                 ", outside veto " + fmt("%.2f s", r.seconds_veto));
            if (opt->veto_winding > 0) note("outside veto: " + std::to_string(r.vetoed_nodes) + " nodes turned outside");
            note("peak memory: " + peak_memory());
        }
        if (!r.residual_history.empty() && r.residual_history.back() > opt->tolerance)
            note("warning: the solver stopped at relative residual " + fmt("%.2e", r.residual_history.back()) + " (tolerance " +
                 fmt("%.1e", opt->tolerance) + ")");
        if (!r.fit_history.empty() && r.fit_history.back() > opt->tolerance)
            note("warning: the zero-set fit stopped at relative residual " + fmt("%.2e", r.fit_history.back()) + " (tolerance " +
                 fmt("%.1e", opt->tolerance) + ")");
        // Build everything before writing anything: no partial outputs.
        PolygonMesh zero;
        if (!contour_out->empty()) {
            zero = contour(g, r.phi, 0.0);
            if (zero.face_count() == 0) throw Error(*contour_out, "the zero level set does not cross the grid");
        }
        write_grid(*output, g, r.phi, 1, "shm");
        if (!contour_out->empty()) {
            try {
                io::write_mesh(*contour_out, zero);
            } catch (...) {
                remove_output(*output);
                throw;
            }
        }
        note("wrote " + *output + (contour_out->empty() ? "" : " and " + *contour_out));
    });
    add_shm_adaptive(*shm);
    add_shm_surface(*shm);
}

void add_mesh(CLI::App& app) {
    auto* m = app.add_subcommand("mesh", "Make a closed mesh of an analytic shape, or damage a mesh (holes, flipped faces, noise)");
    auto shape = std::make_shared<std::string>();
    auto from = std::make_shared<std::string>();
    auto output = std::make_shared<std::string>();
    auto resolution = std::make_shared<int>(48);
    auto seed = std::make_shared<std::uint64_t>(1);
    auto c = std::make_shared<shapes::MeshCorruption>();
    auto* s = m->add_option("SHAPE", *shape, "sphere | torus | capsule | rounded-box | double-torus (genus 2, for "
                                             "curves that bound nothing)")
                  ->check(CLI::IsMember({"sphere", "torus", "capsule", "rounded-box", "double-torus"}));
    auto* f = m->add_option("--from", *from, "Damage this mesh instead of making one");
    s->excludes(f);
    m->add_option("-r,--resolution", *resolution, "Contouring grid nodes per axis")->check(CLI::Range(8, 1024))->capture_default_str();
    m->add_option("--holes", c->holes, "Number of holes")->check(CLI::Range(0, 1000));
    m->add_option("--hole-area", c->hole_area, "Fraction of the area the holes remove")->check(finite_number())->check(CLI::Range(0.0, 0.95))->capture_default_str();
    m->add_option("--flip", c->flip_fraction, "Fraction of faces flipped")->check(finite_number())->check(CLI::Range(0.0, 1.0));
    m->add_option("--noise", c->vertex_noise, "Gaussian noise on vertices (× bounding-box diagonal)")->check(finite_number())->check(CLI::Range(0.0, 1.0));
    m->add_option("--seed", *seed, "Random seed")->capture_default_str();
    m->add_option("-o,--output", *output, "Output mesh (.obj .ply .off .stl)")->required()->check(output_file({".obj", ".ply", ".off", ".stl"}));
    m->callback([=] {
        if (shape->empty() && from->empty()) throw CLI::RequiredError("SHAPE or --from");
        const PolygonMesh base = !from->empty()             ? io::read_mesh(*from)
                                 : *shape == "double-torus" ? shapes::double_torus_mesh(std::max(*resolution, 16))
                                                            : shapes::mesh(*shapes::by_name(*shape), *resolution);
        const PolygonMesh out = shapes::corrupt(base, *c, *seed);
        io::write_mesh(*output, out);
        note("wrote " + std::to_string(out.face_count()) + " faces to " + *output);
    });
}

void add_winding(CLI::App& app) {
    auto* wn = app.add_subcommand("winding", "Generalized winding number (≈1 inside, 0 outside) of a mesh in any state or an oriented cloud: fast (treecode) or exact");
    auto input = std::make_shared<std::string>();
    auto output = std::make_shared<std::string>();
    auto domain = std::make_shared<Domain>();
    auto opt = std::make_shared<WindingOptions>();
    wn->add_option("INPUT", *input, "Mesh (a file with faces: any holes, flips, self-intersections) or point cloud with normals")->required();
    wn->add_option("-o,--output", *output, "Output float32 .npy: (N,N,N) for a grid, (M,) for queries; or .vdb for a grid (a float grid named winding)")->required()->check(output_file({".npy", ".vdb"}));
    domain->add_to(*wn, true);
    wn->add_flag("--exact", opt->exact, "Sum every element exactly (O(queries × elements)): the reference");
    wn->add_option("--beta", opt->beta, "Opening criterion: a cluster is summed by its expansion only farther than β × its radius")
        ->check(finite_number())->check(CLI::Range(1.01, 100.0))->capture_default_str();
    wn->add_option("--tolerance", opt->tolerance, "... and only if its truncation error bound is below this (0: β alone, as libigl)")
        ->check(finite_number())->check(CLI::Range(0.0, 1.0))->capture_default_str();
    wn->add_option("--device", opt->device, "auto | gpu | cpu | device index | name substring");
    wn->callback([=] {
        if (!domain->is_grid() && domain->queries.empty()) throw CLI::RequiredError("--grid or --queries");
        const DevicePrefetch prefetch(opt->device);
        OrientedElements elements;
        if (io::file_has_faces(*input)) {
            elements = OrientedElements::from_mesh(io::read_mesh(*input));
        } else {
            try {
                elements = OrientedElements::from_cloud(io::read_point_cloud(*input));
            } catch (const Error& e) {
                throw Error(*input, e.what());
            }
        }
        const WindingField field(std::move(elements), *opt);
        // The tree, its upload and the kernel's pipeline while the queries are read.
        const std::future<void> prepared = prepare_in_background([&field] { field.prepare(); });
        auto eval = [&](const Points& q, const ProgressFn& p) {
            WindingResult r = field.winding_numbers(q, p);
            FieldValues v;
            v.phi.assign(r.w.begin(), r.w.end());
            v.device = r.device;
            if (globals().verbose)
                note(std::to_string(field.elements().size()) + " elements, " + fmt("%.4g", double(r.terms) / std::max<double>(1, double(q.rows()))) +
                     " terms per query");
            return v;
        };
        evaluate_and_write(
            *domain, bounding_box(field.elements().corners), *output, "", eval,
            [&](const GridSpec& g, const ProgressFn& p) { return eval(g.nodes(), p); }, "winding", "winding",
            kWindingGridBytesPerNode);
    });
}

// ---- gsd render --------------------------------------------------------------------------

void add_render(CLI::App& app) {
    auto* r = app.add_subcommand(
        "render", "Picture of a field's zero level set, sphere-traced on a Vulkan device or the CPU: PAT from a cloud or "
                  ".tori, a grid (trilinear), or a field expression (--expr), shaded by its gradient");
    auto input = std::make_shared<std::string>();
    auto tori = std::make_shared<std::string>();
    auto output = std::make_shared<std::string>();
    auto bounds = std::make_shared<std::vector<double>>();
    auto size = std::make_shared<std::vector<int>>(std::vector<int>{800, 600});
    auto view = std::make_shared<std::vector<double>>();
    auto up = std::make_shared<std::vector<double>>();
    auto color = std::make_shared<std::string>();
    auto opt = std::make_shared<FieldRenderOptions>();
    opt->supersample = 2;
    auto fit = std::make_shared<FitArgs>();
    auto blend = std::make_shared<BlendArgs>();
    auto outliers = std::make_shared<OutlierArgs>();
    auto expr = std::make_shared<std::string>();
    auto* in = r->add_option("INPUT", *input, "Point cloud with normals, a .tori file, or an (N,N,N) .npy grid of φ");
    auto* tin = r->add_option("--tori", *tori, "Fitted tori from `gsd pat fit`");
    auto* ein = r->add_option("--expr", *expr,
                              "Or a field made of fields, as `gsd field` reads it: \"union(a.tori, offset(b.obj, 0.05))\" "
                              "(docs/field.md); marched through its device program where --device finds a device, else on the CPU");
    in->excludes(tin);
    ein->excludes(in)->excludes(tin);
    auto morphology = std::make_shared<MorphologyArgs>();
    add_morphology_grid(*r, *morphology);
    r->add_option("-o,--output", *output, "Output .png")->required()->check(output_file({".png"}));
    r->add_option("--size", *size, "Image width and height in pixels")->expected(2)->check(CLI::Range(1, 16384))->capture_default_str();
    r->add_option("--view-from", *view, "Direction the camera looks from, toward the center (default 1 0.8 1.6)")->expected(3);
    auto camera = std::make_shared<std::vector<double>>();
    r->add_option("--camera", *camera, "Or the camera's position x y z, looking at the center (no automatic framing)")
        ->expected(3)->excludes("--view-from");
    r->add_option("--up", *up, "Up direction of the picture (default 0 1 0)")->expected(3);
    r->add_option("--fov", opt->fov_degrees, "Vertical field of view in degrees")->check(finite_number())->check(CLI::Range(1.0, 170.0))->capture_default_str();
    r->add_option("--supersample", opt->supersample, "Rays per pixel along each axis (antialiasing)")->check(CLI::Range(1, 4))->capture_default_str();
    r->add_option("--max-steps", opt->max_steps, "March steps per ray")->check(CLI::Range(1, 100000))->capture_default_str();
    r->add_option("--step-scale", opt->step_scale, "Each step advances this × |φ|")->check(finite_number())->check(CLI::Range(0.01, 1.0))->capture_default_str();
    r->add_flag("!--no-empty-skip", opt->skip_empty_space,
                "Blended fields: march every ray through the whole box, without first finding the cells that hold no surface");
    r->add_option("--bounds", *bounds,
                  "Box the rays march in, x0 y0 z0 x1 y1 z1 (default: a grid's own bounds from GRID.npy.json; for PAT the "
                  "cloud's bounding cube + 10%)")->expected(6);
    r->add_option("--color", *color, "Color the surface by a second grid (.npy with its sidecar), diverging colors");
    r->add_option("--color-range", opt->color_range, "--color saturates at ±range (default: max |value| on the surface)")
        ->check(finite_number())->check(CLI::NonNegativeNumber);
    fit->add_to(*r, false);
    blend->add_to(*r);
    outliers->add_to(*r, true);
    r->callback([=] {
        if (input->empty() && tori->empty() && expr->empty()) throw CLI::RequiredError("INPUT, --tori or --expr");
        fit->check();
        fit->device = blend->device;
        opt->width = (*size)[0];
        opt->height = (*size)[1];
        if (!view->empty()) opt->view_from = {(*view)[0], (*view)[1], (*view)[2]};
        if (!up->empty()) opt->up = {(*up)[0], (*up)[1], (*up)[2]};
        if (!camera->empty()) opt->eye = Eigen::Vector3d((*camera)[0], (*camera)[1], (*camera)[2]);
        opt->device = blend->device;
        std::optional<Box> box;
        if (!bounds->empty()) box = bounds_from(*bounds, "--bounds");
        const DevicePrefetch prefetch(blend->device);  // while the input is read and its field made
        // The color field, read (and checked) before the costly work.
        std::optional<GridSpec> color_grid;
        std::vector<float> color_values;
        if (!color->empty()) {
            const io::NpyArray a = io::read_grid(*color);
            color_grid = grid_of(a.shape, *color, {});
            color_values = as_float(a);
            opt->color_grid = &*color_grid;
            opt->color_values = &color_values;
        }
        const auto t0 = std::chrono::steady_clock::now();
        RenderedField picture;
        std::optional<Progress> progress;  // started once the inputs are read (and fitted)
        auto start = [&] { return progress.emplace("render " + std::filesystem::path(*output).filename().string()).fn(); };
        const std::string source = !tori->empty() ? *tori : *input;
        fit->check_fits_a_cloud(expr->empty() && io::extension(source) != ".npy" && !is_tori_file(source));
        if (!expr->empty()) {
            const ParsedField p = parse_field_expression(*expr, blend->device, *morphology);
            if (!box) box = default_bounds(p.box);
            picture = render_field(*p.field, *box, *opt, start());
        } else if (io::extension(source) == ".npy") {
            const io::NpyArray a = io::read_grid(source);
            const GridSpec g = grid_of(a.shape, source, *bounds);
            const std::vector<float> values = as_float(a);
            naming_file(source, "values", [&] { picture = render_field(g, values, *opt, start()); });
        } else {
            FittedTori fitted = is_tori_file(source) ? load_tori(source) : fit->fit(io::read_point_cloud(source), source);
            if (!box) box = default_bounds(bounding_box(fitted.points));
            const Eigen::Index total = fitted.size();
            const TorusField field(std::move(fitted), blend->options(), outliers->options());
            OutlierArgs::report(field.confidence(), total);
            picture = render_field(field, *box, *opt, start());
        }
        progress->finish();
        if (globals().verbose && picture.empty_cells) note("empty-space skipping: " + std::to_string(picture.empty_cells) + " cells hold no surface");
        write_png(*output, picture.image);
        note("wrote " + *output + " (" + std::to_string(picture.image.width) + "×" + std::to_string(picture.image.height) +
             ", " + fmt("%.1f", 100 * picture.hit_fraction) + " % of rays on the surface, marched on " + picture.device +
             (globals().verbose ? ", " + fmt("%.2f s", seconds_since(t0)) : std::string()) + ")");
    });
}

void add_info(CLI::App& app) {
    auto* info = app.add_subcommand("info", "Version, the Vulkan devices seen, and what --device auto picks");
    info->callback([] {
        std::printf("gsd %s\n", std::string(version()).c_str());
        const gpu::Inventory inv = gpu::list_devices();
        if (inv.devices.empty()) std::printf("Vulkan: %s\n", inv.problem.empty() ? "no devices" : inv.problem.c_str());
        for (const auto& d : inv.devices) {
            std::string ops;  // the subgroup operations gsd's kernels use
            for (const auto& [has, name] : {std::pair{d.subgroup_vote, "vote"}, std::pair{d.subgroup_ballot, "ballot"},
                                            std::pair{d.subgroup_arithmetic, "arithmetic"}, std::pair{d.subgroup_shuffle, "shuffle"}})
                if (has) ops += (ops.empty() ? ": " : ", ") + std::string(name);
            std::printf("  device %u: %s (%s, Vulkan %s, %.1f GiB, subgroup %u%s)%s\n", d.index, d.name.c_str(), d.type.c_str(),
                        d.api_version.c_str(), double(d.device_local_bytes) / (1u << 30), d.subgroup_size, ops.c_str(),
                        d.usable ? "" : (" — unusable: " + d.why_not).c_str());
        }
        const gpu::Selection sel = gpu::select("auto");
        std::printf("--device auto: %s%s\n", sel.device_name.c_str(), sel.context ? "" : " (the CPU path)");
        const gpu::Selection any = gpu::select("gpu");
        std::printf("--device gpu:  %s%s\n", any.device_name.c_str(), any.context ? "" : " (the CPU path)");
        if (gpu::validation_active()) std::printf("Vulkan validation layer: on\n");
    });
}

}  // namespace

namespace {

// The library's errors name the option field at fault (ShmOptions::t_coef); the CLI reports
// the flag that sets it.
std::string flag_for(const std::string& where) {
    static const std::pair<const char*, const char*> flags[] = {
        {"GridSpec", "--grid"},
        {"GridSpec::box", "--bounds"},
        {"ShmOptions::t_coef", "--t-coef"},
        {"ShmOptions::fit_zero_set", "--fit-zero-set"},
        {"ShmOptions::veto_winding", "--veto-winding"},
        {"ShmOptions::veto_margin", "--veto-margin"},
        {"ShmOptions::sum_tolerance", "--sum-tolerance"},
        {"ShmOptions::solver", "--solver"},
        {"solver", "--solver"},
        {"JetFitterOptions::k", "--k"},
        {"WindingOptions::beta", "--beta"},
        {"WindingOptions::tolerance", "--tolerance"},
        {"device", "--device"},
        {"FieldRenderOptions::width", "--size"},
        {"FieldRenderOptions::view_from", "--view-from"},
        {"FieldRenderOptions::up", "--up"},
        {"FieldRenderOptions::eye", "--camera"},
        {"FieldRenderOptions::color_range", "--color-range"},
        {"FieldRenderOptions::color_values", "--color"},
        {"box", "--bounds"},
        {"SurfaceShmSetup::t_coef", "--t-coef"},
        {"SurfaceShmSetup::refine_min_angle", "--min-angle"},
        {"SurfaceShmOptions::soft_weight", "--soft-weight"},
        {"SharpenOptions::iterations", "--iterations"},
        {"SurfaceSharpenOptions::iterations", "--iterations"},
        {"SwnOptions::curve_weight", "--curve-weight"},
    };
    for (const auto& [field, flag] : flags)
        if (where == field) return flag;
    return where;
}

}  // namespace

// A list option (--curves a.txt b.txt …) takes every value up to the next flag, so a
// positional written after it ends up in the list and is then missing. Says so when a required
// positional got nothing and a list option's last value is an existing mesh file.
void hint_swallowed_positional(const CLI::App& app) {
    std::vector<const CLI::App*> stack{&app};
    while (!stack.empty()) {
        const CLI::App* a = stack.back();
        stack.pop_back();
        for (const CLI::App* sub : a->get_subcommands()) stack.push_back(sub);
        const auto options = a->get_options();
        const bool positional_missing = std::any_of(options.begin(), options.end(), [](const CLI::Option* o) {
            return o->get_positional() && o->get_required() && o->count() == 0;
        });
        if (!positional_missing) continue;
        for (const CLI::Option* o : options) {
            if (o->get_positional() || o->get_items_expected_max() < 2 || o->results().size() < 2) continue;
            const std::string& last = o->results().back();
            bool mesh = false;
            try {
                mesh = io::file_has_faces(last);
            } catch (const Error&) {  // not a readable mesh: no hint
            }
            if (!mesh) continue;
            std::fprintf(stderr, "gsd: %s took '%s' as one of its files: put the positional arguments before %s, "
                                 "or end its list with --\n",
                         o->get_name().c_str(), last.c_str(), o->get_name().c_str());
            return;
        }
    }
}

int main(int argc, char** argv) {
    keep_freed_memory();
    quiet_blas_threads();
    place_threads(argc, argv);
    CLI::App app{"gsd — generalized signed distance and winding numbers from imperfect geometry"};
    app.set_version_flag("--version", std::string(version()));
    app.require_subcommand(1);
    app.fallthrough();
    app.add_flag("-q,--quiet", globals().quiet, "No progress or notes on stderr");
    app.add_flag("-v,--verbose", globals().verbose, "Timings and devices on stderr");
    add_pat(app);
    add_baseline(app);
    add_contour(app);
    add_slice(app);
    add_shm(app);
    add_sample(app);
    add_mesh(app);
    add_winding(app);
    add_sdf(app);
    add_field(app);
    add_curve(app);
    add_swn(app);
    add_render(app);
    add_info(app);
    // The library's one-line notices (device fallback, …) go where the CLI's own do: -q silences them.
    set_log_sink([](std::string_view message) { note(std::string(message)); });
    try {
        globals().argv.assign(argv, argv + argc);
        globals().app = &app;
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        app.exit(e);
        if (dynamic_cast<const CLI::RequiredError*>(&e)) hint_swallowed_positional(app);
        return kUsage;
    } catch (const Error& e) {
        if (e.where().empty()) std::fprintf(stderr, "gsd: error: %s\n", e.what());
        else std::fprintf(stderr, "gsd: error: %s: %s\n", flag_for(e.where()).c_str(), e.what());
        return kDataError;
    } catch (const std::bad_alloc&) {
        std::fprintf(stderr, "gsd: error: out of memory\n");
        return kDataError;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "gsd: error: %s\n", e.what());
        return kDataError;
    }
    return kOk;
}
