#version 450
#extension GL_GOOGLE_include_directive : require
// Prolongation: e_fine += P e_coarse, trilinear from the coarse cells' centers (each axis's
// sources c0, c1 and weights w0, w1). Rows of fine cells along z (mg_common.glsl); pc.dims is the fine level, pc.odims the coarse. The fine e is bound twice,
// read and written (each cell its own).
#include "mg_common.glsl"
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 1) uniform samplerBuffer ec_texels;
layout(binding = 2) uniform samplerBuffer ef_texels;
float ec_at(uint q) { return texelFetch(ec_texels, int(q)).x; }
float ef_at(uint q) { return texelFetch(ef_texels, int(q)).x; }
#else
layout(std430, binding = 1) readonly buffer EC { float ec[]; };
layout(std430, binding = 2) readonly buffer EF { float ef[]; };
float ec_at(uint q) { return ec[q]; }
float ef_at(uint q) { return ef[q]; }
#endif
layout(std430, binding = 3) writeonly buffer EFOut { float ef_out[]; };

// The two z sources of the coarse row (ci, cj).
float along_z(uint ci, uint cj, uvec2 ck, vec2 wk) {
    uint row = (ci * pc.odims.y + cj) * pc.ozstride;
    return wk.x * ec_at(row + ck.x) + wk.y * ec_at(row + ck.y);
}

void main() {
    bool inside;
    uvec3 c = row_cell(inside);
    uint p = index_of(c, pc.dims, pc.zstride);
    vec4 x = axis_cell(0u, c.x, 1u), y = axis_cell(1u, c.y, 1u), z = axis_cell(2u, c.z, 1u);  // (c0, c1, w0, w1)
    uvec2 ci = uvec2(x.xy), cj = uvec2(y.xy), ck = uvec2(z.xy);
    float s = x.z * (y.z * along_z(ci.x, cj.x, ck, z.zw) + y.w * along_z(ci.x, cj.y, ck, z.zw)) +
              x.w * (y.z * along_z(ci.y, cj.x, ck, z.zw) + y.w * along_z(ci.y, cj.y, ck, z.zw));
    float here = ef_at(p);
    if (inside) ef_out[p] = here + s;
}
