// Shared pieces of the gsd command-line tool: exit codes, progress, grid/bounds arguments.
#pragma once

#include <gsd/core.hpp>
#include <gsd/field.hpp>
#include <gsd/gpu.hpp>
#include <gsd/shm.hpp>

#include <CLI/CLI.hpp>

#include <chrono>
#include <functional>
#include <memory>
#include <future>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace gsd::cli {

enum Exit { kOk = 0, kDataError = 1, kUsage = 2 };

/// Global flags every command understands.
struct Globals {
    bool quiet = false;
    bool verbose = false;
    std::vector<std::string> argv;  ///< the command line, recorded in grid sidecars
    const CLI::App* app = nullptr;  ///< the parsed command line, for the options a sidecar records
};
Globals& globals();

/// Reports progress of long work on stderr: a bar on a terminal, plain lines otherwise. Stays
/// silent for the first second, so quick jobs print nothing.
class Progress {
public:
    explicit Progress(std::string task);
    ~Progress();
    ProgressFn fn();
    void update(std::string_view stage, double fraction);
    void finish();

private:
    std::string task_;
    std::chrono::steady_clock::time_point start_;
    bool tty_;
    bool shown_ = false;
    int last_decile_ = -1;
    std::string last_stage_;
};

/// --grid N [--bounds x0 y0 z0 x1 y1 z1] | --queries Q.npy
struct Domain {
    int grid = 0;
    std::vector<double> bounds;
    std::string queries;
    void add_to(CLI::App& app, bool bounds_optional);
    bool is_grid() const { return grid > 0; }
    /// The grid on the given bounds, or on `fallback` (the input's bounding cube + 10%), checked
    /// against the memory budget at `bytes_per_node` (check_grid_memory).
    GridSpec grid_spec(const std::optional<Box>& fallback, double bytes_per_node) const;
};

/// Refuses (gsd::Error naming --grid) a grid whose estimated memory — bytes_per_node, the
/// command's own measured peak per node with room (docs/io.md, "Memory budget") — passes
/// memory_budget().
void check_grid_memory(const GridSpec& g, double bytes_per_node);
/// Peak bytes per grid node of each grid command (measured at 128³ and 256³, about 1.2× room).
constexpr double kShmGridBytesPerNode = 96, kWindingGridBytesPerNode = 64, kBlendGridBytesPerNode = 12,
                 kBlendGradientBytesPerNode = 20;
/// gsd sdf: 65 bytes a node measured between 100³ and 128³ (peak RSS 173 and 245 MB, a
/// 9·10⁴-face mesh), with room.
constexpr double kSdfGridBytesPerNode = 80;

/// The input's bounding cube, centered on its box, enlarged by 10%.
Box default_bounds(const Box& b);
/// gsd::reorient_normals on a cloud a command is about to use, and a note of how many it turned
/// (`prefix` before it, e.g. the file; `keep`: how the user keeps them instead).
void turn_back_normals(PointCloud& cloud, const std::string& prefix = {}, const std::string& keep = "--keep-normals keeps them");
Box bounds_from(const std::vector<double>& v, const std::string& option);
/// "--bounds x0 y0 z0 x1 y1 z1" for notes.
std::string bounds_text(const Box& b);

/// Writes a grid's float32 values, (nx,ny,nz[,components]), and its sidecar GRID.npy.json
/// (bounds, shape, `method`, the options given, the command line): both or neither. A `.vdb`
/// path gets an OpenVDB grid instead (values only; φ as a level set, winding numbers as they
/// are), whose own transform says where the nodes are.
void check_grid_output(const std::string& path, bool is_grid);
void write_grid(const std::string& path, const GridSpec& g, const std::vector<float>& values, int components,
                const std::string& method);

/// The grid of an (nx,ny,nz) array read from `path`: on `bounds` (--bounds) when given, else on
/// the bounds of its sidecar, whose shape must match; an error naming --bounds when neither.
GridSpec grid_of(const std::vector<std::size_t>& shape, const std::string& path, const std::vector<double>& bounds);

/// Writes a float32 result for a domain: (N,N,N[,3]) for a grid, (M[,3]) for queries.
/// Evaluates a field over a domain (queries or a grid) and writes the outputs (values, and
/// gradients to `gradient_out` if not empty), both or neither; `what` names the progress,
/// `method` the grid sidecar's method.
using EvalPoints = std::function<FieldValues(const Points&, const ProgressFn&)>;
using EvalGrid = std::function<FieldValues(const GridSpec&, const ProgressFn&)>;
void evaluate_and_write(const Domain& domain, const std::optional<Box>& input_box, const std::string& out,
                        const std::string& gradient_out, const EvalPoints& eval_points, const EvalGrid& eval_grid,
                        const std::string& what, const std::string& method, double grid_bytes_per_node);

void write_values(const std::string& path, const Domain& d, const GridSpec& g, std::size_t count,
                  const std::vector<float>& values, int components, const std::string& method);

/// A check for an output option: its extension must be one of `extensions` (".npy", …;
/// case-insensitive), so a run never computes for minutes and then writes the wrong format or
/// nothing. An existing character device or FIFO (`-o /dev/null`) is accepted as it is.
CLI::Validator output_file(std::vector<std::string> extensions);
/// Refuses NaN and ±inf before any range check sees them (a range test lets NaN through, and
/// would print the largest double in full for inf). Goes first: ->check(finite_number())->check(…).
CLI::Validator finite_number();

/// Undoes an output already written when a later one fails (all outputs or none). Only a
/// regular file is removed: `-o /dev/null` or a FIFO was written into, not created. A .npy
/// takes its grid sidecar (GRID.npy.json) with it.
void remove_output(const std::string& path);

