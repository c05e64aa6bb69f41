// A grid's values as a field (gsd/field_algebra.hpp): trilinear inside the box, the value at
// the box's nearest point plus the distance to it outside.
#include <gsd/field_algebra.hpp>

#include "core/grid_sampling.hpp"

#include <cmath>

namespace gsd {

GridField::GridField(GridSpec grid, std::vector<float> values) : grid_(grid), values_(std::move(values)) {
    grid_.validate();
    if (values_.size() != grid_.node_count())
        throw Error("values", std::to_string(values_.size()) + " values for a grid of " + std::to_string(grid_.node_count()) +
                                  " nodes");
    for (std::size_t i = 0; i < values_.size(); ++i)
        if (!std::isfinite(values_[i])) throw Error("values", "value " + std::to_string(i) + " is not finite");
}

FieldValues GridField::evaluate(PointsView q, bool with_gradient, const ProgressFn&) const {
    FieldValues out;
    const auto n = std::ptrdiff_t(q.rows());
    for (std::ptrdiff_t i = 0; i < n; ++i)
        if (!q.row(i).allFinite()) throw Error("queries", "query " + std::to_string(i) + " is not finite");
    out.phi.resize(std::size_t(n));
    if (with_gradient) out.gradient.resize(3 * std::size_t(n));
    out.device = "cpu";
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < n; ++i) {
        const Eigen::Vector3d x = q.row(i).transpose();
        const Eigen::Vector3d c = x.cwiseMax(grid_.box.lo).cwiseMin(grid_.box.hi);  // the box's nearest point
        Eigen::Vector3d g;
        double v = detail::trilinear(grid_, values_, c, with_gradient ? &g : nullptr);
        const Eigen::Vector3d out_of_box = x - c;
        const double d = out_of_box.norm();
        v += d;
        out.phi[std::size_t(i)] = float(v);
        if (!with_gradient) continue;
        if (d > 0) {
            // Along the axes where x is past the box the distance term takes over from the
            // interpolant (which is constant there).
            for (int a = 0; a < 3; ++a)
                if (out_of_box[a] != 0) g[a] = 0;
            g += out_of_box / d;
        }
        for (int a = 0; a < 3; ++a) out.gradient[3 * std::size_t(i) + std::size_t(a)] = float(g[a]);
    }
    return out;
}

FieldValues GridField::evaluate(const GridSpec& grid, bool with_gradient, const ProgressFn& progress) const {
    grid.validate();
    const bool same = grid.nx == grid_.nx && grid.ny == grid_.ny && grid.nz == grid_.nz && grid.box.lo == grid_.box.lo &&
                      grid.box.hi == grid_.box.hi;
    if (same && !with_gradient) return {values_, {}, "cpu"};
    return evaluate(grid.nodes(), with_gradient, progress);
}

}  // namespace gsd
