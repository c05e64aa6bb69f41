// gsd/io.hpp — reading and writing point clouds, meshes, grids and query lists.
//
// Formats are chosen by file extension (case-insensitive). Every reader validates what it
// reads and throws gsd::Error{path, what} on anything malformed: missing file, empty file,
// truncated data, wrong counts, non-numeric tokens, NaN/Inf, missing normals. Writers write
// to a temporary file beside the target and rename it, so a failure never leaves a partial
// output behind.
#pragma once

#include <gsd/export.hpp>

#include <gsd/core.hpp>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace gsd::io {

// ---- point clouds with normals --------------------------------------------------------
// .ply (ascii, binary_little_endian, binary_big_endian; vertex properties x y z nx ny nz in
//       any order among others such as colors, any scalar type float/double/int/uchar/...;
//       other elements such as faces are skipped)
// .xyz .xyzn .txt (6 numbers per line: x y z nx ny nz; '#' comments and blank lines skipped)
// .pc  (lines "v x y z" and "vn nx ny nz"; counts must match)
// .obj (v and vn lines; vn paired with v by order)
// .npy (N×6, float32 or float64, C order)
// The returned cloud has passed gsd::validate (normals normalized).
GSD_EXPORT PointCloud read_point_cloud(const std::string& path);
/// The same formats with normals optional (nx ny nz, vn lines, 6 columns): `normals` comes
/// back empty when the file has none — an unoriented cloud, for methods that fit their own
/// tangent planes (gsd::cloud_surface). Otherwise as read_point_cloud.
GSD_EXPORT PointCloud read_cloud_points(const std::string& path);
/// Writes .ply (binary little endian, float32), .xyz/.xyzn/.txt, .pc, .obj or .npy (float32).
GSD_EXPORT void write_point_cloud(const std::string& path, const PointCloud& cloud);

// ---- meshes ---------------------------------------------------------------------------
// .obj (v + f with polygons; "f v/vt/vn" forms and negative indices; l lines ignored)
// .ply (vertex x y z + face vertex_indices/vertex_index list, any list/count types)
// .off (OFF header, optional comments; colors after face indices ignored)
// .stl (ascii or binary; coincident vertices are welded exactly)
GSD_EXPORT PolygonMesh read_mesh(const std::string& path);
/// Writes .obj, .ply (binary little endian), .off or .stl (binary; polygons fan-triangulated).
GSD_EXPORT void write_mesh(const std::string& path, const PolygonMesh& mesh);
/// Writes a triangle/polygon mesh as binary little-endian .ply with per-vertex colors
/// (red green blue, uchar) and, if `values` is non-empty, a float per vertex named `value_name`
/// (NaN allowed), e.g. colors from gsd::diverging_color and the values they show. Throws
/// gsd::Error for a path not ending in .ply, an invalid mesh, a color or value count other
/// than the vertex count, or a value name that is empty, has whitespace or clashes with
/// x y z red green blue. read_mesh reads the file back (colors and values are skipped).
GSD_EXPORT void write_colored_mesh(const std::string& path, const PolygonMesh& mesh,
                        const std::vector<std::array<std::uint8_t, 3>>& colors,
                        const std::vector<double>& values = {}, const std::string& value_name = "value");

/// True if the file at `path` holds faces (a mesh) rather than only points. Used by the CLI
/// to decide how to treat an input that could be either (.ply, .obj).
GSD_EXPORT bool file_has_faces(const std::string& path);

// ---- curves on surfaces -----------------------------------------------------------------
/// Raw records of a file of curves on a surface, checked for syntax but not against a mesh.
struct CurveFile {
    struct Point {
        char kind = 'v';          ///< 'v' vertex, 'e' edge, 'f' triangle
        std::uint64_t index = 0;  ///< 0-based vertex / edge / triangle index
        double a = 0, b = 0;      ///< 'e': t; 'f': u, v
        std::size_t line = 0;     ///< line number in the file, for errors found later
        std::uint8_t base = 1;    ///< the file's numbering there: it wrote index + base
    };
    struct Line {
        std::vector<std::uint32_t> points;  ///< indices into `points`
        std::size_t line = 0;
    };
    std::vector<Point> points;
    std::vector<Line> lines;
};
/// Reads the curve text format (any extension but .obj) or the l/p lines of an .obj (each l
/// token becomes a 'v' point). Throws gsd::Error naming the file and line for: unknown records,
/// wrong token counts, non-integer or negative indices, indices too large, t outside [0,1],
/// NaN/Inf, bad barycentric weights, an `l` with fewer than 2 points or naming a point record
/// that does not exist, a file with no points at all.
GSD_EXPORT CurveFile read_curve_file(const std::string& path);

// ---- .npy arrays ----------------------------------------------------------------------
/// A dense array in C order, values widened to double.
struct NpyArray {
    std::vector<std::size_t> shape;
    std::vector<double> data;
    std::size_t size() const { return data.size(); }
};
/// Reads a .npy file holding float32 or float64 (either byte order), C order
/// (Fortran order is rejected with a clear message), any rank.
GSD_EXPORT NpyArray read_npy(const std::string& path);
/// Writes float32 values with the given shape (product of shape must equal values.size()).
GSD_EXPORT void write_npy(const std::string& path, const std::vector<std::size_t>& shape,
               const float* values, std::size_t count);
GSD_EXPORT void write_npy(const std::string& path, const std::vector<std::size_t>& shape,
               const std::vector<float>& values);
/// Writes int32 values ('<i4'), e.g. labels.
GSD_EXPORT void write_npy(const std::string& path, const std::vector<std::size_t>& shape,
               const std::vector<std::int32_t>& values);

