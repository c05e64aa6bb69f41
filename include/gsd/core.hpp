// gsd/core.hpp — the types every module shares: errors, point clouds, meshes, grids, progress.
//
// Public headers take and return plain containers and Eigen types; nothing here knows about
// Vulkan. Coordinates are double on the API; the GPU path converts to float32 internally.
#pragma once

#include <gsd/export.hpp>

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace gsd {

/// Library version ("major.minor.patch").
GSD_EXPORT std::string_view version();

/// The one exception type thrown at the API boundary. `where` names the file, option or
/// argument at fault (may be empty); `what()` says what is wrong with it.
class GSD_EXPORT Error : public std::runtime_error {
public:
    Error(std::string where, const std::string& what)
        : std::runtime_error(what), where_(std::move(where)) {}
    explicit Error(const std::string& what) : std::runtime_error(what) {}
    const std::string& where() const noexcept { return where_; }

private:
    std::string where_;
};

/// N×3 row-major matrix: row i is (x, y, z) of element i. Row-major so that the coordinates
/// of one point are contiguous (zero-copy into spatial indices and GPU uploads).
using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
/// A read-only view of N×3 double coordinates: a Points, a block of one, or an Eigen::Map over
/// an application's row-major buffer (any row stride), without a copy.
using PointsView = Eigen::Ref<const Points, 0, Eigen::OuterStride<>>;
/// float32 coordinates, e.g. a renderer's vertex buffer (Eigen::Map with OuterStride<>(4) for
/// x, y, z, w records). Fields take them too, converted to double once.
using PointsF = Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>;
using PointsFView = Eigen::Ref<const PointsF, 0, Eigen::OuterStride<>>;

/// A polyline in 3D (consecutive points joined), and several: curves drawn on surfaces, curve
/// decompositions, contour lines. The one polyline type of the API.
using Polyline = std::vector<Eigen::Vector3d>;
using Polylines = std::vector<Polyline>;

/// An oriented point cloud. `normals` has the same row count as `points`; normals need not be
/// unit length on input (the readers normalize them: normalize_normals()) but must not be zero.
struct PointCloud {
    Points points;
    Points normals;

    Eigen::Index size() const { return points.rows(); }
    bool empty() const { return points.rows() == 0; }
};

/// A polygon mesh, faces stored compressed: face f has the vertex indices
/// indices[offsets[f] .. offsets[f+1]). Triangles, quads and n-gons may be mixed.
struct GSD_EXPORT PolygonMesh {
    Points vertices;
    std::vector<std::uint32_t> indices;
    std::vector<std::uint32_t> offsets{0};

    std::size_t face_count() const { return offsets.empty() ? 0 : offsets.size() - 1; }
    std::size_t face_size(std::size_t f) const { return offsets[f + 1] - offsets[f]; }
    void add_face(std::initializer_list<std::uint32_t> f);
    void add_face(const std::uint32_t* f, std::size_t n);
};

/// Calls f(face, a, b, c) for every triangle of every face, fanned from the face's first corner
/// (the triangulation every gsd stage gives a polygon), in face order. A face of n corners gives
/// n − 2 triangles.
template <class F>
void for_each_triangle(const PolygonMesh& mesh, F&& f) {
    for (std::size_t face = 0; face < mesh.face_count(); ++face) {
        const std::uint32_t* v = mesh.indices.data() + mesh.offsets[face];
        for (std::size_t k = 1; k + 1 < mesh.face_size(face); ++k) f(face, v[0], v[k], v[k + 1]);
    }
}

/// Axis-aligned box.
struct Box {
    Eigen::Vector3d lo{0, 0, 0};
    Eigen::Vector3d hi{0, 0, 0};

    Eigen::Vector3d extent() const { return hi - lo; }
    double diagonal() const { return (hi - lo).norm(); }
};

/// A regular grid of nodes on a box: node (i, j, k) sits at
/// lo + (i·(hi−lo)_x/(nx−1), j·…/(ny−1), k·…/(nz−1)). Values are stored C order:
/// index = (i·ny + j)·nz + k, the layout of a (nx, ny, nz) .npy array.
struct GSD_EXPORT GridSpec {
    int nx = 0, ny = 0, nz = 0;
    Box box;

    static GridSpec cube(int n, const Box& b) { return {n, n, n, b}; }
    std::size_t node_count() const { return std::size_t(nx) * std::size_t(ny) * std::size_t(nz); }
    Eigen::Vector3d node(int i, int j, int k) const;
    /// All node positions in storage order.
    Points nodes() const;
    /// Throws gsd::Error unless every dimension is ≥ 2 and the box passes validate_box.
    void validate() const;
};

/// Coordinates (of points, vertices, queries and bounds) must lie within ±kMaxCoordinate.
/// Beyond it, squared distances and products of extents overflow double precision in the
/// methods' intermediate sums (1e30² = 1e60, far from the 1.8e308 limit, leaves room for the
/// sums of millions of terms), so such input is refused with the element named.
inline constexpr double kMaxCoordinate = 1e30;

/// Inputs whose extent exceeds kMaxExtentRatio times their typical spacing (median nearest
/// neighbor distance or median edge length) are refused: one stray coordinate that far out
/// makes every grid, tree and quadrature built over the whole input meaningless.
inline constexpr double kMaxExtentRatio = 1e12;

/// The memory, in bytes, that one computation may plan to allocate: $GSD_MEMORY_LIMIT (bytes,
/// or with a suffix K, M, G, T: "8G"), else three quarters of the machine's physical memory.
GSD_EXPORT std::size_t memory_budget();

/// Throws Error(where, …) when `bytes`, an estimate made before allocating, exceeds
/// memory_budget(); `what` names the work ("a 1024³ grid", "splitting 7 large faces").
GSD_EXPORT void check_memory(double bytes, const std::string& where, const std::string& what);

/// Throws Error(where, …) unless the box is finite, non-empty on every axis, within
/// ±kMaxCoordinate, and hi − lo is finite.
GSD_EXPORT void validate_box(const Box& box, const std::string& where);

/// Bounding box of a set of points (throws on an empty set).
GSD_EXPORT Box bounding_box(PointsView p);

/// The cube centered on a box whose side is the box's longest side enlarged by `margin`
/// (0.1: 10%): the default grid bounds of every command.
GSD_EXPORT Box padded_cube(const Box& b, double margin = 0.1);

/// Progress callback for long work: `stage` names the step, `fraction` runs from 0 to 1.
/// Called from the calling thread only, at most a few hundred times per job.
using ProgressFn = std::function<void(std::string_view stage, double fraction)>;

/// Checks a point cloud once at the boundary: non-empty, equal row counts, finite
/// coordinates within ±kMaxCoordinate, finite non-zero normals, an extent within
/// kMaxExtentRatio of the median spacing. Like validate(mesh), it only checks: it never
/// changes its input (the readers then call normalize_normals).
/// `where` names the source (usually a file) for the error message.
GSD_EXPORT void validate(const PointCloud& cloud, const std::string& where = {});

/// Scales every normal to unit length (what the methods assume; readers and the Python
/// bindings do it after validate). Throws gsd::Error for a zero-length or non-finite normal.
GSD_EXPORT void normalize_normals(PointCloud& cloud, const std::string& where = {});

/// Checks a mesh: at least one face, finite vertices within ±kMaxCoordinate, indices in
/// range, faces with ≥ 3 vertices, an extent within kMaxExtentRatio of the median edge length. Degenerate (zero-area) faces are allowed here; algorithms that cannot use
/// them say so.
GSD_EXPORT void validate(const PolygonMesh& mesh, const std::string& where = {});

/// Coordinates within ±kMaxCoordinate, and the whole extent within kMaxExtentRatio of the bulk's
/// size (the largest interquartile range over the axes): a stray element far out is named
/// ("<element> <row> …"). Part of validate(); for other point sets (tori, queries).
GSD_EXPORT void check_coordinates(const Points& p, const std::string& where, const char* element);

/// robust_mean() caps every value at this many times the median.
constexpr double kRobustMeanCap = 100;
/// The mean of the values, each capped at kRobustMeanCap × their median (0 for none): the
/// scale of an input, which one stray element must not set. A face with a corner 10⁹ edges
/// away would otherwise make the mean edge length 10⁴× the typical one, and every parameter
/// scaled by it (SHM's diffusion time, PAT's blend radius) meaningless; below the cap — every
/// shared test mesh and cloud — the mean is unchanged.
GSD_EXPORT double robust_mean(std::vector<double> values);

/// The robust_mean() of the faces' edge lengths, each edge counted once per face that has it
/// (0 for a mesh without faces). The mesh's scale: SHM's h, the distance past which fast
/// winding numbers keep their error bound.
GSD_EXPORT double mean_edge_length(const PolygonMesh& mesh);

}  // namespace gsd
