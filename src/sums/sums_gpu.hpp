// The SumTree on a Vulkan device (shaders/sums_tree.glsl): nodes as `Node` (box, element
// range), 9 vec4 of center, radius and moments per node, and 3 vec4 per element
// ((a, v.x), (b, v.y), (c, v.z)), all float32 in tree order. Private to the library.
#pragma once

#include <gsd/sums.hpp>

#include <memory>
#include <string>

namespace gsd::gpu { class Context; }
namespace gsd::detail { class SumTree; }

namespace gsd::sums_detail {

/// Why the device cannot hold the tree ("" when it can).
std::string gpu_unfit(const gpu::Context& ctx, const detail::SumTree& tree);

/// Winding numbers on the device. False (and a reason) when the device cannot take the tree.
bool gpu_winding(const std::shared_ptr<gpu::Context>& ctx, const detail::SumTree& tree, PointsView queries,
                 const WindingOptions& options, WindingResult& out, const ProgressFn& progress, std::string& why_not);

}  // namespace gsd::sums_detail

#if defined(GSD_HAVE_VULKAN)
#include "gpu/runtime.hpp"

namespace gsd::sums_detail {

/// llvmpipe (lavapipe) silently ends every loop of a shader once the SIMD group running it has
/// iterated 65535 times in all. On a software device the kernels count their own iterations
/// and flag a query past lane_cap = 65535 / lanes; the host redoes the flagged query's whole
/// group of `lanes` consecutive queries (lanes_per_group) on the CPU. 0: no limit (hardware).
std::uint32_t lane_cap(const gpu::Context& ctx);
std::uint32_t lanes_per_group(const gpu::Context& ctx);

/// Marks the group of consecutive invocations (within one dispatch starting at `first`) that
/// holds query q.
void mark_group(std::vector<char>& redo, std::size_t first, std::size_t q, std::uint32_t lanes, std::size_t count);

struct DeviceSumTree {
    gpu::Buffer nodes, moments, elements;
    std::uint32_t first_leaf = 0;
};
DeviceSumTree upload(gpu::Context& ctx, const detail::SumTree& tree);

}  // namespace gsd::sums_detail
#endif
