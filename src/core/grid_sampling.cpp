// grid_sampling.cpp — see grid_sampling.hpp.
#include "core/grid_sampling.hpp"

#include <algorithm>
#include <cmath>

namespace gsd::detail {

double trilinear(const GridSpec& grid, const std::vector<float>& v, const Eigen::Vector3d& x, Eigen::Vector3d* grad) {
    const int n[3] = {grid.nx, grid.ny, grid.nz};
    int c[3];
    double f[3], h[3];
    for (int a = 0; a < 3; ++a) {
        h[a] = (grid.box.hi[a] - grid.box.lo[a]) / (n[a] - 1);
        // Clamped in double first: a hit far outside the grid's box (a --color grid of another
        // extent) would otherwise convert a number past int's range.
        const double s = std::clamp((x[a] - grid.box.lo[a]) / h[a], -1.0, double(n[a]));
        c[a] = std::clamp(int(std::floor(s)), 0, n[a] - 2);
        f[a] = std::clamp(s - c[a], 0.0, 1.0);
    }
    auto at = [&](int i, int j, int k) {
        return double(v[(std::size_t(c[0] + i) * std::size_t(n[1]) + std::size_t(c[1] + j)) * std::size_t(n[2]) +
                        std::size_t(c[2] + k)]);
    };
    auto mix = [](double a, double b, double t) { return a + (b - a) * t; };
    const double v000 = at(0, 0, 0), v100 = at(1, 0, 0), v010 = at(0, 1, 0), v110 = at(1, 1, 0);
    const double v001 = at(0, 0, 1), v101 = at(1, 0, 1), v011 = at(0, 1, 1), v111 = at(1, 1, 1);
    const double a00 = mix(v000, v100, f[0]), a10 = mix(v010, v110, f[0]);
    const double a01 = mix(v001, v101, f[0]), a11 = mix(v011, v111, f[0]);
    const double b0 = mix(a00, a10, f[1]), b1 = mix(a01, a11, f[1]);
    if (grad) {
        const double dx0 = mix(v100 - v000, v110 - v010, f[1]), dx1 = mix(v101 - v001, v111 - v011, f[1]);
        *grad = {mix(dx0, dx1, f[2]) / h[0], mix(a10 - a00, a11 - a01, f[2]) / h[1], (b1 - b0) / h[2]};
    }
    return mix(b0, b1, f[2]);
}

}  // namespace gsd::detail
