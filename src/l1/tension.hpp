// tension.hpp — L1 "tension" problems: choose a value per node so that the jumps across edges
// are small in the weighted L1 sense. Surface Winding Numbers' residual function is one (nodes:
// faces, or groups of faces; edges: mesh edges); so is the surface Signed Heat Method's L1
// integration (src/surface_shm/jumps.cpp: nodes: faces; edges: mesh edges at each end).
// Private to the surface methods (src/surface_shm, src/swn).
//
// The problem is a linear program, and the dual of a minimum-cost circulation, so it can be
// solved two ways: as a general LP with COIN-OR CLP (solve_tension_lp, the thesis' formulation)
// or by network simplex on the circulation (solve_tension_network, LEMON) — exact on data
// rounded to a fine integer grid, and one to two orders of magnitude faster.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

namespace gsd::l1 {

/// minimize Σ_e cost_e·|J_e| over x (one value per node), J_e = x[left_e] − x[right_e] + offset_e,
/// subject to lo_e ≤ J_e ≤ hi_e. Bounds may be infinite; costs must be positive. x is defined
/// up to a constant per connected component of the edge graph.
struct TensionProblem {
    static constexpr double kInfinity = std::numeric_limits<double>::infinity();
    struct Edge {
        std::uint32_t left = 0, right = 0;
        double offset = 0, cost = 1;
        double lo = -kInfinity, hi = kInfinity;
    };
    std::size_t nodes = 0;
    std::vector<Edge> edges;
};

struct TensionSolution {
    std::vector<double> x;
    double objective = 0;   ///< Σ cost·|J| at x
    double violation = 0;   ///< largest amount by which a J leaves [lo, hi] (0 when feasible)
};

/// Network simplex (LEMON) on the dual circulation. Costs and offsets are rounded to integers on
/// grids fine enough (relative 2⁻²⁰ of the largest) not to change the optimum but by rounding;
/// the bounds become arcs of a capacity above any useful flow, so an infeasible problem gives
/// the solution that violates them least instead of failing.
TensionSolution solve_tension_network(const TensionProblem& p);

/// The same problem as a general linear program with CLP's dual simplex (slower; a check on
/// the network solver). Throws gsd::Error if the bounds cannot all be met.
TensionSolution solve_tension_lp(const TensionProblem& p);

}  // namespace gsd::l1
