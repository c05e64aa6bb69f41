// CHOLMOD behind the small Cholesky<Scalar> interface: 64-bit indices (large meshes), supernodal
// or simplicial as CHOLMOD judges best, its default ordering (AMD, METIS when AMD fills badly).
#include "surface_shm/cholesky.hpp"

#include <gsd/core.hpp>

#include <cholmod.h>

#include <algorithm>
#include <cstring>
#include <string>
#include <type_traits>

namespace gsd::surface_shm {

namespace {

template <class Scalar>
constexpr int kXtype = std::is_same_v<Scalar, double> ? CHOLMOD_REAL : CHOLMOD_COMPLEX;

std::string status_text(const cholmod_common& c) {
    switch (c.status) {
        case CHOLMOD_OUT_OF_MEMORY: return "out of memory";
        case CHOLMOD_TOO_LARGE: return "problem too large";
        case CHOLMOD_NOT_POSDEF: return "matrix not positive definite";
        case CHOLMOD_INVALID: return "invalid input";
        default: return "status " + std::to_string(c.status);
    }
}

}  // namespace

template <class Scalar>
struct Cholesky<Scalar>::Impl {
    cholmod_common common;
    cholmod_factor* factor = nullptr;
    std::size_t n = 0;

    Impl() {
        cholmod_l_start(&common);
        common.print = 0;
        common.error_handler = nullptr;
        // Quiet on "not positive definite": we check the status and throw instead.
        common.quick_return_if_not_posdef = 1;

    }
    ~Impl() {
        if (factor) cholmod_l_free_factor(&factor, &common);
        cholmod_l_finish(&common);
    }

    /// Triplets → compressed lower-triangular CHOLMOD matrix (duplicates summed).
    cholmod_sparse* to_sparse(const SparseLower<Scalar>& A) {
        cholmod_triplet* t =
            cholmod_l_allocate_triplet(A.n, A.n, std::max<std::size_t>(A.entries(), 1), -1, kXtype<Scalar>, &common);
        if (!t) throw Error("CHOLMOD: " + status_text(common) + " while assembling a " + std::to_string(A.n) + "² matrix");
        auto* ti = static_cast<SuiteSparse_long*>(t->i);
        auto* tj = static_cast<SuiteSparse_long*>(t->j);
        for (std::size_t k = 0; k < A.entries(); ++k) {
            ti[k] = A.rows[k];
            tj[k] = A.cols[k];
        }
        std::memcpy(t->x, A.values.data(), A.entries() * sizeof(Scalar));
        t->nnz = A.entries();
        cholmod_sparse* s = cholmod_l_triplet_to_sparse(t, A.entries(), &common);
        cholmod_l_free_triplet(&t, &common);
        if (!s) throw Error("CHOLMOD: " + status_text(common) + " while assembling a " + std::to_string(A.n) + "² matrix");
        return s;
    }

    /// Numeric factorization of A with the current symbolic factor; analyses first if asked.
    void factorize(const SparseLower<Scalar>& A, bool analyse) {
        cholmod_sparse* s = to_sparse(A);
        if (analyse) factor = cholmod_l_analyze(s, &common);
        const bool ok = factor && cholmod_l_factorize(s, factor, &common) && common.status == CHOLMOD_OK;
        cholmod_l_free_sparse(&s, &common);
        if (!factor)
            throw Error("CHOLMOD could not analyse a " + std::to_string(n) + "² operator: " + status_text(common));
        // Not positive definite: cotan weights of near-degenerate triangles overwhelm the rest
        // (a sliver strip, say). The mesh is the cause, so the error names it.
        if (!ok)
            throw Error("mesh", "its surface operator (" + std::to_string(n) + " unknowns) could not be factored: " +
                                    status_text(common) + "; its triangles are too thin or degenerate for the cotan Laplacian");
    }
};

template <class Scalar>
Cholesky<Scalar>::Cholesky(const SparseLower<Scalar>& A) : impl_(std::make_unique<Impl>()) {
    impl_->n = A.n;
    impl_->factorize(A, true);
}

template <class Scalar>
Cholesky<Scalar>::Cholesky(const Cholesky& like, const SparseLower<Scalar>& A) : impl_(std::make_unique<Impl>()) {
    if (A.n != like.impl_->n) throw Error("Cholesky: size differs from the analysed matrix");
    impl_->n = A.n;
    impl_->factor = cholmod_l_copy_factor(like.impl_->factor, &impl_->common);
    if (!impl_->factor) throw Error("CHOLMOD: " + status_text(impl_->common) + " while copying a factor");
    refactor(A);
}

template <class Scalar>
Cholesky<Scalar>::~Cholesky() = default;
template <class Scalar>
Cholesky<Scalar>::Cholesky(Cholesky&&) noexcept = default;
template <class Scalar>
Cholesky<Scalar>& Cholesky<Scalar>::operator=(Cholesky&&) noexcept = default;

template <class Scalar>
void Cholesky<Scalar>::refactor(const SparseLower<Scalar>& A) {
    if (A.n != impl_->n) throw Error("Cholesky::refactor: size changed");
    impl_->factorize(A, false);
}

template <class Scalar>
void Cholesky<Scalar>::solve(Scalar* b, std::size_t columns) const {
    if (columns == 0 || impl_->n == 0) return;
    // Wrap the caller's memory as a dense matrix (no copy in), solve, copy the result back.
    cholmod_dense B;
    std::memset(&B, 0, sizeof(B));
    B.nrow = impl_->n;
    B.ncol = columns;
    B.nzmax = impl_->n * columns;
    B.d = impl_->n;
    B.x = b;
    B.xtype = kXtype<Scalar>;
    B.dtype = CHOLMOD_DOUBLE;
    cholmod_common& c = impl_->common;
    cholmod_dense* X = cholmod_l_solve(CHOLMOD_A, impl_->factor, &B, &c);
    if (!X) throw Error("CHOLMOD solve failed: " + status_text(c));
    std::memcpy(b, X->x, impl_->n * columns * sizeof(Scalar));
    cholmod_l_free_dense(&X, &c);
}

template <class Scalar>
std::vector<Scalar> Cholesky<Scalar>::solve(const std::vector<Scalar>& b) const {
    std::vector<Scalar> x = b;
    solve(x.data(), 1);
    return x;
}

template <class Scalar>
std::size_t Cholesky<Scalar>::size() const {
    return impl_->n;
}

template <class Scalar>
std::size_t Cholesky<Scalar>::factor_entries() const {
    const cholmod_factor* L = impl_->factor;
    if (!L) return 0;
    return L->is_super ? std::size_t(L->xsize) : std::size_t(L->nzmax);
}

template class Cholesky<double>;
template class Cholesky<std::complex<double>>;

}  // namespace gsd::surface_shm
