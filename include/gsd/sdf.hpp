// gsd/sdf.hpp — signed distance to a triangle mesh as it comes (holes, flipped faces, duplicates,
// self-intersections): the exact distance to its triangles, signed by pseudonormals where the
// mesh is clean and by its generalized winding number (inside where w > ½, its faces' orientation
// repaired first) where it is not, so that the sign survives what breaks ray parity and
// pseudonormals. docs/sdf.md has the method, the options and measurements.
//
//   gsd::MeshSdfResult r = gsd::mesh_sdf(gsd::io::read_mesh("scan.obj"), queries);
//   // r.phi[i] < 0 inside; |r.phi[i]| is the distance to the nearest triangle
//   gsd::SdfSamples s = gsd::sample_sdf(mesh, 500000);   // training samples: near the surface and in its box
#pragma once

#include <gsd/export.hpp>

#include <gsd/core.hpp>
#include <gsd/field.hpp>
#include <gsd/gpu.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace gsd {

/// How the distance gets its sign.
enum class SdfSign {
    /// Diagnose the mesh: pseudonormal if it is closed, manifold, consistently oriented, without
    /// duplicated triangles and its components apart; else the winding number of its triangles
    /// with duplicates dropped and each manifold patch turned to one orientation (the one most of
    /// its area had), and where the mesh has holes, the grid SHM's sign (shm_grid) wherever that
    /// winding number is within kSdfAmbiguousWinding of ½ (in front of large holes, where w
    /// says little). Queries outside the mesh's bounding box are outside without a sum (what a
    /// surface encloses lies within its box). MeshSdfResult::sign says which, `diagnosis` why.
    automatic,
    winding,       ///< negative where the generalized winding number of the faces as given exceeds inside_threshold
    pseudonormal,  ///< angle-weighted pseudonormals at the nearest point (exact on clean meshes only)
    shm,           ///< the sign of the grid Signed Heat Method's φ (gsd/shm.hpp) on a shm_grid³ grid
    none,          ///< unsigned distance
};
/// SdfSign::automatic on a mesh with holes: winding numbers this close to ½ take SHM's sign.
constexpr double kSdfAmbiguousWinding = 0.2;
/// "auto" | "winding" | "pseudonormal" | "shm" | "none", and back.
GSD_EXPORT SdfSign sdf_sign_from_name(const std::string& name);
GSD_EXPORT const char* sdf_sign_name(SdfSign sign);

/// Where it runs (Execution: the nearest-triangle search, the winding numbers and SHM on the
/// device; the exact distance to the triangle found is always computed in double) and how the
/// sign is decided.
struct MeshSdfOptions : Execution {
    SdfSign sign = SdfSign::automatic;
    /// Inside where w > this (winding numbers are ≈ 1 inside a closed mesh, 0 outside, and
    /// fractional near holes): ½ splits the difference. In (0, 1).
    double inside_threshold = 0.5;
    /// SdfSign::shm: the grid's nodes per axis, on the mesh's bounding cube + 10 % (queries
    /// outside it are outside). In [8, 512].
    int shm_grid = 32;
    /// Also ∇φ: the unit vector from the nearest point of the mesh to the query, times φ's sign
    /// (the exact distance's gradient wherever the nearest point is unique; 0 on the surface).
    bool gradient = false;
};

struct MeshSdfResult {
    std::vector<double> phi;      ///< per query: ± distance to the nearest triangle (negative inside)
    /// Per query: the winding number that set the sign (winding signs only; the automatic sign's
    /// are 0 outside the mesh's bounding box, where it sums none).
    std::vector<double> winding;
    std::vector<double> gradient; ///< 3 per query (x, y, z) if MeshSdfOptions::gradient
    std::size_t triangles = 0;    ///< triangles the distance was taken to (polygons fanned)
    std::size_t degenerate = 0;   ///< zero-area triangles left out (their points lie on other triangles' sides or nowhere)
    SdfSign sign = SdfSign::none; ///< the sign used (automatic resolved)
    std::size_t reoriented = 0;   ///< triangles the automatic sign turned before summing winding numbers
    std::size_t shm_decided = 0;  ///< queries whose sign the automatic sign took from SHM
    std::string diagnosis;        ///< what the mesh check found, and the sign it led to
    std::string device;           ///< where the work ran: a Vulkan device if any stage did (distance, winding numbers, SHM), else "cpu"
};

