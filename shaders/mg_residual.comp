#version 450
#extension GL_GOOGLE_include_directive : require
// t = r − A e on one level (float). A workgroup takes a row of cells along z, as mg_smooth.
// The workgroup size must be declared before mg_common.glsl uses gl_WorkGroupSize.
layout(local_size_x_id = 0) in;
#include "mg_common.glsl"
layout(std430, binding = 0) readonly buffer Axes { AxisEntry axes[]; };
layout(std430, binding = 1) readonly buffer R { float r[]; };
layout(std430, binding = 2) readonly buffer E { float e[]; };
layout(std430, binding = 3) writeonly buffer T { float t[]; };
#include "mg_row.glsl"

void main() {
    uvec3 d = pc.dims;
    uint i = gl_WorkGroupID.z, j = gl_WorkGroupID.y, k = gl_GlobalInvocationID.x;
    if (k >= d.z) return;
    uint p = (i * d.y + j) * d.z + k;
    Couplings c = couplings(i, j, k);
    uint slab = d.y * d.z;
    float ep = e[p], Ae = 0.0;
    if (i > 0u) Ae += c.w[0] * (ep - e[p - slab]);
    if (i + 1u < d.x) Ae += c.w[1] * (ep - e[p + slab]);
    if (j > 0u) Ae += c.w[2] * (ep - e[p - d.z]);
    if (j + 1u < d.y) Ae += c.w[3] * (ep - e[p + d.z]);
    if (k > 0u) Ae += c.w[4] * (ep - e[p - 1u]);
    if (k + 1u < d.z) Ae += c.w[5] * (ep - e[p + 1u]);
    t[p] = r[p] - Ae;
}
