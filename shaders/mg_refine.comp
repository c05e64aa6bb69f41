#version 450
#extension GL_GOOGLE_include_directive : require
// The finest level in float64: φ += e (the correction of the last cycle, when `color` is 1),
// then r = b − L φ, written as float for the next cycle, with per-workgroup partial sums of r²
// for the convergence test. This is mixed-precision iterative refinement: the cycles run in
// float32, the residual and the solution stay in float64.
// The workgroup size must be declared before mg_common.glsl uses gl_WorkGroupSize.
layout(local_size_x_id = 0) in;
#include "mg_common.glsl"
layout(std430, binding = 0) buffer Phi { double phi[]; };
layout(std430, binding = 1) readonly buffer B { double b[]; };
layout(std430, binding = 2) readonly buffer E { float e[]; };
layout(std430, binding = 3) writeonly buffer R { float r[]; };
layout(std430, binding = 4) writeonly buffer Partial { double partial[]; };

shared double sums[256];

void main() {
    uint p = linear_id();
    uvec3 d = pc.dims;
    bool valid = p < d.x * d.y * d.z;
    double res = 0.0;
    if (valid) {
        uvec3 c = cell_of(p, d);
        double Aphi = 0.0;
        // Neighbors were updated by other invocations of this same dispatch: read φ + e for them.
        double here = phi[p] + (pc.color == 1u ? double(e[p]) : 0.0);
        for (int a = 0; a < 3; ++a) {
            double w = double(pc.inv_h2[a]);
            if (c[a] > 0) {
                uvec3 q = c;
                q[a] -= 1;
                uint iq = index_of(q, d);
                Aphi += w * (here - (phi[iq] + (pc.color == 1u ? double(e[iq]) : 0.0)));
            }
            if (c[a] + 1 < d[a]) {
                uvec3 q = c;
                q[a] += 1;
                uint iq = index_of(q, d);
                Aphi += w * (here - (phi[iq] + (pc.color == 1u ? double(e[iq]) : 0.0)));
            }
        }
        res = b[p] - Aphi;
        r[p] = float(res);
    }
    uint l = gl_LocalInvocationID.x;
    sums[l] = res * res;
    barrier();
    for (uint s = gl_WorkGroupSize.x / 2; s > 0; s >>= 1) {
        if (l < s) sums[l] += sums[l + s];
        barrier();
    }
    // Large grids split the dispatch over y; groups past the last cell must not write.
    uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (l == 0 && group * gl_WorkGroupSize.x < d.x * d.y * d.z) partial[group] = sums[0];
}
