#version 450
#extension GL_GOOGLE_include_directive : require
// One red-black Gauss–Seidel sweep of one color: e_p = (r_p + Σ c e_q) / Σ c. Rows of cells
// along z as mg_common.glsl's row_cell, but a row's lanes take its cells of this color only
// (k = 2·x + parity), so that no lane idles on the other color. The software build takes a
// block of the row a lane and updates its quad of this color's cells (mg_common.glsl). e is
// bound twice: read (the other color's cells) and written (this color's); no cell is both in
// one sweep. A level's first half-sweep of a cycle (pc.first_sweep) takes e as 0 instead of
// reading it, so that no cycle clears e first; so no sweep multiplies what it reads by a 0
// coupling either.
#ifdef GSD_SOFTWARE_SHAPED
#define MG_NO_AXIS_TABLE  // the couplings come from the push constants
#endif
#include "mg_common.glsl"
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 0) uniform samplerBuffer r_quads;
layout(binding = 1) uniform samplerBuffer e_quads;  // the other color's cells
layout(std430, binding = 2) writeonly buffer EOut { vec4 e_out[]; };  // this color's
#else
layout(std430, binding = 1) readonly buffer R { float r[]; };
layout(std430, binding = 2) readonly buffer E { float e[]; };
layout(std430, binding = 3) writeonly buffer EOut { float e_out[]; };
#endif
#include "mg_row.glsl"

#ifdef GSD_SOFTWARE_SHAPED
void main() {
    // A lane per block of the row: its quad of this color's cells (k ≡ i + j + color mod 2).
    uint odd = (gl_WorkGroupID.z + gl_GlobalInvocationID.y + pc.color) & 1u;
    bool inside;
    uvec3 c = lane_quad(2u * gl_GlobalInvocationID.x + odd, inside);
    QuadStencil s = quad_stencil(c);
    vec4 e[6] = quad_neighbours(s, c);
    // e is not cleared between cycles: a level's first half-sweep takes it as 0, and a missing
    // neighbour (coupling 0, read from this color's own cells, not yet stored in the second
    // half-sweep) is selected away, not multiplied by 0, as what e holds may not be finite.
    bool zero = pc.first_sweep != 0u;
    vec4 sum = texelFetch(r_quads, int(s.t[0])), diag = vec4(0.0);
    for (int n = 0; n < 6; ++n) {
        vec4 w = zero ? vec4(0.0) : s.w[n];
        sum += mix(vec4(0.0), w * e[n], greaterThan(w, vec4(0.0)));
        diag += s.w[n];
    }
    // The padding stays 0 (a cell with no neighbour at all, alone in its grid, too).
    vec4 updated = mix(vec4(0.0), sum / diag, lessThan(s.k, uvec4(pc.dims.z)));
    if (inside) e_out[s.t[0]] = mix(vec4(0.0), updated, greaterThan(diag, vec4(0.0)));
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
    for (int n = 0; n < 6; ++n) diag += s.w[n];
    // e is not cleared between cycles: a level's first half-sweep takes it as 0, and a missing
    // neighbour (coupling 0, index p: a cell of this color) is not read.
    if (pc.first_sweep == 0u)
        for (int n = 0; n < 6; ++n)
            if (s.w[n] > 0.0) sum += s.w[n] * e[s.q[n]];
    if (inside) e_out[p] = diag > 0.0 ? sum / diag : 0.0;
}
#endif
