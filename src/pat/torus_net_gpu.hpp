#pragma once
#include "pat/torus_net_model.hpp"
#include <gsd/pat.hpp>
namespace gsd::gpu { class Context; }
namespace gsd::pat {
/// Predicts every point's jet and tangent on the device (docs/torusnet.md), chaining neighbor
/// search, features, network in one submission per chunk. chunk_size 0: from device limits.
void predict_jets_gpu(const TorusNetModel& model, const PointCloud& cloud, gpu::Context& ctx,
                      std::vector<Jet>& jets, Points& tangents, std::size_t chunk_size,
                      const ProgressFn& progress);
/// Whether predict_jets_gpu runs this model on this device with torus_net.comp's software
/// build (a subgroup a point, rows through shuffles) rather than the GPU build (tiles).
bool runs_lanes_kernel(const TorusNetModel& model, gpu::Context& ctx);
}
