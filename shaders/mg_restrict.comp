#version 450
#extension GL_GOOGLE_include_directive : require
// r_coarse = Pᵀ t_fine: each coarse cell gathers its fine cells with the transposed
// prolongation weights (tensor product of per-axis lists). This level is the coarse one;
// the other level (odims) is the fine one. A workgroup takes a row of cells along z, as
// mg_smooth: the x and y lists are the same on every lane, and each lane reads its own z list
// once (at most MAX_TAPS entries, missing ones weighing 0), not once per (x, y) pair.
// The workgroup size must be declared before mg_common.glsl uses gl_WorkGroupSize.
layout(local_size_x_id = 0) in;
layout(constant_id = 1) const int MAX_TAPS = 4;  // the longest gather list of any axis and level
#include "mg_common.glsl"
layout(std430, binding = 0) readonly buffer Axes { AxisEntry axes[]; };
layout(std430, binding = 1) readonly buffer Gathers { Gather gathers[]; };
layout(std430, binding = 2) readonly buffer T { float t[]; };
layout(std430, binding = 3) writeonly buffer R { float rc[]; };

void main() {
    uvec3 d = pc.dims;
    uvec3 c = uvec3(gl_WorkGroupID.z, gl_WorkGroupID.y, gl_GlobalInvocationID.x);
    if (c.z >= d.z) return;
    uint p = index_of(c, d);
    AxisEntry ax = axes[pc.axes_off.x + c.x], ay = axes[pc.axes_off.y + c.y], az = axes[pc.axes_off.z + c.z];
    uint iz[MAX_TAPS];
    float wz[MAX_TAPS];
    for (int g = 0; g < MAX_TAPS; ++g) {
        bool has = az.g_begin + g < az.g_end;
        Gather e = gathers[has ? az.g_begin + g : az.g_begin];
        iz[g] = uint(e.index);
        wz[g] = has ? e.weight : 0.0;
    }
    float s = 0.0;
    for (int a = ax.g_begin; a < ax.g_end; ++a)
        for (int b = ay.g_begin; b < ay.g_end; ++b) {
            float wab = gathers[a].weight * gathers[b].weight;
            uint row = (uint(gathers[a].index) * pc.odims.y + uint(gathers[b].index)) * pc.odims.z;
            for (int g = 0; g < MAX_TAPS; ++g) s += wab * wz[g] * t[row + iz[g]];
        }
    rc[p] = s;
}
