#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
// Mixed-precision refinement on the finest level (uniform cells): r = b − Aφ in float64, stored
// as float32 for the next cycle, and one partial sum of r² per workgroup for the residual norm.
// Rows of cells along z (mg_common.glsl; the software build a quad a lane, φ and b read as two
// doubles a texel).
#define MG_NO_AXIS_TABLE
#include "mg_common.glsl"
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 0) uniform usamplerBuffer phi_pairs;
layout(binding = 1) uniform usamplerBuffer b_pairs;
layout(std430, binding = 2) writeonly buffer R { vec4 r_quads[]; };
#else
layout(std430, binding = 0) readonly buffer Phi { double phi[]; };
layout(std430, binding = 1) readonly buffer B { double b[]; };
layout(std430, binding = 2) writeonly buffer R { float r[]; };
#endif
layout(std430, binding = 3) writeonly buffer Partial { double partial[]; };

shared double sums[256];

// One partial sum of r² per workgroup (`own`: this lane's part).
void add_partial(double own) {
    own = subgroupAdd(own);
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

#ifdef GSD_SOFTWARE_SHAPED
void main() {
    uvec3 d = pc.dims;
    bool inside;
    uvec3 c = quad_cell(inside);
    uint q = quad_texel(c), row = pc.zstride / 4u, slab = d.y * row;
    dvec4 here = double_quad(phi_pairs, q);
    // Aφ's terms along x and y: the quads beside (a missing one: the quad itself, 0) ...
    dvec4 x = (here - double_quad(phi_pairs, c.x > 0u ? q - slab : q)) + (here - double_quad(phi_pairs, c.x + 1u < d.x ? q + slab : q));
    dvec4 y = (here - double_quad(phi_pairs, c.y > 0u ? q - row : q)) + (here - double_quad(phi_pairs, c.y + 1u < d.y ? q + row : q));
    // ... and along z, each cell's neighbours in the row, from the other parity's quads before
    // and after (as mg_row.glsl's quad_neighbours; a missing one: the cell itself).
    dvec4 before = double_quad(phi_pairs, c.z > 0u ? q - 1u : q), after = double_quad(phi_pairs, c.z + 1u < row ? q + 1u : q);
    bool odd = (c.z & 1u) != 0u;
    uvec4 k = quad_cells(c.z);
    dvec4 prev = mix(odd ? before : dvec4(before.w, after.xyz), here, equal(k, uvec4(0u)));
    dvec4 next = mix(odd ? dvec4(before.yzw, after.x) : after, here, greaterThanEqual(k + 1u, uvec4(d.z)));
    dvec4 z = (here - prev) + (here - next);
    dvec4 Aphi = double(pc.inv_h2.x) * x + double(pc.inv_h2.y) * y + double(pc.inv_h2.z) * z;
    dvec4 res = double_quad(b_pairs, q) - Aphi;
    res = mix(dvec4(0.0), res, lessThan(k, uvec4(d.z)));  // the padding: 0
    if (inside) r_quads[q] = vec4(res);
    add_partial(inside ? dot(res, res) : 0.0);
}
#else
// The two terms of Aφ along one axis at cell p (a missing neighbour is p itself: 0).
double along(double here, uint p, uint step, uint c, uint n, float inv_h2) {
    uint below = c > 0u ? p - step : p, above = c + 1u < n ? p + step : p;
    return double(inv_h2) * ((here - phi[below]) + (here - phi[above]));
}

void main() {
    uvec3 d = pc.dims;
    bool inside;
    uvec3 c = row_cell(inside);
    uint p = index_of(c, d, pc.zstride);
    double here = phi[p];
    double Aphi = along(here, p, d.y * pc.zstride, c.x, d.x, pc.inv_h2.x) + along(here, p, pc.zstride, c.y, d.y, pc.inv_h2.y) +
                  along(here, p, 1u, c.z, d.z, pc.inv_h2.z);
    double res = inside ? b[p] - Aphi : 0.0;
    if (inside) r[p] = float(res);
    add_partial(res * res);
}
#endif
