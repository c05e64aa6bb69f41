#version 450
#extension GL_GOOGLE_include_directive : require
// Distance sharpening, the primal step (src/shm/sharpen.hpp; as the CPU loop in sharpen.cpp):
// φ ← φ − τ(Dᵀp + βPᵀq) + τs, bounded to φ₀'s side, φ̄ = 2φ_new − φ_old, and φ's running sum.
layout(local_size_x_id = 0) in;
layout(std430, binding = 0) buffer Phi { float phi[]; };
layout(std430, binding = 1) writeonly buffer PhiBar { float phi_bar[]; };
layout(std430, binding = 2) readonly buffer Dual { float p[]; };
layout(std430, binding = 3) readonly buffer RowDual { float q[]; };
layout(std430, binding = 4) readonly buffer Steps { vec2 tau_sign[]; };  // (τ, s) per node
layout(std430, binding = 5) readonly buffer NodeFirst { uint node_first[]; };
layout(std430, binding = 6) readonly buffer Entries { uvec2 entry[]; };  // (row, weight bits)
layout(std430, binding = 7) buffer PhiSum { float phi_sum[]; };
#include "push_constants.h"
layout(push_constant) uniform Push { SharpenPush pc; };  // push_constants.h

void main() {
    const uint id = gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    if (id >= pc.nodes) return;
    const uint sx = pc.dims.y * pc.dims.z, sy = pc.dims.z;
    const uint k[3] = uint[3](id / sx, id / sy % pc.dims.y, id % pc.dims.z);
    const uint st[3] = uint[3](sx, sy, 1u);
    const float ih[3] = float[3](pc.inv_h.x, pc.inv_h.y, pc.inv_h.z);
    float div = 0.0;
    for (int a = 0; a < 3; ++a) {
        const float prev = k[a] > 0u ? p[3u * (id - st[a]) + uint(a)] : 0.0;
        div += (prev - p[3u * id + uint(a)]) * ih[a];
    }
    float pq = 0.0;
    for (uint e = node_first[id]; e < node_first[id + 1u]; ++e) pq += uintBitsToFloat(entry[e].y) * q[entry[e].x];
    const float old = phi[id];
    const vec2 ts = tau_sign[id];
    float v = old - ts.x * (div + pc.row_scale * pq) + ts.x * ts.y;
    if (pc.keep_sign != 0u) v = ts.y > 0.0 ? max(v, pc.sign_floor) : ts.y < 0.0 ? min(v, -pc.sign_floor) : v;
    phi_bar[id] = 2.0 * v - old;
    phi[id] = v;
    phi_sum[id] += v;
}