/// Writes every requested output (pairs of path and writer; an empty path is skipped), or
/// none: a failure removes what was already written.
void write_all(const std::vector<std::pair<std::string, std::function<void()>>>& outputs);

/// Prints "gsd: <message>" unless --quiet.
void note(const std::string& message);

/// Runs `work`. An error the library raises about its argument `field` ("values" of a grid, a
/// "mesh") is raised again naming `file`, the input that argument came from, so the message
/// reads "gsd: error: <file>: <what>" like every other data error.
void naming_file(const std::string& file, const std::string& field, const std::function<void()>& work);

double seconds_since(std::chrono::steady_clock::time_point t0);
/// printf-style formatting of one number.
std::string fmt(const char* format, double value);
/// Peak resident memory of this process (Linux), for --verbose reports.
std::string peak_memory();

/// Binds the OpenMP threads to one CPU each (core/threads.hpp) when the whole run stays on the
/// CPU path: every device choice on the command line and in $GSD_DEVICE is "cpu" or "auto",
/// and "auto" cannot find a GPU (no GPU device node); not for `gsd info`. Call first thing in
/// main(); with -v, prints what it did.
void place_threads(int argc, char** argv);
/// Has glibc keep freed memory for reuse rather than return it at once (cli.cpp says why);
/// nothing with other C libraries. Call first thing in main().
void keep_freed_memory();
/// Stops OpenBLAS's worker threads, which start spinning as the library loads (cli.cpp says
/// why); nothing where the BLAS is another. Call first thing in main().
void quiet_blas_threads();

/// Finds the Vulkan devices on another thread while a command reads its input: loading the
/// loader and its drivers takes tens of milliseconds (Mesa's software driver ~30 ms), which a
/// whole run on the CPU would otherwise pay on top. Waits for it when it goes out of scope.
/// Nothing to find when the device asked for (or $GSD_DEVICE) is "cpu"; with a GPU, its context
/// is made there too.
class DevicePrefetch {
public:
    explicit DevicePrefetch(const Device& device);
    ~DevicePrefetch();
    DevicePrefetch(const DevicePrefetch&) = delete;
    DevicePrefetch& operator=(const DevicePrefetch&) = delete;

private:
    std::future<void> found_;
};

/// Runs `work` on a thread of its own (a field's prepare() while the queries are read); the
/// returned future waits for it when destroyed. No thread to be had: nothing (the work is done
/// when first needed anyway).
std::future<void> prepare_in_background(std::function<void()> work);

/// A mesh file format that cannot hold curves (.ply .off .stl): curves must come from --curves.
bool is_curveless_mesh_format(const std::string& path);

/// A file where the surface commands expect a mesh that has no faces: a point cloud, whose
/// surface gsd::cloud_surface makes (tools/gsd/surface.cpp).
bool is_cloud_file(const std::string& path);
/// Polylines as an OBJ file: `header` (comment lines, each starting with #) and one group per
/// entry (tools/gsd/surface.cpp).
std::string polylines_obj(const std::string& header, const std::vector<std::pair<std::string, const Polylines*>>& groups);
/// A splat radius per point for pictures of clouds (tools/gsd/surface.cpp).
std::vector<double> splat_radii(const Points& points);

/// The SHM's source from input files (meshes by their faces, clouds by their points and
/// normals; several combined), and the inputs' bounding box. `read(box)`, if given, runs once
/// the files are read and before the sources are built (a memory check that needs the extent).
/// `drop_outliers`: clouds lose the points PAT's outlier scores reject (gsd::without_outliers);
/// `reorient`: then their flipped normals are turned back (gsd::reorient_normals).
struct LoadedShmSource {
    ShmSource source;
    Box box;
};
LoadedShmSource load_shm_source(const std::vector<std::string>& inputs, const std::function<void(const Box&)>& read = {},
                                bool drop_outliers = false, bool reorient = false);
/// `gsd shm adaptive` (tools/gsd/shm_adaptive.cpp), added under the `shm` command.
void add_shm_adaptive(CLI::App& shm);
/// `gsd shm surface` (tools/gsd/surface.cpp), added under the `shm` command.
void add_shm_surface(CLI::App& shm);
/// `gsd curve` (tools/gsd/surface.cpp): curves on meshes for demos and tests.
void add_curve(CLI::App& app);
/// `gsd swn` (tools/gsd/swn.cpp): Surface Winding Numbers.
void add_swn(CLI::App& app);
/// gsd sdf (sdf.cpp).
void add_sdf(CLI::App& app);
/// gsd field (field.cpp): the field algebra.
void add_field(CLI::App& app);
/// A field expression (docs/field.md) read, its leaves loaded: the field, and the box where its
/// zero set can be (the leaves' boxes, grown by outward offsets).
struct ParsedField {
    std::shared_ptr<const Field> field;
    Box box;
};
/// Nodes per axis of the grids opening and closing re-distance on, unless --morphology-grid.
constexpr int kMorphologyGrid = 128;
/// How opening and closing re-distance: a cloud's or .tori's by resampling its points (no grid)
/// unless `by_grid`; anything else on a grid of `grid` nodes per axis.
struct MorphologyArgs {
    int grid = kMorphologyGrid;
    bool by_grid = false;
};
ParsedField parse_field_expression(const std::string& expression, const std::string& device,
                                   const MorphologyArgs& morphology = {});
/// --morphology-grid N and --morphology-by-grid, for the commands that read expressions.
void add_morphology_grid(CLI::App& app, MorphologyArgs& morphology);

}  // namespace gsd::cli
