#include "cli.hpp"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "core/threads.hpp"
#include "gpu/device_choice.hpp"

#include <dlfcn.h>
#include <sys/stat.h>

#include <gsd/io.hpp>
#include <gsd/spatial.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <system_error>
#include <unistd.h>

namespace gsd::cli {

Globals& globals() {
    static Globals g;
    return g;
}

CLI::Validator output_file(std::vector<std::string> extensions) {
    std::string names;
    for (const std::string& e : extensions) names += (names.empty() ? "" : " ") + e;
    return CLI::Validator(
        [extensions, names](std::string& path) -> std::string {
            struct stat st {};
            if (::stat(path.c_str(), &st) == 0 && (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode))) return {};
            const std::string ext = io::extension(path);
            for (const std::string& e : extensions)
                if (ext == e) return {};
            return "'" + path + "' must end in " + names;
        },
        names);
}

CLI::Validator finite_number() {
    return CLI::Validator(
        [](std::string& text) -> std::string {
            char* end = nullptr;
            const double x = std::strtod(text.c_str(), &end);
            if (end != text.c_str() && !std::isfinite(x)) return "'" + text + "' is not a finite number";
            return {};
        },
        "FINITE");
}

void remove_output(const std::string& path) {
    std::error_code ec;
    if (std::filesystem::is_regular_file(path, ec)) std::filesystem::remove(path, ec);
    // A grid's sidecar goes with it.
    const std::string sidecar = io::grid_metadata_path(path);
    if (io::extension(path) == ".npy" && std::filesystem::is_regular_file(sidecar, ec)) std::filesystem::remove(sidecar, ec);
}

void write_all(const std::vector<std::pair<std::string, std::function<void()>>>& outputs) {
    // Two outputs into one file would leave only the second (devices like /dev/null excepted).
    std::vector<std::filesystem::path> seen;
    for (const auto& [path, write] : outputs) {
        if (path.empty()) continue;
        struct stat st {};
        if (::stat(path.c_str(), &st) == 0 && (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode))) continue;
        std::error_code ec;
        const std::filesystem::path canonical = std::filesystem::weakly_canonical(path, ec);
        const std::filesystem::path key = ec ? std::filesystem::path(path) : canonical;
        if (std::find(seen.begin(), seen.end(), key) != seen.end())
            throw Error(path, "named by two outputs: give each output its own file");
        seen.push_back(key);
    }
    std::vector<std::string> done;
    try {
        for (const auto& [path, write] : outputs) {
            if (path.empty()) continue;
            write();
            done.push_back(path);
        }
    } catch (...) {
        for (const std::string& p : done) remove_output(p);
        throw;
    }
}

void keep_freed_memory() {
    // glibc hands a freed block back to the kernel once the heap's free top passes its trim
    // threshold (a few MB at most, as it adapts), and the next allocation of that size faults
    // every page in again, zeroed. Work done in steps (the render's wavefront: a few MB of rays'
    // points, values and bookkeeping a step, some 250 steps) paid that each step: 2.3·10⁴ page
    // faults for a 320×240 picture against 4.8·10³ on the CPU path. The CLI keeps up to 256 MB
    // freed for reuse; blocks of 64 MB or more still come from and go back to the kernel.
#if defined(__GLIBC__)
    mallopt(M_MMAP_THRESHOLD, 64 << 20);
    mallopt(M_TRIM_THRESHOLD, 256 << 20);
#endif
}

void quiet_blas_threads() {
    // OpenBLAS (Debian's libblas, which CHOLMOD and LAPACK bring in) starts its worker threads
    // when it loads, and each spins for about 0.1 s waiting for work before it sleeps: on the
    // 2-core machine that took a core from the first tenth of a second of every command (the
    // Vulkan device's making, a small grid's whole evaluation). No gsd command calls the BLAS
    // before main(); one that does later starts the threads again. Looked up by name, so a
    // different BLAS is left alone.
    using Shutdown = int (*)();
    if (auto shutdown = reinterpret_cast<Shutdown>(dlsym(RTLD_DEFAULT, "blas_thread_shutdown_"))) shutdown();
}

