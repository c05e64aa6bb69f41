#version 450
#extension GL_GOOGLE_include_directive : require
// Fast generalized winding numbers (mirrors SumTree::winding in src/sums/sum_tree.cpp): nodes
// that pass accept_winding by their second-order dipole expansion, the rest triangle by triangle.
#include "box_tree.glsl"

layout(local_size_x_id = 0) in;

const int STACK = 64;

layout(std430, binding = 0) readonly buffer Nodes { Node nodes[]; };
layout(std430, binding = 1) readonly buffer Moments { vec4 moments[]; };
layout(std430, binding = 2) readonly buffer Elems { vec4 elems[]; };
layout(std430, binding = 3) readonly buffer Queries { vec4 qs[]; };
layout(std430, binding = 4) writeonly buffer Out { vec2 outv[]; };  // (w, terms)

layout(push_constant) uniform Push {
    uint count;
    uint first_leaf;
    float beta;
    float tolerance;
    uint lane_cap;  // loop iterations one lane may run (0: no limit), see sums_tree.glsl
} pc;

#include "sums_tree.glsl"

// Σ v·∇Φ(x − y), Φ = 1/(4πr), to second order about the node's center; d = x − c.
float winding_expansion(uint i, vec3 d) {
    float r = length(d), ir = 1.0 / r;
    vec3 u = d * ir;
    float f1 = -ir * ir / FOUR_PI, f2 = 2.0 * ir * ir * ir / FOUR_PI, f3 = -6.0 * ir * ir * ir * ir / FOUR_PI;
    float A = f2 - f1 * ir, B = f1 * ir, C = f3 - 3.0 * f2 * ir + 3.0 * f1 * ir * ir, D = A * ir;
    float t0 = f1 * dot(mom3(i, 4u), u);
    float uMu = 0.0, trM1 = 0.0, t2c = 0.0, t2d = 0.0;
    for (uint a = 0u; a < 3u; ++a) {
        vec3 m1 = mom3(i, 8u + 3u * a);
        uMu += u[a] * dot(m1, u);
        trM1 += m1[a];
        uint k2 = 17u + 6u * a;
        t2c += u[a] * sym_quad(i, k2, u);
        t2d += u[a] * sym_trace(i, k2) + 2.0 * sym_row(i, k2, a, u);
    }
    return t0 - (A * uMu + B * trM1) + 0.5 * (C * t2c + D * t2d);
}

void main() {
    uint q = gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    if (q >= pc.count) return;
    vec3 x = qs[q].xyz;
    float w = 0.0;
    uint terms = 0u, iters = 0u;
    uint stack[STACK];
    int top = 0;
    stack[top++] = 0u;
    while (top > 0) {
        uint i = stack[--top];
        ++iters;
        vec3 d = x - mom3(i, 0u);
        float rho = mom(i, 3u), d2 = dot(d, d);
        // sums::accept_winding (src/sums/sum_tree.hpp).
        bool ok = d2 > pc.beta * pc.beta * rho * rho;
        if (ok && pc.tolerance > 0.0) {
            float g = sqrt(d2) - rho, g2 = g * g;
            ok = mom(i, 7u) * rho * rho * rho <= pc.tolerance * 3.14159265 * g2 * g2 * g;
        }
        if (ok) {
            w += winding_expansion(i, d);
            ++terms;
        } else if (i >= pc.first_leaf) {
            for (uint j = nodes[i].begin; j < nodes[i].end; ++j) {
                vec4 a = elems[3u * j], b = elems[3u * j + 1u], c = elems[3u * j + 2u];
                if (a.xyz == b.xyz && a.xyz == c.xyz) {
                    vec3 y = a.xyz - x;
                    float r2 = dot(y, y);
                    if (r2 > 0.0) w += dot(vec3(a.w, b.w, c.w), y) / (FOUR_PI * r2 * sqrt(r2));
                } else {
                    w += triangle_winding(x, a.xyz, b.xyz, c.xyz);
                }
                ++terms;
                ++iters;
            }
        } else {
            stack[top++] = 2u * i + 1u;
            stack[top++] = 2u * i + 2u;
        }
    }
    outv[q] = vec2(w, pc.lane_cap > 0u && iters >= pc.lane_cap ? -1.0 : float(terms));
}
