#version 450
#extension GL_GOOGLE_include_directive : require
// t = r − A e on one level (float).
// The workgroup size must be declared before mg_common.glsl uses gl_WorkGroupSize.
layout(local_size_x_id = 0) in;
#include "mg_common.glsl"
layout(std430, binding = 0) readonly buffer Axes { AxisEntry axes[]; };
layout(std430, binding = 1) readonly buffer R { float r[]; };
layout(std430, binding = 2) readonly buffer E { float e[]; };
layout(std430, binding = 3) writeonly buffer T { float t[]; };
#include "mg_ops.glsl"

void main() {
    uint p = linear_id();
    uvec3 d = pc.dims;
    if (p >= d.x * d.y * d.z) return;
    uvec3 c = cell_of(p, d);
    float Ae = 0.0;
    for (int a = 0; a < 3; ++a) {
        if (c[a] > 0) {
            uvec3 q = c;
            q[a] -= 1;
            Ae += coupling(q, a) * (e[p] - e[index_of(q, d)]);
        }
        if (c[a] + 1 < d[a]) {
            uvec3 q = c;
            q[a] += 1;
            Ae += coupling(c, a) * (e[p] - e[index_of(q, d)]);
        }
    }
    t[p] = r[p] - Ae;
}
