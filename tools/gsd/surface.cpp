// `gsd shm surface`: the Signed Heat Method on a triangle mesh or a point cloud — geodesic signed
// distance to (broken) curves and points on it, with optional pictures and derived outputs.
#include "cli.hpp"

#include <gsd/io.hpp>
#include <gsd/spatial.hpp>
#include <gsd/surface.hpp>
#include <gsd/swn.hpp>
#include <gsd/viz.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <tuple>
#include <optional>

namespace gsd::cli {

namespace {

struct SurfaceArgs {
    std::string mesh, points, output, colored, isolines, render, corners, jumps;
    std::vector<std::string> curves;
    std::string integrate = "l2";
    bool is_unsigned = false;
    bool filter_nonbounding = false;
    std::string level_set = "zero";
    double isoline_spacing = 0;
    SurfaceShmOptions options;
    SurfaceShmSetup setup;
    bool sharpen = false;
    SurfaceSharpenOptions sharpening;
    CloudSurfaceOptions cloud;
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

/// Curves whose nodes lie on edges moved onto points, each node to the nearer end of its edge,
/// repeats and back-and-forth steps (a → b → a) dropped: the same curves through cloud points,
/// as a cloud's curve files name them.
std::vector<SurfaceCurve> snapped_to_points(const SurfaceMesh& mesh, const std::vector<SurfaceCurve>& curves) {
    std::vector<SurfaceCurve> out;
    for (const SurfaceCurve& c : curves) {
        SurfaceCurve s;
        s.is_signed = c.is_signed;
        for (const SurfacePoint& p : c.nodes) {
            std::uint32_t v = p.index;
            if (p.kind == SurfacePoint::Kind::Edge) v = mesh.edge(p.index)[p.u < 0.5 ? 0 : 1];
            else if (p.kind == SurfacePoint::Kind::Face) v = mesh.triangle(p.index)[0];
            if (!s.nodes.empty() && s.nodes.back().index == v) continue;
            if (s.nodes.size() >= 2 && s.nodes[s.nodes.size() - 2].index == v) {
                s.nodes.pop_back();
                continue;
            }
            s.nodes.push_back(SurfacePoint::at_vertex(v));
        }
        if (s.nodes.size() >= 2) out.push_back(std::move(s));
    }
    return out;
}

}  // namespace

bool is_cloud_file(const std::string& path) { return !io::file_has_faces(path); }

std::string polylines_obj(const std::string& header, const std::vector<std::pair<std::string, const Polylines*>>& groups) {
    std::string out = header;
    std::size_t vertices = 0;
    for (const auto& [name, lines] : groups) {
        out.append("g ").append(name).append("\n");
        for (const auto& line : *lines) {
            std::string l = "l";
            for (const Eigen::Vector3d& x : line) {
                char v[128];
                std::snprintf(v, sizeof(v), "v %.9g %.9g %.9g\n", x.x(), x.y(), x.z());
                out += v;
                l.append(" ").append(std::to_string(++vertices));
            }
            out.append(l).append("\n");
        }
    }
    return out;
}

namespace {

/// A triangle mesh with a vertex per corner of each triangle (nothing shared), and φ at each:
/// draws a function that jumps across edges (L1 integration) as it is.
std::pair<PolygonMesh, std::vector<double>> corner_mesh(const SurfaceMesh& mesh,
                                                        const std::vector<std::array<double, 3>>& corner_phi) {
    const PolygonMesh& in = mesh.polygons();
    PolygonMesh out;
    out.vertices.resize(Eigen::Index(3 * mesh.triangle_count()), 3);
    std::vector<double> values(3 * mesh.triangle_count());
    for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
        const auto tri = mesh.triangle(t);
        for (std::size_t k = 0; k < 3; ++k) {
            out.vertices.row(Eigen::Index(3 * t + k)) = in.vertices.row(Eigen::Index(tri[k]));
            values[3 * t + k] = corner_phi[t][k];
        }
        out.add_face({std::uint32_t(3 * t), std::uint32_t(3 * t + 1), std::uint32_t(3 * t + 2)});
    }
    return {std::move(out), std::move(values)};
}

}  // namespace

/// A splat radius per point: 1.5 × the mean distance to its 6 nearest neighbours, so discs
/// overlap on even sampling and grow where the sampling thins.
std::vector<double> splat_radii(const Points& points) {
    const KdTree tree(points);
    std::vector<double> r(std::size_t(points.rows()));
    std::vector<Neighbor> near;
    for (Eigen::Index i = 0; i < points.rows(); ++i) {
        tree.knn(points.row(i).transpose(), 7, near);
        double sum = 0;
        for (const Neighbor& n : near) sum += n.distance;
        r[std::size_t(i)] = 1.5 * sum / double(std::max<std::size_t>(near.size() - 1, 1));
    }
    return r;
}

namespace {

std::size_t jump_edges(const SurfaceShmResult& r) {
    std::size_t n = 0;
    for (const Polyline& line : r.jumps) n += line.size() - 1;
    return n;
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
        if (a.integrate == "l1")
            note("L1 integration: φ jumps along " + std::to_string(r.jumps.size()) + " polylines (" +
                 std::to_string(jump_edges(r)) + " edges), program optimum " + fmt("%.4g", r.jump_cost));
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


/// The curves without their parts that bound nothing (thesis §6.4.1's first remedy): Surface
/// Winding Numbers' decomposition, on the mesh (a cloud: its triangulation, same vertices).
SurfaceSources bounding_part(const SurfaceSources& sources, const SurfaceMesh& mesh, const SurfaceArgs& a,
                             Polylines& left_out) {
    if (sources.curves.empty()) throw CLI::ValidationError("--filter-nonbounding", "needs curves (points bound nothing to filter)");
    Progress progress("shm surface --filter-nonbounding");
    SwnResult w;
    naming_file(a.mesh, "mesh", [&] { w = SurfaceWindingNumbers(mesh).solve(sources, {}, progress.fn()); });
    progress.finish();
    std::size_t pieces = 0, kept = 0;
    for (const SurfaceCurve& c : sources.curves) pieces += c.nodes.size() - 1;
    for (const SurfaceCurve& c : w.bounding_curves.curves) kept += c.nodes.size() - 1;
    note("filter-nonbounding: " + std::to_string(w.nonbounding.size()) + " nonbounding polylines left out; " +
         std::to_string(w.bounding_curves.curves.size()) + " bounding curves kept (" + std::to_string(kept) +
         " pieces; the input had " + std::to_string(pieces) + ")");
    if (w.bounding_curves.curves.empty() && sources.points.empty())
        throw Error(a.curves.empty() ? a.mesh : a.curves.front(),
                    "every curve bounds nothing (it goes around a handle): no inside to sign the distance by; "
                    "without --filter-nonbounding, --integrate l1 gives a distance that jumps instead");
    SurfaceSources out = w.bounding_curves;
    out.points = sources.points;
    left_out = std::move(w.nonbounding);
    return out;
}

void run(const SurfaceArgs& a) {
    if (a.curves.empty() && a.points.empty() && io::extension(a.mesh) != ".obj")
        throw CLI::RequiredError("--curves or --points (or an .obj mesh with `l` lines)");
    if (!a.render.empty() && io::extension(a.render) != ".png") throw CLI::ValidationError("--render", "must be a .png file");
    if (!a.colored.empty() && io::extension(a.colored) != ".ply") throw CLI::ValidationError("--colored", "must be a .ply file");
    if (!a.isolines.empty() && io::extension(a.isolines) != ".obj") throw CLI::ValidationError("--isolines", "must be an .obj file");
    if (io::extension(a.output) != ".npy") throw CLI::ValidationError("--output", "must be a .npy file");
    const bool l1 = surface_integration_from_name(a.integrate) == SurfaceIntegration::L1;
    if (!l1 && !(a.corners.empty() && a.jumps.empty()))
        throw CLI::ValidationError(a.corners.empty() ? "--jumps" : "--corners", "needs --integrate l1");
    if (l1 && a.sharpen) throw CLI::ValidationError("--sharpen", "sharpens a continuous φ: not with --integrate l1");
    if (a.filter_nonbounding && a.is_unsigned)
        throw CLI::ValidationError("--filter-nonbounding", "needs oriented curves (not --unsigned): it runs Surface Winding Numbers");
    const auto t0 = std::chrono::steady_clock::now();
    // A file without faces is a point cloud: its surface is the union of its points' fans.
    const bool is_cloud = is_cloud_file(a.mesh);
    Points cloud_normals;
    PolygonMesh cloud_triangulation;
    SurfaceMesh mesh = [&] {
        if (!is_cloud) return SurfaceMesh(io::read_mesh(a.mesh), a.mesh);
        const PointCloud cloud = io::read_cloud_points(a.mesh);
        CloudSurface s = cloud_surface(cloud.points, cloud.normals, a.cloud, a.mesh);
        cloud_normals = std::move(s.normals);
        cloud_triangulation = std::move(s.triangulation);
        if (globals().verbose)
            note("cloud: " + std::to_string(cloud.points.rows()) + " points" +
                 (cloud.normals.rows() ? " (normals: their majority sign per piece)" : " (unoriented)") + ", " +
                 std::to_string(s.mesh.triangle_count()) + " fan triangles from " + std::to_string(a.cloud.neighbors) +
                 " neighbours each");
        return std::move(s.mesh);
    }();
    SurfaceSources sources = load_sources(a, mesh);
    if (is_cloud) require_cloud_points(sources, a.curves.empty() ? (a.points.empty() ? a.mesh : a.points) : a.curves.front());
    Polylines left_out;  // --filter-nonbounding: the curves' parts that bound nothing
    if (a.filter_nonbounding) sources = bounding_part(sources, is_cloud ? SurfaceMesh(cloud_triangulation) : mesh, a, left_out);
    if (is_cloud && !a.corners.empty())
        throw CLI::ValidationError("--corners", "φ per triangle corner is for meshes (a cloud's φ is per point: --output)");
    const double load_seconds = seconds_since(t0);

    SurfaceShmOptions options = a.options;
    options.level_set = level_set_from_name(a.level_set);
    options.integration = l1 ? SurfaceIntegration::L1 : SurfaceIntegration::L2;
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
    // What the outputs draw on: the mesh, or a cloud's manifold triangulation.
    // With L1 integration on a mesh: a vertex per triangle corner, so that jumps show as they are.
    PolygonMesh triangles = is_cloud ? std::move(cloud_triangulation) : mesh.triangles();
    std::vector<double> drawn = r.phi;
    if (l1 && !is_cloud) std::tie(triangles, drawn) = corner_mesh(mesh, r.corner_phi);
    std::string isolines;
    if (!a.isolines.empty()) isolines = isolines_obj(is_cloud || l1 ? SurfaceMesh(triangles) : mesh, drawn, spacing);
    Image picture;
    if (!a.render.empty()) {
        SurfacePicture p;
        SurfaceRenderOptions o;
        o.range = top > 0 ? top : 1.0;
        o.isolines = int(std::lround(std::min(2 * o.range / spacing, kMaxIsolines)));
        PolygonMesh splats;
        if (is_cloud) {
            // A cloud is drawn as it is, a disc per point in the color of its φ (no isolines:
            // a disc holds one value).
            splats = splat_mesh(mesh.polygons().vertices, cloud_normals, splat_radii(mesh.polygons().vertices));
            p.mesh = &splats;
            for (double v : r.phi) p.vertex_values.insert(p.vertex_values.end(), kSplatVertices, v);
            o.isolines = 0;
            o.zero_contour = false;
            o.mark_back_faces = false;  // a disc seen through a gap is the far side, not a flipped normal
        } else {
            p.mesh = &triangles;
            p.vertex_values = drawn;
        }
        p.curves.push_back({source_polylines(mesh, sources), {20, 150, 60}, 3.0});  // green: apart from the black zero contour
        if (l1) p.curves.push_back({r.jumps, {200, 30, 30}, 3.0});                  // red: where φ jumps
        p.curves.push_back({left_out, {150, 150, 150}, 2.0});                       // gray: left out
        picture = render_surface(p, o);
    }
    write_all({{a.output, [&] { io::write_npy(a.output, {phi.size()}, phi); }},
               {a.colored,
                [&] {
                    std::vector<std::array<std::uint8_t, 3>> colors(drawn.size());
                    for (std::size_t i = 0; i < colors.size(); ++i) colors[i] = diverging_color(drawn[i], top > 0 ? top : 1.0);
                    io::write_colored_mesh(a.colored, triangles, colors, drawn, "phi");
                }},
               {a.corners,
                [&] {
                    std::vector<float> c;
                    c.reserve(3 * r.corner_phi.size());
                    for (const auto& t : r.corner_phi) c.insert(c.end(), t.begin(), t.end());
                    io::write_npy(a.corners, {r.corner_phi.size(), 3}, c);
                }},
               {a.jumps,
                [&] {
                    io::write_file_atomic(a.jumps, polylines_obj("# where the L1 surface distance of gsd shm surface jumps: "
                                                                 "higher on the left of each line (seen from the normal side)\n",
                                                                 {{"jumps", &r.jumps}}));
                }},
               {a.isolines, [&] { io::write_file_atomic(a.isolines, isolines); }},
               {a.render, [&] { write_png(a.render, picture); }}});
    if (globals().verbose) note("write " + fmt("%.3f s", seconds_since(t1)));
    std::string written = a.output;
    for (const std::string* o : {&a.colored, &a.isolines, &a.render, &a.corners, &a.jumps})
        if (!o->empty()) written.append(", ").append(*o);
    note("wrote " + written + " (φ per " + (is_cloud ? "point, " : "vertex, ") + fmt("%.4g", lo) + " to " + fmt("%.4g", hi) + ")");
}

}  // namespace

void add_curve(CLI::App& app) {
    auto* c = app.add_subcommand("curve", "Draw curves on a mesh or a point cloud (demo and test input for the surface "
                                          "methods): the intersection with a plane or a sphere, optionally broken");
    auto mesh_path = std::make_shared<std::string>();
    auto output = std::make_shared<std::string>();
    auto plane = std::make_shared<std::vector<double>>();
    auto sphere = std::make_shared<std::vector<double>>();
    auto harm = std::make_shared<CurveDamage>();
    auto seed = std::make_shared<std::uint64_t>(1);
    c->add_option("MESH", *mesh_path,
                  "Mesh (.obj .ply .off .stl) or point cloud (a file without faces): on a cloud the curve runs "
                  "through cloud points (`v i` records), those nearest where it crosses the points' fans")
        ->required();
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
        const bool is_cloud = is_cloud_file(*mesh_path);
        const SurfaceMesh mesh = [&] {
            if (!is_cloud) return SurfaceMesh(io::read_mesh(*mesh_path), *mesh_path);
            // The file's normals, if any, orient the triangulation as shm surface and swn will.
            const PointCloud cloud = io::read_cloud_points(*mesh_path);
            return SurfaceMesh(cloud_surface(cloud.points, cloud.normals, {}, *mesh_path).triangulation);
        }();
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
        if (is_cloud) src.curves = snapped_to_points(mesh, src.curves);
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
        "surface", "Solve on a triangle mesh or a point cloud: geodesic signed distance to (broken) curves and points "
                   "drawn on it");
    auto a = std::make_shared<SurfaceArgs>();
    s->add_option("MESH", a->mesh,
                  "Triangle or polygon mesh (.obj .ply .off .stl), or a point cloud (a .ply or .obj without faces, "
                  ".xyz .txt .pc .npy; normals optional): its surface is its points' local Delaunay fans")
        ->required();
    s->add_option("--curves", a->curves,
                  "Curves on the mesh, one or more files: the curve text format (v/e/f points, l lines) or an "
                  ".obj's l lines (default: the mesh's own l lines). On a cloud: `v i` records, point i");
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
    s->add_option("--integrate", a->integrate,
                  "Step 3: l2 (least squares, one continuous φ) or l1 (φ may jump along the cheapest edges where "
                  "the field cannot be integrated: curves that bound nothing, around a handle; docs/shm-surface.md)")
        ->check(CLI::IsMember({"l2", "l1"}))
        ->capture_default_str();
    s->add_flag("--filter-nonbounding", a->filter_nonbounding,
                "Leave out the parts of the curves that bound nothing (around a handle), found by Surface Winding "
                "Numbers, and measure the distance to the rest (thesis §6.4.1)");
    s->add_option("--corners", a->corners, "With --integrate l1: also write φ per triangle corner (.npy, float32 (T, 3), "
                                           "the mesh's triangles in order: polygons fanned from their first corner)")
        ->check(output_file({".npy"}));
    s->add_option("--jumps", a->jumps, "With --integrate l1: also write where φ jumps as .obj polylines")
        ->check(output_file({".obj"}));
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
    s->add_option("--neighbors", a->cloud.neighbors,
                  "On a point cloud: neighbours whose Delaunay triangulation in a point's tangent plane gives its fan")
        ->check(CLI::Range(3, 64))
        ->capture_default_str();
    s->add_option("-o,--output", a->output, "Output .npy: φ per vertex (per point of a cloud), float32 (V,), in the input's order")->required()->check(output_file({".npy"}));
    s->add_option("--colored", a->colored, "Also write the mesh colored by φ (.ply with red green blue and phi per vertex; a cloud: its triangulation)")->check(output_file({".ply"}));
    s->add_option("--isolines", a->isolines, "Also write isolines of φ as .obj polylines (one group per level)")->check(output_file({".obj"}));
    s->add_option("--isoline-spacing", a->isoline_spacing, "Spacing of isolines (default: a round number, ~20 levels; at most 1000 levels)")
        ->check(finite_number())->check(CLI::PositiveNumber);
    s->add_option("--render", a->render, "Also render a picture (.png): the mesh shaded and colored by φ, isolines, the curves (a cloud: a disc per point)")->check(output_file({".png"}));
    s->callback([a] { run(*a); });
}

}  // namespace gsd::cli
