#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_vote : require
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

layout(local_size_x_id = 0) in;

// Per node, 8 vec4: the acceptance test (c, reach²) — reach² = sums::winding_reach2 for this
// call's β and tolerance, made on the host in float32 as the CPU's float walk makes it, so the
// two accept the same nodes —, the element range (begin, end, -, -) and the expansion
// (SumTree::WindingNodeT<float>: k0, m0[3], p[3], s1[6], t3[10], padded to 24 floats).
layout(std430, binding = 0) readonly buffer Nodes { vec4 nodes[]; };
// Per element, 3 vec4: (a, v.x), (b, v.y), (c, v.z), a point when a = b = c.
layout(std430, binding = 1) readonly buffer Elems { vec4 elems[]; };
layout(std430, binding = 2) readonly buffer Queries { vec4 qs[]; };
layout(std430, binding = 3) writeonly buffer Out { vec2 outv[]; };  // (w, terms; −1: cut short)

layout(push_constant) uniform Push {
    uint count;
    uint first_leaf;
    uint group_cap;     // loop iterations one subgroup may run (0: no limit), see below
} pc;

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
    return 2.0 * atan(num, den) / FOUR_PI;
}

// An element's exact term: a triangle's solid angle, or a point's dipole (a = b = c).
float element_winding(vec3 x, vec4 ea, vec4 eb, vec4 ec) {
    if (ea.xyz == eb.xyz && ea.xyz == ec.xyz) {
        vec3 y = ea.xyz - x;
        float r2 = max(dot(y, y), 1e-37);  // at the point itself the numerator is 0 too
        return dot(vec3(ea.w, eb.w, ec.w), y) / (FOUR_PI * r2 * sqrt(r2));
    }
    return triangle_winding(x, ea.xyz, eb.xyz, ec.xyz);
}

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
        vec4 test = nodes[8u * node];  // (c, reach²): all a visit reads, unless it sums
        vec3 d = x - test.xyz;
        float d2 = dot(d, d);
        bool accepted = walking && d2 > test.w;
        if (accepted) {
            w_far += winding_expansion(nodes[8u * node + 2u], nodes[8u * node + 3u], nodes[8u * node + 4u],
                                       nodes[8u * node + 5u], nodes[8u * node + 6u], nodes[8u * node + 7u], d, inversesqrt(d2));
            ++terms;
        }
        bool open = walking && !accepted;
        bool leaf = node >= pc.first_leaf;
        bool any_open = subgroupAny(open);
        if (leaf && any_open) {  // the leaf's elements exactly, on the lanes that opened it
            uvec2 range = floatBitsToUint(nodes[8u * node + 1u].xy);
            uint begin = range.x, end = range.y;
            for (uint j = begin; j < end; ++j) {
                ++iters;
                float v = element_winding(x, elems[3u * j], elems[3u * j + 1u], elems[3u * j + 2u]);
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
