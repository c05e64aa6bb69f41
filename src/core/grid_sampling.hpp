// grid_sampling.hpp — values of a grid between its nodes: trilinear interpolation, as the
// render_grid shader samples (the renderer, the signed distance's SHM sign).
#pragma once

#include <gsd/core.hpp>

#include <vector>

namespace gsd::detail {

/// The trilinear interpolant of `values` (GridSpec storage order) at x, clamped to the grid's
/// box; its gradient too if `grad` is given.
double trilinear(const GridSpec& grid, const std::vector<float>& values, const Eigen::Vector3d& x, Eigen::Vector3d* grad);

}  // namespace gsd::detail
