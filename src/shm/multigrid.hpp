// The multigrid hierarchy of the grid Poisson problem, shared by the CPU reference and the GPU
// kernels: cell-centered coarsening by 2 in every axis (any grid size: an odd last cell stays
// alone), coarse operators rediscretized from the aggregated cell sizes, linear (cell-centered)
// prolongation P and restriction R = Pᵀ, and a dense pseudo-inverse on the coarsest level.
// Private to src/shm.
#pragma once

#include <gsd/core.hpp>

#include <array>
#include <cstdint>
#include <vector>

namespace gsd::shm {

/// One axis of one level: per cell, its size in finest cells and its coupling to the next cell.
struct AxisLevel {
    int n = 0;
    std::vector<double> size;       ///< finest cells per cell (1 at level 0)
    std::vector<double> center;     ///< cell center in finest-cell units
    /// link[i] = 1/(Δ² · distance between the centers of cells i and i+1 in finest cells); 0 for
    /// the last cell. The coupling across that face is link[i] times the face's area (the sizes
    /// of the other two axes), so the sweeps multiply instead of dividing.
    std::vector<double> link;
    // Prolongation to the next finer level along this axis: fine cell i takes
    // w0[i]·coarse[c0[i]] + w1[i]·coarse[c1[i]].
    std::vector<int> c0, c1;
    std::vector<double> w0, w1;
    // Restriction (Pᵀ) gather lists: coarse cell I receives Σ weight·fine[index] over
    // gather[offsets[I] .. offsets[I+1]).
    std::vector<int> offsets, gather_index;
    std::vector<double> gather_weight;
};

struct Level {
    std::array<AxisLevel, 3> axis;
    std::size_t count() const { return std::size_t(axis[0].n) * std::size_t(axis[1].n) * std::size_t(axis[2].n); }
    std::size_t index(int i, int j, int k) const { return (std::size_t(i) * std::size_t(axis[1].n) + std::size_t(j)) * std::size_t(axis[2].n) + std::size_t(k); }
};

struct Hierarchy {
    std::vector<Level> levels;     ///< levels[0] is the grid
    std::array<double, 3> inv_h2;  ///< 1/Δ_a² of the finest grid
    std::vector<double> coarse_pinv;  ///< dense pseudo-inverse of the coarsest operator (row-major)

    explicit Hierarchy(const GridSpec& grid);
    /// Coupling between cell (i,j,k) and its +axis neighbor at level l.
    double coupling(int l, int axis, int i, int j, int k) const;

    /// Calls f(p, q, w) once per edge of level l: cells p and q (storage indices) coupled by w.
    template <class F>
    void for_each_edge(int l, F&& f) const {
        const Level& lv = levels[std::size_t(l)];
        for (int i = 0; i < lv.axis[0].n; ++i)
            for (int j = 0; j < lv.axis[1].n; ++j)
                for (int k = 0; k < lv.axis[2].n; ++k) {
                    const int ijk[3] = {i, j, k};
                    for (int a = 0; a < 3; ++a) {
                        if (ijk[a] + 1 >= lv.axis[std::size_t(a)].n) continue;
                        int nb[3] = {i, j, k};
                        ++nb[a];
                        f(lv.index(i, j, k), lv.index(nb[0], nb[1], nb[2]), coupling(l, a, i, j, k));
                    }
                }
    }
};

// Inline: the smoother and the residual call it for every edge of every sweep.
inline double Hierarchy::coupling(int l, int a, int i, int j, int k) const {
    const Level& lv = levels[std::size_t(l)];
    const int ijk[3] = {i, j, k};
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    const double face = lv.axis[std::size_t(b)].size[std::size_t(ijk[b])] * lv.axis[std::size_t(c)].size[std::size_t(ijk[c])];
    return face * lv.axis[std::size_t(a)].link[std::size_t(ijk[a])];
}

}  // namespace gsd::shm
