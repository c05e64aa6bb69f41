#version 450
#extension GL_GOOGLE_include_directive : require
// t = r − A e on one level (rows of cells along z, mg_common.glsl).
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
layout(std430, binding = 3) writeonly buffer T { float t[]; };
#include "mg_row.glsl"

void main() {
    bool inside;
    uvec3 c = row_cell(inside);
    uint p = index_of(c, pc.dims);
    Stencil s = stencil(c, p);
    float ep = e_at(p), Ae = 0.0;
    for (int n = 0; n < 6; ++n) Ae += s.w[n] * (ep - e_at(s.q[n]));
    if (inside) t[p] = r_at(p) - Ae;
}
