#version 450
#extension GL_GOOGLE_include_directive : require
// Distance sharpening, a restart (src/shm/sharpen.hpp): φ, p and q become their averages over the
// iterations since the last restart, φ̄ = φ, and the sums start again. Items below `nodes` are
// nodes, the rest zero-set rows.
layout(local_size_x_id = 0) in;
layout(std430, binding = 0) buffer Phi { float phi[]; };
layout(std430, binding = 1) writeonly buffer PhiBar { float phi_bar[]; };
layout(std430, binding = 2) buffer Dual { float p[]; };
layout(std430, binding = 3) buffer RowDual { float q[]; };
layout(std430, binding = 4) buffer PhiSum { float phi_sum[]; };
layout(std430, binding = 5) buffer DualSum { float p_sum[]; };
layout(std430, binding = 6) buffer RowDualSum { float q_sum[]; };
#include "push_constants.h"
layout(push_constant) uniform Push { SharpenPush pc; };  // push_constants.h

void main() {
    const uint id = gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    if (id < pc.nodes) {
        const float v = phi_sum[id] * pc.inv_count;
        phi[id] = v;
        phi_bar[id] = v;
        phi_sum[id] = 0.0;
        for (uint a = 0u; a < 3u; ++a) {
            p[3u * id + a] = p_sum[3u * id + a] * pc.inv_count;
            p_sum[3u * id + a] = 0.0;
        }
    } else if (id < pc.nodes + pc.rows) {
        const uint r = id - pc.nodes;
        q[r] = q_sum[r] * pc.inv_count;
        q_sum[r] = 0.0;
    }
}
