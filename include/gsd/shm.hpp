// gsd/shm.hpp — the Signed Heat Method on a regular grid (thesis ch. 4): generalized signed
// distance from broken meshes and point clouds, robust to holes, self-intersections, noise and
// flipped orientations.
//
//   gsd::ShmSource src = gsd::shm_source(mesh);          // or shm_source(cloud)
//   gsd::SignedHeatGrid shm(src, grid, options);          // options: t_coef, solver, device
//   gsd::ShmResult r = shm.solve();                       // r.phi in GridSpec storage order
//
// Step 1 diffuses the source normals with the screened kernel exp(−λr)/(4πr), λ = 1/√t,
// t = t_coef·h²; step 2 normalizes them to Y; step 3 solves Δφ = ∇·Y with ∂φ/∂n = n·Y on the
// box (7-point stencil, geometric multigrid), then shifts φ so the source is its zero set on
// average (or fits it softly), and turns outside what only the completion over a large hole put
// inside (the outside veto). docs/shm.md has the details and the error bounds.
#pragma once

#include <gsd/export.hpp>

#include <gsd/core.hpp>
#include <gsd/gpu.hpp>
#include <gsd/sums.hpp>

#include <optional>

#include <memory>
#include <span>
#include <string>
#include <vector>

namespace gsd {

/// The source of the grid SHM: oriented area elements (gsd/sums.hpp) — a mesh's triangles,
/// integrated exactly to second order, and/or a cloud's points — and its spacing h.
struct ShmSource {
    OrientedElements elements;
    double spacing = 0; ///< h: mean neighbor spacing (clouds) or mean edge length (meshes)
    std::size_t size() const { return elements.size(); }
};

/// Point cloud → sources: each point with its unit normal times the area π d_8²/8 it
/// represents (gsd::point_areas). h = mean nearest-neighbor spacing.
GSD_EXPORT ShmSource shm_source(const PointCloud& cloud);

/// Mesh in any state (holes, self-intersections, nonmanifold or duplicate faces, inconsistent
/// orientation: all kept as they are) → sources: its (fanned) triangles with their vector
/// areas. However coarse the faces, step 1 integrates the kernel over each triangle (expansions
/// far away, adaptive refinement near it), so nothing is split up front. h = mean edge length.
/// Degenerate faces contribute nothing; a mesh whose faces are all degenerate is an error.
GSD_EXPORT ShmSource shm_source(const PolygonMesh& mesh);

/// Mesh and cloud together (bonus): their sources concatenated; h is the larger spacing.
GSD_EXPORT ShmSource combine(const ShmSource& a, const ShmSource& b);

enum class PoissonSolver {
    Multigrid,  ///< geometric multigrid V-cycles (GPU when a device is chosen, else CPU)
    CG,         ///< conjugate gradients with a Jacobi preconditioner (CPU reference)
    Direct,     ///< sparse Cholesky (CHOLMOD, CPU; small grids)
};
GSD_EXPORT PoissonSolver poisson_solver_from_name(const std::string& name);  // "mg" | "cg" | "direct"

/// Where it runs and the grid nodes per GPU chunk in step 1: Execution (gsd/gpu.hpp).
struct ShmOptions : Execution {
    /// Diffusion time t = t_coef · h².
    double t_coef = 1.0;
    /// Step 1 drops sources whose kernel weight is below exp(−cutoff) of the nearest source's
    /// (for a smooth sheet the dropped share of the total weight is ≤ e^(−cutoff) = 3e-4).
    double cutoff = 8.0;
    /// Step 1 evaluates the field exactly at nodes closer than this many cells (of a level)
    /// to the source and interpolates it from a coarser level farther out. 0: exact everywhere.
    double interpolation_cells = 6.0;
    /// Step 1's accuracy: a cluster of elements (or a piece of a triangle) is summed by its
    /// second-order expansion when a bound on its truncation error is below this fraction of
    /// 2π/λ, the magnitude of the diffused field of a sheet (docs/shm.md). Smaller is slower
    /// and closer to the exact integral.
    double sum_tolerance = 0.3;
    PoissonSolver solver = PoissonSolver::Multigrid;
    /// Stop when ‖b − Lφ‖ ≤ tolerance·‖b‖.
    double tolerance = 1e-6;
    /// Cycles (multigrid) or iterations (CG); 0: 50 cycles, 5000 CG iterations.
    int max_iterations = 0;
    bool f_cycle = false;       ///< F-cycles instead of V-cycles
    /// φ is first shifted so that its area-weighted mean over the source is zero. w > 0 then fits
    /// φ = 0 on the source softly: a smooth correction, on a grid of a quarter of the resolution, that
    /// minimizes its Poisson energy plus (w/h) Σ_j A_j φ(y_j)² (trilinear φ at each source sample).
    /// It bends the zero set back onto the source where holes and flips pulled it away (docs/shm.md:
    /// inside/outside on broken meshes); 0: the shift alone.
    double fit_zero_set = 1.0;
    /// The outside veto, last: a node that φ puts inside (φ < 0) is turned outside when its
    /// sign rests on nothing but SHM's completion over a hole — it lies farther from every
    /// element than veto_slope·|φ| + veto_margin·E (E: the largest extent of the source's
    /// bounding box) *and* the source's winding number there is below veto_winding. Such nodes
    /// are where the completion bulges out of a large hole; deep inside, |φ| is about the
    /// distance, and in thin parts the distance is below ¾ of the margin, so neither is touched.
    /// φ → |φ| there, blended over a band (half the margin in distance, 0.1 in winding number)
    /// so that φ stays continuous. veto_winding = 0 turns it off (docs/shm.md: the measurements).
    double veto_winding = 0.2;
    double veto_slope = 3.0;
    double veto_margin = 0.1;
    /// Last: keep φ's sign and zero set and make |φ| the exact distance to that zero set (its
    /// contour on this grid): a true signed distance function of the broken input, where SHM's
    /// own φ is a generalized distance that strays from the Euclidean one away from the surface.
    bool redistance = false;
};

/// What a solve produced, with its diagnostics.
struct ShmResult {
    std::vector<float> phi;                ///< φ per node, GridSpec storage order
    std::vector<double> residual_history;  ///< relative residual after each cycle/iteration
    std::vector<double> fit_history;       ///< the same for the zero-set fit (empty without one)
    double seconds_diffuse = 0, seconds_solve = 0;
    /// Parts of seconds_diffuse: the setup (the source's tree, its upload to a device), the sums
    /// at the nodes summed exactly, and the rest (interpolation between levels, node lists).
    double seconds_setup = 0, seconds_sums = 0;
    /// Parts of seconds_solve: the Poisson solve itself (with the divergence and the mean
    /// shift), the zero-set fit and the outside veto (both on the CPU).
    double seconds_poisson = 0, seconds_fit = 0, seconds_veto = 0, seconds_redistance = 0;
    std::size_t exact_nodes = 0;           ///< nodes where step 1 summed the kernel (the rest interpolated)
    std::size_t kernel_terms = 0;          ///< source terms summed in step 1 (its cost)
    std::size_t vetoed_nodes = 0;          ///< nodes the outside veto turned from inside to outside
    std::string device;                    ///< "cpu" or the Vulkan device that ran step 1 / step 3
};

// ---- distance sharpening (thesis §4.4, eq. 4.13) ---------------------------------------------

/// Sharpening turns a generalized signed distance φ₀ (an SHM result, blurred by its diffusion
/// time) into the sharpest function that keeps its sign: max Σ sign(φ₀)·φ subject to |∇φ| ≤ 1
/// and φ = 0 on the source, by the primal–dual hybrid gradient method warm-started from φ₀
/// (docs/shm.md: distance sharpening).
struct SharpenOptions : Execution {
    /// PDHG iterations; 0: 6 × the grid's largest dimension (the dual has to carry the objective
    /// across the grid, about a cell per iteration or two).
    int iterations = 0;
    /// Keep every node on φ₀'s side: sign(φ₀)·φ ≥ 0 (a bound the prox step enforces at no cost),
    /// so the inside/outside label of every node survives exactly. Off: eq. 4.13 as written.
    bool keep_sign = true;
    /// w > 0: the zero set is fitted softly, (w/2)·Σ_rows (P φ / h)² (one row per grid cell the
    /// source crosses); 0: exactly. The source of a broken shape (a noisy cloud, overlapping
    /// scans) cannot all lie on the zero set of a function with |∇φ| ≤ 1; the soft fit lets it
    /// miss where it must instead of pinning φ to 0 over a band.
    double zero_set_weight = 0;
};

struct SharpenResult {
    std::vector<float> phi;          ///< per node, GridSpec storage order
    int iterations = 0;
    std::size_t zero_set_rows = 0;   ///< grid cells the source crosses (constraint rows)
    /// The largest |∇φ| by forward differences (1 at convergence, ≥ 1 just short of it) and
    /// the mean over nodes of max(|∇φ| − 1, 0): what is left of the constraint.
    double max_slope = 0, mean_excess_slope = 0;
    std::size_t sign_changes = 0;    ///< nodes whose sign differs from φ₀'s (0 with keep_sign)
    double seconds = 0;
    std::string device;              ///< "cpu" or the Vulkan device
};

/// Sharpens `phi0` (on `grid`, GridSpec storage order) against the zero set of `source`.
/// Throws gsd::Error for a size mismatch, a non-finite value or a source outside the grid.
GSD_EXPORT SharpenResult sharpen_distance(const GridSpec& grid, std::span<const float> phi0, const ShmSource& source,
                                          const SharpenOptions& options = {}, const ProgressFn& progress = {});

/// The grid SHM solver: sources and grid fixed at construction; solve() runs the three steps.
class GSD_EXPORT SignedHeatGrid {
public:
    SignedHeatGrid(ShmSource source, GridSpec grid, ShmOptions options = {});
    ~SignedHeatGrid();
    SignedHeatGrid(SignedHeatGrid&&) noexcept;
    SignedHeatGrid& operator=(SignedHeatGrid&&) noexcept;

