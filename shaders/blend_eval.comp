#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_vote : require
#extension GL_KHR_shader_subgroup_ballot : require
#ifdef GSD_SOFTWARE_SHAPED
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_EXT_control_flow_attributes : require
#endif
// The blend engine on the GPU (mirrors src/blend/blend_cpu.cpp): for each query, choose the
// summed set (all points, the ball of radius r_eval, or the k nearest), then blend the
// per-point terms of PAT (tori), SSPD (tangent planes) or signed Hopf–Cole (screened dipoles).
// Neighbor search walks a complete kd-tree built once per cloud on the host.
#include "box_tree.glsl"
#include "torus.glsl"

layout(local_size_x_id = 0) in;
#include "workgroup_order.glsl"  // workgroup_share (after the size: it reads gl_WorkGroupSize)
layout(constant_id = 1) const int KIND = 0;      // 0 PAT, 1 SSPD, 2 SHC
layout(constant_id = 2) const int EXACT = 0;     // 1: sum over every point
layout(constant_id = 3) const int GRADIENT = 0;  // 1: write (φ, ∇φ) per query
layout(constant_id = 4) const int SHARED_KNN = 0;  // 1: the k-nearest fallback walked per subgroup (blend_field.glsl)

const int TILE = 256;     // shared-memory tile for the exact sum (≥ workgroup size)

// Points in tree order, their terms (PAT: 3 per point; else (n, area)), the kd-tree's nodes:
// storage buffers, or texel buffers in blend_eval_software, built with GSD_SOFTWARE_SHAPED
// (box_tree_buffers.glsl).
#define POINTS_BINDING 0
#define TERMS_BINDING 1
#define NODES_BINDING 2
#include "box_tree_buffers.glsl"
layout(std430, binding = 3) readonly buffer Queries { vec4 qs[]; };
layout(std430, binding = 4) writeonly buffer Out { float outv[]; };

#include "push_constants.h"
layout(push_constant) uniform Push { BlendPush pc; };  // push_constants.h

#include "blend_field.glsl"

shared vec4 tile_p[TILE];
shared vec4 tile_t[3 * TILE];

// Loads points [base, base + TILE) into shared memory (every invocation must call it).
uint load_tile(uint base) {
    uint n = min(uint(TILE), pc.point_count - base);
    for (uint m = gl_LocalInvocationID.x; m < n; m += gl_WorkGroupSize.x) {
        tile_p[m] = point_at(base + m);
        if (KIND == 0) {
            tile_t[3 * m] = term_at(3 * (base + m));
            tile_t[3 * m + 1] = term_at(3 * (base + m) + 1);
            tile_t[3 * m + 2] = term_at(3 * (base + m) + 2);
        } else {
            tile_t[m] = term_at(base + m);
        }
    }
    barrier();
    return n;
}

void main() {
    uint i = workgroup_share_item();
    bool valid = i < pc.query_count;
    vec3 x = valid ? qs[i].xyz : vec3(0.0);
    const bool grad = GRADIENT == 1;
    Acc a = acc_zero();
    float rho = pc.r_eval;
    bool rho_varies = false;
    vec3 far_p = vec3(0.0);

    if (EXACT == 1) {
        // Pass 1: the farthest point sets ρ; pass 2 sums. Tiles are shared by the workgroup.
        rho = 0.0;
        float nearest = 3.0e38;
        for (uint base = 0; base < pc.point_count; base += TILE) {
            uint n = load_tile(base);
            for (uint m = 0; m < n; ++m) {
                float d = distance(x, tile_p[m].xyz);
                if (d > rho) { rho = d; far_p = tile_p[m].xyz; }
                nearest = min(nearest, d);
            }
            barrier();
        }
        rho = max(rho, 1e-30);
        rho_varies = true;
        float sigma = 0.5 * rho, lambda = pc.C / sigma, ref = weight_ref(sigma, nearest);
        for (uint base = 0; base < pc.point_count; base += TILE) {
            uint n = load_tile(base);
            for (uint m = 0; m < n; ++m) {
                vec4 t0, t1 = vec4(0.0), t2 = vec4(0.0);
                if (KIND == 0) { t0 = tile_t[3 * m]; t1 = tile_t[3 * m + 1]; t2 = tile_t[3 * m + 2]; }
                else t0 = tile_t[m];
                add_term(a, x, tile_p[m].xyz, t0, t1, t2, distance(x, tile_p[m].xyz), lambda, ref, rho, false, grad);
            }
            barrier();
        }
    } else {
        blend_accelerated(x, valid, grad, a, rho, rho_varies, far_p);  // every lane: the walks are shared
    }
    if (!valid) return;
    vec3 g;
    float phi = blend_finish(a, x, rho, rho_varies, far_p, grad, g);
    if (KIND == 2 || !grad) {
        outv[i] = phi;
        return;
    }
    outv[4 * i] = phi;
    outv[4 * i + 1] = g.x;
    outv[4 * i + 2] = g.y;
    outv[4 * i + 3] = g.z;
}
