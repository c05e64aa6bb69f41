// gsd/adaptive_shm.hpp — the Signed Heat Method on an adaptive grid: resolution where the
// input is, memory that grows with its area rather than with the box's volume.
//
//   gsd::ShmSource src = gsd::shm_source(cloud);                 // or shm_source(mesh)
//   gsd::AdaptiveShmOptions opt;  opt.depth = 9;                 // finest cell: box / 2^9
//   gsd::OctreeField phi = gsd::SignedHeatOctree(src, opt).solve().field;
//   gsd::FieldValues v = phi.evaluate(queries);                  // a gsd::Field like any other
//
// The grid is a 2:1-balanced octree over a cube, refined to the finest level within a band
// of finest cells around every source element and graded outward (a cell is never larger than
// about its distance to the source). The three steps are the uniform grid's (gsd/shm.hpp):
// step 1's screened sums at the octree's nodes; step 3 the least-squares fit of ∇φ to Y over
// the octree's edges, each weighted by the volume it stands for, by conjugate gradients
// preconditioned with a multigrid V-cycle over the octree's levels, then the zero set fitted
// softly as a correction on a coarser level (fit_scale); then the outside veto. docs/shm.md ("The adaptive grid") has the details.
#pragma once

#include <gsd/export.hpp>

#include <gsd/core.hpp>
#include <gsd/field.hpp>
#include <gsd/shm.hpp>

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace gsd {

struct AdaptiveShmOptions : Execution {
    /// Finest level D: the finest cell is the cube's side / 2^D (D = 10: 1024³ near the
    /// input). 1 ≤ D ≤ 20.
    int depth = 8;
    /// Cells within this many finest cells of a source element are all of the finest level.
    /// (The grading below makes more: a cell of side 2h is split within 2h·(√3/2 + grading) of
    /// the source, so with grading 2 the finest shell reaches ~5.7h and a band below 4 adds
    /// nothing.)
    double band = 3.0;
    /// Away from the band a cell of side s is split while its center is closer than
    /// s·(√3/2 + grading) to the source: the larger, the more gradual the coarsening.
    double grading = 2.0;
    /// The grid's cube; default: the source's bounding cube enlarged by 10 %. Bounds that are
    /// not a cube are grown to one (from their low corner, by their longest side).
    std::optional<Box> bounds;
    /// As ShmOptions: diffusion time t = t_coef·h², step 1's cutoff and accuracy.
    double t_coef = 1.0;
    double cutoff = 8.0;
    double sum_tolerance = 0.3;
    /// Step 3: stop when ‖b − Aφ‖ ≤ tolerance·‖b‖, after at most max_iterations CG iterations.
    double tolerance = 1e-6;
    int max_iterations = 200;
    /// As ShmOptions::fit_zero_set: w > 0 fits φ = 0 on the source softly, (w/h) Σ_j A_j φ(y_j)²
    /// (h: the finest cell), after the solve and the shift of φ by its mean on the source, as a
    /// correction on a coarser level (fit_scale); 0: the shift alone.
    double fit_zero_set = 1.0;
    /// The fit is a correction of φ made on the octree cut at the finest level whose cells are
    /// at least fit_scale·h_source wide (h_source: the source's mean spacing or edge length;
    /// never coarser than the multigrid's coarsest level): as smooth as the sampling, so that φ
    /// does not bend toward each noisy sample between the others (docs/shm-adaptive.md: the
    /// error near the surface). 0: on the finest level.
    double fit_scale = 4.0;
    /// As ShmOptions: the outside veto (0: off).
    double veto_winding = 0.2;
    double veto_slope = 3.0;
    double veto_margin = 0.1;
    /// Keep SHM's sign and zero set and replace |φ| at every node, and in the field's answers
    /// anywhere (OctreeField), by the exact distance to that zero set (its pieces in the leaves
    /// it crosses, contoured leaf by leaf, kept in a tree for the queries): a true signed distance
    /// function of the broken input, where SHM's own φ is a generalized distance that strays from
    /// the Euclidean one away from the surface. Each query then pays a nearest-piece search.
    bool redistance = false;
};

/// φ on an adaptive grid: values at the nodes of a balanced octree, trilinear inside each
/// leaf from its eight corners (so continuous within the finest band; across a change of level
/// the finer side's hanging nodes make a small step). Outside the cube, φ of the nearest point
/// of the cube plus the distance to it. Redistanced (AdaptiveShmOptions::redistance), evaluate()
/// answers |φ| as the exact distance to the zero set's pieces, the sign (and the gradient) the
/// interpolated φ's; narrow_band() keeps the interpolated values (within a few finest cells of
/// the zero set, where the two differ least).
class GSD_EXPORT OctreeField : public Field {
public:
    OctreeField();
    ~OctreeField() override;
    OctreeField(const OctreeField&);
    OctreeField& operator=(const OctreeField&);
    OctreeField(OctreeField&&) noexcept;
    OctreeField& operator=(OctreeField&&) noexcept;

    FieldValues evaluate(PointsView queries, bool with_gradient = false, const ProgressFn& progress = {}) const override;
    FieldValues evaluate(const GridSpec& grid, bool with_gradient = false, const ProgressFn& progress = {}) const override;
    bool has_gradient() const override { return true; }

    const Box& box() const;     ///< the octree's cube
    int depth() const;          ///< its finest level
    double finest_cell() const; ///< side of a finest cell
    std::size_t leaf_count() const;
    std::size_t node_count() const;
    /// Node positions (n × 3) and φ there.
    Points node_positions() const;
    const std::vector<float>& node_values() const;

    /// The narrow band on the finest lattice (point (i, j, k) at box().lo + (i, j, k)·finest_cell()):
    /// every lattice point within a leaf that could hold |φ| < half_width·finest_cell(), where
    /// it is, with φ there. For a sparse level set (io::write_vdb_sparse).
    void narrow_band(double half_width, std::vector<std::array<std::int32_t, 3>>& ijk, std::vector<float>& phi) const;

    struct Impl;
    explicit OctreeField(std::shared_ptr<const Impl> impl);

private:
    std::shared_ptr<const Impl> impl_;
};

struct AdaptiveShmResult {
    OctreeField field;
    std::size_t cells = 0, leaves = 0, nodes = 0;
    std::vector<std::size_t> leaves_per_level;  ///< leaves of each level, 0 … D
    std::vector<std::size_t> multigrid_nodes;   ///< nodes of each multigrid level, finest first
    std::vector<double> residual_history;       ///< relative residual after each CG iteration
    std::vector<double> fit_history;            ///< the same for the zero-set fit (empty without one)
    int fit_level = -1;                         ///< the octree level the fit was made on (-1: none)
    std::size_t kernel_terms = 0;               ///< step 1's source terms summed
    std::size_t vetoed_nodes = 0;
    std::size_t zero_set_triangles = 0;         ///< with redistance: the zero set's pieces
    double seconds_octree = 0, seconds_diffuse = 0, seconds_setup = 0, seconds_solve = 0, seconds_fit = 0, seconds_veto = 0,
           seconds_redistance = 0;
    double estimated_bytes = 0;  ///< the memory estimate checked before building
    std::string device;          ///< step 1's device ("cpu" or the Vulkan device)
};

/// The adaptive SHM solver: source and options fixed at construction; solve() builds the
/// octree and runs the three steps.
class GSD_EXPORT SignedHeatOctree {
public:
    /// Throws gsd::Error for an empty source, options out of range, or (from solve()) an
    /// octree whose estimated memory exceeds memory_budget().
    SignedHeatOctree(ShmSource source, AdaptiveShmOptions options = {});
    ~SignedHeatOctree();
    SignedHeatOctree(SignedHeatOctree&&) noexcept;
    SignedHeatOctree& operator=(SignedHeatOctree&&) noexcept;

    AdaptiveShmResult solve(const ProgressFn& progress = {}) const;
    /// The cube the octree covers (AdaptiveShmOptions::bounds, made a cube, or the default).
    Box cube() const;
    /// Bytes the solve will need, estimated from the source's area inside the cube (before
    /// anything is built).
    double estimated_bytes() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace gsd
