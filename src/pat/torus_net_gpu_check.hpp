// Test entry of the TorusNet kernels (src/pat/torus_net_gpu.cpp): the network kernel on
// given neighborhoods instead of a cloud's kNN, returning what it computed on the way, so the
// tests can hold features, scale and coefficients to PyTorch's golden file. Private.
#pragma once

#include "pat/torus_net_model.hpp"

#include <gsd/pat.hpp>

#include <cmath>
#include <vector>

namespace gsd::gpu { class Context; }

namespace gsd::pat {

struct TorusNetGpuTrace {
    std::vector<float> features;  ///< [count][k][7]
    std::vector<float> scale;     ///< [count] (m)
    std::vector<Jet> jets;        ///< [count]
    bool global_workspace = false;  ///< whether the activations lived in device memory
};

/// Runs torus_net.comp on `count` = positions.rows() / k neighborhoods: rows [i·k, (i+1)·k) of
/// positions / normals are neighborhood i, token 0 its center. `global_workspace` forces the
/// device-memory workspace (used automatically when a model exceeds shared memory).
TorusNetGpuTrace torusnet_gpu_neighborhoods(const TorusNetModel& model, gpu::Context& ctx, const Points& positions,
                                            const Points& normals, bool global_workspace = false);

/// The coordinate axis tangent_of(n) crosses n with (0: x, 1: y, 2: z; the thresholds of
/// src/pat/torus.cpp, decided in double): the kernels get it with each normal, so their float32
/// tangent s = normalize(n × axis) never takes the other branch. Tested against tangent_of.
inline int tangent_axis(const Eigen::Vector3d& n) {
    return std::abs(n.x()) < 0.57735 ? 0 : std::abs(n.y()) < 0.57735 ? 1 : 2;
}

}  // namespace gsd::pat
