#version 450
#extension GL_GOOGLE_include_directive : require
// t = r − A e on one level after a half-sweep of the smoother: on the cells of color pc.color;
// on the other color's, which that half-sweep has just solved for (each one's equation holds
// with its neighbours' values as they are), t is 0 up to rounding and stored as 0. Rows of
// cells along z (mg_common.glsl), a lane per pair of cells (the software build: per block, its
// quad of color pc.color computed, the other quad stored as zeros).
#ifdef GSD_SOFTWARE_SHAPED
#define MG_NO_AXIS_TABLE  // the couplings come from the push constants
#endif
#include "mg_common.glsl"
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 0) uniform samplerBuffer r_quads;
layout(binding = 1) uniform samplerBuffer e_quads;
layout(std430, binding = 2) writeonly buffer T { vec4 t_quads[]; };
#else
layout(std430, binding = 1) readonly buffer R { float r[]; };
layout(std430, binding = 2) readonly buffer E { float e[]; };
layout(std430, binding = 3) writeonly buffer T { float t[]; };
#endif
#include "mg_row.glsl"

#ifdef GSD_SOFTWARE_SHAPED
void main() {
    uint odd = (gl_WorkGroupID.z + gl_GlobalInvocationID.y + pc.color) & 1u;
    bool inside;
    uvec3 c = lane_quad(2u * gl_GlobalInvocationID.x + odd, inside);
    QuadStencil s = quad_stencil(c);
    vec4 e[6] = quad_neighbours(s, c), here = texelFetch(e_quads, int(s.t[0]));
    vec4 Ae = vec4(0.0);
    for (int n = 0; n < 6; ++n) Ae += s.w[n] * (here - e[n]);
    vec4 t = mix(vec4(0.0), texelFetch(r_quads, int(s.t[0])) - Ae, lessThan(s.k, uvec4(pc.dims.z)));
    if (inside) {  // the padding: 0
        t_quads[s.t[0]] = t;
        t_quads[s.t[0] ^ 1u] = vec4(0.0);  // the block's other quad (rows hold whole blocks: an even texel count)
    }
}
#else
void main() {
    uvec3 d = pc.dims;
    uvec3 c = uvec3(gl_WorkGroupID.z, gl_GlobalInvocationID.y, 2u * gl_GlobalInvocationID.x);
    uint other = c.z + 1u - ((c.x + c.y + pc.color) & 1u);  // the pair's cell of the other color
    c.z += (c.x + c.y + pc.color) & 1u;
    bool row = c.y < d.y, inside = row && c.z < d.z;
    c.yz = min(c.yz, d.yz - 1u);  // past the grid: a real cell, nothing stored
    uint p = index_of(c, d, pc.zstride);
    Stencil s = stencil(c, p);
    float ep = e[p], Ae = 0.0;
    for (int n = 0; n < 6; ++n) Ae += s.w[n] * (ep - e[s.q[n]]);
    float res = r[p] - Ae;
    if (inside) t[p] = res;
    if (row && other < d.z) t[index_of(uvec3(c.xy, other), d, pc.zstride)] = 0.0;
}
#endif
