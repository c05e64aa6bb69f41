#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_vote : require
#ifdef GSD_SOFTWARE_SHAPED
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_shuffle : require
#extension GL_EXT_control_flow_attributes : require
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
#include "workgroup_order.glsl"  // workgroup_share (after the size: it reads gl_WorkGroupSize)

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
    uint q = workgroup_share_item();
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
// The walk shaped for llvmpipe, which runs a subgroup as one SIMD thread (8 lanes of 32 bits
// with AVX2), runs the body of every `if` whether a lane takes it or not, and gathers a load lane
// by lane inside any loop even when every lane reads one address. So here the lanes are not the
// queries: a workgroup (one subgroup) sums a group of Q Morton-adjacent queries (16, or 12 or 8
// on trees too large for 16-bit node indices), each lane holds all of them in registers (as Q/4
// vec4 per axis: every per-query step is four-wide vector code, no loop at run time), and the
// lanes share out the tree's nodes. This is the CPU's packet walk (SumTree::winding_lanes) with a
// node's record read once for the group, not once per query.
//
// The walk keeps a stack in shared memory of inner nodes whose two children some of the queries
// need tested, with those queries' bits. Each round every lane pops an entry, tests both children
// against the group's queries, and pushes: a child with the queries that accept its expansion onto
// the far list, a leaf with the queries that opened it onto the leaf list, an inner child with
// those queries back onto the stack (the places from one prefix sum over the subgroup). The lists
// are summed when they fill and at the end, an entry a lane: a far entry's expansion for the
// group's queries, or a leaf's elements exactly. Each query sums the terms the CPU's float walk
// sums (the same count: test_gpu), in another order; a query's sum depends on the others of its
// group, so the host streams whole groups (StreamJob::granule) and results do not depend on the
// chunk size.
//
// The walk's rounds (pops, pushes, prefix sums: about half the kernel's time with 8 queries) are
// paid once per group, and 16 neighbouring queries open far fewer than twice the nodes 8 open:
// the kernel's time falls by a sixth from 8 to 16 (sums_gpu.cpp).
layout(constant_id = 2) const uint QUERIES = 16u;  // 8, 12 or 16: sums_gpu.cpp chooses (software_group)
const uint Q = QUERIES;
const uint G = Q / 4u;                // vec4 of queries per axis
const uint QUERY_BITS = (1u << Q) - 1u;  // an entry is node << Q | the queries it is for
const uint STACK = 1024u;      // entries; a walk needing more is cut
const uint FAR = 256u, LEAVES = 128u;
const uint WIDEST = 64u;      // lanes a subgroup may have: each has its own slots past the ends
shared uint stack_entries[STACK + 2u * WIDEST];
shared uint far_entries[FAR + 2u * WIDEST];
shared uint leaf_entries[LEAVES + 2u * WIDEST];

// The group's queries, every lane all of them: X[g] holds queries 4g..4g+3's x (G of 4 used).
// Every loop over g is unrolled ([[unroll]]): X[g] stays in registers, and a rolled loop would
// count against llvmpipe's loop limit where the walk's count (iters) does not include it.
vec4 X[4], Y[4], Z[4];

// Shared memory between the rounds: the workgroup is one subgroup (gpu::loop_capped_workgroup).
void sync_subgroup() {
    subgroupMemoryBarrierShared();
    subgroupBarrier();
}

// The queries whose bit is set in m from bit `first` on, as a bvec4.
bvec4 bits4(uint m, uint first) {
    return notEqual((uvec4(m) >> uvec4(first, first + 1u, first + 2u, first + 3u)) & 1u, uvec4(0u));
}

