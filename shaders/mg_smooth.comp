#version 450
#extension GL_GOOGLE_include_directive : require
// One red-black Gauss–Seidel sweep of one color: e_p = (r_p + Σ c e_q) / Σ c. Rows of cells
// along z as mg_common.glsl's row_cell, but a row's lanes take its cells of this color only
// (k = 2·x + parity), so that no lane idles on the other color. e is bound twice: read (the other color's cells)
// and written (this color's); no cell is both in one sweep.
#include "mg_common.glsl"
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 1) uniform samplerBuffer r_texels;
layout(binding = 2) uniform samplerBuffer e_texels;
float r_at(uint q) { return texelFetch(r_texels, int(q)).x; }
float e_at(uint q) { return texelFetch(e_texels, int(q)).x; }
#else
layout(std430, binding = 1) readonly buffer R { float r[]; };
layout(std430, binding = 2) readonly buffer E { float e[]; };
float r_at(uint q) { return r[q]; }
float e_at(uint q) { return e[q]; }
#endif
layout(std430, binding = 3) writeonly buffer EOut { float e_out[]; };
#include "mg_row.glsl"

void main() {
    uvec3 d = pc.dims;
    uvec3 c = uvec3(gl_WorkGroupID.z, gl_GlobalInvocationID.y, 2u * gl_GlobalInvocationID.x);
    c.z += (c.x + c.y + pc.color) & 1u;
    bool inside = c.z < d.z && c.y < d.y;
    c.yz = min(c.yz, d.yz - 1u);  // past the grid: a real cell, nothing stored
    uint p = index_of(c, d);
    Stencil s = stencil(c, p);
    float sum = r_at(p), diag = 0.0;
    for (int n = 0; n < 6; ++n) {
        sum += s.w[n] * e_at(s.q[n]);
        diag += s.w[n];
    }
    if (inside && diag > 0.0) e_out[p] = sum / diag;
}
