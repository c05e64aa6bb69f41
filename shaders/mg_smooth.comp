#version 450
#extension GL_GOOGLE_include_directive : require
// One red-black Gauss–Seidel sweep of one color: e_p = (r_p + Σ c e_q) / Σ c. Rows of cells
// along z as mg_common.glsl's row_cell, but a row's lanes take its cells of this color only
// (k = 2·x + parity), so that no lane idles on the other color. The software build takes a
// quad a lane (mg_common.glsl) and updates its two cells of this color. e is bound twice or
// three times: read (the other color's cells) and written (this color's); no cell is both in
// one sweep.
#ifdef GSD_SOFTWARE_SHAPED
#define MG_NO_AXIS_TABLE  // the couplings come from the push constants
#endif
#include "mg_common.glsl"
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 0) uniform samplerBuffer r_quads;
layout(binding = 1) uniform samplerBuffer e_quads;
layout(binding = 2) uniform samplerBuffer e_cells;
#else
layout(std430, binding = 1) readonly buffer R { float r[]; };
layout(std430, binding = 2) readonly buffer E { float e[]; };
#endif
layout(std430, binding = 3) writeonly buffer EOut { float e_out[]; };
#include "mg_row.glsl"

#ifdef GSD_SOFTWARE_SHAPED
void main() {
    bool inside;
    uvec3 c = quad_cell(inside);
    QuadStencil s = quad_stencil(c);
    QuadValues e = quad_values(s, c);
    vec4 sum = texelFetch(r_quads, int(s.t[0])), diag = vec4(0.0);
    for (int n = 0; n < 6; ++n) {
        sum += s.w[n] * e.beside[n];
        diag += s.w[n];
    }
    // This color's two cells of the quad: k ≡ i + j + color (mod 2), the quad starting even.
    uint odd = (c.x + c.y + pc.color) & 1u;
    vec2 num = odd == 0u ? sum.xz : sum.yw, den = odd == 0u ? diag.xz : diag.yw;
    uint k = c.z + odd;
    if (inside && den.x > 0.0 && k < pc.dims.z) e_out[s.row + k] = num.x / den.x;
    if (inside && den.y > 0.0 && k + 2u < pc.dims.z) e_out[s.row + k + 2u] = num.y / den.y;
}
#else
void main() {
    uvec3 d = pc.dims;
    uvec3 c = uvec3(gl_WorkGroupID.z, gl_GlobalInvocationID.y, 2u * gl_GlobalInvocationID.x);
    c.z += (c.x + c.y + pc.color) & 1u;
    bool inside = c.z < d.z && c.y < d.y;
    c.yz = min(c.yz, d.yz - 1u);  // past the grid: a real cell, nothing stored
    uint p = index_of(c, d, pc.zstride);
    Stencil s = stencil(c, p);
    float sum = r[p], diag = 0.0;
    for (int n = 0; n < 6; ++n) {
        sum += s.w[n] * e[s.q[n]];
        diag += s.w[n];
    }
    if (inside && diag > 0.0) e_out[p] = sum / diag;
}
#endif
