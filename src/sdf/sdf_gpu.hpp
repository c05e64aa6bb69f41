// sdf_gpu.hpp — the signed distance's nearest-triangle search on a Vulkan device
// (shaders/sdf_nearest.comp). Built only with Vulkan; called from an attempt of gpu::on_device,
// so a build without it needs no stand-in. Private to src/sdf.
#pragma once

#include <gsd/core.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace gsd::gpu { class Context; }
namespace gsd::sums { class SumTree; }

namespace gsd::sdf {

/// Each query's nearest element of `tree` (tree order), found in float32 on the device; queries
/// a software device cut short at its loop limit are searched again on the CPU. False (and a
/// reason) when the device cannot take the tree.
bool gpu_nearest(const std::shared_ptr<gpu::Context>& ctx, const sums::SumTree& tree, PointsView queries,
                 std::size_t chunk_size, std::vector<std::uint32_t>& nearest, const ProgressFn& progress,
                 std::string& why_not);

}  // namespace gsd::sdf
