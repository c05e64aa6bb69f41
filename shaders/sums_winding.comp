#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_vote : require
#ifdef GSD_SOFTWARE_SHAPED
#extension GL_KHR_shader_subgroup_arithmetic : require
#endif
// Fast generalized winding numbers: the CPU's packet walk (SumTree::winding_lanes, src/sums/
// winding_walk.inl) with a subgroup as the packet. The queries come sorted along a Morton curve,
// so the lanes of a subgroup are neighbours and walk nearly the same nodes. The subgroup walks
// the tree once, together: at each node every lane makes its own decision (accept the node's
// expansion, or not), and the walk descends when any lane still needs the node's children. A
// lane that accepted a node sits out the node's subtree. The node index is the same on every
// lane, so the node's records are read once per subgroup, not gathered lane by lane, and no lane
// waits on another's branch.
//
// The walk needs no stack: the tree is complete (children of i at 2i+1, 2i+2), so the next node
// in depth-first order after finishing node i is found from i's index alone (climb while i is a
// right child, then step to the right sibling), and a lane that accepted a node at depth d sits
// out exactly until the walk comes back to depth ≤ d.
//
// Records (uploaded by src/sums/sums_gpu.cpp) are in the CPU walk's coordinates: centered on
// the root and scaled by its radius, so float32 keeps its precision wherever the model is.

#include "box_tree.glsl"  // next_in_depth_first

layout(local_size_x_id = 0) in;

// Per node, first a vec4: the acceptance test (c, reach²) — reach² = sums::winding_reach2 for
// this call's β and tolerance, made on the host in float32 as the CPU's float walk makes it, so
// the two accept the same nodes. Then, from node_count on, 7 vec4 per node: the element range
// (begin, end, -, -) and the expansion (SumTree::WindingNodeT<float>: k0, m0[3], p[3], s1[6],
// t3[10], padded to 24 floats).
// Per element, 3 vec4: (a, v.x), (b, v.y), (c, v.z), a point when a = b = c.
// Built twice (cmake/EmbedShaders.cmake): as storage buffers, and with GSD_SOFTWARE_SHAPED
// (gpu::software_shaped) as uniform texel buffers, for llvmpipe, which reads a storage buffer
// inside a loop one lane and one float at a time, where a texel fetch is one gather.
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 0) uniform samplerBuffer node_texels;
layout(binding = 1) uniform samplerBuffer elem_texels;
#define NODE(i) texelFetch(node_texels, int(i))
#define ELEM(i) texelFetch(elem_texels, int(i))
#else
layout(std430, binding = 0) readonly buffer Nodes { vec4 nodes[]; };
layout(std430, binding = 1) readonly buffer Elems { vec4 elems[]; };
#define NODE(i) nodes[i]
#define ELEM(i) elems[i]
#endif
layout(std430, binding = 2) readonly buffer Queries { vec4 qs[]; };
layout(std430, binding = 3) writeonly buffer Out { vec2 outv[]; };  // (w, terms; −1: cut short)

#include "push_constants.h"
layout(push_constant) uniform Push { WindingPush pc; };  // push_constants.h

// Which kinds of elements the tree holds (bit 0: triangles, bit 1: points): code for a kind the
// tree lacks is left out (llvmpipe would run both branches of the test for every element).
layout(constant_id = 1) const int ELEMENT_KINDS = 3;

const float FOUR_PI = 12.566370614359172;
const uint NONE = 0xffffffffu;

// SumTree's winding_expansion: a polynomial in d = x − c with the node's scaled moments.
float winding_expansion(vec4 e0, vec4 e1, vec4 e2, vec4 e3, vec4 e4, vec4 e5, vec3 d, float ir) {
    // e0 = (k0, m0), e1 = (p, s0), e2 = (s1..s4), e3 = (s5, t0..t2), e4 = (t3..t6), e5 = (t7..t9, -)
    float ir2 = ir * ir;
    float xx = d.x * d.x, yy = d.y * d.y, zz = d.z * d.z;
    float linear = e0.x + dot(e0.yzw, d);
    float second = dot(e1.xyz, d) + e1.w * xx + e2.x * yy + e2.y * zz + d.x * (e2.z * d.y + e2.w * d.z) + e3.x * d.y * d.z;
    float third = d.x * (e3.y * xx + e4.z * yy + e5.x * zz + e5.z * d.y * d.z) + d.y * (e3.z * yy + e4.x * xx + e5.y * zz) +
                  d.z * (e3.w * zz + e4.y * xx + e4.w * yy);
    return ir * ir2 * (linear + ir2 * (second + ir2 * third));
}

