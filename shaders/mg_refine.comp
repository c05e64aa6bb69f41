#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
// Mixed-precision refinement on the finest level (uniform cells), after a cycle: φ += e and
// r −= A e in float64, r stored again as float32 for the next cycle, and one partial sum of r²
// per workgroup for the residual norm. The float64 residual starts as b and is updated, not
// recomputed as b − Aφ: A e from float32 values in float64 arithmetic is what A φ gains from
// φ += e, to the rounding of float64, so the two agree to ~1e-16 of A's scale while a cell reads
// e at its neighbours (float32, as the smoother does) instead of φ (float64 pairs: two texels a
// quad, and float64 arithmetic on all seven). pc.first_sweep: 0 as above; 1: φ is 0, not read
// (the first cycle: φ is not cleared), so φ = e; 2: no cycle before (e not read, nothing
// stored in float64): r = b as float32, and its norm. Each cell reads and writes its own φ and
// r only, so both are updated in place. Rows of cells along z (mg_common.glsl; the software
// build a quad a lane, φ and r read as two doubles a texel).
#define MG_NO_AXIS_TABLE
#include "mg_common.glsl"
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 0) uniform samplerBuffer e_quads;
layout(binding = 1) uniform usamplerBuffer res_pairs;  // r in float64 (b before the first cycle)
layout(binding = 2) uniform usamplerBuffer phi_pairs;
layout(std430, binding = 3) writeonly buffer ResOut { dvec4 res_out[]; };  // binding 1's buffer
layout(std430, binding = 4) writeonly buffer PhiOut { dvec4 phi_out[]; };  // binding 2's buffer
layout(std430, binding = 5) writeonly buffer R { vec4 r_quads[]; };
#else
layout(std430, binding = 0) readonly buffer E { float e[]; };
layout(std430, binding = 1) readonly buffer Res { double res[]; };
layout(std430, binding = 2) readonly buffer Phi { double phi[]; };
layout(std430, binding = 3) writeonly buffer ResOut { double res_out[]; };
layout(std430, binding = 4) writeonly buffer PhiOut { double phi_out[]; };
layout(std430, binding = 5) writeonly buffer R { float r[]; };
#endif
layout(std430, binding = 6) writeonly buffer Partial { double partial[]; };

#ifdef GSD_SOFTWARE_SHAPED
// One partial sum of r² per subgroup (`own`: this lane's part), without a barrier: on llvmpipe
// a barrier switches through every subgroup of the workgroup. Its subgroups are the SIMD width
// of every workgroup (poisson_gpu.cpp sizes the buffer so).
void add_partial(double own) {
    own = subgroupAdd(own);
    uint group = (gl_WorkGroupID.z * gl_NumWorkGroups.y + gl_WorkGroupID.y) * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (subgroupElect()) partial[group * gl_NumSubgroups + gl_SubgroupID] = own;
}
#else
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
#endif

#ifdef GSD_SOFTWARE_SHAPED
dvec4 e_at(uint q) { return dvec4(texelFetch(e_quads, int(q))); }

void main() {
    uvec3 d = pc.dims;
    bool inside;
    uvec3 c = quad_cell(inside);
    uint q = quad_texel(c), row = pc.zstride / 4u, slab = d.y * row;
    dvec4 here = e_at(q);
    // A e's terms along x and y: the quads beside (a missing one: the quad itself, 0) ...
    dvec4 x = (here - e_at(c.x > 0u ? q - slab : q)) + (here - e_at(c.x + 1u < d.x ? q + slab : q));
    dvec4 y = (here - e_at(c.y > 0u ? q - row : q)) + (here - e_at(c.y + 1u < d.y ? q + row : q));
    // ... and along z, each cell's neighbours in the row, from the other parity's quads before
    // and after (as mg_row.glsl's quad_neighbours; a missing one: the cell itself).
    dvec4 before = e_at(c.z > 0u ? q - 1u : q), after = e_at(c.z + 1u < row ? q + 1u : q);
    bool odd = (c.z & 1u) != 0u;
    uvec4 k = quad_cells(c.z);
    dvec4 prev = mix(odd ? before : dvec4(before.w, after.xyz), here, equal(k, uvec4(0u)));
    dvec4 next = mix(odd ? dvec4(before.yzw, after.x) : after, here, greaterThanEqual(k + 1u, uvec4(d.z)));
    dvec4 z = (here - prev) + (here - next);
    dvec4 Ae = double(pc.inv_h2.x) * x + double(pc.inv_h2.y) * y + double(pc.inv_h2.z) * z;
    // What an unread e or φ holds may not be finite: selected away, not multiplied by 0.
    bool cycled = pc.first_sweep != 2u;
    dvec4 res = double_quad(res_pairs, q) - (cycled ? Ae : dvec4(0.0));
    res = mix(dvec4(0.0), res, lessThan(k, uvec4(d.z)));  // the padding: 0
    dvec4 phi = (pc.first_sweep == 1u ? dvec4(0.0) : double_quad(phi_pairs, q)) + here;
    if (inside) {
        r_quads[q] = vec4(res);
        if (cycled) {
            res_out[q] = res;
            phi_out[q] = phi;  // the padding stays 0: its e is
        }
    }
    add_partial(inside ? dot(res, res) : 0.0);
}
#else
// The two terms of A e along one axis at cell p (a missing neighbour is p itself: 0).
double along(double here, uint p, uint step, uint c, uint n, float inv_h2) {
    uint below = c > 0u ? p - step : p, above = c + 1u < n ? p + step : p;
    return double(inv_h2) * ((here - double(e[below])) + (here - double(e[above])));
}

void main() {
    uvec3 d = pc.dims;
    bool inside;
    uvec3 c = row_cell(inside);
    uint p = index_of(c, d, pc.zstride);
    bool cycled = pc.first_sweep != 2u;
    double updated = res[p];
    if (cycled) {
        double here = double(e[p]);
        updated -= along(here, p, d.y * pc.zstride, c.x, d.x, pc.inv_h2.x) + along(here, p, pc.zstride, c.y, d.y, pc.inv_h2.y) +
                   along(here, p, 1u, c.z, d.z, pc.inv_h2.z);
        if (inside) {
            res_out[p] = updated;
            phi_out[p] = (pc.first_sweep == 1u ? 0.0 : phi[p]) + here;
        }
    }
    if (inside) r[p] = float(updated);
    add_partial(inside ? updated * updated : 0.0);
}
#endif
