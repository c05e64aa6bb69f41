// `gsd swn`: inside/outside of (broken) curves on a surface — Surface Winding Numbers, or the
// sign of the surface Signed Heat Method for comparison — on a mesh or a point cloud.
#include "cli.hpp"

#include <gsd/io.hpp>
#include <gsd/surface.hpp>
#include <gsd/swn.hpp>
#include <gsd/viz.hpp>

#include <Eigen/Geometry>

#include <filesystem>
#include <functional>
#include <map>
#include <optional>

namespace gsd::cli {

namespace {

struct SwnArgs {
    std::string mesh, output, w, loops, render;
    std::vector<std::string> curves;
    std::string lp = "reduced", solver = "network", method = "swn";
    SwnOptions options;
    CloudSurfaceOptions cloud;
};

/// The bounding, nonbounding and completed curves as OBJ polylines, one group each.
std::string loops_obj(const SwnResult& r) {
    return polylines_obj("# curve decomposition written by gsd swn: bounding and nonbounding parts of the input curves,\n"
                         "# and where the nonbounding ones were completed\n",
                         {{"bounding", &r.bounding}, {"nonbounding", &r.nonbounding}, {"completed", &r.completed}});
}

/// "0 (61.2 %), 1 (38.8 %)": the labels of a cloud's points and their share of the points.
std::string point_label_summary(const std::vector<int>& labels) {
    std::map<int, std::size_t> count;
    for (int l : labels) ++count[l];
    std::string s;
    for (const auto& [label, n] : count) {
        if (!s.empty()) s += ", ";
        s += std::to_string(label) + " (" + fmt("%.1f %%", 100.0 * double(n) / double(labels.size())) + " of the points)";
    }
    return s;
}

/// "3 regions: 0 (61.2 %), 1 (38.8 %)": the labels and their share of the area.
std::string label_summary(const SurfaceMesh& mesh, const std::vector<int>& labels) {
    const auto& polygons = mesh.polygons();
    std::map<int, double> area;
    double total = 0;
    const auto vertex = [&](std::uint32_t v) -> Eigen::Vector3d { return polygons.vertices.row(v).transpose(); };
    std::vector<double> face_area(polygons.face_count(), 0.0);
    for_each_triangle(polygons, [&](std::size_t f, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
        face_area[f] += 0.5 * (vertex(b) - vertex(a)).cross(vertex(c) - vertex(a)).norm();
    });
    for (std::size_t f = 0; f < labels.size(); ++f) {
        area[labels[f]] += face_area[f];
        total += face_area[f];
    }
    std::string s;
    for (const auto& [label, a] : area) {
        if (!s.empty()) s += ", ";
        s += std::to_string(label) + " (" + fmt("%.1f %%", total > 0 ? 100 * a / total : 0.0) + ")";
    }
    return s;
}

SurfaceSources load_curves(const SwnArgs& a, const SurfaceMesh& mesh) {
    SurfaceSources src;
    for (const std::string& file : a.curves.empty() ? std::vector<std::string>{a.mesh} : a.curves) {
        SurfaceSources more = read_surface_curves(file, mesh);
        src.curves.insert(src.curves.end(), more.curves.begin(), more.curves.end());
        src.points.insert(src.points.end(), more.points.begin(), more.points.end());
    }
    if (src.curves.empty())
        throw Error(a.curves.empty() ? a.mesh : a.curves.front(), "no curves (give --curves, or `l` lines in the .obj)");
    if (!src.points.empty())
        note("note: " + std::to_string(src.points.size()) + " isolated points ignored (points bound no region)");
    src.points.clear();
    return src;
}

void run(const SwnArgs& a) {
    // A mesh format without curve records needs --curves; anything else (a missing file, a
    // folder, a curve file given as the mesh) gets the reader's own error about MESH below.
    if (a.curves.empty() && io::extension(a.mesh) != ".obj")
        throw CLI::RequiredError("--curves (or an .obj mesh with `l` lines)");
    if (io::extension(a.output) != ".npy") throw CLI::ValidationError("--output", "must be a .npy file");
    if (!a.w.empty() && io::extension(a.w) != ".npy") throw CLI::ValidationError("--w", "must be a .npy file");
    if (!a.loops.empty() && io::extension(a.loops) != ".obj") throw CLI::ValidationError("--loops", "must be an .obj file");
    if (!a.render.empty() && io::extension(a.render) != ".png") throw CLI::ValidationError("--render", "must be a .png file");
    const bool shm = a.method == "shm";
    if (shm && (!a.w.empty() || !a.loops.empty()))
        throw CLI::ValidationError("--method shm", "writes labels only (--w and --loops come from --method swn)");

    const auto t0 = std::chrono::steady_clock::now();
    // A point cloud: SWN on its manifold triangulation, the SHM on its fans (as `shm surface`),
    // labels per point.
    const bool is_cloud = is_cloud_file(a.mesh);
    std::optional<SurfaceMesh> fans;
    Points cloud_normals;
    SurfaceMesh mesh = [&] {
        if (!is_cloud) return SurfaceMesh(io::read_mesh(a.mesh), a.mesh);
        const PointCloud cloud = io::read_cloud_points(a.mesh);  // normals, if any, set the side (as shm surface)
        CloudSurface s = cloud_surface(cloud.points, cloud.normals, a.cloud, a.mesh);
        fans.emplace(std::move(s.mesh));
        cloud_normals = std::move(s.normals);
        return SurfaceMesh(std::move(s.triangulation), a.mesh);
    }();
    const SurfaceSources curves = load_curves(a, mesh);
    if (is_cloud) require_cloud_points(curves, a.curves.empty() ? a.mesh : a.curves.front());
    const double load_seconds = seconds_since(t0);

    std::vector<int> labels;
    SwnResult r;
    Progress progress(shm ? "swn (shm sign)" : "swn");
    naming_file(a.mesh, "mesh", [&] {
        if (shm) {
            SignedHeatSurface solver(is_cloud ? *fans : mesh);
            const SurfaceShmResult shm_result = solver.solve(curves, {}, progress.fn());
            if (is_cloud)
                for (double phi : shm_result.phi) labels.push_back(phi < 0 ? 1 : 0);
            else
                labels = shm_labels(mesh, shm_result.phi);
            if (shm_result.unreached_vertices)
                note("warning: " + std::to_string(shm_result.unreached_vertices) +
                     " vertices lie in mesh components that no curve reaches: labeled 0 (outside)");
        } else {
            SwnOptions o = a.options;
            o.residual = swn_residual_from_name(a.lp);
            o.solver = swn_solver_from_name(a.solver);
            SurfaceWindingNumbers solver(mesh);
            r = solver.solve(curves, o, progress.fn());
            labels = is_cloud ? vertex_labels(mesh, r.labels) : r.labels;
        }
    });
    progress.finish();
    if (globals().verbose) {
        note("mesh: " + std::to_string(mesh.vertex_count()) + " vertices, " + std::to_string(mesh.face_count()) +
             " faces; load " + fmt("%.3f s", load_seconds));
        if (is_cloud) {
            // Holes and handles where the fans disagree (noise) change what SWN reads as
            // boundary and as loops around handles: say what the triangulation came out as.
            const SurfaceMesh::Summary t = mesh.summary();
            note("cloud triangulation: " + std::to_string(t.components) + " components, Euler characteristic " +
                 std::to_string(t.euler_characteristic) + ", " + std::to_string(t.boundary_edges) + " boundary edges, " +
                 std::to_string(t.unreferenced_vertices) + " points on no triangle");
        }
        if (!shm) {
            note(std::string(r.simply_connected ? "every component a disk or sphere: no residual step"
                                                : "not simply connected: residual by the " + a.lp + " program") +
                 (r.split ? "; curves off the edges: solved on a mesh cut along them" : ""));
            note("jump solves " + fmt("%.3f s", r.seconds_jump) + ", Hodge " + fmt("%.3f s", r.seconds_hodge) +
                 ", residual " + fmt("%.3f s", r.seconds_residual) + " (" + std::to_string(r.lp_variables) +
                 " variables, " + std::to_string(r.lp_rows) + " rows, L1 cost " + fmt("%.6g", r.lp_objective) + ", bound violation " + fmt("%.2g", r.lp_violation) +
                 ")" + (r.seconds_boundary > 0 ? ", boundary-aware " + fmt("%.3f s", r.seconds_boundary) : std::string()) +
                 ", total " + fmt("%.3f s", r.seconds_total));
            note(std::to_string(r.bounding.size()) + " bounding, " + std::to_string(r.nonbounding.size()) +
                 " nonbounding, " + std::to_string(r.completed.size()) + " completing polylines");
        }
        note("peak memory: " + peak_memory());
    }

    // Everything in memory first, then write all outputs or none.
    std::vector<std::int32_t> label32(labels.begin(), labels.end());
    std::vector<float> w;
    for (const auto& c : r.w) w.insert(w.end(), c.begin(), c.end());
    const std::string loops = a.loops.empty() ? std::string() : loops_obj(r);
    Image picture;
    PolygonMesh splats;
    if (!a.render.empty()) {
        SurfacePicture p;
        p.mesh = &mesh.polygons();
        p.face_labels = labels;
        SurfaceRenderOptions o;
        if (is_cloud) {  // a disc per point in its label's color
            splats = splat_mesh(mesh.polygons().vertices, cloud_normals, splat_radii(mesh.polygons().vertices));
            p.mesh = &splats;
            p.face_labels.clear();
            for (int l : labels) p.face_labels.insert(p.face_labels.end(), kSplatVertices - 1, l);
            o.mark_back_faces = false;
        }
        if (shm) {
            p.curves.push_back({source_polylines(mesh, curves), {20, 20, 20}, 3.0});
        } else {
            p.curves.push_back({r.bounding, {20, 20, 20}, 3.0});
            p.curves.push_back({r.nonbounding, {200, 30, 30}, 3.0});
            p.curves.push_back({r.completed, {230, 150, 0}, 2.0});
        }
        picture = render_surface(p, o);
    }
    std::vector<std::pair<std::string, std::function<void()>>> outputs = {
        {a.output, [&] { io::write_npy(a.output, {label32.size()}, label32); }},
        {a.w, [&] { io::write_npy(a.w, {r.w.size(), 3}, w); }},
        {a.loops, [&] { io::write_file_atomic(a.loops, loops); }},
        {a.render, [&] { write_png(a.render, picture); }}};
    write_all(outputs);
    std::string written;
    for (const auto& [p, write] : outputs)
        if (!p.empty()) written.append(written.empty() ? "" : ", ").append(p);
    note("wrote " + written + "; labels: " + (is_cloud ? point_label_summary(labels) : label_summary(mesh, labels)));
}

}  // namespace

void add_swn(CLI::App& app) {
    auto* s = app.add_subcommand("swn", "Surface Winding Numbers (thesis ch. 6): inside/outside of broken curves on a "
                                        "surface of any topology, as integer labels per face");
    auto a = std::make_shared<SwnArgs>();
    s->add_option("MESH", a->mesh,
                  "Triangle or polygon mesh (.obj .ply .off .stl), manifold and oriented for --method swn; or a point "
                  "cloud (a file without faces; normals optional): SWN runs on its triangulation, labels per point")
        ->required();
    s->add_option("--curves", a->curves,
                  "Oriented curves on the mesh, one or more files: the curve text format (v/e/f points, l lines) "
                  "or an .obj's l lines (default: the mesh's own l lines)");
    s->add_option("-o,--output", a->output,
                  "Output .npy: int32 label per input face (+1 left of a counter-clockwise loop, 0 outside); per point "
                  "for a cloud")
        ->required()
        ->check(output_file({".npy"}));
    s->add_option("--neighbors", a->cloud.neighbors, "On a point cloud: neighbours of each point's Delaunay fan (gsd shm surface)")
        ->check(CLI::Range(3, 64))
        ->capture_default_str();
    s->add_option("--w", a->w, "Also write w per triangle corner, float32 (T, 3) (T = faces for a triangle mesh; a cloud: its triangulation's)")
        ->check(output_file({".npy"}));
    s->add_option("--method", a->method,
                  "swn: winding numbers; shm: the sign of the surface Signed Heat Method (1 where φ < 0), often "
                  "better on badly corrupted curves (docs/swn.md)")
        ->check(CLI::IsMember({"swn", "shm"}))
        ->capture_default_str();
    s->add_option("--lp", a->lp,
                  "Residual step on surfaces that are not simply connected: reduced (linear program over the pieces of "
                  "a cut: fast, and on broken curves usually the better labels), full (over every face: the thesis' "
                  "minimal-L1 optimum), none (naive rounding of u)")
        ->check(CLI::IsMember({"full", "reduced", "none"}))
        ->capture_default_str();
    s->add_option("--lp-solver", a->solver,
                  "network: network simplex on the program's dual (exact, fast); clp: COIN-OR CLP on the program itself")
        ->check(CLI::IsMember({"network", "clp"}))
        ->capture_default_str();
    s->add_option("--curve-weight", a->options.curve_weight,
                  "Cost of a residual jump along an input curve relative to elsewhere (ε of the linear program); "
                  "0: the program's default (reduced 0.3, full 0.001)")
        ->check(finite_number())->check(CLI::Range(0.0, 1.0))
        ->capture_default_str();
    s->add_flag("--close-gaps,!--no-close-gaps", a->options.close_gaps,
                "Join the curves' ends across their gaps before the residual step (on by default: broken loops around "
                "handles; --no-close-gaps: the program on the broken curves as they are; docs/swn.md)")
        ->capture_default_str();
    s->add_flag("--boundary-aware", a->options.boundary_aware,
                "On meshes with boundary: labels near the boundary like free-space winding numbers (thesis §6.2)");
    s->add_option("--loops", a->loops, "Also write the curve decomposition as .obj polylines (groups bounding, "
                                       "nonbounding, completed)")
        ->check(output_file({".obj"}));
    s->add_option("--render", a->render,
                  "Also render a picture (.png): regions colored by label, bounding curves black, nonbounding red, "
                  "completions orange")
        ->check(output_file({".png"}));
    s->callback([a] { run(*a); });
}

}  // namespace gsd::cli