void place_threads(int argc, char** argv) {
    bool verbose = false, quiet = false, listing = false;
    std::string given;  // the last --device: the choice select() will resolve
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "-v" || a == "--verbose") verbose = true;
        if (a == "-q" || a == "--quiet") quiet = true;
        if (a == "info") listing = true;  // lists the Vulkan devices
        if (a == "--device" && i + 1 < argc) given = argv[i + 1];
        if (a.rfind("--device=", 0) == 0) given = a.substr(9);
    }
    std::string device = gpu::requested_choice(Device(given));
    for (char& c : device) c = char(std::tolower(static_cast<unsigned char>(c)));
    // Vulkan drivers' threads would inherit the first thread's single CPU: bind only where none
    // is loaded ("auto" loads them only where a GPU might be).
    const bool cpu_path = device == "cpu" || (device == "auto" && !gpu::has_gpu_device_node());
    if (listing || !cpu_path) return;
    const std::string what = detail::bind_openmp_threads();
    if (verbose && !quiet) std::fprintf(stderr, "gsd: %s\n", what.c_str());
}

void note(const std::string& message) {
    if (!globals().quiet) std::fprintf(stderr, "gsd: %s\n", message.c_str());
}

void naming_file(const std::string& file, const std::string& field, const std::function<void()>& work) {
    try {
        work();
    } catch (const Error& e) {
        if (e.where() == field) throw Error(file, e.what());
        throw;
    }
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::string fmt(const char* format, double value) {
    char buf[64];
    std::snprintf(buf, sizeof(buf), format, value);
    return buf;
}

std::string peak_memory() {
    std::FILE* f = std::fopen("/proc/self/status", "r");
    if (!f) return "unknown";
    char line[256];
    std::string out = "unknown";
    while (std::fgets(line, sizeof(line), f))
        if (std::strncmp(line, "VmHWM:", 6) == 0) {
            out = fmt("%.0f MiB", std::atof(line + 6) / 1024.0);
            break;
        }
    std::fclose(f);
    return out;
}

Progress::Progress(std::string task)
    : task_(std::move(task)), start_(std::chrono::steady_clock::now()), tty_(isatty(STDERR_FILENO) != 0) {}

Progress::~Progress() { finish(); }

ProgressFn Progress::fn() {
    return [this](std::string_view stage, double fraction) { update(stage, fraction); };
}

void Progress::update(std::string_view stage, double fraction) {
    if (globals().quiet) return;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    if (elapsed < 1.0 && !shown_) return;
    shown_ = true;
    const int pct = int(std::lround(100 * std::clamp(fraction, 0.0, 1.0)));
    if (tty_) {
        const int width = 30, filled = pct * width / 100;
        std::fprintf(stderr, "\r%s %-10.*s [%s%s] %3d%% %6.1fs", task_.c_str(), int(stage.size()), stage.data(),
                     std::string(std::size_t(filled), '#').c_str(), std::string(std::size_t(width - filled), '.').c_str(),
                     pct, elapsed);
        std::fflush(stderr);
    } else {
        const int decile = pct / 10;
        if (decile == last_decile_ && stage == last_stage_) return;
        last_decile_ = decile;
        last_stage_ = std::string(stage);
        std::fprintf(stderr, "gsd: %s: %.*s %d%% (%.1fs)\n", task_.c_str(), int(stage.size()), stage.data(), pct, elapsed);
    }
}

void Progress::finish() {
    if (shown_ && tty_) std::fprintf(stderr, "\n");
    shown_ = false;
}

void Domain::add_to(CLI::App& app, bool bounds_optional) {
    // 1290³ is the largest cube under 2^31 nodes (GridSpec::validate), so a larger N fails here.
    auto* g = app.add_option("--grid", grid, "Evaluate on an N×N×N grid of nodes (N ≤ 1290: 2^31 nodes)")->check(CLI::Range(2, 1290));
    auto* b = app.add_option("--bounds", bounds,
                             bounds_optional ? "Grid box x0 y0 z0 x1 y1 z1 (default: the input's bounding cube + 10%)"
                                             : "Grid box x0 y0 z0 x1 y1 z1")
                  ->expected(6);
    auto* q = app.add_option("--queries", queries, "Evaluate at the points of an (M,3) .npy file");
    b->needs(g);
    g->excludes(q);
    if (!bounds_optional) g->needs(b);
}

std::string bounds_text(const Box& b) {
    char buf[160];
    std::snprintf(buf, sizeof(buf), "--bounds %.6g %.6g %.6g %.6g %.6g %.6g", b.lo.x(), b.lo.y(), b.lo.z(), b.hi.x(), b.hi.y(), b.hi.z());
    return buf;
}

Box bounds_from(const std::vector<double>& v, const std::string& option) {
    if (v.size() != 6) throw Error(option, "expects 6 numbers: x0 y0 z0 x1 y1 z1");
    Box b{{v[0], v[1], v[2]}, {v[3], v[4], v[5]}};
    for (int a = 0; a < 3; ++a) {
        if (!std::isfinite(b.lo[a]) || !std::isfinite(b.hi[a])) throw Error(option, "bounds must be finite");
        if (!(b.hi[a] > b.lo[a])) throw Error(option, "bounds must satisfy x0 < x1, y0 < y1, z0 < z1");
    }
    return b;
}

Box default_bounds(const Box& b) { return padded_cube(b); }

void turn_back_normals(PointCloud& cloud, const std::string& prefix, const std::string& keep) {
    if (const std::size_t turned = reorient_normals(cloud); turned > 0)
        note(prefix + std::to_string(turned) + " of " + std::to_string(cloud.size()) +
             " normals turned back, against their neighbours' (" + keep + ")");
}

void check_grid_memory(const GridSpec& g, double bytes_per_node) {
    const double bytes = bytes_per_node * double(g.node_count());
    check_memory(bytes, "--grid", "a " + std::to_string(g.nx) + "³ grid");
}

GridSpec Domain::grid_spec(const std::optional<Box>& fallback, double bytes_per_node) const {
    Box box;
    if (!bounds.empty()) box = bounds_from(bounds, "--bounds");
    else if (fallback) {
        box = default_bounds(*fallback);
        note("grid bounds (saved in the grid's .json sidecar, which contour and slice read): " + bounds_text(box));
    }
    else throw Error("--bounds", "a grid needs --bounds");
    GridSpec g = GridSpec::cube(grid, box);
    g.validate();
    check_grid_memory(g, bytes_per_node);
    return g;
}

bool is_curveless_mesh_format(const std::string& path) {
    const std::string ext = io::extension(path);
    return ext == ".ply" || ext == ".off" || ext == ".stl";
}

DevicePrefetch::DevicePrefetch(const Device& device) {
    // gpu::select resolves the choice as the command will ("cpu" returns at once, $GSD_DEVICE
    // counts) and makes the device list, and a GPU's context, once per process: the command's
    // own call then finds them made, or waits for them. An error is left for that call to raise.
    // No thread to be had: the command does it all itself, as it would have anyway.
    try {
        found_ = std::async(std::launch::async, [device] { gpu::select(device); });
    } catch (const std::system_error&) {
    }
}

DevicePrefetch::~DevicePrefetch() {
    if (found_.valid()) found_.wait();
}

std::future<void> prepare_in_background(std::function<void()> work) {
    try {
        return std::async(std::launch::async, std::move(work));
    } catch (const std::exception&) {  // no thread (std::system_error), no memory
        return {};
    }
}

namespace {

// The options given on the command line, from the root command down to the one that ran:
// {"--grid": "96", "INPUT": "cloud.ply", "--flag": true, ...}.
std::string given_options_json() {
    nlohmann::json j = nlohmann::json::object();
    for (const CLI::App* a = globals().app; a != nullptr;) {
        for (const CLI::Option* o : a->get_options()) {
            if (o->count() == 0 || o->get_name() == "--help" || o->get_name() == "--version") continue;
            const std::vector<std::string> r = o->results();
            if (o->get_expected_max() == 0) j[o->get_name()] = true;  // a flag
            else if (r.size() == 1) j[o->get_name()] = r[0];
            else j[o->get_name()] = r;
        }
        const auto subs = a->get_subcommands();
        a = subs.empty() ? nullptr : subs.front();
    }
    return j.dump();
}

// A sidecar only beside a file this run creates: not for `-o /dev/null` or a FIFO.
bool writes_regular_file(const std::string& path) {
    struct stat st {};
    return !(::stat(path.c_str(), &st) == 0 && (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode)));
}

}  // namespace

