#version 450
#extension GL_GOOGLE_include_directive : require
// Distance sharpening, the dual step (src/shm/sharpen.hpp; the CPU loop in sharpen.cpp does the
// same per item in the same order): items below `nodes` are gradient blocks, p ← shrink(p + σ D φ̄);
// the rest are zero-set rows, q ← (q + P φ̄)·damping. Both add their new value to the running
// sums that the next restart averages.
layout(local_size_x_id = 0) in;
layout(std430, binding = 0) readonly buffer PhiBar { float phi_bar[]; };
layout(std430, binding = 1) buffer Dual { float p[]; };
layout(std430, binding = 2) buffer RowDual { float q[]; };
layout(std430, binding = 3) readonly buffer RowCell { uint row_cell[]; };
layout(std430, binding = 4) readonly buffer RowWeight { float row_weight[]; };
layout(std430, binding = 5) buffer DualSum { float p_sum[]; };
layout(std430, binding = 6) buffer RowDualSum { float q_sum[]; };
#include "push_constants.h"
layout(push_constant) uniform Push { SharpenPush pc; };  // push_constants.h

void main() {
    const uint id = gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    const uint sx = pc.dims.y * pc.dims.z, sy = pc.dims.z;
    if (id < pc.nodes) {
        const uint k[3] = uint[3](id / sx, id / sy % pc.dims.y, id % pc.dims.z);
        const uint st[3] = uint[3](sx, sy, 1u);
        const uint n[3] = uint[3](pc.dims.x, pc.dims.y, pc.dims.z);
        const float ih[3] = float[3](pc.inv_h.x, pc.inv_h.y, pc.inv_h.z);
        const float c = phi_bar[id];
        float v[3];
        for (int a = 0; a < 3; ++a) {
            const float g = k[a] + 1u < n[a] ? (phi_bar[id + st[a]] - c) * ih[a] : 0.0;
            v[a] = p[3u * id + uint(a)] + pc.sigma_d * g;
        }
        const float len = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        const float keep = len > pc.sigma_d ? 1.0 - pc.sigma_d / len : 0.0;
        for (int a = 0; a < 3; ++a) {
            const float w = v[a] * keep;
            p[3u * id + uint(a)] = w;
            p_sum[3u * id + uint(a)] += w;
        }
    } else if (id < pc.nodes + pc.rows) {
        const uint r = id - pc.nodes;
        const uint base = row_cell[r];
        const uint corner[8] = uint[8](0u, sx, sy, sx + sy, 1u, sx + 1u, sy + 1u, sx + sy + 1u);  // c = x + 2y + 4z
        float z = 0.0;
        for (int c = 0; c < 8; ++c) z += row_weight[8u * r + uint(c)] * phi_bar[base + corner[c]];
        const float w = (q[r] + z) * pc.damping;
        q[r] = w;
        q_sum[r] += w;
    }
}
