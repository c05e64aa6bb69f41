// laplace_eigen.hpp — the lowest eigenfunctions of a triangle mesh's cotan Laplacian, for the
// benchmarks' test curves (level sets of low-frequency eigenfunctions, thesis §7.1). Spectra's
// shift-invert Lanczos on L φ = λ M φ (cotan stiffness L, lumped masses M).
#pragma once

#include <gsd/core.hpp>

#include <Eigen/Geometry>
#include <Eigen/SparseCore>
#include <Spectra/MatOp/SparseSymMatProd.h>
#include <Spectra/MatOp/SymShiftInvert.h>
#include <Spectra/SymGEigsShiftSolver.h>

#include <stdexcept>
#include <vector>

namespace gsd::bench {

/// Columns 0…count−1: the eigenfunctions of the `count` smallest eigenvalues, M-orthonormal (the
/// first is constant on a connected closed mesh). Triangle meshes only.
inline Eigen::MatrixXd laplace_eigenfunctions(const PolygonMesh& m, int count) {
    const Eigen::Index n = m.vertices.rows();
    std::vector<Eigen::Triplet<double>> stiffness, mass;
    for (std::size_t f = 0; f < m.face_count(); ++f) {
        const std::uint32_t* v = m.indices.data() + m.offsets[f];
        std::array<Eigen::Vector3d, 3> p;
        for (int k = 0; k < 3; ++k) p[k] = m.vertices.row(v[k]).transpose();
        const double area2 = (p[1] - p[0]).cross(p[2] - p[0]).norm();
        if (!(area2 > 0)) continue;
        for (int k = 0; k < 3; ++k) {
            // The angle at corner k weighs the opposite edge (i, j): ½ cot = ½ (u·w)/|u×w|.
            const int i = (k + 1) % 3, j = (k + 2) % 3;
            const double w = 0.5 * (p[i] - p[k]).dot(p[j] - p[k]) / area2;
            stiffness.emplace_back(v[i], v[i], w);
            stiffness.emplace_back(v[j], v[j], w);
            stiffness.emplace_back(v[i], v[j], -w);
            stiffness.emplace_back(v[j], v[i], -w);
            mass.emplace_back(v[k], v[k], area2 / 6);
        }
    }
    Eigen::SparseMatrix<double> L(n, n), M(n, n);
    L.setFromTriplets(stiffness.begin(), stiffness.end());
    M.setFromTriplets(mass.begin(), mass.end());
    for (Eigen::Index i = 0; i < n; ++i) M.coeffRef(i, i) += 1e-12;  // vertices on no face
    // A shift just below 0 keeps L − σM positive definite (L itself is singular).
    const double sigma = -1e-3 * L.diagonal().sum() / M.diagonal().sum();
    using Op = Spectra::SymShiftInvert<double, Eigen::Sparse, Eigen::Sparse>;
    using BOp = Spectra::SparseSymMatProd<double>;
    Op op(L, M);
    BOp bop(M);
    Spectra::SymGEigsShiftSolver<Op, BOp, Spectra::GEigsMode::ShiftInvert> eigs(op, bop, count,
                                                                               std::min<Eigen::Index>(n, 3 * count + 10), sigma);
    eigs.init();
    eigs.compute(Spectra::SortRule::LargestMagn, 2000, 1e-10, Spectra::SortRule::SmallestAlge);
    if (eigs.info() != Spectra::CompInfo::Successful) throw std::runtime_error("laplace_eigenfunctions: no convergence");
    return eigs.eigenvectors();
}

}  // namespace gsd::bench