// Signed solid angle of a triangle seen from x, / 4π (Van Oosterom–Strackee).
float triangle_winding(vec3 x, vec3 a, vec3 b, vec3 c) {
    a -= x; b -= x; c -= x;
    float la = length(a), lb = length(b), lc = length(c);
    float num = dot(a, cross(b, c));
    float den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
    return atan(num, den) * (2.0 / FOUR_PI);
}

// An element's exact term: a triangle's solid angle, or a point's dipole (a = b = c).
float element_winding(vec3 x, vec4 ea, vec4 eb, vec4 ec) {
    if (ELEMENT_KINDS == 2 || (ELEMENT_KINDS == 3 && ea.xyz == eb.xyz && ea.xyz == ec.xyz)) {
        vec3 y = ea.xyz - x;
        float r2 = max(dot(y, y), 1e-37);  // at the point itself the numerator is 0 too
        return dot(vec3(ea.w, eb.w, ec.w), y) / (FOUR_PI * r2 * sqrt(r2));
    }
    return triangle_winding(x, ea.xyz, eb.xyz, ec.xyz);
}

#ifndef GSD_SOFTWARE_SHAPED
void main() {
    uint q = gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    bool valid = q < pc.count;  // lanes past the end walk along, idle: the subgroup stays whole
    vec3 x = valid ? qs[q].xyz : vec3(0.0);
    float w_far = 0.0, w_near = 0.0;
    uint terms = 0u;
    uint sit_out = valid ? NONE : 0u;  // depth of the node this lane accepted (NONE: walking)
    uint node = 0u, depth = 0u, iters = 0u;
    bool cut = false;
    while (true) {
        // llvmpipe (lavapipe) ends every loop of a shader, silently, once a SIMD group has
        // iterated 65535 times in all; the subgroup counts its own (uniform) iterations and
        // stops short of that, and the host redoes the queries it flags (sums_gpu.cpp).
        if (pc.group_cap > 0u && iters >= pc.group_cap) {
            cut = true;
            break;
        }
        ++iters;
        if (valid && depth <= sit_out) sit_out = NONE;  // the walk left the subtree it sat out
        bool walking = sit_out == NONE;
        vec4 test = NODE(node);  // (c, reach²): all a visit reads, unless it sums
        vec3 d = x - test.xyz;
        float d2 = dot(d, d);
        bool accepted = walking && d2 > test.w;
        if (accepted) {
            uint r = pc.node_count + 7u * node;
            w_far += winding_expansion(NODE(r + 1u), NODE(r + 2u), NODE(r + 3u), NODE(r + 4u), NODE(r + 5u), NODE(r + 6u), d,
                                       inversesqrt(d2));
            ++terms;
        }
        bool open = walking && !accepted;
        bool leaf = node >= pc.first_leaf;
        bool any_open = subgroupAny(open);
        if (leaf && any_open) {  // the leaf's elements exactly, on the lanes that opened it
            uvec2 range = floatBitsToUint(NODE(pc.node_count + 7u * node).xy);
            uint begin = range.x, end = range.y;
            for (uint j = begin; j < end; ++j) {
                ++iters;
                float v = element_winding(x, ELEM(3u * j), ELEM(3u * j + 1u), ELEM(3u * j + 2u));
                if (open) w_near += v;
            }
            if (open) terms += end - begin;
        }
        if (!leaf && any_open) {
            if (accepted) sit_out = depth;
            node = 2u * node + 1u;
            ++depth;
            continue;
        }
        // Next in depth-first order. With k = node + 1 (1-based heap numbering: left children
        // even, right children odd), climb past the trailing 1 bits — the right children — and
        // step to the right sibling; all ones is the root's rightmost path: the walk is over.
        uint k = node + 1u;
        uint up = uint(findLSB(~k));
        k >>= up;
        if (k == 0u) break;
        node = k;  // the sibling k + 1, 0-based
        depth -= up;
    }
    if (valid) outv[q] = vec2(w_far + w_near, cut ? -1.0 : float(terms));
}
#else
// The walk shaped for llvmpipe, which runs the body of every `if` whether a lane takes it or
// not, every loop's body at least once, and a subgroup vote as a loop over the lanes. So each
// lane walks the tree on its own (the same stackless order: a texel fetch gathers 8 lanes'
// nodes as fast as one), and the walk only lists the nodes the lane accepted and the leaves it
// opened; the sums run in loops of their own every ROUND steps, where every pass is work for
// some lane. Each lane sums the same terms as the walk above, in another order.
const uint ROUND = 32u;  // walk steps between the sums: each list holds at most this many

