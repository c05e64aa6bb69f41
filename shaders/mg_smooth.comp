#version 450
#extension GL_GOOGLE_include_directive : require
// One red-black Gauss–Seidel sweep of one color: e_p = (r_p + Σ c e_q) / Σ c.
// The workgroup size must be declared before mg_common.glsl uses gl_WorkGroupSize.
layout(local_size_x_id = 0) in;
#include "mg_common.glsl"
layout(std430, binding = 0) readonly buffer Axes { AxisEntry axes[]; };
layout(std430, binding = 1) readonly buffer R { float r[]; };
layout(std430, binding = 2) buffer E { float e[]; };
#include "mg_ops.glsl"

void main() {
    uint p = linear_id();
    uvec3 d = pc.dims;
    if (p >= d.x * d.y * d.z) return;
    uvec3 c = cell_of(p, d);
    if (((c.x + c.y + c.z) & 1u) != pc.color) return;
    float s = r[p], diag = 0.0;
    for (int a = 0; a < 3; ++a) {
        if (c[a] > 0) {
            uvec3 q = c;
            q[a] -= 1;
            float w = coupling(q, a);
            s += w * e[index_of(q, d)];
            diag += w;
        }
        if (c[a] + 1 < d[a]) {
            uvec3 q = c;
            q[a] += 1;
            float w = coupling(c, a);
            s += w * e[index_of(q, d)];
            diag += w;
        }
    }
    if (diag > 0.0) e[p] = s / diag;
}
