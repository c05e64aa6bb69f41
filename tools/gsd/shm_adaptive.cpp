// gsd shm adaptive: the Signed Heat Method on an adaptive octree (gsd/adaptive_shm.hpp).
#include "cli.hpp"

#include <gsd/adaptive_shm.hpp>
#include <gsd/io.hpp>
#include <gsd/pat.hpp>
#include <gsd/shm.hpp>

namespace gsd::cli {

LoadedShmSource load_shm_source(const std::vector<std::string>& inputs, const std::function<void(const Box&)>& read,
                                bool drop_outliers, bool reorient) {
    LoadedShmSource out;
    std::vector<std::pair<std::string, PolygonMesh>> meshes;
    std::vector<PointCloud> clouds;
    bool have_box = false;
    auto grow = [&](const Points& p) {
        const Box b = bounding_box(p);
        out.box = have_box ? Box{out.box.lo.cwiseMin(b.lo), out.box.hi.cwiseMax(b.hi)} : b;
        have_box = true;
    };
    for (const std::string& in : inputs) {
        if (io::file_has_faces(in)) {
            meshes.emplace_back(in, io::read_mesh(in));
            grow(meshes.back().second.vertices);
        } else {
            clouds.push_back(io::read_point_cloud(in));
            grow(clouds.back().points);
        }
    }
    if (read) read(out.box);  // checks that need only the inputs' extent, before the sources' cost
    bool first = true;
    auto add = [&](const ShmSource& s) {
        out.source = first ? s : combine(out.source, s);
        first = false;
    };
    // Meshes first, then clouds (the order of a combined source does not change φ).
    for (const auto& [in, mesh] : meshes) {
        try {
            add(shm_source(mesh));
        } catch (const Error& e) {
            throw Error(in, e.what());  // name the file: sources don't know where their mesh came from
        }
    }
    for (PointCloud& cloud : clouds) {
        const std::size_t n = std::size_t(cloud.size());
        if (drop_outliers) {
            std::size_t dropped = 0;
            cloud = without_outliers(cloud, {}, &dropped);
            if (dropped > 0)
                note(std::to_string(dropped) + " of " + std::to_string(n) + " points left out as outliers (PAT's scores; --keep-outliers keeps them)");
        }
        // After the outliers: their random normals would vote.
        if (reorient) turn_back_normals(cloud);
        add(shm_source(cloud));
    }
    return out;
}

void add_shm_adaptive(CLI::App& shm) {
    auto* a = shm.add_subcommand(
        "adaptive", "Solve on an adaptive octree: finest cells (box / 2^D) near the input, coarse far away; memory grows with the input's area");
    auto inputs = std::make_shared<std::vector<std::string>>();
    auto output = std::make_shared<std::string>();
    auto queries = std::make_shared<std::string>();
    auto contour_out = std::make_shared<std::string>();
    auto grid = std::make_shared<int>(0);
    auto bounds = std::make_shared<std::vector<double>>();
    auto opt = std::make_shared<AdaptiveShmOptions>();
    auto keep_outliers = std::make_shared<bool>(false);
    auto keep_normals = std::make_shared<bool>(false);
    a->add_option("INPUT", *inputs, "Mesh(es) and/or point cloud(s) with normals; several are combined into one source")->required();
    a->add_option("--depth", opt->depth, "Finest level D: finest cell = the cube's side / 2^D (D = 10: 1024³ near the input)")
        ->check(CLI::Range(1, 20))->capture_default_str();
    a->add_option("--band", opt->band, "Cells within this many finest cells of the input are all of the finest level")
        ->check(finite_number())->check(CLI::Range(0.0, 1000.0))->capture_default_str();
    a->add_option("--grading", opt->grading, "A cell of side s is split while its center is within s·(0.87 + this) of the input")
        ->check(finite_number())->check(CLI::Range(0.0, 1000.0))->capture_default_str();
    a->add_option("--bounds", *bounds, "The octree's cube from x0 y0 z0, side the longest of x1−x0, y1−y0, z1−z0 (default: the input's bounding cube + 10%)")
        ->expected(6);
    auto* q = a->add_option("--queries", *queries, "Write φ at the points of an (M,3) .npy file to -o (.npy, (M,))");
    auto* g = a->add_option("--grid", *grid, "Write φ sampled on an N×N×N grid over the cube to -o (.npy or .vdb)")->check(CLI::Range(2, 1290));
    q->excludes(g);
    a->add_option("-o,--output", *output, "Output: .npy (with --queries or --grid), or .vdb (a sparse level set at the finest level)")
        ->required()->check(output_file({".npy", ".vdb"}));
    a->add_option("--contour", *contour_out, "Also write the zero level set as a mesh (.obj .ply .off .stl)")
        ->check(output_file({".obj", ".ply", ".off", ".stl"}));
    a->add_option("--t-coef", opt->t_coef, "Diffusion time t = t_coef · h² (h: mean spacing or edge length)")
        ->check(finite_number())->check(CLI::Range(1e-6, 1e6))->capture_default_str();
    a->add_option("--tolerance", opt->tolerance, "Relative residual to stop at")->check(finite_number())->check(CLI::PositiveNumber)->capture_default_str();
    a->add_option("--fit-zero-set", opt->fit_zero_set, "Fit φ = 0 on the source softly with this weight (0: shift by the mean)")
        ->check(finite_number())->check(CLI::NonNegativeNumber)->capture_default_str();
    a->add_option("--fit-scale", opt->fit_scale,
                  "The fit corrects φ on octree cells at least this many source spacings wide, as smooth as the sampling (0: the finest)")
        ->check(finite_number())->check(CLI::NonNegativeNumber)->capture_default_str();
    a->add_option("--veto-winding", opt->veto_winding, "Outside veto's winding number (0: no veto); as in `gsd shm grid`")
        ->check(CLI::Range(0.0, 0.999))->capture_default_str();
    a->add_flag("--keep-normals", *keep_normals,
                "Keep a cloud's normals as they are (by default normals that their neighbours contradict are turned back first)");
    a->add_flag("--keep-outliers", *keep_outliers,
                "Keep every point of a cloud (by default points that PAT's outlier scores reject are left out before step 1)");
    a->add_flag("--redistance", opt->redistance,
                "Keep SHM's sign and zero set, and make |φ| the exact distance to that zero set (a true SDF)");
    a->add_option("--device", opt->device, "Step 1's device: auto | gpu | cpu | device index | name substring");
    a->callback([=] {
        const bool to_vdb = io::extension(*output) == ".vdb";
        if (!to_vdb && queries->empty() && *grid == 0)
            throw CLI::ValidationError("-o", "a .npy output needs --queries or --grid (or write a .vdb level set)");
        if (to_vdb && !queries->empty()) throw CLI::ValidationError("--queries", "writes a .npy (M,), not a .vdb");
        if (to_vdb) io::require_vdb(*output);
        Points query_points;
        if (!queries->empty()) query_points = io::read_queries(*queries);  // before the work
        if (!bounds->empty()) opt->bounds = bounds_from(*bounds, "--bounds");
        const DevicePrefetch prefetch(opt->device);
        const LoadedShmSource loaded = load_shm_source(*inputs, {}, !*keep_outliers, !*keep_normals);
        const SignedHeatOctree solver(loaded.source, *opt);
        const Box cube = solver.cube();
        if (!opt->bounds) note("octree cube: " + bounds_text(cube));
        Progress progress("shm adaptive");
        const AdaptiveShmResult r = solver.solve(progress.fn());
        progress.finish();
        if (globals().verbose) {
            std::string levels;
            for (std::size_t l = 0; l < r.leaves_per_level.size(); ++l)
                if (r.leaves_per_level[l]) levels += " " + std::to_string(l) + ":" + std::to_string(r.leaves_per_level[l]);
            note("source: " + std::to_string(loaded.source.size()) + " elements, h = " + fmt("%.4g", loaded.source.spacing) +
                 "; step 1 on " + r.device);
            note("octree: depth " + std::to_string(opt->depth) + " (finest cell " + fmt("%.4g", r.field.finest_cell()) + "), " +
                 std::to_string(r.leaves) + " leaves (level:count" + levels + "), " + std::to_string(r.nodes) + " nodes; " +
                 fmt("%.2f s", r.seconds_octree));
            std::string mg;
            for (std::size_t n : r.multigrid_nodes) mg += (mg.empty() ? "" : ", ") + std::to_string(n);
            note("step 1 (diffuse): " + fmt("%.2f s", r.seconds_diffuse) + ", " + std::to_string(r.kernel_terms) + " kernel terms");
            note("nodes and step 3's operators: " + fmt("%.2f s", r.seconds_setup) + ", multigrid levels of " + mg + " nodes");
            note("step 3 (solve): " + fmt("%.2f s", r.seconds_solve) + ", " + std::to_string(r.residual_history.size()) +
                 " CG iterations, relative residual " + fmt("%.2e", r.residual_history.empty() ? 0.0 : r.residual_history.back()));
            std::string history;
            for (double v : r.residual_history) history += " " + fmt("%.2e", v);
            note("step 3's residual after each iteration:" + history);
            if (r.fit_level >= 0) {
                // The multigrid's coarsest level is factored: a fit there is one direct solve.
                const bool direct = std::size_t(r.fit_level) + r.multigrid_nodes.size() == r.leaves_per_level.size();
                note("zero-set fit: " + fmt("%.2f s", r.seconds_fit) + " on level " + std::to_string(r.fit_level) + ", " +
                     (direct ? std::string("solved directly") : std::to_string(r.fit_history.size()) + " CG iterations") +
                     ", relative residual " + fmt("%.2e", r.fit_history.empty() ? 0.0 : r.fit_history.back()));
            }
            if (opt->veto_winding > 0)
                note("outside veto: " + fmt("%.2f s", r.seconds_veto) + ", " + std::to_string(r.vetoed_nodes) + " nodes turned outside");
            if (opt->redistance)
                note("redistance: " + fmt("%.2f s", r.seconds_redistance) + ", " + std::to_string(r.zero_set_triangles) +
                     " triangles of the zero set");
            note("memory: estimated " + fmt("%.0f MB", r.estimated_bytes / 1e6) + ", peak " + peak_memory());
        }
        if (!r.residual_history.empty() && r.residual_history.back() > opt->tolerance)
            note("warning: the solver stopped at relative residual " + fmt("%.2e", r.residual_history.back()) + " (tolerance " +
                 fmt("%.1e", opt->tolerance) + ")");
        if (!r.fit_history.empty() && r.fit_history.back() > opt->tolerance)
            note("warning: the zero-set fit stopped at relative residual " + fmt("%.2e", r.fit_history.back()) + " (tolerance " +
                 fmt("%.1e", opt->tolerance) + ")");
        // Everything is computed before anything is written: no partial outputs.
        std::vector<std::pair<std::string, std::function<void()>>> writers;
        if (!queries->empty()) {
            const FieldValues v = r.field.evaluate(query_points);
            Domain d;
            d.queries = *queries;
            writers.emplace_back(*output, [=] { write_values(*output, d, GridSpec{}, v.phi.size(), v.phi, 1, "shm"); });
        } else if (*grid > 0) {
            const GridSpec gs = GridSpec::cube(*grid, cube);
            check_grid_memory(gs, 16);
            const FieldValues v = r.field.evaluate(gs);
            writers.emplace_back(*output, [=] { write_grid(*output, gs, v.phi, 1, "shm"); });
        }
        auto band = std::make_shared<io::SparseLevelSet>();
        if (to_vdb || !contour_out->empty()) {
            band->lo = cube.lo;
            band->voxel = r.field.finest_cell();
            band->half_width = 3;
            r.field.narrow_band(band->half_width, band->ijk, band->phi);
            if (band->phi.empty())
                throw Error(to_vdb ? *output : *contour_out, "φ has no zero crossing inside the cube: no narrow band to write");
        }
        if (to_vdb) writers.emplace_back(*output, [=] { io::write_vdb_sparse(*output, *band, {"surface", true, 3, "shm"}); });
        if (!contour_out->empty()) {
            auto mesh = std::make_shared<PolygonMesh>(io::mesh_level_set(*band));
            if (mesh->face_count() == 0) throw Error(*contour_out, "the zero level set does not cross the octree's cube");
            writers.emplace_back(*contour_out, [=] { io::write_mesh(*contour_out, *mesh); });
        }
        write_all(writers);
        note("wrote " + *output + (contour_out->empty() ? "" : " and " + *contour_out));
    });
}

}  // namespace gsd::cli
