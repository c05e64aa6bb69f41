#version 450
#extension GL_GOOGLE_include_directive : require
// e_fine += P e_coarse (cell-centered linear interpolation, tensor product). This level is the
// fine one; the other level (odims) is the coarse one. A workgroup takes a row of cells along
// z, as mg_smooth.
// The workgroup size must be declared before mg_common.glsl uses gl_WorkGroupSize.
layout(local_size_x_id = 0) in;
#include "mg_common.glsl"
layout(std430, binding = 0) readonly buffer Axes { AxisEntry axes[]; };
layout(std430, binding = 1) readonly buffer EC { float ec[]; };
layout(std430, binding = 2) buffer EF { float ef[]; };

void main() {
    uvec3 d = pc.dims;
    uvec3 c = uvec3(gl_WorkGroupID.z, gl_WorkGroupID.y, gl_GlobalInvocationID.x);  // a row per workgroup (mg_smooth)
    if (c.z >= d.z) return;
    uint p = index_of(c, d);
    AxisEntry ax = axes[pc.axes_off.x + c.x], ay = axes[pc.axes_off.y + c.y], az = axes[pc.axes_off.z + c.z];
    int ci[2] = int[2](ax.c0, ax.c1), cj[2] = int[2](ay.c0, ay.c1), ck[2] = int[2](az.c0, az.c1);
    float wi[2] = float[2](ax.w0, ax.w1), wj[2] = float[2](ay.w0, ay.w1), wk[2] = float[2](az.w0, az.w1);
    float s = 0.0;
    for (int a = 0; a < 2; ++a)
        for (int b = 0; b < 2; ++b)
            for (int g = 0; g < 2; ++g) s += wi[a] * wj[b] * wk[g] * ec[index_of(uvec3(ci[a], cj[b], ck[g]), pc.odims)];
    ef[p] += s;
}
