// Empty-space skipping for the march (render.hpp's EmptySpace): which cells of a coarse grid
// hold no surface, by the march's own rule, so that rays cross them without evaluating φ. Most
// rays of a picture miss the surface, and far from it a blended field's every evaluation is its
// k-nearest fallback: the costliest kind.
#include "render/render.hpp"

#include <algorithm>
#include <cmath>

namespace gsd::render {

GridSpec EmptySpace::corners() const { return {n[0] + 1, n[1] + 1, n[2] + 1, {lo, lo + h * Eigen::Vector3d(n[0], n[1], n[2])}}; }

double EmptySpace::skip(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t, int sign) const {
    int c[3];
    const Eigen::Vector3d x = o + t * d;
    for (int a = 0; a < 3; ++a) {
        const double f = (x[a] - lo[a]) / h;
        // A ray starts on the box's face, where f is 0 or n up to rounding: within a hair of
        // the grid it is in the cell at the face (or every ray entering through a far face,
        // and some through a near one, would start unskipped).
        if (!(f >= -1e-9 && f <= n[a] + 1e-9)) return t;  // outside the grid (or NaN)
        c[a] = std::clamp(int(std::floor(f)), 0, n[a] - 1);
    }
    const std::size_t first = cell(c);
    if (!is_empty(first) || (sign != 0 && is_negative(first) != (sign < 0))) return t;
    // Cell by cell along the ray (a 3D DDA): next[a], where it crosses the next plane of cells
    // normal to a.
    double next[3], delta[3];
    int step[3];
    for (int a = 0; a < 3; ++a) {
        step[a] = d[a] > 0 ? 1 : -1;
        next[a] = d[a] != 0 ? (lo[a] + h * (c[a] + (d[a] > 0 ? 1 : 0)) - o[a]) / d[a] : 3e38;
        delta[a] = d[a] != 0 ? h / std::abs(d[a]) : 3e38;
    }
    double exit = t;
    for (int i = 0; i < 256; ++i) {  // a ray crosses at most n_x + n_y + n_z ≤ 192 cells
        const int a = next[0] <= next[1] ? (next[0] <= next[2] ? 0 : 2) : (next[1] <= next[2] ? 1 : 2);
        exit = next[a];
        c[a] += step[a];
        next[a] += delta[a];
        if (c[a] < 0 || c[a] >= n[a] || !is_empty(cell(c))) break;
    }
    // A hair past the last empty cell's exit, so that φ is next sampled in the cell after it;
    // far below the hit tolerance (10⁻⁴ of the box diagonal against 10⁻⁴ of a cell).
    return std::max(exit, t) + 1e-4 * h;
}

bool skip_empty(const March& m, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double span, double& t, int sign) {
    if (!m.empty) return true;
    t = m.empty->skip(o, d, t, sign);
    return t <= span;
}

int empty_space_resolution(const Camera& cam) {
    const double rays = double(cam.width) * double(cam.height);
    return std::clamp(int(std::lround(std::cbrt(rays / 8))), 8, 64);
}

EmptySpace find_empty_space(const Box& box, int cells, double step_scale, const NodeSampler& phi_at_nodes) {
    EmptySpace e;
    const Eigen::Vector3d ext = box.extent();
    e.h = ext.maxCoeff() / cells;
    for (int a = 0; a < 3; ++a) e.n[a] = std::max(1, int(std::ceil(ext[a] / e.h - 1e-9)));
    e.lo = box.lo;
    const GridSpec g = e.corners();
    const std::vector<float> phi = phi_at_nodes(g);
    auto node = [&](int i, int j, int k) {
        return phi[(std::size_t(i) * std::size_t(g.ny) + std::size_t(j)) * std::size_t(g.nz) + std::size_t(k)];
    };
    // Every point of a cube lies within half its diagonal of the nearest corner, and within the
    // whole diagonal of any corner.
    const double half_diagonal = 0.5 * std::sqrt(3.0) * e.h;
    e.bits.assign(2 * e.words(), 0u);
    for (int i = 0; i < e.n[0]; ++i)
        for (int j = 0; j < e.n[1]; ++j)
            for (int k = 0; k < e.n[2]; ++k) {
                double least = 3e38, most = 0;
                int negative = 0;
                bool finite = true;
                for (int q = 0; q < 8; ++q) {
                    const double v = node(i + (q >> 2), j + ((q >> 1) & 1), k + (q & 1));
                    finite = finite && std::isfinite(v);
                    negative += v < 0;
                    least = std::min(least, step_scale * std::abs(v));
                    most = std::max(most, step_scale * std::abs(v));
                }
                if (!finite || (negative != 0 && negative != 8)) continue;
                if (least < half_diagonal && most < 2 * half_diagonal) continue;
                const int at[3] = {i, j, k};
                const std::size_t c = e.cell(at);
                e.bits[c >> 5] |= 1u << (c & 31);
                if (negative == 8) e.bits[e.words() + (c >> 5)] |= 1u << (c & 31);
                ++e.empty_cells;
            }
    return e;
}

}  // namespace gsd::render
