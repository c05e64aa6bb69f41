#version 450
#extension GL_GOOGLE_include_directive : require
// t = r − A e on one level (rows of cells along z, mg_common.glsl; the software build a quad a
// lane).
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
    bool inside;
    uvec3 c = quad_cell(inside);
    QuadStencil s = quad_stencil(c);
    vec4 e[6] = quad_neighbours(s, c), here = texelFetch(e_quads, int(s.t[0]));
    vec4 Ae = vec4(0.0);
    for (int n = 0; n < 6; ++n) Ae += s.w[n] * (here - e[n]);
    vec4 t = mix(vec4(0.0), texelFetch(r_quads, int(s.t[0])) - Ae, lessThan(s.k, uvec4(pc.dims.z)));
    if (inside) t_quads[s.t[0]] = t;  // the padding: 0
}
#else
void main() {
    bool inside;
    uvec3 c = row_cell(inside);
    uint p = index_of(c, pc.dims, pc.zstride);
    Stencil s = stencil(c, p);
    float ep = e[p], Ae = 0.0;
    for (int n = 0; n < 6; ++n) Ae += s.w[n] * (ep - e[s.q[n]]);
    if (inside) t[p] = r[p] - Ae;
}
#endif
