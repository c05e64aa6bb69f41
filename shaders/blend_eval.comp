#version 450
#extension GL_GOOGLE_include_directive : require
// The blend engine on the GPU (mirrors src/blend/blend_cpu.cpp): for each query, choose the
// summed set (all points, the ball of radius r_eval, or the k nearest), then blend the
// per-point terms of PAT (tori), SSPD (tangent planes) or signed Hopf–Cole (screened dipoles).
// Neighbor search walks a complete kd-tree built once per cloud on the host.
#include "box_tree.glsl"
#include "torus.glsl"

layout(local_size_x_id = 0) in;
layout(constant_id = 1) const int KIND = 0;      // 0 PAT, 1 SSPD, 2 SHC
layout(constant_id = 2) const int EXACT = 0;     // 1: sum over every point
layout(constant_id = 3) const int GRADIENT = 0;  // 1: write (φ, ∇φ) per query

const int K_MAX = 32;     // largest fallback_k the kernel supports
const int STACK = 48;     // kd-tree depth bound (2^48 leaves)
const int TILE = 256;     // shared-memory tile for the exact sum (≥ workgroup size)
const float PI = 3.14159265358979;

layout(std430, binding = 0) readonly buffer Points { vec4 pts[]; };    // tree order
layout(std430, binding = 1) readonly buffer Terms { vec4 terms[]; };   // PAT: 3 per point; else (n, area)
layout(std430, binding = 2) readonly buffer Nodes { Node nodes[]; };
layout(std430, binding = 3) readonly buffer Queries { vec4 qs[]; };
layout(std430, binding = 4) writeonly buffer Out { float outv[]; };

layout(push_constant) uniform Push {
    uint query_count;
    uint point_count;
    uint first_leaf;  // nodes at or past this index are leaves
    uint k_fallback;
    float r_eval;
    float C;
    float dmin;       // smallest distance used by the SHC kernel (1e-6 h)
} pc;

#define KNN_MAX K_MAX
#include "box_tree_knn.glsl"

// Running sums, as in src/blend/blend_cpu.cpp: w = e·T(d/ρ), q = e·T'(d/ρ), e = A·exp(−λ(d − σ)).
struct Acc { float W, G, D, GD, QD, QGD, shc; vec3 Gg, U, GU, QU, QGU; };

Acc acc_zero() { return Acc(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0)); }

// The taper T(v) = (1 − v²)³ + 1e-9 and its derivative (blend_taper in blend.hpp).
float taper(float v) { float a = 1.0 - min(v * v, 1.0); return a * a * a + 1e-9; }
float taper_derivative(float v) { float a = 1.0 - min(v * v, 1.0); return -6.0 * v * a * a; }

// Adds point p with term data t0..t2 (PAT: the torus; else t0 = (n, area)) at distance d.
void add_term(inout Acc a, vec3 x, vec3 p, vec4 t0, vec4 t1, vec4 t2, float d, float lambda, float sigma,
              float rho, bool tapered) {
    float v = d / rho;
    float t = tapered ? taper(v) : 1.0;
    if (KIND == 2) {  // not tapered: SHC depends on the scale of its sum (blend_cpu.cpp)
        float dd = max(d, pc.dmin);
        a.shc += t0.w * (lambda * dd + 1.0) * dot(x - p, t0.xyz) / (2.0 * PI * dd * dd * dd) *
                 exp(-lambda * (dd - sigma));
        return;
    }
    float g, scale;
    vec3 gg;
    if (KIND == 0) {
        g = torus_sdf(t0, t1, t2, x, gg);
        scale = 1.0;
    } else {
        g = dot(x - p, t0.xyz);
        gg = t0.xyz;
        scale = t0.w;
    }
    float e = scale * exp(-lambda * (d - sigma));
    float w = e * t;
    a.W += w;
    a.G += w * g;
    if (GRADIENT == 1) {
        vec3 u = d > 0.0 ? (x - p) / d : vec3(0.0);
        a.Gg += w * gg;
        a.U += w * u;
        a.GU += w * g * u;
        a.D += w * d;
        a.GD += w * g * d;
        if (tapered) {
            float q = e * taper_derivative(v);
            a.QU += q * u;
            a.QGU += q * g * u;
            a.QD += q * d;
            a.QGD += q * g * d;
        }
    }
}

void add_point(inout Acc a, vec3 x, uint j, float d, float lambda, float sigma, float rho, bool tapered) {
    vec4 t0, t1 = vec4(0.0), t2 = vec4(0.0);
    if (KIND == 0) { t0 = terms[3 * j]; t1 = terms[3 * j + 1]; t2 = terms[3 * j + 2]; }
    else t0 = terms[j];
    add_term(a, x, pts[j].xyz, t0, t1, t2, d, lambda, sigma, rho, tapered);
}