// winding_expansion above, for four queries at once (d = x − c per axis).
vec4 expansion4(vec4 e0, vec4 e1, vec4 e2, vec4 e3, vec4 e4, vec4 e5, vec4 dx, vec4 dy, vec4 dz) {
    vec4 xx = dx * dx, yy = dy * dy, zz = dz * dz;
    vec4 ir = inversesqrt(xx + yy + zz), ir2 = ir * ir;
    vec4 linear = e0.x + e0.y * dx + e0.z * dy + e0.w * dz;
    vec4 second = e1.x * dx + e1.y * dy + e1.z * dz + e1.w * xx + e2.x * yy + e2.y * zz + dx * (e2.z * dy + e2.w * dz) +
                  e3.x * dy * dz;
    vec4 third = dx * (e3.y * xx + e4.z * yy + e5.x * zz + e5.z * dy * dz) + dy * (e3.z * yy + e4.x * xx + e5.y * zz) +
                 dz * (e3.w * zz + e4.y * xx + e4.w * yy);
    return ir * ir2 * (linear + ir2 * (second + ir2 * third));
}

// element_winding above, for four queries at once.
vec4 element4(vec4 X, vec4 Y, vec4 Z, vec4 ea, vec4 eb, vec4 ec) {
    vec4 w = vec4(0.0);
    bool point = ELEMENT_KINDS == 2 || (ELEMENT_KINDS == 3 && ea.xyz == eb.xyz && ea.xyz == ec.xyz);
    if (ELEMENT_KINDS != 1) {  // a point's dipole
        vec4 yx = ea.x - X, yy = ea.y - Y, yz = ea.z - Z;
        vec4 r2 = max(yx * yx + yy * yy + yz * yz, vec4(1e-37));
        w = (ea.w * yx + eb.w * yy + ec.w * yz) / (FOUR_PI * r2 * sqrt(r2));
    }
    if (ELEMENT_KINDS != 2) {  // a triangle's solid angle
        vec4 ax = ea.x - X, ay = ea.y - Y, az = ea.z - Z;
        vec4 bx = eb.x - X, by = eb.y - Y, bz = eb.z - Z;
        vec4 cx = ec.x - X, cy = ec.y - Y, cz = ec.z - Z;
        vec4 la = sqrt(ax * ax + ay * ay + az * az), lb = sqrt(bx * bx + by * by + bz * bz), lc = sqrt(cx * cx + cy * cy + cz * cz);
        vec4 num = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx);
        vec4 den = la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (bx * cx + by * cy + bz * cz) * la +
                   (cx * ax + cy * ay + cz * az) * lb;
        vec4 t = atan(num, den) * (2.0 / FOUR_PI);
        w = point ? w : t;
    }
    return w;
}

// The group's queries farther from c than the node's reach: d² computed as the CPU's walk does.
uint accepting(vec4 test) {
    uvec4 a = uvec4(0u);
    [[unroll]] for (uint g = 0u; g < G; ++g) {
        vec4 dx = X[g] - test.x, dy = Y[g] - test.y, dz = Z[g] - test.z;
        a |= uvec4(greaterThan(dx * dx + dy * dy + dz * dz, vec4(test.w))) << (uvec4(0u, 1u, 2u, 3u) + 4u * g);
    }
    return a.x | a.y | a.z | a.w;
}

