// gsd/sums.hpp — fast sums over oriented area elements: generalized winding numbers of meshes
// in any state and of oriented point clouds, in O(log n) per query (a treecode with
// second-order multipole expansions, Barnes–Hut opening; the approach of Barill et al. 2018,
// "Fast Winding Numbers for Soups and Clouds"). The same engine runs step 1 of the grid Signed
// Heat Method (gsd/shm.hpp). docs/sums.md has the error bounds and the measured speed.
//
//   gsd::OrientedElements e = gsd::OrientedElements::from_mesh(mesh);   // or from_cloud(cloud)
//   std::vector<double> w = gsd::fast_winding_numbers(e, queries).w;     // ≈ 1 inside, 0 outside
#pragma once

#include <gsd/export.hpp>

#include <gsd/core.hpp>
#include <gsd/field.hpp>
#include <gsd/gpu.hpp>

#include <memory>
#include <string>
#include <vector>

namespace gsd {

class KdTree;

/// Oriented area elements: flat triangles of uniform density, or points, each carrying its
/// vector area v_j = A_j·N_j. The sums integrate each kernel over each triangle (not just at
/// its centroid), so a coarse mesh needs no splitting.
struct GSD_EXPORT OrientedElements {
    Points corners;  ///< (3n, 3): rows 3j, 3j+1, 3j+2 are element j's corners (a point repeats itself)
    Points vectors;  ///< (n, 3): v_j; for a triangle ½(b − a)×(c − a)
    std::size_t size() const { return std::size_t(vectors.rows()); }

    /// Faces of a mesh in any state (holes, flips, self-intersections, duplicates kept as
    /// they are); polygons are fanned; zero-area faces are dropped. Error if none is left.
    static OrientedElements from_mesh(const PolygonMesh& mesh);
    /// Points of an oriented cloud, each with its unit normal times the area π d_8²/8 it
    /// represents (gsd::point_areas, d_8: distance to the 8th neighbor).
    static OrientedElements from_cloud(const PointCloud& cloud);
    /// The same with a kd-tree of the cloud's points the caller already has.
    static OrientedElements from_cloud(const PointCloud& cloud, const KdTree& tree);
    /// Points with given vector areas (n×3 each).
    static OrientedElements from_points(const Points& positions, const Points& vector_areas);
    /// Checks sizes and finiteness (called by every sum); throws Error.
    void validate() const;
};

/// Where it runs and the queries per GPU chunk: Execution (gsd/gpu.hpp).
struct WindingOptions : Execution {
    /// Sum every element exactly (O(queries × elements)): the reference.
    bool exact = false;
    /// Opening criterion, two parts. A node of radius ρ and area A whose center is at distance
    /// d from the query is summed by its second-order expansion when d > β·ρ (β > 1: the
    /// series converges; Barill et al. and libigl use β = 2 alone) and its truncation error
    /// bound A·ρ³/(π(d − ρ)⁵) is at most `tolerance` (0: β alone). The defaults keep the error
    /// under 1e-3 at queries more than one edge length from the surface (docs/sums.md).
    /// On the CPU the expansions run in float32 (~1e-6 from double) unless the criterion asks
    /// for more than that can give: tolerance below 1e-4, or β above 4 with tolerance 0.
    double beta = 1.5;
    double tolerance = 2.5e-3;
};

struct WindingResult {
    std::vector<double> w;   ///< one per query
    std::string device;      ///< "cpu" or the Vulkan device that ran the sums
    std::size_t terms = 0;   ///< node expansions + elements summed exactly (the cost)
};

/// The generalized winding number at each query: Σ over elements of their signed solid angle
/// / 4π (points: the dipole v·(y − x)/(4π|y − x|³)). 1 inside and 0 outside a closed,
/// outward-oriented mesh; fractional where the surface is open or broken. Per-query results
/// do not depend on the other queries or on how they are chunked. CPU (OpenMP): exact terms in
/// double, node expansions in float32 at the default criterion (WindingOptions); the GPU path
/// computes in float32 and agrees to ~1e-5.
///
/// The one entry point for winding numbers at given queries, once: the exact sum (Jacobson et
/// al. 2013, the baseline thesis ch. 3 thresholds at ½) is `WindingOptions::exact`. For a field
/// evaluated many times (the tree built once), or one to compose, use WindingField.
GSD_EXPORT WindingResult fast_winding_numbers(const OrientedElements& elements, PointsView queries,
                                   const WindingOptions& options = {}, const ProgressFn& progress = {});

/// Generalized winding numbers as a Field (gsd/field.hpp): φ = w, ≈ 1 inside and 0 outside,
/// stored as float32; no gradient. The tree over the elements is built once, on the first
/// evaluation, and reused by every later one (fast_winding_numbers builds it per call).
class GSD_EXPORT WindingField final : public Field {
public:
    explicit WindingField(OrientedElements elements, WindingOptions options = {});
    ~WindingField() override;
    WindingField(WindingField&&) noexcept;
    WindingField& operator=(WindingField&&) noexcept;

    using Field::evaluate;  // the float32 overload
    FieldValues evaluate(PointsView queries, bool with_gradient = false,
                         const ProgressFn& progress = {}) const override;
    FieldValues evaluate(const GridSpec& grid, bool with_gradient = false,
                         const ProgressFn& progress = {}) const override;
    bool has_gradient() const override { return false; }
    /// w in double, with the cost of the sums.
    WindingResult winding_numbers(PointsView queries, const ProgressFn& progress = {}) const;
    /// When the options' device is a GPU, does now what the first evaluation would: builds the
    /// tree, uploads it and makes the kernel's pipeline (tens of ms on a software device).
    /// Thread-safe: run it on another thread while the queries are read (gsd's CLI does). On the
    /// CPU path it does nothing. Errors are left for the evaluation to raise.
    void prepare() const;

    const OrientedElements& elements() const;
    const WindingOptions& options() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace gsd
