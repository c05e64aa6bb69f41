#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_vote : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_arithmetic : require
// SHM step 1–2 at a batch of points (mirrors SumTree::screened in src/sums/sum_tree.cpp): the
// distance r_min to the nearest element, then X = Σ_j v_j ∫ e^(−λ(r − r_min))/r dA_j / A_j over
// what lies within r_min + cutoff/λ — nodes by their second-order expansion where
// accept() allows it, triangles refined adaptively elsewhere — and Y = X/|X|.
// Two ways to walk (TOGETHER, a specialization constant). On software devices (1) the subgroup
// walks together, as sums_winding.comp's walk (grid nodes come in C order: the lanes are
// neighbours along z): at each node every lane decides for itself (out of its reach, accepted,
// or opened), the walk descends when any lane opened the node, and a lane that did not sits
// out the node's subtree; node records and a leaf's elements are read once for the subgroup,
// and each lane refines the elements it opened on its own. llvmpipe runs every lane through
// every iteration of a loop any lane is in, so sharing the walk costs it nothing: 1.7× the
// speed there. On GPUs (0) each lane walks alone, with its own stack: 32 lanes' walks taken
// together visited so many more nodes than one lane's that the kernel took twice as long on
// an H200 (228 ms against 109 ms at 256³, 10⁵ points). Built with GSD_SOFTWARE_SHAPED (the
// kernel software devices run, gpu::software_shaped), the sum is walk_listed's instead: each
// lane alone, listing what it sums and summing it in loops of their own; the nearest element
// is still found together.
#include "box_tree.glsl"

layout(local_size_x_id = 0) in;
#include "workgroup_order.glsl"  // workgroup_share (after the size: it reads gl_WorkGroupSize)
layout(constant_id = 1) const int TOGETHER = 1;  // the subgroup walks together (software devices)
// Which kinds of element the tree holds (sums::DeviceSumTree::element_kinds: bit 0 triangles,
// bit 1 points, a = b = c). A cloud's points are summed whole, one term each, and are nearest
// at their own position: for a tree of points only (2) the triangles' code is left out —
// llvmpipe runs every branch of it and every store of the refinement's piece stack whether a
// lane takes them or not.
layout(constant_id = 2) const int ELEMENT_KINDS = 3;

const int STACK = 64;
const int PIECES = 24;  // one entry a level that splits (levels 0–19: 20 at most); > that, never full
const int MAX_SPLITS = 4096;  // sums::kMaxSplits
const float NEEDLE_ASPECT = 768.0;  // sums::kNeedleAspectGpu: below the CPU's 1024, so the GPU never refines what the CPU bisects

// The tree, its moments and the elements. Built twice (cmake/EmbedShaders.cmake): as storage
// buffers, and with GSD_SOFTWARE_SHAPED (gpu::software_shaped) as uniform texel buffers of vec4
// — a Node is two: (lo, begin), (hi, end) —, for llvmpipe, which reads a storage buffer inside
// a loop one lane and one float at a time behind a branch on the lane's mask bit, where a texel
// fetch is one gather.
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 0) uniform samplerBuffer node_texels;
layout(binding = 1) uniform samplerBuffer moment_texels;
layout(binding = 2) uniform samplerBuffer elem_texels;
vec3 node_lo(uint i) { return texelFetch(node_texels, int(2u * i)).xyz; }
vec3 node_hi(uint i) { return texelFetch(node_texels, int(2u * i + 1u)).xyz; }
uint node_begin(uint i) { return floatBitsToUint(texelFetch(node_texels, int(2u * i)).w); }
uint node_end(uint i) { return floatBitsToUint(texelFetch(node_texels, int(2u * i + 1u)).w); }
#define MOMENT(i) texelFetch(moment_texels, int(i))
#define ELEM(i) texelFetch(elem_texels, int(i))
#else
layout(std430, binding = 0) readonly buffer Nodes { Node nodes[]; };
layout(std430, binding = 1) readonly buffer Moments { vec4 moments[]; };
layout(std430, binding = 2) readonly buffer Elems { vec4 elems[]; };
vec3 node_lo(uint i) { return nodes[i].lo; }
vec3 node_hi(uint i) { return nodes[i].hi; }
uint node_begin(uint i) { return nodes[i].begin; }
uint node_end(uint i) { return nodes[i].end; }
#define MOMENT(i) moments[i]
#define ELEM(i) elems[i]
#endif
layout(std430, binding = 3) readonly buffer Queries { vec4 qs[]; };
layout(std430, binding = 4) writeonly buffer Out { vec4 outv[]; };  // (Y, r_min), (terms, 0, 0, 0)