// Sums the ball of radius r_eval with ρ = r_eval (constant λ); returns how many points it held.
uint sum_ball(vec3 x, inout Acc a) {
    float r2 = pc.r_eval * pc.r_eval;
    float sigma = 0.5 * pc.r_eval, lambda = pc.C / sigma;
    uint found = 0;
    uint stack[STACK];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        uint i = stack[--top];
        if (node_distance2(x, i) > r2) continue;
        if (i >= pc.first_leaf) {
            for (uint j = nodes[i].begin; j < nodes[i].end; ++j) {
                vec3 dv = x - pts[j].xyz;
                float d2 = dot(dv, dv);
                if (d2 <= r2) {
                    add_point(a, x, j, sqrt(d2), lambda, sigma, pc.r_eval, true);
                    ++found;
                }
            }
        } else {
            stack[top++] = 2 * i + 1;
            stack[top++] = 2 * i + 2;
        }
    }
    return found;
}

shared vec4 tile_p[TILE];
shared vec4 tile_t[3 * TILE];

// Loads points [base, base + TILE) into shared memory (every invocation must call it).
uint load_tile(uint base) {
    uint n = min(uint(TILE), pc.point_count - base);
    for (uint m = gl_LocalInvocationID.x; m < n; m += gl_WorkGroupSize.x) {
        tile_p[m] = pts[base + m];
        if (KIND == 0) {
            tile_t[3 * m] = terms[3 * (base + m)];
            tile_t[3 * m + 1] = terms[3 * (base + m) + 1];
            tile_t[3 * m + 2] = terms[3 * (base + m) + 2];
        } else {
            tile_t[m] = terms[base + m];
        }
    }
    barrier();
    return n;
}

void main() {
    uint i = gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    bool valid = i < pc.query_count;
    vec3 x = valid ? qs[i].xyz : vec3(0.0);
    Acc a = acc_zero();
    float rho = pc.r_eval;
    bool rho_varies = false;
    vec3 far_p = vec3(0.0);

    if (EXACT == 1) {
        // Pass 1: the farthest point sets ρ; pass 2 sums. Tiles are shared by the workgroup.
        rho = 0.0;
        for (uint base = 0; base < pc.point_count; base += TILE) {
            uint n = load_tile(base);
            for (uint m = 0; m < n; ++m) {
                float d = distance(x, tile_p[m].xyz);
                if (d > rho) { rho = d; far_p = tile_p[m].xyz; }
            }
            barrier();
        }
        rho = max(rho, 1e-30);
        rho_varies = true;
        float sigma = 0.5 * rho, lambda = pc.C / sigma;
        for (uint base = 0; base < pc.point_count; base += TILE) {
            uint n = load_tile(base);
            for (uint m = 0; m < n; ++m) {
                vec4 t0, t1 = vec4(0.0), t2 = vec4(0.0);
                if (KIND == 0) { t0 = tile_t[3 * m]; t1 = tile_t[3 * m + 1]; t2 = tile_t[3 * m + 2]; }
                else t0 = tile_t[m];
                add_term(a, x, tile_p[m].xyz, t0, t1, t2, distance(x, tile_p[m].xyz), lambda, sigma, rho, false);
            }
            barrier();
        }
    } else {
        if (!valid) return;
        if (sum_ball(x, a) < pc.k_fallback) {
            // Fewer than k points within r_eval: the k nearest, ρ = d_k.
            a = acc_zero();
            float kd[K_MAX];
            uint ki[K_MAX];
            knn(x, pc.k_fallback, 0xffffffffu, pc.first_leaf, kd, ki);
            uint k = pc.k_fallback;
            rho = max(kd[k - 1], 1e-30);
            rho_varies = true;
            far_p = pts[ki[k - 1]].xyz;
            float sigma = 0.5 * rho, lambda = pc.C / sigma;
            for (uint m = 0; m < k; ++m) add_point(a, x, ki[m], kd[m], lambda, sigma, rho, true);
        }
    }
    if (!valid) return;
    float sigma = 0.5 * rho, lambda = pc.C / sigma;

    if (KIND == 2) {
        float mag = max(abs(a.shc), 1e-37);
        outv[i] = (a.shc < 0.0 ? -1.0 : 1.0) * (-log(mag) / lambda + sigma);
        return;
    }
    float phi = a.G / a.W;
    if (GRADIENT == 0) {
        outv[i] = phi;
        return;
    }
    vec3 g = a.Gg - lambda * (a.GU - phi * a.U) + (a.QGU - phi * a.QU) / rho;
    if (rho_varies) {
        vec3 xf = x - far_p;
        float dfar = length(xf);
        if (dfar > 0.0)
            g += (xf / dfar) * ((lambda / rho) * (a.GD - phi * a.D) - (a.QGD - phi * a.QD) / (rho * rho));
    }
    g /= a.W;
    outv[4 * i] = phi;
    outv[4 * i + 1] = g.x;
    outv[4 * i + 2] = g.y;
    outv[4 * i + 3] = g.z;
}
