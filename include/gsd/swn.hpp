// gsd/swn.hpp — Surface Winding Numbers (thesis ch. 6): inside/outside of broken curves on
// surfaces of any topology. From oriented curves on a triangle mesh it completes the curves,
// labels the regions they bound with integer winding numbers, and separates the loops that
// bound nothing (around a handle, say), which naive rounding of a jump harmonic function gets
// wrong.
//
//   gsd::SurfaceMesh mesh(gsd::io::read_mesh("torus.obj"));
//   gsd::SurfaceWindingNumbers swn(mesh);                       // operators cached per mesh
//   gsd::SwnResult r = swn.solve(gsd::read_surface_curves("loops.txt", mesh));
//   // r.labels[f]: winding number of input face f; r.nonbounding: the loops that bound nothing
//
// Sign convention (as everywhere in gsd): a counter-clockwise loop (seen from the side the face
// normals point to) has winding number +1 on its left, 0 outside. docs/swn.md has the method.
#pragma once

#include <gsd/export.hpp>

#include <gsd/core.hpp>
#include <gsd/surface.hpp>

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace gsd {

/// How step ④ finds the residual function whose jumps are the nonbounding curves (only on
/// surfaces that are not simply connected).
enum class SwnResidual {
    Full,     ///< the linear program over every face (minimal L1 jumps, thesis §6.1)
    Reduced,  ///< the same program over the components of a shortest-path cut (fig. 6.11)
    None,     ///< skip: labels from rounding the jump harmonic function u (the naive baseline)
};
GSD_EXPORT SwnResidual swn_residual_from_name(const std::string& name);  // "full" | "reduced" | "none"

/// How the residual's linear program is solved. Both give an optimum of the same program; where
/// it has several (ties), they may pick different ones.
enum class SwnSolver {
    Network,  ///< network simplex on its dual, a minimum-cost circulation (LEMON): exact on data
              ///< rounded to ~2⁻²⁸ of its range, and much faster
    Clp,      ///< COIN-OR CLP's dual simplex on the program as written in the thesis
};
GSD_EXPORT SwnSolver swn_solver_from_name(const std::string& name);  // "network" | "clp"

/// The reduced program's curve weight: well below 1, so nonbounding curves are read off the input
/// where they run and completed elsewhere only across gaps; not near 0, so the length of input a
/// decomposition takes still counts (the thesis' shortest nonbounding curves) and a short
/// completion across the neck of a region does not turn its long broken boundary into a loop
/// that bounds nothing. Safe because the reduced program's jumps off the curves can only run
/// along its cut, not along any short loop of the surface.
constexpr double kSwnReducedCurveWeight = 0.3;
/// The full program's: the reference's ε. Every face is free there, so a loop around a thin part
/// of a handle would beat a curve drawn around a thick part at any weight above the ratio of
/// their lengths (the shared annulus: 13 % of its area mislabeled at 0.3).
constexpr double kSwnFullCurveWeight = 1e-3;

struct SwnOptions {
    /// Reduced by default: over the benchmark's broken curves its labels are closer to the truth
    /// than the full program's (whose optimum can complete a broken loop through a narrow neck
    /// of a region), and it runs in milliseconds. docs/swn.md has the figures.
    SwnResidual residual = SwnResidual::Reduced;
    SwnSolver solver = SwnSolver::Network;
    /// Cost per unit length of a jump of the residual along an input curve, relative to a jump
    /// anywhere else (ε of the linear program), times how straight the curve runs there (a
    /// staircase along mesh edges costs what the curve it stands for would). In (0, 1]; 0 picks
    /// the program's own: kSwnReducedCurveWeight or kSwnFullCurveWeight (above).
    double curve_weight = 0;
    /// Thesis §6.2's goal, by a different means: on meshes with boundary, make labels near the
    /// boundary behave like free-space winding numbers instead of bending to meet it at right
    /// angles. gsd solves the final jump equation with an absorbing (Robin) condition on each
    /// component's outer boundary loop; docs/swn.md says why, with measurements.
    bool boundary_aware = false;
    /// Close the curves' gaps before the residual step: every curve end joined to an end of the
    /// opposite sense by a short path that leaves forward and turns little (never back along its
    /// own piece; an end with no clear best join stays open), so the residual program sees curves
    /// that wind a whole number of times around each handle. A broken loop winds a fraction of a
    /// time otherwise, and with long gaps the program can place its jump away from every curve
    /// and take the loop for a boundary (tori with a broken small loop and a loop around the hole
    /// half cut away: 3 of 5 mislabeled 27–38 % without this, none above 0.2 % with it). Whole
    /// curves are unchanged. docs/swn.md ("Closing the gaps") has the figures, losses included.
    bool close_gaps = true;
};

struct SwnResult {
    std::vector<int> labels;                     ///< per input face: the rounded winding number
    std::vector<std::array<double, 3>> w;        ///< per triangle (SurfaceMesh numbering) and corner
    std::vector<int> naive_labels;               ///< per input face: rounding of u (no step ②–⑤)
    Polylines bounding;                          ///< input curves that bound regions
    Polylines nonbounding;                       ///< input curves that bound nothing
    Polylines completed;                         ///< where the nonbounding curves were completed
    SurfaceSources bounding_curves;              ///< the bounding part of the input curves as curves on the
                                                 ///< mesh (e.g. for the surface SHM without the loops that
                                                 ///< bound nothing: gsd shm surface --filter-nonbounding)
    bool simply_connected = true;                ///< every component a disk or a sphere: steps ②–⑤ skipped
    bool split = false;                          ///< curves off the edges: solved on a mesh cut along them
    std::size_t lp_variables = 0, lp_rows = 0;   ///< size of the residual's linear program
    double lp_objective = 0;                     ///< Σ length·|jump| of the residual over every edge (curve_weight
                                                 ///< on curves): the full program's cost, whichever ran
    double lp_violation = 0;                     ///< how far a jump on a curve leaves [0, multiplicity] (0: none)
    double seconds_jump = 0, seconds_hodge = 0, seconds_residual = 0, seconds_boundary = 0, seconds_total = 0;
};

/// The SWN solver: one per mesh. The mesh must be manifold and consistently oriented (SWN reads
/// curves' sides from the orientation); other meshes get a clear error (the surface Signed Heat
/// Method works on them: shm_labels). Boundaries and several components are fine.
class GSD_EXPORT SurfaceWindingNumbers {
public:
    explicit SurfaceWindingNumbers(SurfaceMesh mesh);
    ~SurfaceWindingNumbers();
    SurfaceWindingNumbers(SurfaceWindingNumbers&&) noexcept;
    SurfaceWindingNumbers& operator=(SurfaceWindingNumbers&&) noexcept;

    /// Curves must be signed (oriented); points are not used. Curves along mesh edges are solved
    /// on the mesh itself; curves with nodes on edges or inside triangles on a copy of the mesh
    /// cut along them (labels then go to each input face by area majority).
    SwnResult solve(const SurfaceSources& curves, const SwnOptions& options = {}, const ProgressFn& progress = {});

    const SurfaceMesh& mesh() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// Inside/outside from the sign of a surface signed distance (thesis §7.1): label 1 for faces
/// whose mean φ over their corners is negative, 0 otherwise; per input face, area majority. A
/// component where |φ| stays below 1e-6 of its largest value elsewhere was reached by no curve
/// (φ there is rounding noise) and is 0.
GSD_EXPORT std::vector<int> shm_labels(const SurfaceMesh& mesh, const std::vector<double>& phi);

/// Per-face labels (one per input face) carried to the vertices: each vertex takes the label
/// that covers most of the area of its faces (ties: the smaller label); a vertex on no face of
/// positive area gets 0. How a point cloud gets labels from SWN on its triangulation
/// (CloudSurface::triangulation, whose vertices are the points).
GSD_EXPORT std::vector<int> vertex_labels(const SurfaceMesh& mesh, const std::vector<int>& face_labels);

}  // namespace gsd

#include <gsd/accuracy.hpp>  // mislabeled_area