#include "push_constants.h"
layout(push_constant) uniform Push { DiffusePush pc; };  // push_constants.h

const uint NONE = 0xffffffffu;

#include "sums_tree.glsl"

uint iters = 0u;  // this lane's iterations in its refinements (render_march.glsl's guard, below)

// Squared distance from x to element j (a point where the tree holds points only).
float element_distance2(vec3 x, uint j) {
    if (ELEMENT_KINDS == 2) {
        vec3 d = x - ELEM(3u * j).xyz;
        return dot(d, d);
    }
    return triangle_distance2(x, ELEM(3u * j).xyz, ELEM(3u * j + 1u).xyz, ELEM(3u * j + 2u).xyz);
}

#include "nearest_element.glsl"

// The distance to the nearest element for every lane, the subgroup walking together
// (nearest_element.glsl; no cap: the sum's walk after it checks `group_iters`).
float nearest_distance(vec3 x, bool live, inout uint group_iters) {
    float best2;
    nearest_element_together(x, live, 0u, group_iters, best2);
    return sqrt(best2);
}

// nearest_distance on one lane's own, best first.
float nearest_distance_alone(vec3 x) {
    float best2 = 3.0e38;
    uint stack[STACK];
    int top = 0;
    stack[top++] = 0u;
    while (top > 0) {
        uint i = stack[--top];
        if (box_distance2(x, node_lo(i), node_hi(i)) >= best2) continue;
        if (i >= pc.first_leaf) {
            for (uint j = node_begin(i); j < node_end(i); ++j)
                best2 = min(best2, element_distance2(x, j));
        } else {
            uint l = 2u * i + 1u, r = 2u * i + 2u;
            bool left_first = box_distance2(x, node_lo(l), node_hi(l)) <= box_distance2(x, node_lo(r), node_hi(r));
            stack[top++] = left_first ? r : l;
            stack[top++] = left_first ? l : r;
        }
    }
    return sqrt(best2);
}

// sums::accept_screened (src/sums/sum_tree.hpp).
bool accept(float rho, float d, float area, float r_min) {
    if (!(d > 2.0 * rho)) return false;
    if (rho == 0.0) return true;
    // As on the CPU: area·e^(−λ(gap − r_min))/gap·q³ ≤ 6·budget, q = ρ(λ·gap + 2)/gap.
    float gap = d - rho, s = rho * (pc.lambda * gap + 2.0), g2 = gap * gap;
    return area * exp(-pc.lambda * (gap - r_min)) * s * s * s <= 6.0 * pc.budget * g2 * g2;
}

// e^(−λ(r − r_min))/r and its first two radial derivatives.
vec3 radial(float r, float r_min) {
    float E = exp(-pc.lambda * (r - r_min)), ir = 1.0 / r, l = pc.lambda;
    return vec3(E * ir, -E * (l * ir + ir * ir), E * (l * l * ir + 2.0 * l * ir * ir + 2.0 * ir * ir * ir));
}

