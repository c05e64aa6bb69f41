// L1 tension problems, by network simplex on the dual circulation or as a general LP.
//
// Duality used by the network path: for a circulation f with 0 ≤ f_a ≤ u_a and arc costs k_a,
// min Σ k·f = max over potentials π of −Σ_a u_a·max(0, π_head − π_tail − k_a). So a term
// c·max(0, x_l − x_r + d) of our objective is an arc r → l with cost −d and capacity c, and a
// bound J ≤ hi an arc r → l with cost hi − d and a capacity larger than any flow that could use
// it (an exact penalty). LEMON's optimal potentials are then an optimal x.
#include "l1/tension.hpp"

#include "l1/lp.hpp"

#include <gsd/core.hpp>

#include <lemon/network_simplex.h>
#include <lemon/smart_graph.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace gsd::l1 {

namespace {

void check(const TensionProblem& p) {
    for (const TensionProblem::Edge& e : p.edges) {
        if (e.left >= p.nodes || e.right >= p.nodes) throw Error("tension problem", "an edge names a node that does not exist");
        if (!(e.cost > 0) || !std::isfinite(e.cost) || !std::isfinite(e.offset) || std::isnan(e.lo) || std::isnan(e.hi) ||
            e.lo > e.hi)
            throw Error("tension problem", "edge costs must be positive and finite, offsets finite, lo ≤ hi");
    }
}

double objective_at(const TensionProblem& p, const std::vector<double>& x, double* violation) {
    double sum = 0, worst = 0;
    for (const TensionProblem::Edge& e : p.edges) {
        const double J = x[e.left] - x[e.right] + e.offset;
        sum += e.cost * std::abs(J);
        worst = std::max({worst, e.lo - J, J - e.hi});
    }
    if (violation) *violation = worst;
    return sum;
}

}  // namespace

TensionSolution solve_tension_network(const TensionProblem& p) {
    check(p);
    TensionSolution s;
    s.x.assign(p.nodes, 0.0);
    if (p.edges.empty()) return s;
    // Integer grids: capacities (our costs) to 2^24 at the largest, arc costs (our offsets and
    // bounds) to 2^28 at the largest magnitude. Potentials stay below 2^28·nodes.
    double cost_max = 0, value_max = 1;
    for (const TensionProblem::Edge& e : p.edges) {
        cost_max = std::max(cost_max, e.cost);
        value_max = std::max(value_max, std::abs(e.offset));
        for (double b : {e.lo, e.hi})
            if (std::isfinite(b)) value_max = std::max(value_max, std::abs(b - e.offset));
    }
    const double cap_scale = std::ldexp(1.0, 24) / cost_max, cost_scale = std::ldexp(1.0, 28) / value_max;
    using Digraph = lemon::SmartDigraph;
    Digraph g;
    g.reserveNode(int(p.nodes));
    g.reserveArc(int(4 * p.edges.size()));
    for (std::size_t i = 0; i < p.nodes; ++i) g.addNode();
    Digraph::ArcMap<long long> capacity(g), cost(g);
    long long finite_total = 1;
    std::vector<Digraph::Arc> bound_arcs;
    auto arc = [&](std::uint32_t tail, std::uint32_t head, double k, long long u) {
        const Digraph::Arc a = g.addArc(g.nodeFromId(int(tail)), g.nodeFromId(int(head)));
        cost[a] = std::llround(k * cost_scale);
        capacity[a] = u;
        return a;
    };
    for (const TensionProblem::Edge& e : p.edges) {
        const long long u = std::max<long long>(1, std::llround(e.cost * cap_scale));
        arc(e.right, e.left, -e.offset, u);  // c·max(0, J)
        arc(e.left, e.right, e.offset, u);   // c·max(0, −J)
        finite_total += 2 * u;
        if (std::isfinite(e.hi)) bound_arcs.push_back(arc(e.right, e.left, e.hi - e.offset, 0));
        if (std::isfinite(e.lo)) bound_arcs.push_back(arc(e.left, e.right, e.offset - e.lo, 0));
    }
    // Some optimal circulation splits into cycles that each hold a finite arc, so no bound arc
    // carries more than the finite capacities' total: that much makes the penalty exact.
    for (const Digraph::Arc& a : bound_arcs) capacity[a] = finite_total;
    lemon::NetworkSimplex<Digraph, long long, long long> simplex(g);
    simplex.upperMap(capacity).costMap(cost);
    if (simplex.run() != lemon::NetworkSimplex<Digraph, long long, long long>::OPTIMAL)
        throw Error("tension problem", "network simplex found no optimum");  // cannot happen: bounded, feasible (f = 0)
    // LEMON's reduced cost is k + π_tail − π_head, its potentials the maximizer of the dual
    // above: x = π (the arc r → l with k = −d charges max(0, π_l − π_r + d) = max(0, J)).
    for (std::size_t i = 0; i < p.nodes; ++i) s.x[i] = double(simplex.potential(g.nodeFromId(int(i)))) / cost_scale;
    s.objective = objective_at(p, s.x, &s.violation);
    return s;
}

TensionSolution solve_tension_lp(const TensionProblem& p) {
    check(p);
    LinearProgram lp;
    constexpr double inf = LinearProgram::kInfinity;
    for (std::size_t i = 0; i < p.nodes; ++i) lp.add_column(0.0, -inf, inf);
    for (const TensionProblem::Edge& e : p.edges) {
        // J = x_l − x_r + d = pos − neg with pos, neg ≥ 0 inside the bounds.
        const std::size_t row = lp.add_row(-e.offset, -e.offset);
        lp.add(row, e.left, 1.0);
        lp.add(row, e.right, -1.0);
        const double pos_hi = std::isfinite(e.hi) ? std::max(e.hi, 0.0) : inf;
        const double neg_hi = std::isfinite(e.lo) ? std::max(-e.lo, 0.0) : inf;
        const double pos_lo = std::isfinite(e.lo) ? std::max(e.lo, 0.0) : 0.0;
        const double neg_lo = std::isfinite(e.hi) ? std::max(-e.hi, 0.0) : 0.0;
        lp.add(row, lp.add_column(e.cost, pos_lo, pos_hi), -1.0);
        lp.add(row, lp.add_column(e.cost, neg_lo, neg_hi), 1.0);
    }
    const LpSolution sol = solve_lp(lp);
    TensionSolution s;
    s.x.assign(sol.x.begin(), sol.x.begin() + std::ptrdiff_t(p.nodes));
    s.objective = objective_at(p, s.x, &s.violation);
    return s;
}

}  // namespace gsd::l1
