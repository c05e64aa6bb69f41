// The 7-point stencil of cell c at index p of the level in pc.dims / pc.axes_off, for mg_smooth
// and mg_residual: the couplings to its six neighbours (in the order −x, +x, −y, +y, −z, +z) and
// their indices. A coupling is the face's area (the other two axes' sizes) times the axis's
// factor toward that neighbour. Toward a missing neighbour it is 0 and the index is p itself,
// so that the kernels load all six without a branch.
#ifndef GSD_SOFTWARE_SHAPED
struct Stencil { float w[6]; uint q[6]; };

Stencil stencil(uvec3 c, uint p) {
    uvec3 d = pc.dims;
    vec4 x = axis_cell(0u, c.x, 0u), y = axis_cell(1u, c.y, 0u), z = axis_cell(2u, c.z, 0u);
    float yz = y.x * z.x, zx = z.x * x.x, xy = x.x * y.x;
    Stencil s;
    s.w[0] = yz * x.y;
    s.w[1] = yz * x.z;
    s.w[2] = zx * y.y;
    s.w[3] = zx * y.z;
    s.w[4] = xy * z.y;
    s.w[5] = xy * z.z;
    uint slab = d.y * pc.zstride;
    s.q[0] = c.x > 0u ? p - slab : p;
    s.q[1] = c.x + 1u < d.x ? p + slab : p;
    s.q[2] = c.y > 0u ? p - pc.zstride : p;
    s.q[3] = c.y + 1u < d.y ? p + pc.zstride : p;
    s.q[4] = c.z > 0u ? p - 1u : p;
    s.q[5] = c.z + 1u < d.z ? p + 1u : p;
    return s;
}

#else
// The 7-point stencil of the lane's quad c = (i, j, tq) (mg_common.glsl), as `stencil` above for
// each of its cells: the couplings toward the six neighbours (−x, +x, −y, +y, −z, +z), and the
// texels of the quad (t[0]), of the quads beside it across x and y (t[1] … t[4]: the same cells
// of the rows beside) and of the other parity's quads before and after it in the row (t[5],
// t[6]: its cells' neighbours along z). A missing one is the quad itself, with coupling 0.
struct QuadStencil {
    vec4 w[6];
    uint t[7];
    uvec4 k;  // its cells
};

QuadStencil quad_stencil(uvec3 c) {
    uvec3 d = pc.dims;
    QuadStencil s;
    s.k = quad_cells(c.z);
    float sx = size_at(0u, c.x), sy = size_at(1u, c.y);
    vec4 sz = sizes_z(s.k);
    vec4 yz = sy * sz, zx = sz * sx;
    float xy = sx * sy;
    s.w[0] = yz * link_before(0u, c.x);
    s.w[1] = yz * link_at(0u, c.x);
    s.w[2] = zx * link_before(1u, c.y);
    s.w[3] = zx * link_at(1u, c.y);
    s.w[4] = xy * mix(vec4(0.0), links_z(s.k - 1u), greaterThan(s.k, uvec4(0u)));
    s.w[5] = xy * links_z(s.k);
    uint q = quad_texel(c), row = pc.zstride / 4u, slab = d.y * row;
    s.t[0] = q;
    s.t[1] = c.x > 0u ? q - slab : q;
    s.t[2] = c.x + 1u < d.x ? q + slab : q;
    s.t[3] = c.y > 0u ? q - row : q;
    s.t[4] = c.y + 1u < d.y ? q + row : q;
    s.t[5] = c.z > 0u ? q - 1u : q;
    s.t[6] = c.z + 1u < row ? q + 1u : q;
    return s;
}

// e at each of the quad's cells' six neighbours, in the stencil's order. Along z: an even quad's
// cells 8b + 2m have the odd cells 8b + 2m ± 1 beside them, the odd quad of the block after
// (t[6]) but for the first, the last of the block before's (t[5]); an odd quad's, the even quad
// before (t[5]) and, for the last, the first of the block after's (t[6]). The kernel declares
// e_quads (e as vec4s) before including this file.
vec4[6] quad_neighbours(QuadStencil s, uvec3 c) {
    vec4 v[6];
    for (int n = 0; n < 4; ++n) v[n] = texelFetch(e_quads, int(s.t[n + 1]));
    vec4 before = texelFetch(e_quads, int(s.t[5])), after = texelFetch(e_quads, int(s.t[6]));
    bool odd = (c.z & 1u) != 0u;
    v[4] = odd ? before : vec4(before.w, after.xyz);
    v[5] = odd ? vec4(before.yzw, after.x) : after;
    return v;
}
#endif