// A node's second-order expansion: X_a += M0_a f − f1 (M1_a·u) + ½ (A uᵀM2_a u + B tr M2_a).
vec3 node_expansion(uint i, vec3 d, float r_min) {
    float r = length(d);
    vec3 u = d / r;
    vec3 f = radial(r, r_min);
    float A = f.z - f.y / r, B = f.y / r;
    vec3 X = mom3(i, 4u) * f.x;
    for (uint a = 0u; a < 3u; ++a) {
        uint k2 = 17u + 6u * a;
        X[a] += -f.y * dot(mom3(i, 8u + 3u * a), u) + 0.5 * (A * sym_quad(i, k2, u) + B * sym_trace(i, k2));
    }
    return X;
}

// Covariance of the triangle a, a + ab, a + ac: (1/12) Σ (p − g)(p − g)ᵀ as its diagonal cd
// and off-diagonal co (xy xz yz); its radius about the centroid.
void triangle_shape(vec3 ab, vec3 ac, out vec3 cd, out vec3 co, out float rho) {
    vec3 g = (ab + ac) / 3.0, qa = -g, qb = ab - g, qc = ac - g;
    cd = (qa * qa + qb * qb + qc * qc) / 12.0;
    co = vec3(qa.x * qa.y + qb.x * qb.y + qc.x * qc.y, qa.x * qa.z + qb.x * qb.z + qc.x * qc.z,
              qa.y * qa.z + qb.y * qb.z + qc.y * qc.z) / 12.0;
    rho = max(length(qa), max(length(qb), length(qc)));
}