    ShmResult solve(const ProgressFn& progress = {}) const;

    /// Distance sharpening of a solve's φ against this solver's source (sharpen_distance).
    SharpenResult sharpen(std::span<const float> phi, const SharpenOptions& options = {},
                          const ProgressFn& progress = {}) const;

    /// Step 1–2 alone: the unit vector field Y at every node (3 per node; 0 where undefined).
    std::vector<float> diffused_directions(const ProgressFn& progress = {}) const;

    const GridSpec& grid() const;
    const ShmSource& source() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// The default SHM box: the bounding cube of the source, enlarged by 10%.
GSD_EXPORT Box shm_default_bounds(const ShmSource& source);

// ---- the Poisson solver, usable on its own ----------------------------------------------

/// When GridPoissonSolver::solve stops (the direct solver ignores these: it is exact).
struct PoissonSolveOptions {
    /// Stop when ‖b − Lφ‖ ≤ tolerance·‖b‖.
    double tolerance = 1e-6;
    /// Cycles (multigrid) or iterations (CG) at most; 0: 50 cycles, 5000 CG iterations.
    int max_iterations = 0;
    bool f_cycle = false;  ///< multigrid: F-cycles instead of V-cycles
};

/// Solves the 7-point least-squares Poisson problem on a grid: find φ minimizing
/// Σ_edges ((φ_j − φ_i)/Δ − Ȳ·e)², i.e. L φ = b with natural Neumann boundary, L the
/// (positive semi-definite) 7-point Laplacian. The constant nullspace is removed (mean φ = 0).
class GSD_EXPORT GridPoissonSolver {
public:
    GridPoissonSolver(GridSpec grid, PoissonSolver solver = PoissonSolver::Multigrid, Device device = Device::cpu());
    ~GridPoissonSolver();
    GridPoissonSolver(GridPoissonSolver&&) noexcept;
    GridPoissonSolver& operator=(GridPoissonSolver&&) noexcept;

