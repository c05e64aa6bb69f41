// jumps.hpp — the L1 integration of the surface Signed Heat Method (thesis §6.4.1, fig. 6.13):
// where the unit field Y cannot be integrated (curves that bound nothing, around a handle),
// φ may jump, along the cheapest set of edges. Private to src/surface_shm.
//
// Step 1 (l1_jumps) is the thesis' linear program: φ linear on each face with gradient exactly
// Y_f, so one unknown per face (its level); minimize Σ_edges w_e ∫_e |jump of φ|, the jump
// linear along the edge, integrated by the trapezoid rule (its values at the two ends). The
// weight w_e falls where Y is far from integrable across e — its curl there, Polthier–Preuß's
// nonconforming rotation ⟨Y_f − Y_g, e⟩ — so jumps go where the field itself is broken; and it
// falls with the distance to the curves, so a jump no curl places (a thin handle, where the
// field arrives from both sides nearly parallel) goes where the sign is least determined, the
// farthest from the curves, and not next to them. The
// curves are tied to one level per component (a jump along a curve would move φ off it), as the
// zero-set constraint will tie them. Solved by network simplex (src/l1).
//
// Step 2 keeps the jumps that the field needs — edges along which φ jumps by more than the
// field's own variation can explain — cuts the triangulation along them (cut_triangulation),
// and integrates Y there in least squares with the usual level-set constraints. Where Y is
// integrable the program needs no jump, nothing is cut, and the result is the L² one.
#pragma once

#include "surface_shm/curves.hpp"
#include "mesh/triangulation.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace gsd::surface_shm {

struct JumpSet {
    std::vector<std::int8_t> cut;  ///< per edge of the triangulation: 0, or ±1 where φ jumps across it
                                   ///< (+1: φ is higher on the left of the edge's direction)
    std::size_t cut_edges = 0;
    double objective = 0;           ///< the program's optimum: Σ w·∫|jump| (length × distance)
    std::size_t lp_nodes = 0, lp_edges = 0;
};

/// Step 1 and the choice of jump edges. `Y`: the unit field per face (face_frame coordinates),
/// `distance`: the unsigned distance to the curves per vertex, `h`: the mean edge length (the
/// scale below which a jump is the field's own variation).
JumpSet l1_jumps(const mesh::Triangulation& T, const std::vector<double>& areas, const std::vector<Eigen::Vector2d>& Y,
                 const std::vector<double>& distance, const ResolvedSources& S, double h);

/// A triangulation cut along edges: corners on either side of a cut edge become different
/// vertices (vertices none of whose edges is cut stay whole, nonmanifold or not). Faces keep
/// their numbering and lengths, so face points and pieces on T are valid on the cut one.
struct CutTriangulation {
    mesh::Triangulation T;
    std::vector<std::uint32_t> vertex_of;  ///< per cut vertex: the vertex of T it came from
};
CutTriangulation cut_triangulation(const mesh::Triangulation& T, const std::vector<std::int8_t>& cut);

}  // namespace gsd::surface_shm