// Element j's part of X for one lane (the refinement of SumTree::screened_element); sets `wide`
// when the element is to be left to the CPU. A lane that is not `live` adds nothing (the
// software kernel runs every lane through its element passes): its one piece is out of reach.
void add_element(uint j, vec3 x, float rmin, float R, bool live, inout vec3 X, inout uint terms, inout bool wide) {
    if (!live) R = -3.0e38;  // every piece out of reach
    if (ELEMENT_KINDS == 2) {
        // A point: the refinement's first piece, accepted whole (ρ = 0) — the same term as
        // below, without its covariance (zero) and its piece stack.
        vec4 p = ELEM(3u * j);
        float dist = length(x - p.xyz);
        ++iters;
        if (dist > R) return;
        vec3 v = vec3(p.w, ELEM(3u * j + 1u).w, ELEM(3u * j + 2u).w);
        float f = dist > 0.0 ? radial(dist, rmin).x : exp(-pc.lambda * (dist - rmin)) / max(dist, pc.r_floor);
        X += v * f;
        ++terms;
        return;
    }
    vec4 ea = ELEM(3u * j), eb = ELEM(3u * j + 1u), ec = ELEM(3u * j + 2u);
    vec3 a = ea.xyz, ab = eb.xyz - a, ac = ec.xyz - a, v = vec3(ea.w, eb.w, ec.w), cd, co;
    float rho0;
    triangle_shape(ab, ac, cd, co, rho0);
    // Wider than the reach (a face with a far corner): only its part within the reach counts,
    // cut out on the CPU (SumTree::screened_element), which redoes this query; so does a
    // needle, which the CPU refines by bisection (the 1→4 split here keeps a needle's shape and
    // ran to the split cap beside one). Not here: llvmpipe runs an if's body under a lane mask
    // whether a lane takes it or not, and the clipping, run so for every element, made step 1
    // 2.5× slower there.
    float longest2 = max(dot(ab, ab), max(dot(ac, ac), dot(ac - ab, ac - ab)));
    bool too_wide = live && (rho0 > R || longest2 > NEEDLE_ASPECT * length(cross(ab, ac)));
    wide = wide || too_wide;
    if (too_wide) R = -3.0e38;  // left to the CPU: nothing of it summed here
    float area = length(v);
    // The refinement, depth first: the element, then where a piece is split its four
    // half-sized children, the last first (as the CPU). Shaped for llvmpipe, which stores a
    // lane's value to a private array component by component behind a branch on the lane's mask
    // bit, and for a masked-off lane reloads the old value first — in this loop, where most lanes
    // have finished their element long before the last, that reload was most of step 1's time
    // (perf, `shm grid bunny_small.obj`). So the loop keeps every lane in it, the subgroup
    // deciding together when to stop, and every store is unmasked: a lane with nothing to store
    // writes the spare slot PIECES. And a split piece's four children are one entry — (s, t, h,
    // w) of the first and, in h's low mantissa bits (h is a power of two), how many are left
    // after the one taken —, not four.
    vec4 pieces[PIECES + 1];
    int np = 0, splits = 0;
    bool whole = !too_wide;  // the element itself, not yet taken (none for the CPU's)
    while (true) {
        bool refining = whole || np > 0;
        if (!subgroupAny(refining)) break;
        vec4 top = pieces[max(np - 1, 0)];
        uint bits = floatBitsToUint(top.z), k = bits & 3u;
        float half_size = uintBitsToFloat(bits & ~3u), sh = sign(top.w) * half_size;
        bool taken = refining && !whole;  // from the stack: its entry loses a child, or goes
        pieces[taken && k != 0u ? np - 1 : PIECES].z = uintBitsToFloat(bits - 1u);
        np -= taken && k == 0u ? 1 : 0;
        vec4 pq = whole ? vec4(0.0, 0.0, 1.0, 1.0)
                        : vec4(top.x + ((k & 1u) != 0u ? sh : 0.0), top.y + ((k & 2u) != 0u ? sh : 0.0), half_size,
                               k == 3u ? -top.w : top.w);
        whole = false;
        iters += refining ? 1u : 0u;
        float sigma = sign(pq.w), level = abs(pq.w) - 1.0;
        vec3 g = a + (pq.x + sigma * pq.z / 3.0) * ab + (pq.y + sigma * pq.z / 3.0) * ac;
        float rho = rho0 * pq.z;
        vec3 dg = x - g;
        float dist = length(dg);
        bool reached = refining && !(dist - rho > R);
        float share = pq.z * pq.z;
        vec3 m0 = v * share;
        bool accepted = reached && accept(rho, dist, area * share, rmin);
        bool floor_term = reached && !accepted && (rho <= pc.r_floor || level >= 20.0 || splits >= MAX_SPLITS);
        bool split = reached && !accepted && !floor_term;
        // (Branches with no store in them: llvmpipe runs both anyway, a GPU the one it takes.)
        if (accepted) {
            vec3 u = dg / dist;
            vec3 f = radial(dist, rmin);
            float A = f.z - f.y / dist, B = f.y / dist;
            float cq = cd.x * u.x * u.x + cd.y * u.y * u.y + cd.z * u.z * u.z +
                       2.0 * (co.x * u.x * u.y + co.y * u.x * u.z + co.z * u.y * u.z);
            float ct = cd.x + cd.y + cd.z;
            X += m0 * (f.x + 0.5 * share * (A * cq + B * ct));
        } else if (floor_term) {
            X += m0 * (exp(-pc.lambda * (dist - rmin)) / max(dist, pc.r_floor));
        }
        terms += accepted || floor_term ? 1u : 0u;
        // Children (s, t), (s + σh, t), (s, t + σh), (s + σh, t + σh) of half size h, the last
        // turned over (−w).
        float h = pq.z * 0.5, w = sigma * (level + 2.0);
        splits += split ? 1 : 0;
        pieces[split ? min(np, PIECES - 1) : PIECES] = vec4(pq.x, pq.y, uintBitsToFloat(floatBitsToUint(h) | 3u), w);
        np += split ? 1 : 0;
    }
}

