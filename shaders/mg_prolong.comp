#version 450
#extension GL_GOOGLE_include_directive : require
// Prolongation: e_fine += P e_coarse, trilinear from the coarse cells' centers (each axis's
// sources c0, c1 and weights w0, w1). Rows of fine cells along z (mg_common.glsl; the software
// build a quad a lane); pc.dims is the fine level, pc.odims the coarse. The fine e is bound
// twice, read and written (each cell its own). Only the cells of color pc.color are updated: the
// post-smoothing's first half-sweep, of the other color, reads no cell of its own color and
// overwrites them all, so their prolonged values would go unread (poisson_gpu.cpp). A row's
// lanes take its cells of that color (as mg_smooth.comp's), the software build a block's quad
// of them a lane.
#include "mg_common.glsl"
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 1) uniform samplerBuffer ec_quads;
layout(binding = 2) uniform samplerBuffer ef_quads;
layout(std430, binding = 3) writeonly buffer EFOut { vec4 ef_out[]; };

// A fine quad's cells 8b + p + 2m (mg_common.glsl) interpolate from coarse cells 4b − 1 … 4b + 4
// (a fine cell's sources lie around its parent: Hierarchy's `link`). Those six of the coarse row
// (ci, cj), as (lo, hi): the coarse block 4b falls in (B = b / 2), its even quad E and odd quad O,
// and for even b the odd quad before it (P), for odd b the even quad after it (N):
//   b even: P.w, E.x, O.x, E.y, O.y, E.z        b odd: O.y, E.z, O.z, E.w, O.w, N.x
// The row's ends clamp (cells before or past the row go unused).
struct Window {
    vec4 lo;
    vec2 hi;
};

Window window(uint ci, uint cj, uint b) {
    uint quads = pc.ozstride / 4u, row = (ci * pc.odims.y + cj) * quads, e = row + 2u * (b >> 1u);
    vec4 E = texelFetch(ec_quads, int(e)), O = texelFetch(ec_quads, int(e + 1u));
    bool odd = (b & 1u) != 0u;
    vec4 X = texelFetch(ec_quads, int(odd ? min(e + 2u, row + quads - 1u) : max(e, row + 1u) - 1u));
    Window w;
    w.lo = odd ? vec4(O.y, E.z, O.z, E.w) : vec4(X.w, E.x, O.x, E.y);
    w.hi = odd ? vec2(O.w, X.x) : vec2(O.y, E.z);
    return w;
}
// Entry o (0 … 5) of a window, without an indexed read (llvmpipe's goes through memory lane by
// lane).
float pick(Window w, uint o) {
    return o < 4u ? (o == 0u ? w.lo.x : o == 1u ? w.lo.y : o == 2u ? w.lo.z : w.lo.w) : (o == 4u ? w.hi.x : w.hi.y);
}
// Fine cell k of the quad whose window (interpolated in x and y) is w, starting at coarse cell
// base; 0 in the padding.
float along_z(Window w, uint base, uint k) {
    vec4 z = axis_cell(2u, min(k, pc.dims.z - 1u), 1u);  // (c0, c1, w0, w1)
    float s = z.z * pick(w, uint(z.x) - base) + z.w * pick(w, uint(z.y) - base);
    return k < pc.dims.z ? s : 0.0;
}

void main() {
    uint odd = (gl_WorkGroupID.z + gl_GlobalInvocationID.y + pc.color) & 1u;
    bool inside;
    uvec3 c = lane_quad(2u * gl_GlobalInvocationID.x + odd, inside);
    uint b = c.z >> 1u;
    vec4 x = axis_cell(0u, c.x, 1u), y = axis_cell(1u, c.y, 1u);  // (c0, c1, w0, w1)
    uvec2 ci = uvec2(x.xy), cj = uvec2(y.xy);
    Window w00 = window(ci.x, cj.x, b), w01 = window(ci.x, cj.y, b), w10 = window(ci.y, cj.x, b), w11 = window(ci.y, cj.y, b);
    Window xy;  // the window interpolated in x and y
    xy.lo = x.z * (y.z * w00.lo + y.w * w01.lo) + x.w * (y.z * w10.lo + y.w * w11.lo);
    xy.hi = x.z * (y.z * w00.hi + y.w * w01.hi) + x.w * (y.z * w10.hi + y.w * w11.hi);
    uint base = 4u * b - 1u;  // the window's first coarse cell (wraps at b = 0, as the sources do)
    uvec4 k = quad_cells(c.z);
    vec4 s = vec4(along_z(xy, base, k.x), along_z(xy, base, k.y), along_z(xy, base, k.z), along_z(xy, base, k.w));
    uint q = quad_texel(c);
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
    uvec3 d = pc.dims;
    uvec3 c = uvec3(gl_WorkGroupID.z, gl_GlobalInvocationID.y, 2u * gl_GlobalInvocationID.x);
    c.z += (c.x + c.y + pc.color) & 1u;
    bool inside = c.z < d.z && c.y < d.y;
    c.yz = min(c.yz, d.yz - 1u);  // past the grid: a real cell, nothing stored
    uint p = index_of(c, d, pc.zstride);
    vec4 x = axis_cell(0u, c.x, 1u), y = axis_cell(1u, c.y, 1u), z = axis_cell(2u, c.z, 1u);  // (c0, c1, w0, w1)
    uvec2 ci = uvec2(x.xy), cj = uvec2(y.xy), ck = uvec2(z.xy);
    float s = x.z * (y.z * along_z(ci.x, cj.x, ck, z.zw) + y.w * along_z(ci.x, cj.y, ck, z.zw)) +
              x.w * (y.z * along_z(ci.y, cj.x, ck, z.zw) + y.w * along_z(ci.y, cj.y, ck, z.zw));
    float here = ef[p];
    if (inside) ef_out[p] = here + s;
}
#endif