    /// Right-hand side of the least-squares problem from a vector field (3 per node).
    std::vector<double> divergence(std::span<const float> field) const;
    std::vector<double> divergence(const std::vector<float>& field) const {
        return divergence(std::span<const float>(field.data(), field.size()));
    }
    /// Solves L φ = b (b must sum to zero). Returns φ (double) with mean zero; the relative
    /// residual after each cycle or iteration goes to `residual_history` if given.
    std::vector<double> solve(const std::vector<double>& b, const PoissonSolveOptions& options = {},
                              std::vector<double>* residual_history = nullptr, const ProgressFn& progress = {}) const;
    /// The same, free to return φ in b's memory (no new memory to zero: on a device it saves
    /// the result's page faults, ~11 µs a page on the machine measured).
    std::vector<double> solve(std::vector<double>&& b, const PoissonSolveOptions& options = {},
                              std::vector<double>* residual_history = nullptr, const ProgressFn& progress = {}) const;
    /// Makes ready what a multigrid solve on a device would make first (the device's solver, its
    /// pipelines, its host-memory grids touched): call it on another thread while other work
    /// runs (SignedHeatGrid does, during step 1), then solve() once it has returned (not at the
    /// same time as solve() or device() on this solver). Nothing on the CPU path. Errors are
    /// left for solve() to meet and report.
    void prepare(bool f_cycle = false) const;
    /// y = L x (for tests and residuals).
    std::vector<double> apply(const std::vector<double>& x) const;
    /// The device that runs the multigrid ("cpu" or a Vulkan device name).
    std::string device() const;

private:
    std::vector<double> solve_using(const std::vector<double>& b, const PoissonSolveOptions& options,
                                    std::vector<double>* residual_history, const ProgressFn& progress,
                                    std::vector<double>* storage) const;
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace gsd