/// Reads an (M, 3) query list (.npy float32/float64). Throws on other shapes or non-finite values.
GSD_EXPORT Points read_queries(const std::string& path);
/// Reads an (N, N, N) float grid.
GSD_EXPORT NpyArray read_grid(const std::string& path);

// ---- grid metadata (GRID.npy.json) ----------------------------------------------------
/// What a grid's .npy cannot say by itself: where its nodes are and what made it. Every grid
/// the CLI writes gets this beside it as GRID.npy.json (docs/formats.md); `gsd contour` and
/// `gsd slice` read it when no --bounds are given.
struct GridMetadata {
    GridSpec grid;                      ///< node counts and box: node (0,0,0) at box.lo, the last at box.hi
    int components = 1;                 ///< values per node (1: a scalar field, 3: a gradient)
    std::string method;                 ///< what computed the values: "pat", "shm", "winding", "sspd", …
    std::string options_json = "{}";    ///< the options it ran with, as a JSON object
    std::vector<std::string> command;   ///< the command line that wrote it (empty if not the CLI)
    std::string version;                ///< the gsd version that wrote it (write: empty means this one)
};
/// GRID.npy → GRID.npy.json.
GSD_EXPORT std::string grid_metadata_path(const std::string& grid_path);
/// Writes the sidecar of `grid_path` atomically. Throws gsd::Error if options_json is not a
/// JSON object or the grid is invalid.
GSD_EXPORT void write_grid_metadata(const std::string& grid_path, const GridMetadata& meta);
/// Reads the sidecar of `grid_path`: std::nullopt when there is none; gsd::Error naming the
/// sidecar when it is not valid JSON, lacks a field, or describes an invalid grid.
GSD_EXPORT std::optional<GridMetadata> read_grid_metadata(const std::string& grid_path);

// ---- OpenVDB (.vdb) --------------------------------------------------------------------
/// How a scalar grid goes into a .vdb file (docs/formats.md).
struct VdbOptions {
    /// Grid name: "surface" is what Houdini and Blender look for in a level set.
    std::string name = "surface";
    /// true: φ as a narrow-band level set (GRID_LEVEL_SET; signed distance, negative inside, as
    /// in gsd): nodes with |φ| < half_width voxels are active, the rest inactive at ±half_width
    /// voxels by their sign; needs cubic voxels. false: every node's value, active (winding
    /// numbers, any other field; background 0).
    bool level_set = true;
    double half_width = 3;
    /// Stored as the grid's "gsd_method" metadata ("pat", "shm", "winding", …).
    std::string method;
};
/// Whether this gsd can write .vdb: it was built with OpenVDB (libopenvdb-dev) and finds its
/// plugin, libgsd_vdb.so (beside libgsd, or named by $GSD_VDB_PLUGIN); without it write_vdb throws.
GSD_EXPORT bool vdb_available();
/// Throws the Error write_vdb would give for `path` when vdb_available() is false (a check
/// before long work); does nothing otherwise.
GSD_EXPORT void require_vdb(const std::string& path);
/// Writes a scalar grid (values in C order, one per node: GridSpec's layout) as an OpenVDB
/// FloatGrid whose index-to-world transform puts voxel (i, j, k) at the node's position
/// (box.lo + (i, j, k)·step). Atomic, like every writer. Throws Error on a size mismatch,
/// non-finite values, non-cubic voxels for a level set, or when vdb_available() is false.
GSD_EXPORT void write_vdb(const std::string& path, const GridSpec& grid, const std::vector<float>& values,
                          const VdbOptions& options = {});
/// A narrow band on a lattice — a sparse level set: point (i, j, k) at lo + (i, j, k)·voxel
/// holds φ, and |φ| < half_width·voxel at every point given (OctreeField::narrow_band makes one).
struct SparseLevelSet {
    Eigen::Vector3d lo{0, 0, 0};
    double voxel = 0;
    double half_width = 3;  ///< voxels
    std::vector<std::array<std::int32_t, 3>> ijk;
    std::vector<float> phi;
};
/// Writes a sparse level set as an OpenVDB FloatGrid (GRID_LEVEL_SET, voxel (i, j, k) at the
/// lattice point): the band active, everything else inactive at ±half_width voxels by
/// OpenVDB's signed flood fill. `options.level_set` and `half_width` are the band's. Atomic;
/// throws Error as write_vdb does.
GSD_EXPORT void write_vdb_sparse(const std::string& path, const SparseLevelSet& band, const VdbOptions& options = {});
/// The zero level set of a sparse level set as a closed triangle mesh, by OpenVDB's
/// volumeToMesh (its quads split in two). Needs the OpenVDB plugin, as write_vdb does.
GSD_EXPORT PolygonMesh mesh_level_set(const SparseLevelSet& band);

/// Reads a .vdb file's float grid (the one named "surface", else the first) as a dense grid over
/// its active voxels' box — for a level set grown by one voxel, where the inactive outside and
/// inside read ± the background. Its transform must be an axis-aligned scale and translation.
/// Throws gsd::Error naming the file when the plugin is missing, the file cannot be read, it
/// holds no float grid, or the grid would pass the memory budget.
GSD_EXPORT std::pair<GridSpec, std::vector<float>> read_vdb(const std::string& path);

/// Lower-cased extension including the dot (".ply"), or "" if none.
GSD_EXPORT std::string extension(const std::string& path);

/// Writes `bytes` to `path` atomically (temporary file + rename). All writers use this.
GSD_EXPORT void write_file_atomic(const std::string& path, const std::string& bytes);

}  // namespace gsd::io
