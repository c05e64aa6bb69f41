#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_vote : require
#extension GL_KHR_shader_subgroup_ballot : require
// The nearest triangle of a mesh to each query, for the signed distance (mirrors
// SumTree::nearest_triangles in src/sums/sum_tree.cpp, in float32): the host takes the index
// and computes the exact distance to that triangle in double (src/sdf/sdf_gpu.cpp).
// Two ways to walk, as shm_diffuse.comp's nearest element: built with GSD_SOFTWARE_SHAPED (the
// kernel software devices run, gpu::software_shaped) the subgroup walks together, reading the
// tree and the triangles as texel buffers (llvmpipe runs every lane through every iteration of a
// loop any lane is in, so sharing the walk costs it nothing, and a texel fetch is one gather);
// on GPUs each lane walks alone, best first, with its own stack.
#include "box_tree.glsl"

layout(local_size_x_id = 0) in;
#include "workgroup_order.glsl"  // workgroup_share (after the size: it reads gl_WorkGroupSize)

const int STACK = 64;
const uint NONE = 0xffffffffu;

#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 0) uniform samplerBuffer node_texels;
layout(binding = 1) uniform samplerBuffer elem_texels;
vec3 node_lo(uint i) { return texelFetch(node_texels, int(2u * i)).xyz; }
vec3 node_hi(uint i) { return texelFetch(node_texels, int(2u * i + 1u)).xyz; }
uint node_begin(uint i) { return floatBitsToUint(texelFetch(node_texels, int(2u * i)).w); }
uint node_end(uint i) { return floatBitsToUint(texelFetch(node_texels, int(2u * i + 1u)).w); }
#define ELEM(i) texelFetch(elem_texels, int(i))
#else
layout(std430, binding = 0) readonly buffer Nodes { Node nodes[]; };
layout(std430, binding = 1) readonly buffer Elems { vec4 elems[]; };
vec3 node_lo(uint i) { return nodes[i].lo; }
vec3 node_hi(uint i) { return nodes[i].hi; }
uint node_begin(uint i) { return nodes[i].begin; }
uint node_end(uint i) { return nodes[i].end; }
#define ELEM(i) elems[i]
#endif
#define MOMENT(i) vec4(0.0)  // sums_tree.glsl's moments: not read here
layout(std430, binding = 2) readonly buffer Queries { vec4 qs[]; };
layout(std430, binding = 3) writeonly buffer Out { uvec2 outv[]; };  // (nearest element in tree order, cut short)

#include "push_constants.h"
layout(push_constant) uniform Push { SdfNearestPush pc; };  // push_constants.h

#include "sums_tree.glsl"

float element_distance2(vec3 x, uint j) {
    return triangle_distance2(x, ELEM(3u * j).xyz, ELEM(3u * j + 1u).xyz, ELEM(3u * j + 2u).xyz);
}

#ifdef GSD_SOFTWARE_SHAPED
#include "nearest_element.glsl"

// The subgroup walks together (nearest_element.glsl).
uint nearest(vec3 x, bool live, inout uint group_iters) {
    float best2;
    return nearest_element_together(x, live, pc.group_cap, group_iters, best2);
}
#else
// One lane's own walk, best first.
uint nearest(vec3 x, bool live, inout uint group_iters) {
    float best2 = 3.0e38;
    uint best = NONE;
    uint stack[STACK];
    int top = 0;
    stack[top++] = 0u;
    while (live && top > 0) {
        uint i = stack[--top];
        if (box_distance2(x, node_lo(i), node_hi(i)) >= best2) continue;
        if (i >= pc.first_leaf) {
            for (uint j = node_begin(i); j < node_end(i); ++j) {
                float d2 = element_distance2(x, j);
                if (d2 < best2) {
                    best2 = d2;
                    best = j;
                }
            }
        } else {
            uint l = 2u * i + 1u, r = 2u * i + 2u;
            bool left_first = box_distance2(x, node_lo(l), node_hi(l)) <= box_distance2(x, node_lo(r), node_hi(r));
            stack[top++] = left_first ? r : l;
            stack[top++] = left_first ? l : r;
        }
    }
    return best;
}
#endif

void main() {
    uint q = workgroup_share_item();
    bool live = q < pc.count;
    vec3 x = live ? qs[q].xyz : vec3(0.0);
    uint group_iters = 0u;
    uint best = nearest(x, live, group_iters);
    bool cut = pc.group_cap != 0u && group_iters >= pc.group_cap;
    if (live) outv[q] = uvec2(best, cut ? 1u : 0u);
}
