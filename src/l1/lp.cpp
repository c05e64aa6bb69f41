// CLP behind the LinearProgram description: column-major assembly, dual simplex, quiet.
#include "l1/lp.hpp"

#include <gsd/core.hpp>

#include <coin/ClpSimplex.hpp>

#include <algorithm>
#include <numeric>
#include <string>

namespace gsd::l1 {

LpSolution solve_lp(const LinearProgram& lp) {
    const auto cols = int(lp.columns()), rows = int(lp.rows());
    // Triplets → compressed columns (CLP sums nothing itself: merge repeats here).
    std::vector<std::size_t> order(lp.a_value.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return lp.a_col[a] != lp.a_col[b] ? lp.a_col[a] < lp.a_col[b] : lp.a_row[a] < lp.a_row[b];
    });
    std::vector<CoinBigIndex> start(std::size_t(cols) + 1, 0);
    std::vector<int> index;
    std::vector<double> value;
    index.reserve(order.size());
    value.reserve(order.size());
    for (std::size_t k = 0; k < order.size(); ++k) {
        const std::size_t i = order[k];
        if (k > 0 && lp.a_col[i] == lp.a_col[order[k - 1]] && lp.a_row[i] == lp.a_row[order[k - 1]]) {
            value.back() += lp.a_value[i];
            continue;
        }
        index.push_back(lp.a_row[i]);
        value.push_back(lp.a_value[i]);
        ++start[std::size_t(lp.a_col[i]) + 1];
    }
    std::partial_sum(start.begin(), start.end(), start.begin());
    auto clp_bounds = [](std::vector<double> b) {
        for (double& x : b) {
            if (x >= LinearProgram::kInfinity) x = COIN_DBL_MAX;
            if (x <= -LinearProgram::kInfinity) x = -COIN_DBL_MAX;
        }
        return b;
    };
    const std::vector<double> col_lo = clp_bounds(lp.col_lo), col_hi = clp_bounds(lp.col_hi);
    const std::vector<double> row_lo = clp_bounds(lp.row_lo), row_hi = clp_bounds(lp.row_hi);
    ClpSimplex model;
    model.setLogLevel(0);
    model.loadProblem(cols, rows, start.data(), index.data(), value.data(), col_lo.data(), col_hi.data(),
                      lp.cost.data(), row_lo.data(), row_hi.data());
    model.dual();
    if (model.isProvenPrimalInfeasible() || model.isProvenDualInfeasible())
        throw Error("linear program", model.isProvenPrimalInfeasible() ? "infeasible" : "unbounded");
    LpSolution s;
    s.optimal = model.isProvenOptimal();
    s.objective = model.objectiveValue();
    s.iterations = model.numberIterations();
    s.x.assign(model.getColSolution(), model.getColSolution() + cols);
    return s;
}

}  // namespace gsd::l1
