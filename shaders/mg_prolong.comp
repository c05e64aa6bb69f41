#version 450
#extension GL_GOOGLE_include_directive : require
// Prolongation: e_fine += P e_coarse, trilinear from the coarse cells' centers (each axis's
// sources c0, c1 and weights w0, w1). Rows of fine cells along z (mg_common.glsl; the software
// build a quad a lane); pc.dims is the fine level, pc.odims the coarse. The fine e is bound
// twice, read and written (each cell its own).
#include "mg_common.glsl"
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 1) uniform samplerBuffer ec_quads;
layout(binding = 2) uniform samplerBuffer ef_quads;
layout(std430, binding = 3) writeonly buffer EFOut { vec4 ef_out[]; };

// The fine quad of cells 4q … 4q+3 of a row interpolates from coarse cells 2q−1 … 2q+2 (a fine
// cell's sources lie around its parent: Hierarchy's `link`). Those four of the coarse row
// (ci, cj), from two vec4 texels; the row's ends clamp (cells before or past the row go unused).
vec4 window(uint ci, uint cj, uint q) {
    uint row = (ci * pc.odims.y + cj) * pc.ozstride / 4u, last = row + pc.ozstride / 4u - 1u;
    uint first = row + (q > 0u ? (2u * q - 1u) / 4u : 0u);
    vec4 a = texelFetch(ec_quads, int(first)), b = texelFetch(ec_quads, int(min(first + 1u, last)));
    if (q == 0u) return vec4(a.x, a.xyz);
    return (q & 1u) == 0u ? vec4(a.w, b.xyz) : vec4(a.yzw, b.x);
}
// Entry o (0 … 3) of w, without an indexed read (llvmpipe's goes through memory lane by lane).
float pick(vec4 w, uint o) { return o == 0u ? w.x : o == 1u ? w.y : o == 2u ? w.z : w.w; }
// Fine cell k of the quad whose window (interpolated in x and y) is xy, starting at coarse cell
// base; 0 in the padding.
float along_z(vec4 xy, uint base, uint k) {
    vec4 z = axis_cell(2u, min(k, pc.dims.z - 1u), 1u);  // (c0, c1, w0, w1)
    float s = z.z * pick(xy, uint(z.x) - base) + z.w * pick(xy, uint(z.y) - base);
    return k < pc.dims.z ? s : 0.0;
}

void main() {
    bool inside;
    uvec3 c = quad_cell(inside);
    uint q = index_of(c, pc.dims, pc.zstride) / 4u, cq = c.z / 4u;
    vec4 x = axis_cell(0u, c.x, 1u), y = axis_cell(1u, c.y, 1u);  // (c0, c1, w0, w1)
    uvec2 ci = uvec2(x.xy), cj = uvec2(y.xy);
    vec4 xy = x.z * (y.z * window(ci.x, cj.x, cq) + y.w * window(ci.x, cj.y, cq)) +
              x.w * (y.z * window(ci.y, cj.x, cq) + y.w * window(ci.y, cj.y, cq));
    uint base = 2u * cq - 1u;  // the window's first coarse cell (wraps at cq = 0, as the sources do)
    vec4 s = vec4(along_z(xy, base, c.z), along_z(xy, base, c.z + 1u), along_z(xy, base, c.z + 2u), along_z(xy, base, c.z + 3u));
    vec4 updated = texelFetch(ef_quads, int(q)) + s;
    if (inside) ef_out[q] = updated;
}
#else
layout(std430, binding = 1) readonly buffer EC { float ec[]; };
layout(std430, binding = 2) readonly buffer EF { float ef[]; };
layout(std430, binding = 3) writeonly buffer EFOut { float ef_out[]; };
// The two z sources of the coarse row (ci, cj).
float along_z(uint ci, uint cj, uvec2 ck, vec2 wk) {
    uint row = (ci * pc.odims.y + cj) * pc.ozstride;
    return wk.x * ec[row + ck.x] + wk.y * ec[row + ck.y];
}
void main() {
    bool inside;
    uvec3 c = row_cell(inside);
    uint p = index_of(c, pc.dims, pc.zstride);
    vec4 x = axis_cell(0u, c.x, 1u), y = axis_cell(1u, c.y, 1u), z = axis_cell(2u, c.z, 1u);  // (c0, c1, w0, w1)
    uvec2 ci = uvec2(x.xy), cj = uvec2(y.xy), ck = uvec2(z.xy);
    float s = x.z * (y.z * along_z(ci.x, cj.x, ck, z.zw) + y.w * along_z(ci.x, cj.y, ck, z.zw)) +
              x.w * (y.z * along_z(ci.y, cj.x, ck, z.zw) + y.w * along_z(ci.y, cj.y, ck, z.zw));
    float here = ef[p];
    if (inside) ef_out[p] = here + s;
}
#endif