void check_grid_output(const std::string& path, bool is_grid) {
    if (io::extension(path) != ".vdb") return;
    if (!is_grid) throw CLI::ValidationError("--output", ".vdb holds grids (--grid); write --queries results to a .npy");
    io::require_vdb(path);  // before the work
}

void write_grid(const std::string& path, const GridSpec& g, const std::vector<float>& values, int components,
                const std::string& method) {
    if (io::extension(path) == ".vdb") {
        if (components != 1) throw Error(path, ".vdb output takes values, not gradients; write those to a .npy");
        io::VdbOptions o;
        o.level_set = method != "winding";  // signed distances are level sets; winding numbers are not
        o.name = o.level_set ? "surface" : "winding";
        o.method = method;
        return io::write_vdb(path, g, values, o);
    }
    std::vector<std::size_t> shape{std::size_t(g.nx), std::size_t(g.ny), std::size_t(g.nz)};
    if (components > 1) shape.push_back(std::size_t(components));
    io::GridMetadata meta;
    meta.grid = g;
    meta.components = components;
    meta.method = method;
    meta.options_json = given_options_json();
    meta.command = globals().argv;
    io::write_npy(path, shape, values);
    if (!writes_regular_file(path)) return;
    try {
        io::write_grid_metadata(path, meta);
    } catch (...) {
        remove_output(path);
        throw;
    }
}