// The sum's walk on one lane's own (GPUs; no loop limit to count against).
void walk_alone(vec3 x, float rmin, float R, inout vec3 X, inout uint terms, inout bool wide) {
    uint stack[STACK];
    int top = 0;
    stack[top++] = 0u;
    while (top > 0) {
        uint i = stack[--top];
        if (box_distance2(x, node_lo(i), node_hi(i)) > R * R) continue;
        vec3 d = x - mom3(i, 0u);
        if (accept(mom(i, 3u), length(d), mom(i, 7u), rmin)) {
            X += node_expansion(i, d, rmin);
            ++terms;
            continue;
        }
        if (i < pc.first_leaf) {
            stack[top++] = 2u * i + 1u;
            stack[top++] = 2u * i + 2u;
            continue;
        }
        for (uint j = node_begin(i); j < node_end(i); ++j) add_element(j, x, rmin, R, true, X, terms, wide);
    }
}

void write_result(uint q, vec3 X, float rmin, uint terms, bool cut, bool wide) {
    float len = length(X);
    outv[2u * q] = vec4(len > 0.0 ? X / len : vec3(0.0), rmin);
    // y: redo on the CPU — 1: the subgroup stopped short of llvmpipe's loop limit, 2: an element
    // was wider than the reach or a needle.
    outv[2u * q + 1u] = vec4(float(terms), cut ? 1.0 : (wide ? 2.0 : 0.0), 0.0, 0.0);
}

#ifdef GSD_SOFTWARE_SHAPED
// The sum's walk shaped for llvmpipe (as sums_winding.comp's software walk): each lane walks on
// its own, stackless, and only lists the nodes it accepts and the leaves it opens — every lane
// writes its entry, the counts say which hold —; every ROUND steps the lists are summed in
// loops of their own, so that no visit pays for an expansion or an element it does not sum
// (llvmpipe runs an if's body whatever the lanes decide). `group_iters` counts the subgroup's
// loop iterations, the lanes' refinements summed over the lanes, against llvmpipe's limit;
// `cut` is set when it stops short.
const uint ROUND = 32u;

void walk_listed(vec3 x, bool live, float rmin, float R, inout vec3 X, inout uint terms, inout bool wide,
                 inout uint group_iters, out bool cut) {
    const uint first_leaf = pc.first_leaf, group_cap = pc.group_cap;  // read once: gathered in loops
    cut = false;
    bool walking = live;
    uint node = 0u;
    uint accepted_nodes[ROUND], opened_leaves[ROUND];
    while (true) {
        if (group_cap > 0u && group_iters >= group_cap) {
            cut = true;
            return;
        }
        group_iters += ROUND + 2u;
        uint n_accepted = 0u, n_opened = 0u;
        // Every lane takes every step, a lane whose walk is over idly (its stores go past its
        // counts): under a lane mask llvmpipe would store lane by lane, reloading each masked-off
        // lane's old value first (add_element's refinement says more).
        for (uint step = 0u; step < ROUND; ++step) {
            bool reached = walking && box_distance2(x, node_lo(node), node_hi(node)) <= R * R;
            vec3 d = x - mom3(node, 0u);
            bool accepted = reached && accept(mom(node, 3u), length(d), mom(node, 7u), rmin);
            bool leaf = node >= first_leaf;
            accepted_nodes[n_accepted] = node;
            opened_leaves[n_opened] = node;
            n_accepted += accepted ? 1u : 0u;
            n_opened += reached && !accepted && leaf ? 1u : 0u;
            if (reached && !accepted && !leaf) {
                node = 2u * node + 1u;
            } else {
                node = next_in_depth_first(node);
                walking = walking && node != 0u;
            }
        }
        uint passes = subgroupMax(n_accepted);
        group_iters += passes + 1u;
        for (uint i = 0u; i < passes; ++i) {
            uint a = accepted_nodes[min(i, ROUND - 1u)];
            vec3 e = node_expansion(a, x - mom3(a, 0u), rmin);
            if (i < n_accepted) X += e;
        }
        terms += n_accepted;
        passes = subgroupMax(n_opened);
        group_iters += passes + 1u;
        for (uint i = 0u; i < passes; ++i) {
            uint leaf = opened_leaves[min(i, ROUND - 1u)];
            uint begin = node_begin(leaf), count = i < n_opened ? node_end(leaf) - begin : 0u;
            uint longest = subgroupMax(count);
            group_iters += 1u;
            for (uint j = 0u; j < longest; ++j) {
                add_element(begin + min(j, max(count, 1u) - 1u), x, rmin, R, j < count, X, terms, wide);
                group_iters += subgroupAdd(iters) + 1u;
                iters = 0u;
                if (group_cap > 0u && group_iters >= group_cap) {
                    cut = true;
                    return;
                }
            }
        }
        if (!subgroupAny(walking)) return;
    }
}
#endif