/// Signed distance from each query to the mesh: |φ| is the exact distance to the nearest of the
/// mesh's non-degenerate triangles (point–triangle distance, a kd-tree over the triangles pruned
/// by the nearest found so far, OpenMP), the sign as MeshSdfOptions::sign says. Any mesh state;
/// throws Error for an invalid mesh (gsd::validate), a mesh of degenerate faces only, non-finite
/// queries or options out of range.
GSD_EXPORT MeshSdfResult mesh_sdf(const PolygonMesh& mesh, PointsView queries, const MeshSdfOptions& options = {},
                                  const ProgressFn& progress = {});

namespace detail {
struct MeshSdfState;
}

/// mesh_sdf as a gsd::Field, for code that takes any field (grids, the field algebra of
/// gsd/field_algebra.hpp, `gsd field`): φ and, on request, ∇φ (MeshSdfOptions::gradient) in
/// float32. The mesh is checked (and, for the automatic sign, repaired) once, at construction;
/// the tree, the pseudonormals and the SHM grid are built at the first evaluation that needs
/// them and kept, so later evaluations pay for their queries only. Copies share all of it.
class GSD_EXPORT MeshSdfField final : public Field {
public:
    /// Throws gsd::Error for an invalid mesh (gsd::validate), a mesh of degenerate faces only or
    /// options out of range.
    explicit MeshSdfField(PolygonMesh mesh, MeshSdfOptions options = {});
    using Field::evaluate;
    FieldValues evaluate(PointsView queries, bool with_gradient = false, const ProgressFn& progress = {}) const override;
    FieldValues evaluate(const GridSpec& grid, bool with_gradient = false, const ProgressFn& progress = {}) const override;
    bool has_gradient() const override { return true; }
    const PolygonMesh& mesh() const;

private:
    std::shared_ptr<const PolygonMesh> mesh_;
    std::shared_ptr<const detail::MeshSdfState> state_;
};

/// Training samples of a mesh's signed distance, as implicit-shape networks (DeepSDF and its
/// successors) train on: most near the surface, some spread through its box. Lengths are in
/// units of the mesh's bounding sphere (center: the box's center; radius: the farthest vertex
/// from it), so the same options suit meshes of any size.
struct SdfSampleOptions : MeshSdfOptions {
    /// Near-surface samples: points uniform on the surface (by area) offset by an isotropic
    /// Gaussian of each standard deviation, × the radius; split evenly between them. Each > 0.
    std::vector<double> near_sigma = {0.07, 0.022};
    /// The share of samples drawn uniformly in the sphere's bounding cube (center ± radius)
    /// instead, in [0, 1].
    double uniform_fraction = 0.06;
    /// Return the samples and their distances in the unit-sphere frame: (x − center) / radius
    /// and φ / radius.
    bool normalize = false;
    /// The random stream: the same seed, mesh and options give the same samples.
    std::uint64_t seed = 0;
};

struct SdfSamples {
    Points points;                ///< (n, 3): the near samples of each σ in turn, then the uniform ones
    std::vector<double> phi;      ///< per sample, signed as MeshSdfOptions::sign says
    Eigen::Vector3d center;       ///< the bounding sphere: the frame of `normalize`
    double radius = 0;
    std::size_t triangles = 0;    ///< as in MeshSdfResult
    std::size_t degenerate = 0;
    SdfSign sign = SdfSign::none;
    std::string diagnosis;
    std::string device;
};

/// The samples as (n, 4) float32 rows `x y z sdf`, as `gsd sdf --samples` writes them.
GSD_EXPORT std::vector<float> sample_rows(const SdfSamples& samples);

/// `count` samples of the mesh's signed distance (mesh_sdf at points drawn as SdfSampleOptions
/// says). Throws Error for an invalid mesh, count 0 or past the memory budget, or options out of
/// range.
GSD_EXPORT SdfSamples sample_sdf(const PolygonMesh& mesh, std::size_t count, const SdfSampleOptions& options = {},
                                 const ProgressFn& progress = {});

}  // namespace gsd
