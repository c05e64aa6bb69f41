#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
// Mixed-precision refinement on the finest level (uniform cells): r = b − Aφ in float64, stored
// as float32 for the next cycle, and one partial sum of r² per workgroup for the residual norm.
// Rows of cells along z (mg_common.glsl).
#define MG_NO_AXIS_TABLE
#include "mg_common.glsl"
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 0) uniform usamplerBuffer phi_texels;  // a double as two words
layout(binding = 1) uniform usamplerBuffer b_texels;
double phi_at(uint q) { return packDouble2x32(texelFetch(phi_texels, int(q)).xy); }
double b_at(uint q) { return packDouble2x32(texelFetch(b_texels, int(q)).xy); }
#else
layout(std430, binding = 0) readonly buffer Phi { double phi[]; };
layout(std430, binding = 1) readonly buffer B { double b[]; };
double phi_at(uint q) { return phi[q]; }
double b_at(uint q) { return b[q]; }
#endif
layout(std430, binding = 2) writeonly buffer R { float r[]; };
layout(std430, binding = 3) writeonly buffer Partial { double partial[]; };

shared double sums[256];

// The two terms of Aφ along one axis at cell p (a missing neighbour is p itself: 0).
double along(double here, uint p, uint step, uint c, uint n, float inv_h2) {
    uint below = c > 0u ? p - step : p, above = c + 1u < n ? p + step : p;
    return double(inv_h2) * ((here - phi_at(below)) + (here - phi_at(above)));
}

void main() {
    uvec3 d = pc.dims;
    bool inside;
    uvec3 c = row_cell(inside);
    uint p = index_of(c, d);
    double here = phi_at(p);
    double Aphi = along(here, p, d.y * d.z, c.x, d.x, pc.inv_h2.x) + along(here, p, d.z, c.y, d.y, pc.inv_h2.y) +
                  along(here, p, 1u, c.z, d.z, pc.inv_h2.z);
    double res = inside ? b_at(p) - Aphi : 0.0;
    if (inside) r[p] = float(res);
    double own = subgroupAdd(res * res);
    if (subgroupElect()) sums[gl_SubgroupID] = own;
    barrier();
    uint l = gl_LocalInvocationIndex;
    uint group = (gl_WorkGroupID.z * gl_NumWorkGroups.y + gl_WorkGroupID.y) * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (l == 0) {
        double total = 0.0;
        for (uint i = 0; i < gl_NumSubgroups; ++i) total += sums[i];
        partial[group] = total;
    }
}
