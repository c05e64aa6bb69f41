// lp.hpp — sparse linear programs solved with COIN-OR CLP (dual simplex). Private to the modules
// that pose L1 problems (src/l1 itself, through tension.hpp).
#pragma once

#include <cstdint>
#include <vector>

namespace gsd::l1 {

/// minimize Σ cost_j x_j subject to row_lo ≤ A x ≤ row_hi and col_lo ≤ x ≤ col_hi. Bounds may be
/// ±infinity (use kInfinity). A is given by triplets; repeated entries are summed.
struct LinearProgram {
    static constexpr double kInfinity = 1e300;

    std::vector<double> cost, col_lo, col_hi;
    std::vector<double> row_lo, row_hi;
    std::vector<std::int32_t> a_row, a_col;
    std::vector<double> a_value;

    std::size_t add_column(double c, double lo, double hi) {
        cost.push_back(c);
        col_lo.push_back(lo);
        col_hi.push_back(hi);
        return cost.size() - 1;
    }
    std::size_t add_row(double lo, double hi) {
        row_lo.push_back(lo);
        row_hi.push_back(hi);
        return row_lo.size() - 1;
    }
    void add(std::size_t row, std::size_t col, double value) {
        a_row.push_back(std::int32_t(row));
        a_col.push_back(std::int32_t(col));
        a_value.push_back(value);
    }
    std::size_t columns() const { return cost.size(); }
    std::size_t rows() const { return row_lo.size(); }
};

struct LpSolution {
    std::vector<double> x;
    double objective = 0;
    bool optimal = false;
    int iterations = 0;
};

/// Solves with CLP's dual simplex. Throws gsd::Error if CLP finds the problem infeasible or
/// unbounded (callers build problems that are neither).
LpSolution solve_lp(const LinearProgram& lp);

}  // namespace gsd::l1