GridSpec grid_of(const std::vector<std::size_t>& shape, const std::string& path, const std::vector<double>& bounds) {
    GridSpec g{int(shape[0]), int(shape[1]), int(shape[2]), {}};
    if (!bounds.empty()) {
        g.box = bounds_from(bounds, "--bounds");
    } else if (const auto meta = io::read_grid_metadata(path)) {
        if (meta->grid.nx != g.nx || meta->grid.ny != g.ny || meta->grid.nz != g.nz)
            throw Error(io::grid_metadata_path(path), "describes a " + std::to_string(meta->grid.nx) + "×" +
                                                         std::to_string(meta->grid.ny) + "×" + std::to_string(meta->grid.nz) +
                                                         " grid, but the array is " + std::to_string(g.nx) + "×" +
                                                         std::to_string(g.ny) + "×" + std::to_string(g.nz));
        g.box = meta->grid.box;
    } else {
        throw Error("--bounds", "needed: " + path + " has no sidecar " + io::grid_metadata_path(path) +
                                    " saying where its nodes are");
    }
    g.validate();
    return g;
}

void write_values(const std::string& path, const Domain& d, const GridSpec& g, std::size_t count,
                  const std::vector<float>& values, int components, const std::string& method) {
    if (d.is_grid()) return write_grid(path, g, values, components, method);
    std::vector<std::size_t> shape{count};
    if (components > 1) shape.push_back(std::size_t(components));
    io::write_npy(path, shape, values);
}

void evaluate_and_write(const Domain& domain, const std::optional<Box>& input_box, const std::string& out,
                        const std::string& gradient_out, const EvalPoints& eval_points, const EvalGrid& eval_grid,
                        const std::string& what, const std::string& method, double grid_bytes_per_node) {
    check_grid_output(out, domain.is_grid());  // before the work
    GridSpec grid;
    Points queries;
    if (domain.is_grid()) grid = domain.grid_spec(input_box, grid_bytes_per_node);
    else queries = io::read_queries(domain.queries);
    const std::size_t count = domain.is_grid() ? grid.node_count() : std::size_t(queries.rows());
    Progress progress(what);
    const auto t0 = std::chrono::steady_clock::now();
    const FieldValues v = domain.is_grid() ? eval_grid(grid, progress.fn()) : eval_points(queries, progress.fn());
    progress.finish();
    const double dt = seconds_since(t0);
    if (globals().verbose)
        note("evaluated " + std::to_string(count) + " points on " + v.device + " in " + fmt("%.3f s", dt) + " (" +
             fmt("%.3g", double(count) / std::max(dt, 1e-9)) + " points/s)");
    write_values(out, domain, grid, count, v.phi, 1, method);
    if (!gradient_out.empty()) {
        try {
            write_values(gradient_out, domain, grid, count, v.gradient, 3, method);
        } catch (...) {
            remove_output(out);  // all outputs or none
            throw;
        }
    }
    note("wrote " + out + (gradient_out.empty() ? "" : " and " + gradient_out));
}

}  // namespace gsd::cli
