#version 450
#extension GL_GOOGLE_include_directive : require
// A composite of the field algebra in one pass (src/field/composite.hpp): its leaves' results,
// already on the device, combined query by query by the composite's postfix program, with
// gradients. The arithmetic is operators.cpp's (which runs in double): the sharp and smooth
// Booleans as σ·smin(σa·a, σb·b), offset φ − r, shell |φ| − r.
layout(local_size_x_id = 0) in;
layout(std430, binding = 0) readonly buffer Leaves { float leaf[]; };   // leaf l at l·leaf_stride
layout(std430, binding = 1) readonly buffer Program { vec4 op[]; };     // (code, leaf, param, −)
layout(std430, binding = 2) writeonly buffer Results { float result[]; };
#include "push_constants.h"
layout(push_constant) uniform Push { CombinePush pc; };  // push_constants.h

const int kMaxStack = 16;  // composite.hpp: kMaxStack

void main() {
    const uint i = gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    if (i >= pc.count) return;
    vec4 stack[kMaxStack];  // (φ, ∇φ)
    int top = 0;
    for (uint k = 0u; k < pc.ops; ++k) {
        const vec4 o = op[k];
        const int code = int(o.x);
        if (code == 0) {
            const uint base = uint(o.y) * pc.leaf_stride;
            stack[top++] = pc.gradient != 0u ? vec4(leaf[base + 4u * i], leaf[base + 4u * i + 1u], leaf[base + 4u * i + 2u],
                                                    leaf[base + 4u * i + 3u])
                                             : vec4(leaf[base + i], 0.0, 0.0, 0.0);
        } else if (code <= 3) {
            const vec4 b = stack[--top], a = stack[--top];
            // union: (1, 1, 1); intersection: (−1, −1, −1); difference: (−1, 1, −1)
            const float sa = code == 1 ? 1.0 : -1.0, sb = code == 2 ? -1.0 : 1.0, sr = code == 1 ? 1.0 : -1.0;
            const float kk = o.z;
            const float u = sa * a.x, v = sb * b.x;
            const float h = kk > 0.0 ? max(kk - abs(u - v), 0.0) : 0.0;
            const float s = kk > 0.0 ? h / (2.0 * kk) : 0.0;
            const float m = min(u, v) - (kk > 0.0 ? h * h / (4.0 * kk) : 0.0);
            const float wa = (u <= v ? 1.0 - s : s) * sa * sr, wb = (u <= v ? s : 1.0 - s) * sb * sr;
            stack[top++] = vec4(sr * m, wa * a.yzw + wb * b.yzw);
        } else {
            vec4 a = stack[top - 1];
            if (code == 5 && a.x < 0.0) a = -a;  // shell: |φ|, ∇ flipped with it
            a.x -= o.z;
            stack[top - 1] = a;
        }
    }
    if (pc.gradient != 0u) {
        for (uint c = 0u; c < 4u; ++c) result[4u * i + c] = stack[0][c];
    } else {
        result[i] = stack[0].x;
    }
}