void main() {
    uint q = gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    bool walking = q < pc.count;
    vec3 x = walking ? qs[q].xyz : vec3(0.0);
    // Push constants read inside a loop are gathered lane by lane; read them once.
    const uint first_leaf = pc.first_leaf, group_cap = pc.group_cap, records = pc.node_count;
    float w_far = 0.0, w_near = 0.0;
    uint terms = 0u, node = 0u;
    uint iters = 0u;  // the subgroup's loop iterations, all loops together (uniform)
    bool cut = false;
    uint accepted_nodes[ROUND], opened_leaves[ROUND];
    while (true) {
        // The round's walk may take ROUND + 1 iterations and its sums the rest of the host's
        // allowance (sums_gpu.cpp), so a round starts only below the cap.
        if (group_cap > 0u && iters >= group_cap) {
            cut = walking;  // lanes whose walk is over have their whole sum
            break;
        }
        iters += ROUND + 2u;
        uint n_accepted = 0u, n_opened = 0u;
        for (uint step = 0u; step < ROUND; ++step) {
            if (!walking) break;
            vec4 test = NODE(node);  // (c, reach²)
            vec3 d = x - test.xyz;
            bool accepted = dot(d, d) > test.w;
            bool leaf = node >= first_leaf;
            // Every lane writes, and the counts say which entries hold: a masked write is a
            // branch per lane for llvmpipe, and an unpredictable one.
            accepted_nodes[n_accepted] = node;
            opened_leaves[n_opened] = node;
            n_accepted += accepted ? 1u : 0u;
            n_opened += !accepted && leaf ? 1u : 0u;
            if (!accepted && !leaf) {
                node = 2u * node + 1u;
            } else {
                node = next_in_depth_first(node);
                walking = node != 0u;
            }
        }
        // The accepted nodes' expansions.
        uint passes = subgroupMax(n_accepted);
        iters += passes + 1u;
        for (uint i = 0u; i < passes; ++i) {
            uint a = accepted_nodes[min(i, ROUND - 1u)], r = records + 7u * a;
            vec3 d = x - NODE(a).xyz;
            float e = winding_expansion(NODE(r + 1u), NODE(r + 2u), NODE(r + 3u), NODE(r + 4u), NODE(r + 5u), NODE(r + 6u),
                                        d, inversesqrt(dot(d, d)));
            if (i < n_accepted) w_far += e;
        }
        terms += n_accepted;
        // The opened leaves' elements, exactly.
        passes = subgroupMax(n_opened);
        iters += passes + 1u;
        for (uint i = 0u; i < passes; ++i) {
            uvec2 range = i < n_opened ? floatBitsToUint(NODE(records + 7u * opened_leaves[min(i, ROUND - 1u)]).xy) : uvec2(0u);
            uint count = range.y - range.x;
            uint longest = subgroupMax(count);
            iters += longest + 1u;
            for (uint j = 0u; j < longest; ++j) {
                uint e = 3u * (j < count ? range.x + j : 0u);
                float v = element_winding(x, ELEM(e), ELEM(e + 1u), ELEM(e + 2u));
                if (j < count) w_near += v;
            }
            terms += count;
        }
        if (!subgroupAny(walking)) break;
    }
    if (q < pc.count) outv[q] = vec2(w_far + w_near, cut ? -1.0 : float(terms));
}
#endif