void main() {
    const uint S = gl_WorkGroupSize.x, lane = gl_LocalInvocationID.x;
    // Push constants read inside a loop are gathered lane by lane; read them once.
    const uint count = pc.count, first_leaf = pc.first_leaf, group_cap = pc.group_cap, records = pc.node_count;
    const uint base = workgroup_share() * Q;  // workgroup_order.glsl
    // The group's queries, every lane all of them (one address for all lanes: one load each).
    const uint last = count - 1u;
    [[unroll]] for (uint g = 0u; g < G; ++g) {
        vec4 a = qs[min(base + 4u * g, last)], b = qs[min(base + 4u * g + 1u, last)];
        vec4 c = qs[min(base + 4u * g + 2u, last)], d = qs[min(base + 4u * g + 3u, last)];
        X[g] = vec4(a.x, b.x, c.x, d.x);
        Y[g] = vec4(a.y, b.y, c.y, d.y);
        Z[g] = vec4(a.z, b.z, c.z, d.z);
    }
    // The group's queries that exist (none in a workgroup past the end of a 2-D dispatch).
    const uint live = base >= count ? 0u : count - base >= Q ? QUERY_BITS : (1u << (count - base)) - 1u;

    vec4 w_far[4], w_near[4];
    uvec4 terms[4];  // this lane's share of each query's terms
    [[unroll]] for (uint g = 0u; g < G; ++g) {
        w_far[g] = vec4(0.0);
        w_near[g] = vec4(0.0);
        terms[g] = uvec4(0u);
    }
    // The walk's start. Its first rounds would pop one entry, then two, then about three, on
    // lanes that can take eight: where the top four levels are all inner nodes, one round
    // tests them instead, lane l the depth-3 node 7 + l and its three ancestors (the root's
    // record one load for all lanes). A query sums a node's expansion where it accepts it and
    // no ancestor; the depth-3 nodes it still opens go on the stack. The terms are the walk's
    // own, so the count stays the CPU's (test_gpu). 10⁶ random queries on lavapipe, rounds a
    // group (this one included) and kernel time: bunny_small.obj (2 856 faces) 6.2 → 4.3 and
    // 152–170 → 136–149 ms; chair.obj (7 859) 14.4 → 12.5 and 263–271 → 259–266 ms. Else: the
    // root, tested by every lane at once; the walk below takes the children of an inner node
    // together.
    uint top = 0u, n_far = 0u, n_leaves = 0u;
    if (first_leaf > 14u && S >= 8u) {
        const uint n3 = 7u + min(lane, 7u), n2 = (n3 - 1u) / 2u, n1 = (n2 - 1u) / 2u;
        const uint mine = lane < 8u ? live : 0u;  // lanes past the eighth push nothing
        const uint a0 = accepting(NODE(0u)) & mine;
        const uint a1 = accepting(NODE(n1)) & mine & ~a0;
        const uint a2 = accepting(NODE(n2)) & mine & ~(a0 | a1);
        const uint reach3 = mine & ~(a0 | a1 | a2);
        const uint a3 = accepting(NODE(n3)) & reach3, open3 = reach3 & ~a3;
        // An ancestor's entry comes from its leftmost depth-3 descendant's lane.
        const bool far0 = a0 != 0u && lane == 0u, far1 = a1 != 0u && lane % 4u == 0u;
        const bool far2 = a2 != 0u && lane % 2u == 0u, far3 = a3 != 0u;
        const uint fars = uint(far0) + uint(far1) + uint(far2) + uint(far3);
        const uint pushes = fars + (open3 != 0u ? 1u << 10u : 0u);
        const uint before = subgroupExclusiveAdd(pushes), total = subgroupAdd(pushes);
        // Masked stores (the main loop writes idle lanes to spare slots instead): once a group.
        uint at = before & 0x3ffu;
        if (far0) far_entries[at++] = a0;  // the root's index is 0
        if (far1) far_entries[at++] = n1 << Q | a1;
        if (far2) far_entries[at++] = n2 << Q | a2;
        if (far3) far_entries[at] = n3 << Q | a3;
        if (open3 != 0u) stack_entries[before >> 10u] = n3 << Q | open3;
        n_far = total & 0x3ffu;
        top = total >> 10u;
    } else {
        uint accepted = accepting(NODE(0u)) & live, rest = live & ~accepted;
        if (lane == 0u) {
            far_entries[0] = accepted;
            leaf_entries[0] = rest;
            stack_entries[0] = rest;
        }
        n_far = accepted != 0u ? 1u : 0u;
        n_leaves = rest != 0u && first_leaf == 0u ? 1u : 0u;
        top = rest != 0u && first_leaf != 0u ? 1u : 0u;
    }
    // The subgroup's loop iterations, all loops together (uniform); the start's round counts as
    // one, so the guard stays on the safe side of llvmpipe's limit whichever start ran.
    uint iters = 1u;
    bool cut = false;
    sync_subgroup();
    while (true) {
        // Walk until the stack is empty or a list could overflow in the next round. A stack
        // entry is an inner node whose two children its queries need tested.
        while (top > 0u && n_far + 2u * S <= FAR && n_leaves + 2u * S <= LEAVES) {
            if ((group_cap > 0u && iters >= group_cap) || top + S > STACK) {
                cut = true;
                break;
            }
            ++iters;
            uint take = min(top, S);
            uint entry = stack_entries[top - 1u - min(lane, take - 1u)];
            sync_subgroup();  // every pop read before a push overwrites it
            top -= take;
            uint parent = entry >> Q, queries = lane < take ? entry & QUERY_BITS : 0u;
            uint a = 2u * parent + 1u, b = a + 1u;
            uint accepted_a = accepting(NODE(a)) & queries;
            uint accepted_b = accepting(NODE(b)) & queries;
            uint rest_a = queries & ~accepted_a, rest_b = queries & ~accepted_b;
            bool leaf_a = a >= first_leaf, leaf_b = b >= first_leaf;
            bool far_a = accepted_a != 0u, far_b = accepted_b != 0u;
            bool opened_leaf_a = rest_a != 0u && leaf_a, opened_leaf_b = rest_b != 0u && leaf_b;
            bool inner_a = rest_a != 0u && !leaf_a, inner_b = rest_b != 0u && !leaf_b;
            // Places on the three lists from one prefix sum: counts in 10-bit fields.
            uint pushes = (far_a ? 1u : 0u) + (far_b ? 1u : 0u) + (opened_leaf_a ? 1u << 10u : 0u) + (opened_leaf_b ? 1u << 10u : 0u) +
                          (inner_a ? 1u << 20u : 0u) + (inner_b ? 1u << 20u : 0u);
            uint before = subgroupExclusiveAdd(pushes), total = subgroupAdd(pushes);
            // Every lane writes, lanes with nothing to push to slots of their own past the list's
            // end: llvmpipe stores lane by lane, and a masked store branches on every lane's bit.
            uint at = n_far + (before & 0x3ffu), junk = 2u * lane;
            far_entries[far_a ? at : FAR + junk] = a << Q | accepted_a;
            far_entries[far_b ? at + (far_a ? 1u : 0u) : FAR + junk + 1u] = b << Q | accepted_b;
            at = n_leaves + ((before >> 10u) & 0x3ffu);
            leaf_entries[opened_leaf_a ? at : LEAVES + junk] = a << Q | rest_a;
            leaf_entries[opened_leaf_b ? at + (opened_leaf_a ? 1u : 0u) : LEAVES + junk + 1u] = b << Q | rest_b;
            at = top + (before >> 20u);  // b below a: a's children are tested first
            stack_entries[inner_b ? at : STACK + junk] = b << Q | rest_b;
            stack_entries[inner_a ? at + (inner_b ? 1u : 0u) : STACK + junk + 1u] = a << Q | rest_a;
            n_far += total & 0x3ffu;
            n_leaves += (total >> 10u) & 0x3ffu;
            top += total >> 20u;
            sync_subgroup();
        }
        if (cut) break;
        bool done = top == 0u;
        // The far list's expansions, an entry a lane, for the group's queries.
        if (done || n_far + 2u * S > FAR) {
            iters += (n_far + S - 1u) / S + 1u;
            for (uint i = 0u; i < n_far; i += S) {
                uint k = i + lane;
                uint entry = far_entries[min(k, n_far - 1u)];
                uint node = entry >> Q, queries = k < n_far ? entry & QUERY_BITS : 0u;
                vec4 c = NODE(node);
                uint r = records + 7u * node;
                vec4 e0 = NODE(r + 1u), e1 = NODE(r + 2u), e2 = NODE(r + 3u), e3 = NODE(r + 4u), e4 = NODE(r + 5u), e5 = NODE(r + 6u);
                [[unroll]] for (uint g = 0u; g < G; ++g) {
                    bvec4 m = bits4(queries, 4u * g);
                    w_far[g] += mix(vec4(0.0), expansion4(e0, e1, e2, e3, e4, e5, X[g] - c.x, Y[g] - c.y, Z[g] - c.z), m);
                    terms[g] += uvec4(m);
                }
            }
            n_far = 0u;
        }
        // The leaf list's elements, exactly: a leaf a lane, its elements in turn.
        if (done || n_leaves + 2u * S > LEAVES) {
            iters += (n_leaves + S - 1u) / S + 1u;
            for (uint i = 0u; i < n_leaves; i += S) {
                uint k = i + lane;
                uint entry = leaf_entries[min(k, n_leaves - 1u)];
                uint queries = k < n_leaves ? entry & QUERY_BITS : 0u;
                uvec2 range = floatBitsToUint(NODE(records + 7u * (entry >> Q)).xy);
                uint elements = queries != 0u ? range.y - range.x : 0u;
                uint longest = subgroupMax(elements);
                iters += longest + 1u;
                for (uint j = 0u; j < longest; ++j) {
                    uint e = j < elements ? 3u * (range.x + j) : 0u;
                    vec4 ea = ELEM(e), eb = ELEM(e + 1u), ec = ELEM(e + 2u);
                    uint on = j < elements ? queries : 0u;
                    [[unroll]] for (uint g = 0u; g < G; ++g) {
                        bvec4 m = bits4(on, 4u * g);
                        w_near[g] += mix(vec4(0.0), element4(X[g], Y[g], Z[g], ea, eb, ec), m);
                        terms[g] += uvec4(m);
                    }
                }
            }
            n_leaves = 0u;
        }
        if (done) break;
    }
    // Each query's sum over the lanes, by halving: at each step a lane keeps the half of the
    // queries whose bit matches its own and adds what its partner kept of them, so that in the
    // end lane l holds the sums of queries l, l + S, ... (l < 16) — log₂ S shuffles of ever fewer
    // values (the steps between lanes 16 or more apart, in subgroups wider than 16, shuffle all
    // 16), where a reduction per query (subgroupAdd) was about a third of the kernel's time on
    // queries far from the mesh (lavapipe, 10⁶ queries around chair.obj moved away: 81–84 →
    // 67–68 ms). The shuffles pair lanes by their subgroup index; the steps and slots are `if`s
    // on constants (no `continue`), so that the loops unroll into registers.
    const uint me = gl_SubgroupInvocationID;
    float w[16];
    uint t[16];
    [[unroll]] for (uint j = 0u; j < 16u; ++j) {
        w[j] = j < Q ? w_far[j >> 2u][j & 3u] + w_near[j >> 2u][j & 3u] : 0.0;
        t[j] = j < Q ? terms[j >> 2u][j & 3u] : 0u;
    }
    [[unroll]] for (uint step = 0u; step < 6u; ++step) {
        const uint b = 32u >> step;  // the partner's distance
        const bool high = (me & b) != 0u;
        // Slot j, with j's bits from b up (below S) clear, holds the lane's sum for query j plus
        // the lane's own bits above b; it pairs with slot j | b. Lanes 16 or more apart hold the
        // same queries: they add every slot. Slots from Q on hold queries past the group's.
        [[unroll]] for (uint j = 0u; j < 16u; ++j) {
            if (b < S && j < Q && (j & (S - 1u) & ~(b - 1u)) == 0u) {
                const uint k = b < 16u ? j | b : j;
                const float wk = high ? w[k] : w[j], ws = high ? w[j] : w[k];
                const uint tk = high ? t[k] : t[j], ts = high ? t[j] : t[k];
                w[j] = wk + subgroupShuffleXor(ws, b);
                t[j] = tk + subgroupShuffleXor(ts, b);
            }
        }
    }
    // Slot j of lane l (j a multiple of S) is query j + l.
    [[unroll]] for (uint j = 0u; j < 16u; ++j) {
        const uint q = j + me;
        if (j % S == 0u && j < Q && q < Q && base + q < count) outv[base + q] = vec2(w[j], cut ? -1.0 : float(t[j]));
    }
}
#endif