void main() {
    uint q = workgroup_share_item();
    bool valid = q < pc.count;  // lanes past the end walk along, idle: the subgroup stays whole
    vec3 x = valid ? qs[q].xyz : vec3(0.0);
    vec3 X = vec3(0.0);
    uint terms = 0u;
    bool wide = false;  // met an element wider than the reach: the host redoes this query
    if (TOGETHER == 0) {
        if (!valid) return;
        float rmin = nearest_distance_alone(x);
        walk_alone(x, rmin, rmin + pc.cutoff / pc.lambda, X, terms, wide);
        write_result(q, X, rmin, terms, false, wide);
        return;
    }
    uint group_iters = 0u;
    float rmin = nearest_distance(x, valid, group_iters);
    float R = rmin + pc.cutoff / pc.lambda;
    // llvmpipe ends every loop of a shader, silently, once its SIMD group has iterated 65 535
    // times in all: the subgroup counts the walks' iterations once, and the lanes' own (their
    // refinements) summed over the lanes — a bound on what the SIMD group iterated — and stops
    // short of the limit; the host redoes what it flags.
    bool cut = false;
#ifdef GSD_SOFTWARE_SHAPED
    walk_listed(x, valid, rmin, R, X, terms, wide, group_iters, cut);
#else
    uint sit_out = valid ? NONE : 0u;  // depth of the node this lane is out of (NONE: walking)
    uint node = 0u, depth = 0u;
    while (true) {
        if (pc.group_cap > 0u && group_iters >= pc.group_cap) {
            cut = true;
            break;
        }
        ++group_iters;
        if (valid && depth <= sit_out) sit_out = NONE;  // the walk left the subtree it sat out
        bool walking = sit_out == NONE;
        bool reached = walking && box_distance2(x, node_lo(node), node_hi(node)) <= R * R;
        vec3 d = x - mom3(node, 0u);
        bool accepted = reached && accept(mom(node, 3u), length(d), mom(node, 7u), rmin);
        if (accepted) {
            X += node_expansion(node, d, rmin);
            ++terms;
        }
        bool open = reached && !accepted;
        bool leaf = node >= pc.first_leaf;
        bool any_open = subgroupAny(open);
        if (leaf && any_open) {  // the leaf's elements, on the lanes that opened it
            for (uint j = node_begin(node); j < node_end(node); ++j) {
                if (open) add_element(j, x, rmin, R, true, X, terms, wide);
                group_iters += subgroupAdd(iters) + 1u;
                iters = 0u;
                if (pc.group_cap > 0u && group_iters >= pc.group_cap) break;
            }
        }
        if (!leaf && any_open) {
            if (walking && !open) sit_out = depth;  // out of reach or accepted: not its subtree
            node = 2u * node + 1u;
            ++depth;
            continue;
        }
        // Next in depth-first order (sums_winding.comp): climb past the right children, step
        // to the right sibling; all ones is the root's rightmost path: the walk is over.
        uint k = node + 1u;
        uint up = uint(findLSB(~k));
        k >>= up;
        if (k == 0u) break;
        node = k;
        depth -= up;
    }
#endif
    if (valid) write_result(q, X, rmin, terms, cut, wide);
}
