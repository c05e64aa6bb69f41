// gsd sdf — signed distance to meshes as they come: at queries, on a grid, as training samples,
// and over a list of meshes (--batch), sharded for scheduler array jobs (--shard).
//
// A batch never stops at a bad input: it says what was wrong with it, goes on, and exits 1 at
// the end if any input failed. Outputs are written atomically, so an output that exists is
// finished: a batch run again (after being killed, or with more inputs) skips them.
#include "cli.hpp"

#include <gsd/io.hpp>
#include <gsd/sdf.hpp>

#include <nlohmann/json.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

namespace gsd::cli {

namespace {

namespace fs = std::filesystem;

struct SdfArgs {
    std::string input, output, gradient;
    Domain domain;
    std::size_t samples = 0;
    std::vector<double> near_sigma = SdfSampleOptions{}.near_sigma;
    SdfSampleOptions options;
    std::string sign = "auto";
    // --batch
    std::string batch, out_dir, shard;
    bool dry_run = false;

    bool sampling() const { return samples > 0; }
};

// ---- one mesh -------------------------------------------------------------------------------

// Samples as (N, 4) float32 rows `x y z sdf`, and a sidecar OUT.json with the frame (center and
// radius of the bounding sphere: what --normalize divides by) and the options: both or neither.
void write_samples(const std::string& path, const SdfSamples& s, const SdfArgs& a) {
    io::write_npy(path, {s.phi.size(), 4}, sample_rows(s));
    nlohmann::json j;
    j["method"] = "sdf samples";
    j["columns"] = {"x", "y", "z", "sdf"};
    j["center"] = {s.center.x(), s.center.y(), s.center.z()};
    j["radius"] = s.radius;
    j["normalized"] = a.options.normalize;
    j["near_sigma"] = a.near_sigma;
    j["uniform_fraction"] = a.options.uniform_fraction;
    j["seed"] = a.options.seed;
    j["sign"] = a.sign;
    j["command"] = globals().argv;
    try {
        io::write_file_atomic(path + ".json", j.dump(2) + "\n");
    } catch (...) {
        remove_output(path);
        throw;
    }
}

void sdf_samples(const SdfArgs& a, const PolygonMesh& mesh, const std::string& out) {
    Progress progress("sdf");
    const auto t0 = std::chrono::steady_clock::now();
    const SdfSamples s = sample_sdf(mesh, a.samples, a.options, progress.fn());
    progress.finish();
    if (globals().verbose)
        note(std::to_string(a.samples) + " samples of " + std::to_string(s.triangles) + " triangles in " +
             fmt("%.3f s", seconds_since(t0)) + "; bounding sphere center " + fmt("%.9g", s.center.x()) + " " +
             fmt("%.9g", s.center.y()) + " " + fmt("%.9g", s.center.z()) + ", radius " + fmt("%.9g", s.radius) +
             "; sign: " + sdf_sign_name(s.sign) + "; " + s.diagnosis);
    write_samples(out, s, a);
    note("wrote " + out);
}

void sdf_field(const SdfArgs& a, const PolygonMesh& mesh, const std::string& out, const std::string& gradient_out) {
    auto eval = [&](const Points& q, const ProgressFn& p) {
        MeshSdfResult r = mesh_sdf(mesh, q, a.options, p);
        if (globals().verbose) note("sign: " + std::string(sdf_sign_name(r.sign)) + "; " + r.diagnosis);
        else if (r.degenerate) note(std::to_string(r.degenerate) + " degenerate (zero-area) triangles left out");
        FieldValues v;
        v.phi.assign(r.phi.begin(), r.phi.end());
        v.gradient.assign(r.gradient.begin(), r.gradient.end());
        v.device = r.device;
        return v;
    };
    evaluate_and_write(
        a.domain, bounding_box(mesh.vertices), out, gradient_out, eval,
        [&](const GridSpec& g, const ProgressFn& p) { return eval(g.nodes(), p); }, "sdf", "sdf", kSdfGridBytesPerNode);
}

void sdf_one(const SdfArgs& a, const std::string& input, const std::string& out) {
    const PolygonMesh mesh = io::read_mesh(input);
    if (a.sampling()) sdf_samples(a, mesh, out);
    else sdf_field(a, mesh, out, a.gradient);
}

// ---- --batch --------------------------------------------------------------------------------

struct BatchItem {
    std::string input, output;
};

// The list: one mesh path a line (relative paths from the current directory); blank lines and
// lines starting with # are skipped. Each output is OUT_DIR/STEM.npy, STEM the input's file
// name without its extension; two inputs with one stem are an error (one would overwrite the
// other).
std::vector<BatchItem> read_batch(const std::string& list, const std::string& out_dir) {
    std::ifstream in(list);
    if (!in) throw Error(list, "cannot open the batch list");
    std::vector<BatchItem> items;
    std::map<std::string, std::size_t> line_of_output;
    std::string line;
    for (std::size_t number = 1; std::getline(in, line); ++number) {
        const auto first = line.find_first_not_of(" \t\r");
        if (first == std::string::npos || line[first] == '#') continue;
        const auto last = line.find_last_not_of(" \t\r");
        const std::string path = line.substr(first, last - first + 1);
        const std::string stem = fs::path(path).stem().string();
        if (stem.empty()) throw Error(list, "line " + std::to_string(number) + ": no file name in '" + path + "'");
        const std::string out = (fs::path(out_dir) / (stem + ".npy")).string();
        if (auto [it, fresh] = line_of_output.emplace(out, number); !fresh)
            throw Error(list, "lines " + std::to_string(it->second) + " and " + std::to_string(number) + " both write " +
                                  out + " (inputs with one file name in different folders: give them their own lists)");
        items.push_back({path, out});
    }
    if (in.bad()) throw Error(list, "read error");
    if (items.empty()) throw Error(list, "the batch list names no meshes");
    return items;
}

struct Shard {
    std::size_t index = 0, count = 1;
};

std::size_t shard_number(const std::string& text, const std::string& what) {
    std::size_t used = 0;
    unsigned long long v = 0;
    try {
        v = std::stoull(text, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (used == 0 || used != text.size() || text[0] == '-')
        throw Error("--shard", what + " '" + text + "' is not a whole number");
    return std::size_t(v);
}

std::string env(const char* name) {
    const char* v = std::getenv(name);
    return v ? v : "";
}

// "I/N" (0 ≤ I < N); "auto" (a Slurm array task: SLURM_ARRAY_TASK_ID − SLURM_ARRAY_TASK_MIN of
// SLURM_ARRAY_TASK_COUNT); "auto/N" (the index from Slurm or from a Kubernetes Indexed Job's
// JOB_COMPLETION_INDEX, N given).
Shard parse_shard(const std::string& s) {
    if (s.empty()) return {};
    Shard sh;
    const auto slash = s.find('/');
    const std::string index = s.substr(0, slash);
    if (slash != std::string::npos) sh.count = shard_number(s.substr(slash + 1), "the shard count");
    if (index == "auto") {
        if (!env("SLURM_ARRAY_TASK_ID").empty()) {
            const std::size_t id = shard_number(env("SLURM_ARRAY_TASK_ID"), "SLURM_ARRAY_TASK_ID");
            const std::size_t min = env("SLURM_ARRAY_TASK_MIN").empty() ? 0 : shard_number(env("SLURM_ARRAY_TASK_MIN"), "SLURM_ARRAY_TASK_MIN");
            if (id < min) throw Error("--shard", "SLURM_ARRAY_TASK_ID is below SLURM_ARRAY_TASK_MIN");
            sh.index = id - min;
            if (slash == std::string::npos) {
                if (env("SLURM_ARRAY_TASK_COUNT").empty())
                    throw Error("--shard", "auto: SLURM_ARRAY_TASK_COUNT is not set; give the count as auto/N");
                sh.count = shard_number(env("SLURM_ARRAY_TASK_COUNT"), "SLURM_ARRAY_TASK_COUNT");
            }
        } else if (!env("JOB_COMPLETION_INDEX").empty()) {
            if (slash == std::string::npos)
                throw Error("--shard", "auto under a Kubernetes Indexed Job needs the count: auto/N (N: the job's completions)");
            sh.index = shard_number(env("JOB_COMPLETION_INDEX"), "JOB_COMPLETION_INDEX");
        } else {
            throw Error("--shard", "auto: neither SLURM_ARRAY_TASK_ID nor JOB_COMPLETION_INDEX is set");
        }
    } else {
        if (slash == std::string::npos) throw Error("--shard", "expected I/N (this shard's index from 0, and how many), or auto");
        sh.index = shard_number(index, "the shard index");
    }
    if (sh.count == 0) throw Error("--shard", "the shard count must be at least 1");
    if (sh.index >= sh.count)
        throw Error("--shard", "index " + std::to_string(sh.index) + " is not below the count " + std::to_string(sh.count));
    return sh;
}

// Finished: the output exists, with its sidecar where it has one (a run killed between the two
// left the array alone, which is redone).
bool finished(const SdfArgs& a, const std::string& out) {
    const bool sidecar = a.sampling() || a.domain.is_grid();
    return fs::exists(out) && (!sidecar || fs::exists(out + ".json"));
}

// What runs killed while writing this shard's outputs left in the folder: the atomic writer's
// temporary files (OUT.tmp-…, OUT.json.tmp-…, src/io/common.cpp). One pass over the folder.
void remove_leftovers(const std::string& out_dir, const std::vector<BatchItem>& items) {
    std::set<std::string> outputs;
    for (const BatchItem& item : items) outputs.insert(fs::path(item.output).filename().string());
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(out_dir, ec)) {
        std::string f = entry.path().filename().string();
        const auto tmp = f.find(".tmp-");
        if (tmp == std::string::npos) continue;
        f.resize(tmp);
        if (f.size() > 5 && f.compare(f.size() - 5, 5, ".json") == 0) f.resize(f.size() - 5);
        if (outputs.count(f)) fs::remove(entry.path(), ec);
    }
}

void run_batch(const SdfArgs& a) {
    const std::vector<BatchItem> all = read_batch(a.batch, a.out_dir);
    const Shard shard = parse_shard(a.shard);
    std::vector<BatchItem> mine;
    for (std::size_t i = shard.index; i < all.size(); i += shard.count) mine.push_back(all[i]);
    const std::string which = a.shard.empty() ? "" : " (shard " + std::to_string(shard.index) + "/" + std::to_string(shard.count) + ")";
    if (a.dry_run) {
        // What this shard would do, one line each: "INPUT -> OUTPUT" and whether it is done.
        std::ostringstream s;
        s << mine.size() << " of " << all.size() << " inputs" << which << "\n";
        for (const BatchItem& item : mine)
            s << item.input << " -> " << item.output << (finished(a, item.output) ? " (done)" : "") << "\n";
        std::fputs(s.str().c_str(), stdout);
        return;
    }
    std::error_code ec;
    fs::create_directories(a.out_dir, ec);
    if (ec) throw Error(a.out_dir, "cannot create the output folder: " + ec.message());
    remove_leftovers(a.out_dir, mine);
    std::size_t done = 0, skipped = 0;
    std::vector<std::string> failed;
    for (std::size_t k = 0; k < mine.size(); ++k) {
        const BatchItem& item = mine[k];
        if (finished(a, item.output)) {
            ++skipped;
            continue;
        }
        note("[" + std::to_string(k + 1) + "/" + std::to_string(mine.size()) + "] " + item.input);
        try {
            sdf_one(a, item.input, item.output);
            ++done;
        } catch (const Error& e) {
            // "gsd: error: INPUT: what", with the part the error names when it is not the input.
            const std::string why = e.where().empty() || e.where() == item.input ? e.what() : e.where() + ": " + e.what();
            std::fprintf(stderr, "gsd: error: %s: %s\n", item.input.c_str(), why.c_str());
            failed.push_back(item.input);
        } catch (const std::bad_alloc&) {
            std::fprintf(stderr, "gsd: error: %s: out of memory\n", item.input.c_str());
            failed.push_back(item.input);
        }
    }
    note(std::to_string(done) + " written, " + std::to_string(skipped) + " already there, " +
         std::to_string(failed.size()) + " failed, of " + std::to_string(mine.size()) + " inputs" + which);
    if (!failed.empty()) {
        std::string list;
        for (const std::string& f : failed) list += "\n  " + f;
        throw Error(a.batch, std::to_string(failed.size()) + " of " + std::to_string(mine.size()) +
                                 " inputs failed (each said why above):" + list);
    }
}

void check(SdfArgs& a) {
    if (!a.batch.empty()) {
        if (!a.input.empty()) throw CLI::ValidationError("INPUT", "give one mesh or --batch LIST, not both");
        if (!a.output.empty()) throw CLI::ValidationError("--output", "--batch writes OUT_DIR/STEM.npy: give --out-dir, not -o");
        if (a.out_dir.empty()) throw CLI::RequiredError("--out-dir");
    } else {
        if (a.input.empty()) throw CLI::RequiredError("INPUT (or --batch LIST)");
        if (a.output.empty()) throw CLI::RequiredError("--output");
        if (!a.shard.empty() || a.dry_run || !a.out_dir.empty())
            throw CLI::ValidationError("--shard, --dry-run and --out-dir", "go with --batch");
    }
    const int domains = int(a.domain.is_grid()) + int(!a.domain.queries.empty()) + int(a.sampling());
    if (domains != 1) throw CLI::ValidationError("--grid, --queries, --samples", "give exactly one");
    if (!a.gradient.empty() && (a.sampling() || !a.batch.empty()))
        throw CLI::ValidationError("--gradient", "goes with --queries or --grid on one mesh");
    a.options.gradient = !a.gradient.empty();
    if (a.sampling() && !a.output.empty() && io::extension(a.output) != ".npy")
        throw CLI::ValidationError("--output", "samples are written as .npy: (N, 4) rows x y z sdf");
    if (!(a.options.inside_threshold > 0 && a.options.inside_threshold < 1))
        throw Error("--inside", "must be strictly between 0 and 1");
    a.options.sign = sdf_sign_from_name(a.sign);
    a.options.near_sigma = a.near_sigma;
    if (!a.output.empty()) check_grid_output(a.output, a.domain.is_grid());
}

}  // namespace

void add_sdf(CLI::App& app) {
    auto* sdf = app.add_subcommand(
        "sdf", "Signed distance to meshes in any state (holes, flips, duplicates): the exact distance to their triangles, "
               "negative inside by the generalized winding number; at queries, on a grid, as training samples, or over "
               "a list of meshes");
    auto a = std::make_shared<SdfArgs>();
    sdf->add_option("INPUT", a->input, "Mesh (.obj .ply .off .stl)");
    sdf->add_option("-o,--output", a->output,
                    "Output float32 .npy: (N,N,N) for a grid, (M,) for queries, (S,4) rows x y z sdf for samples; or .vdb "
                    "for a grid")
        ->check(output_file({".npy", ".vdb"}));
    a->domain.add_to(*sdf, true);
    sdf->add_option("--gradient", a->gradient,
                    "Also write ∇φ (the unit vector from the nearest point, signed as φ): (M,3) or (N,N,N,3) float32 .npy")
        ->check(output_file({".npy"}));
    sdf->add_option("--samples", a->samples,
                    "Training samples instead: S points near the surface (offset by Gaussians of --near-sigma) and in its "
                    "box (--uniform), with their signed distances")
        ->check(CLI::PositiveNumber);
    sdf->add_option("--near-sigma", a->near_sigma,
                    "With --samples: the offsets' standard deviations, × the bounding sphere's radius (samples split "
                    "evenly between them)")
        ->delimiter(',')->check(finite_number())->check(CLI::PositiveNumber)->capture_default_str();
    sdf->add_option("--uniform", a->options.uniform_fraction,
                    "With --samples: the share drawn uniformly in the bounding sphere's cube")
        ->check(finite_number())->check(CLI::Range(0.0, 1.0))->capture_default_str();
    sdf->add_flag("--normalize", a->options.normalize,
                  "With --samples: points and distances in the unit-sphere frame ((x − center) / radius; the sidecar "
                  "OUT.json has the center and radius)");
    sdf->add_option("--seed", a->options.seed, "With --samples: the random stream (same seed, same samples)")
        ->capture_default_str();
    sdf->add_option("--sign", a->sign,
                    "auto: pseudonormals on a clean closed mesh, else winding numbers of the faces with their orientation "
                    "repaired (-v says which and why); winding: the winding number of the faces as given exceeds --inside; "
                    "pseudonormal: exact on clean meshes only; shm: the grid Signed Heat Method's sign; none: unsigned")
        ->check(CLI::IsMember({"auto", "winding", "pseudonormal", "shm", "none"}))->capture_default_str();
    sdf->add_option("--shm-grid", a->options.shm_grid, "With --sign shm: the SHM grid's nodes per axis")
        ->check(CLI::Range(8, 512))->capture_default_str();
    sdf->add_option("--inside", a->options.inside_threshold, "Winding number above which a point is inside")
        ->check(finite_number())->check(CLI::Range(0.0, 1.0))->capture_default_str();
    sdf->add_option("--device", a->options.device, "The winding numbers' device: auto | gpu | cpu | device index | name substring");
    sdf->add_option("--batch", a->batch,
                    "A list of meshes, one path a line: each gets OUT_DIR/STEM.npy; finished outputs are skipped, a bad "
                    "input is reported and the batch goes on (exit 1 at the end)");
    sdf->add_option("--out-dir", a->out_dir, "With --batch: the folder for the outputs (created if needed)");
    sdf->add_option("--shard", a->shard,
                    "With --batch: I/N does inputs I, I+N, I+2N, … of the list (I from 0); auto takes I (and N) from a "
                    "Slurm array task, auto/N from Slurm or a Kubernetes Indexed Job");
    sdf->add_flag("--dry-run", a->dry_run, "With --batch: list this shard's inputs and outputs (and which are done), do nothing");
    sdf->callback([a] {
        check(*a);
        const DevicePrefetch prefetch(a->options.device);
        if (!a->batch.empty()) return run_batch(*a);
        sdf_one(*a, a->input, a->output);
    });
}

}  // namespace gsd::cli
