#version 450
#extension GL_GOOGLE_include_directive : require
// r_coarse = Pᵀ t_fine: each coarse cell gathers its fine cells with the transposed
// prolongation weights (tensor product of per-axis lists). This level is the coarse one;
// the other level (odims) is the fine one.
// The workgroup size must be declared before mg_common.glsl uses gl_WorkGroupSize.
layout(local_size_x_id = 0) in;
#include "mg_common.glsl"
layout(std430, binding = 0) readonly buffer Axes { AxisEntry axes[]; };
layout(std430, binding = 1) readonly buffer Gathers { Gather gathers[]; };
layout(std430, binding = 2) readonly buffer T { float t[]; };
layout(std430, binding = 3) writeonly buffer R { float rc[]; };

void main() {
    uint p = linear_id();
    uvec3 d = pc.dims;
    if (p >= d.x * d.y * d.z) return;
    uvec3 c = cell_of(p, d);
    AxisEntry ax = axes[pc.axes_off.x + c.x], ay = axes[pc.axes_off.y + c.y], az = axes[pc.axes_off.z + c.z];
    float s = 0.0;
    for (int a = ax.g_begin; a < ax.g_end; ++a)
        for (int b = ay.g_begin; b < ay.g_end; ++b)
            for (int g = az.g_begin; g < az.g_end; ++g) {
                uvec3 f = uvec3(gathers[a].index, gathers[b].index, gathers[g].index);
                s += gathers[a].weight * gathers[b].weight * gathers[g].weight * t[index_of(f, pc.odims)];
            }
    rc[p] = s;
}
