// The outside veto of the SHM (ShmOptions::veto_winding), shared by the uniform grid and the
// adaptive one: both hand it their nodes' positions.
#pragma once

#include <gsd/shm.hpp>

#include <functional>
#include <vector>

namespace gsd::shm {

struct VetoParams {
    double winding = 0.2, slope = 3.0, margin = 0.1;  ///< ShmOptions::veto_*
};

/// Where holes are large, SHM's completion can bulge out over them: nodes there get φ < 0 with
/// no element nearby to say so. Such a node is (1) far from every element for its |φ| — deep
/// inside, |φ| is about the distance to the surface — and (2) at a low winding number of the
/// source, which a hole lowers only so far (docs/shm.md). φ → φ(1 − 2κ), κ ∈ [0, 1] the lesser
/// of two ramps, each ½ where its condition starts to hold: the sign flips exactly where both
/// hold, and φ stays continuous in its inputs (so that a device's φ and the CPU's stay as close
/// after the veto as before). `position(i)`: node i's position; consecutive nodes should be
/// near each other (each search starts from the last node's nearest element). Returns the
/// number of nodes turned outside.
std::size_t veto_outside(const ShmSource& source, const VetoParams& params, std::vector<double>& phi,
                         const std::function<Eigen::Vector3d(std::size_t)>& position);

}  // namespace gsd::shm
