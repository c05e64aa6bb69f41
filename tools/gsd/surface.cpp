// `gsd shm surface`: the Signed Heat Method on a triangle mesh — geodesic signed distance to
// (broken) curves and points on it, with optional pictures and derived outputs.
#include "cli.hpp"

#include <gsd/io.hpp>
#include <gsd/surface.hpp>
#include <gsd/viz.hpp>

#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <optional>

namespace gsd::cli {

namespace {

struct SurfaceArgs {
    std::string mesh, points, output, colored, isolines, render;
    std::vector<std::string> curves;
    bool is_unsigned = false;
    std::string level_set = "zero";
    double isoline_spacing = 0;
    SurfaceShmOptions options;
    SurfaceShmSetup setup;
    bool sharpen = false;
    SurfaceSharpenOptions sharpening;
};

/// A round spacing giving about `count` levels over [lo, hi].
double nice_spacing(double lo, double hi, int count) {
    const double raw = (hi - lo) / count;
    if (!(raw > 0) || !std::isfinite(raw)) return 1.0;
    const double p = std::pow(10.0, std::floor(std::log10(raw)));
    for (double m : {1.0, 2.0, 5.0, 10.0})
        if (m * p >= raw) return m * p;
    return 10 * p;
}

/// Isolines of φ at every multiple of `spacing` as OBJ polylines, one group per level.
std::string isolines_obj(const SurfaceMesh& mesh, const std::vector<double>& phi, double spacing) {
    double lo = INFINITY, hi = -INFINITY;
    for (double x : phi)
        if (std::isfinite(x)) {
            lo = std::min(lo, x);
            hi = std::max(hi, x);
        }
    std::vector<double> finite = phi;
    for (double& x : finite)
        if (!std::isfinite(x)) x = hi + spacing;  // vertices without a value never cross a level
    std::string out = "# isolines of the surface signed distance written by gsd: one group per level\n";
    std::size_t vertices = 0;
    // Levels k·spacing in [lo, hi], counted in double: k itself can be past any integer type
    // (φ ≈ 10 with a spacing of 1e-18) while the count stays small (the caller caps it).
    const double first = std::ceil(lo / spacing), count = std::floor(hi / spacing) - first + 1;
    for (double i = 0; i < count; ++i) {
        const double level = (first + i) * spacing;
        const std::vector<SurfaceCurve> curves = level_set_curves(mesh, finite, level);
        if (curves.empty()) continue;
        char name[64];
        std::snprintf(name, sizeof(name), "g level_%.6g\n", level);
        out += name;
        for (const SurfaceCurve& c : curves) {
            std::string line = "l";
            for (const SurfacePoint& p : c.nodes) {
                const Eigen::Vector3d x = position(mesh, p);
                char v[128];
                std::snprintf(v, sizeof(v), "v %.9g %.9g %.9g\n", x.x(), x.y(), x.z());
                out += v;
                line.append(" ").append(std::to_string(++vertices));
            }
            out.append(line).append("\n");
        }
    }
    return out;
}

/// The sources the command solves for: curves from --curves (or the mesh's own `l` lines),
/// points from --points.
SurfaceSources load_sources(const SurfaceArgs& a, const SurfaceMesh& mesh) {
    SurfaceSources src;
    for (const std::string& file : a.curves) {
        SurfaceSources more = read_surface_curves(file, mesh);
        src.curves.insert(src.curves.end(), more.curves.begin(), more.curves.end());
    }
    if (a.curves.empty() && io::extension(a.mesh) == ".obj" && a.points.empty()) src = read_surface_curves(a.mesh, mesh);
    if (!a.points.empty()) src.points = read_surface_points(a.points, mesh);
    for (SurfaceCurve& c : src.curves) c.is_signed = !a.is_unsigned;
    return src;
}

void report(const SurfaceArgs& a, const SurfaceMesh& mesh, const SignedHeatSurface& shm, const SurfaceShmResult& r,
            double load_seconds) {
    if (globals().verbose) {
        const SurfaceMesh::Summary s = mesh.summary();
        note("mesh: " + std::to_string(mesh.vertex_count()) + " vertices, " + std::to_string(mesh.face_count()) +
             " faces (" + std::to_string(mesh.triangle_count()) + " triangles), " + std::to_string(mesh.edge_count()) +
             " edges; " + std::to_string(s.boundary_edges) + " boundary, " + std::to_string(s.nonmanifold_edges) +
             " nonmanifold, " + std::to_string(s.misoriented_edges) + " misoriented edges; " +
             std::to_string(s.components) + " components, " + std::to_string(s.degenerate_triangles) +
             " degenerate triangles");
        note("t = " + fmt("%.4g", shm.diffusion_time()) + " (t_coef " + fmt("%g", a.setup.t_coef) +
             ", mean edge length " + fmt("%.4g", shm.mean_edge_length()) + ")" +
             (a.setup.intrinsic_delaunay ? ", intrinsic Delaunay: " + std::to_string(r.flips) + " flips, " +
                                               std::to_string(r.solve_vertices) + " vertices"
                                         : std::string()));
        note("load " + fmt("%.3f s", load_seconds) + ", factor " + fmt("%.3f s", r.seconds_factor) + ", diffuse " +
             fmt("%.3f s", r.seconds_diffuse) + ", integrate " + fmt("%.3f s", r.seconds_integrate));
        if (r.constraints)
            note(std::to_string(r.constraints) + " constraint rows, max |residual| " + fmt("%.2e", r.constraint_residual) +
                 " after " + std::to_string(r.constraint_iterations) + " iterations");
        note("peak memory: " + peak_memory());
    }
    if (r.unreached_vertices)
        note("warning: " + std::to_string(r.unreached_vertices) +
             " vertices lie in mesh components that no source reaches: φ there is not a distance");
    const std::size_t unreferenced = mesh.summary().unreferenced_vertices;
    if (unreferenced) note("note: " + std::to_string(unreferenced) + " vertices are on no face: φ is NaN there");
}


void run(const SurfaceArgs& a) {
    if (a.curves.empty() && a.points.empty() && is_curveless_mesh_format(a.mesh))
        throw CLI::RequiredError("--curves or --points (or an .obj mesh with `l` lines)");
    if (!a.render.empty() && io::extension(a.render) != ".png") throw CLI::ValidationError("--render", "must be a .png file");
    if (!a.colored.empty() && io::extension(a.colored) != ".ply") throw CLI::ValidationError("--colored", "must be a .ply file");
    if (!a.isolines.empty() && io::extension(a.isolines) != ".obj") throw CLI::ValidationError("--isolines", "must be an .obj file");
    if (io::extension(a.output) != ".npy") throw CLI::ValidationError("--output", "must be a .npy file");
    const auto t0 = std::chrono::steady_clock::now();
    SurfaceMesh mesh(io::read_mesh(a.mesh), a.mesh);
    const SurfaceSources sources = load_sources(a, mesh);
    const double load_seconds = seconds_since(t0);

    SurfaceShmOptions options = a.options;
    options.level_set = level_set_from_name(a.level_set);
    Progress progress("shm surface");
    std::optional<SignedHeatSurface> shm;
    SurfaceShmResult r;
    naming_file(a.mesh, "mesh", [&] {
        shm.emplace(mesh, a.setup);
        r = shm->solve(sources, options, progress.fn());
    });
    progress.finish();
    report(a, mesh, *shm, r, load_seconds);
    if (a.sharpen) {
        Progress sharpening("shm surface --sharpen");
        SurfaceSharpenResult sr = shm->sharpen(r.phi, sources, a.sharpening, sharpening.fn());
        sharpening.finish();
        note("sharpened: " + std::to_string(sr.iterations) + " PDHG iterations in " + fmt("%.2f s", sr.seconds) +
             ", largest slope " + fmt("%.3f", sr.max_slope));
        r.phi = std::move(sr.phi);
    }

    // Build every output in memory first, then write them all (or none).
    const auto t1 = std::chrono::steady_clock::now();
    std::vector<float> phi(r.phi.begin(), r.phi.end());
    double lo = INFINITY, hi = -INFINITY, top = 0;
    for (double x : r.phi)
        if (std::isfinite(x)) {
            lo = std::min(lo, x);
            hi = std::max(hi, x);
            top = std::max(top, std::abs(x));
        }
    const double spacing = a.isoline_spacing > 0 ? a.isoline_spacing : nice_spacing(lo, hi, 20);
    constexpr double kMaxIsolines = 1000;  // a picture's worth; each level is a pass over the mesh
    if (!a.isolines.empty() && (hi - lo) / spacing > kMaxIsolines)
        throw Error("--isoline-spacing", fmt("%g", spacing) + " gives " + fmt("%.3g", (hi - lo) / spacing) +
                                             " levels over φ's range [" + fmt("%g", lo) + ", " + fmt("%g", hi) +
                                             "]; at most " + fmt("%g", kMaxIsolines) + ": give a larger spacing");
    std::string isolines;
    if (!a.isolines.empty()) isolines = isolines_obj(mesh, r.phi, spacing);
    Image picture;
    const PolygonMesh triangles = mesh.triangles();
    if (!a.render.empty()) {
        SurfacePicture p;
        p.mesh = &triangles;
        p.vertex_values = r.phi;
        p.curves.push_back({source_polylines(mesh, sources), {20, 150, 60}, 3.0});  // green: apart from the black zero contour
        SurfaceRenderOptions o;
        o.range = top > 0 ? top : 1.0;
        o.isolines = int(std::lround(std::min(2 * o.range / spacing, kMaxIsolines)));
        picture = render_surface(p, o);
    }
    write_all({{a.output, [&] { io::write_npy(a.output, {phi.size()}, phi); }},
               {a.colored,
                [&] {
                    std::vector<std::array<std::uint8_t, 3>> colors(r.phi.size());
                    for (std::size_t i = 0; i < colors.size(); ++i) colors[i] = diverging_color(r.phi[i], top > 0 ? top : 1.0);
                    io::write_colored_mesh(a.colored, triangles, colors, r.phi, "phi");
                }},
               {a.isolines, [&] { io::write_file_atomic(a.isolines, isolines); }},
               {a.render, [&] { write_png(a.render, picture); }}});
    if (globals().verbose) note("write " + fmt("%.3f s", seconds_since(t1)));
    std::string written = a.output;
    for (const std::string* o : {&a.colored, &a.isolines, &a.render})
        if (!o->empty()) written.append(", ").append(*o);
    note("wrote " + written + " (φ per vertex, " + fmt("%.4g", lo) + " to " + fmt("%.4g", hi) + ")");
}

}  // namespace

void add_curve(CLI::App& app) {
    auto* c = app.add_subcommand("curve", "Draw curves on a mesh (demo and test input for the surface methods): the "
                                          "intersection with a plane or a sphere, optionally broken");
    auto mesh_path = std::make_shared<std::string>();
    auto output = std::make_shared<std::string>();
    auto plane = std::make_shared<std::vector<double>>();
    auto sphere = std::make_shared<std::vector<double>>();
    auto harm = std::make_shared<CurveDamage>();
    auto seed = std::make_shared<std::uint64_t>(1);
    c->add_option("MESH", *mesh_path, "Mesh (.obj .ply .off .stl)")->required();
    auto* p = c->add_option("--plane", *plane, "Plane nx ny nz d: the curve n·x = d, with n·x < d on its left (inside)")
                  ->expected(4);
    auto* s = c->add_option("--sphere", *sphere, "Sphere cx cy cz r: the curve |x − c| = r, with the inside on its left")
                  ->expected(4);
    p->excludes(s);
    c->add_option("--break", harm->cut,
                  "Cut up to this fraction of every curve away, in --gaps stretches at random places (they may "
                  "overlap; 0: whole curves)")
        ->check(finite_number())->check(CLI::Range(0.0, 0.95))
        ->capture_default_str();
    c->add_option("--gaps", harm->gaps, "Number of stretches --break cuts from each curve")
        ->check(CLI::Range(1, 1000))
        ->capture_default_str();
    c->add_option("--reverse", harm->reversed, "Reverse this many single pieces, picked at random among the surviving ones")
        ->check(CLI::Range(0, 1000000))
        ->capture_default_str();
    auto near = std::make_shared<std::vector<double>>();
    c->add_option("--near", *near, "Keep only the curve passing closest to this point x y z (one loop of several)")
        ->expected(3);
    c->add_option("--seed", *seed, "Random seed for --break")->capture_default_str();
    c->add_option("-o,--output", *output, "Output curve file (the curve text format, 0-based)")->required();
    c->callback([=] {
        if (plane->empty() && sphere->empty()) throw CLI::RequiredError("--plane or --sphere");
        const SurfaceMesh mesh(io::read_mesh(*mesh_path), *mesh_path);
        const Points& x = mesh.polygons().vertices;
        std::vector<double> f(mesh.vertex_count());
        for (std::size_t i = 0; i < f.size(); ++i) {
            const Eigen::Vector3d v = x.row(Eigen::Index(i)).transpose();
            if (!plane->empty()) f[i] = Eigen::Vector3d((*plane)[0], (*plane)[1], (*plane)[2]).dot(v) - (*plane)[3];
            else f[i] = (v - Eigen::Vector3d((*sphere)[0], (*sphere)[1], (*sphere)[2])).norm() - (*sphere)[3];
        }
        SurfaceSources src;
        src.curves = level_set_curves(mesh, f, 0);
        if (src.curves.empty()) throw Error(*mesh_path, "the plane or sphere does not cross the mesh");
        if (!near->empty()) {
            const Eigen::Vector3d p((*near)[0], (*near)[1], (*near)[2]);
            std::size_t best = 0;
            double best_distance = INFINITY;
            for (std::size_t i = 0; i < src.curves.size(); ++i)
                for (const SurfacePoint& q : src.curves[i].nodes) {
                    const double d = (position(mesh, q) - p).norm();
                    if (d < best_distance) {
                        best_distance = d;
                        best = i;
                    }
                }
            src.curves = {src.curves[best]};
        }
        src = damage(src, *harm, *seed);
        std::size_t pieces = 0;
        for (const SurfaceCurve& k : src.curves) pieces += k.nodes.size() - 1;
        if (pieces == 0) throw Error(*output, "--break removed every piece");
        write_surface_curves(*output, src);
        note("wrote " + std::to_string(src.curves.size()) + " curves (" + std::to_string(pieces) + " pieces) to " + *output);
    });
}

void add_shm_surface(CLI::App& shm) {
    auto* s = shm.add_subcommand(
        "surface", "Solve on a triangle mesh: geodesic signed distance to (broken) curves and points drawn on it");
    auto a = std::make_shared<SurfaceArgs>();
    s->add_option("MESH", a->mesh, "Triangle or polygon mesh (.obj .ply .off .stl)")->required();
    s->add_option("--curves", a->curves,
                  "Curves on the mesh, one or more files: the curve text format (v/e/f points, l lines) or an "
                  ".obj's l lines (default: the mesh's own l lines)");
    s->add_option("--points", a->points, "Isolated points (unsigned distance): v/e/f records of a curve text file");
    s->add_flag("--unsigned", a->is_unsigned, "Treat the curves as unsigned (distance without a side)");
    s->add_option("--level-set", a->level_set,
                  "How φ is pinned: zero (φ = 0 at every curve node), components (one level per curve component), "
                  "none (shift so the curves are zero on average)")
        ->check(CLI::IsMember({"none", "zero", "components"}))
        ->capture_default_str();
    s->add_option("--soft-weight", a->options.soft_weight,
                  "With zero/components: weight of the level-set penalty (0: exact, eq. 4.11; exact constraints collapse "
        "φ to 0 next to curves whose nodes are not a level set, see docs/shm-surface.md)")
        ->check(finite_number())->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    s->add_flag("--preserve-normals", a->options.preserve_normals,
                "Keep the diffused field normal to the curves at the curves (one more constrained solve)");
    s->add_option("--t-coef", a->setup.t_coef, "Diffusion time t = t_coef · h², h = half the mean edge length")
        ->check(finite_number())->check(CLI::Range(1e-6, 1e6))
        ->capture_default_str();
    auto* idt = s->add_flag("--intrinsic-delaunay", a->setup.intrinsic_delaunay,
                            "Solve on an intrinsic Delaunay triangulation (edge flips; the mesh is not changed)");
    s->add_flag("--refine", a->setup.refine, "With --intrinsic-delaunay: also insert vertices until no angle is below --min-angle")
        ->needs(idt);
    s->add_option("--min-angle", a->setup.refine_min_angle, "Smallest angle --refine aims for, degrees")
        ->check(finite_number())->check(CLI::Range(1.0, 33.0))
        ->capture_default_str();
    s->add_flag("--sharpen", a->sharpen,
                "Distance sharpening (thesis eq. 4.13): the sharpest φ with |∇φ| ≤ 1 per triangle, zero on the curves and "
                "φ's sign, by PDHG from the solve's φ");
    s->add_option("--iterations", a->sharpening.iterations, "With --sharpen: PDHG iterations (0: 24 × the mesh's diameter in edges)")
        ->check(CLI::Range(0, 1000000))->capture_default_str();
    s->add_option("-o,--output", a->output, "Output .npy: φ per vertex, float32 (V,), in the mesh's vertex order")->required()->check(output_file({".npy"}));
    s->add_option("--colored", a->colored, "Also write the mesh colored by φ (.ply with red green blue and phi per vertex)")->check(output_file({".ply"}));
    s->add_option("--isolines", a->isolines, "Also write isolines of φ as .obj polylines (one group per level)")->check(output_file({".obj"}));
    s->add_option("--isoline-spacing", a->isoline_spacing, "Spacing of isolines (default: a round number, ~20 levels; at most 1000 levels)")
        ->check(finite_number())->check(CLI::PositiveNumber);
    s->add_option("--render", a->render, "Also render a picture (.png): the mesh shaded and colored by φ, isolines, the curves")->check(output_file({".png"}));
    s->callback([a] { run(*a); });
}

}  // namespace gsd::cli
