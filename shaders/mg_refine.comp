#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
// The finest level in float64: φ += e (the correction of the last cycle, when `color` is 1),
// then r = b − L φ, written as float for the next cycle, with per-workgroup partial sums of r²
// for the convergence test. This is mixed-precision iterative refinement: the cycles run in
// float32, the residual and the solution stay in float64. A workgroup takes a row of cells
// along z (mg_smooth); its partial sum goes to its linear index.
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
    uvec3 d = pc.dims;
    uvec3 c = uvec3(gl_WorkGroupID.z, gl_WorkGroupID.y, gl_GlobalInvocationID.x);  // a row per workgroup (mg_smooth)
    bool valid = c.z < d.z;
    uint p = index_of(c, d);
    double res = 0.0;
    if (valid) {
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
    // Each subgroup adds its own, then one lane adds the subgroups': one barrier (llvmpipe runs a
    // barrier by switching between the workgroup's SIMD groups; a tree of them took half the time).
    double own = subgroupAdd(res * res);
    if (subgroupElect()) sums[gl_SubgroupID] = own;
    barrier();
    uint l = gl_LocalInvocationID.x;
    uint group = (gl_WorkGroupID.z * gl_NumWorkGroups.y + gl_WorkGroupID.y) * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (l == 0) {
        double total = 0.0;
        for (uint i = 0; i < gl_NumSubgroups; ++i) total += sums[i];
        partial[group] = total;
    }
}
