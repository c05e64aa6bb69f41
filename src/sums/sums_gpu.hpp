// The SumTree on a Vulkan device (shaders/sums_tree.glsl): nodes as `Node` (box, element
// range), 9 vec4 of center, radius and moments per node, and 3 vec4 per element
// ((a, v.x), (b, v.y), (c, v.z)), all float32 in tree order. Private to the library.
#pragma once

#include <gsd/sums.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace gsd::gpu { class Context; }
namespace gsd::sums { class SumTree; }

namespace gsd::sums {

/// Why the device cannot hold the tree ("" when it can).
std::string gpu_unfit(const gpu::Context& ctx, const sums::SumTree& tree);

/// Uploads the tree and makes the winding kernel's pipeline for it, so that gpu_winding finds
/// both made (WindingField::prepare). Nothing when the device cannot take the tree.
void gpu_prepare_winding(const std::shared_ptr<gpu::Context>& ctx, const sums::SumTree& tree, const WindingOptions& options);

/// Winding numbers on the device. False (and a reason) when the device cannot take the tree.
/// `morton` is the queries' Morton order (spatial::morton_order), the order the device takes
/// them in unless GSD_QUERY_ORDER=input.
bool gpu_winding(const std::shared_ptr<gpu::Context>& ctx, const sums::SumTree& tree, PointsView queries,
                 const std::vector<std::uint32_t>& morton, const WindingOptions& options, WindingResult& out, const ProgressFn& progress, std::string& why_not);

}  // namespace gsd::sums

#if defined(GSD_HAVE_VULKAN)
#include "gpu/runtime.hpp"

namespace gsd::sums {

struct DeviceSumTree {
    gpu::Buffer nodes, moments, elements;
    std::uint32_t first_leaf = 0;
    /// The kinds of element it holds, as the kernels read them: bit 0 triangles, bit 1 points
    /// (a = b = c in float32). Kernels specialized for one kind leave the other's code out.
    std::int32_t element_kinds = 0;
};
DeviceSumTree upload(gpu::Context& ctx, const sums::SumTree& tree);

}  // namespace gsd::sums
#endif
