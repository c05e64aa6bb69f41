// The BoxTree as the kernels see it (shaders/box_tree.glsl): float32 boxes rounded outward so
// every float32 point stays inside its leaf's box, and the point range of each node.
#pragma once

#include "spatial/box_tree.hpp"

#include <cstdint>
#include <vector>

namespace gsd::gpu {

struct DeviceNode {  // std430 layout of `Node` in shaders/box_tree.glsl
    float lo[3];
    std::uint32_t begin;
    float hi[3];
    std::uint32_t end;
};
static_assert(sizeof(DeviceNode) == 32);

std::vector<DeviceNode> device_nodes(const spatial::BoxTree& tree);

}  // namespace gsd::gpu
