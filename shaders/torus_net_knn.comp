#version 450
#extension GL_GOOGLE_include_directive : require
// TorusNet stage 1 (docs/torusnet.md, "GPU kernels"): the neighborhood of each point of a
// chunk. One invocation per point walks the kd-tree for its K − 1 nearest other points and
// writes K token indices (tree order): token 0 is the point itself, then the others, nearest
// first. Duplicates of the point are ordinary neighbors; only its own index is skipped.

layout(local_size_x_id = 0) in;
#include "workgroup_order.glsl"  // workgroup_share (after the size: it reads gl_WorkGroupSize)
layout(constant_id = 1) const int K = 32;  // tokens per point (≥ 2)

#include "box_tree.glsl"

const int STACK = 48;  // kd-tree depth bound

// Points in tree order (xyz: float32 position) and the kd-tree's nodes (box_tree_buffers.glsl).
#define POINTS_BINDING 0
#define NODES_BINDING 1
#include "box_tree_buffers.glsl"
layout(std430, binding = 2) readonly buffer Centers { uint centers[]; };  // the chunk's points (tree order)
layout(std430, binding = 3) writeonly buffer Tokens { uint tokens[]; };   // [count][K]

#include "push_constants.h"
layout(push_constant) uniform Push { TorusNetKnnPush pc; };  // push_constants.h

#define KNN_MAX K
#include "box_tree_knn.glsl"

void main() {
    uint i = workgroup_share_item();
    if (i >= pc.count) return;
    uint c = centers[i];
    float kd[K];
    uint ki[K];
    knn(point_at(c).xyz, uint(K - 1), c, pc.first_leaf, kd, ki);
    uint base = i * uint(K);
    tokens[base] = c;
    for (int m = 0; m < K - 1; ++m) tokens[base + uint(m) + 1] = ki[m];
}
