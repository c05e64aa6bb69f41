// cholesky.hpp — sparse Cholesky factorizations (CHOLMOD) of the surface operators: real
// symmetric or complex Hermitian positive definite matrices given by their lower triangle.
// Analysed once, factored once, reused for every right-hand side; a matrix with the same
// pattern (different values) is refactored without a new analysis. Private to src/surface_shm (and
// src/swn, which uses it).
#pragma once

#include <complex>
#include <cstdint>
#include <memory>
#include <vector>

namespace gsd::surface_shm {

/// Lower-triangle entries (row ≥ col) of a symmetric or Hermitian matrix, as triplets;
/// repeated entries are summed.
template <class Scalar>
struct SparseLower {
    std::size_t n = 0;
    std::vector<std::int64_t> rows, cols;
    std::vector<Scalar> values;

    explicit SparseLower(std::size_t size = 0) : n(size) {}
    void reserve(std::size_t m) {
        rows.reserve(m);
        cols.reserve(m);
        values.reserve(m);
    }
    /// Adds v at (r, c); r ≥ c is required (the caller stores the lower triangle).
    void add(std::size_t r, std::size_t c, Scalar v) {
        rows.push_back(std::int64_t(r));
        cols.push_back(std::int64_t(c));
        values.push_back(v);
    }
    std::size_t entries() const { return values.size(); }
};

template <class Scalar>
class Cholesky {
public:
    /// Analyses (fill-reducing ordering) and factors A. Throws gsd::Error if A is not
    /// positive definite or CHOLMOD runs out of memory.
    explicit Cholesky(const SparseLower<Scalar>& A);
    ~Cholesky();
    Cholesky(Cholesky&&) noexcept;
    Cholesky& operator=(Cholesky&&) noexcept;

    /// Factors A reusing the analysis (ordering, symbolic factor) of `like`, whose matrix had
    /// the same pattern: no new ordering is computed.
    Cholesky(const Cholesky& like, const SparseLower<Scalar>& A);

    /// Factors a new matrix whose pattern is contained in the first one's, reusing the analysis.
    void refactor(const SparseLower<Scalar>& A);

    /// Solves A X = B in place; B is n × columns, column-major.
    void solve(Scalar* b, std::size_t columns = 1) const;
    std::vector<Scalar> solve(const std::vector<Scalar>& b) const;

    std::size_t size() const;
    /// Nonzeros of the factor L (its memory, in entries).
    std::size_t factor_entries() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

extern template class Cholesky<double>;
extern template class Cholesky<std::complex<double>>;

}  // namespace gsd::surface_shm
