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
// The 7-point stencil of the quad at cell c (c.z = 4q), as `stencil` above for each of its
// cells: the couplings toward the six neighbours (−x, +x, −y, +y, −z, +z), and the texel
// indices of the quad (t[0]) and of the quads beside it across x and y (t[1] … t[4]; a missing
// one is the quad itself, coupling 0). The kernel declares e_quads and e_cells (e as vec4s and
// as floats) before including this file.
struct QuadStencil {
    vec4 w[6];
    uint t[5];
    uint row;  // the first cell of the quad's row
};

QuadStencil quad_stencil(uvec3 c) {
    uvec3 d = pc.dims;
    uvec4 k = c.z + uvec4(0u, 1u, 2u, 3u);
    float sx = size_at(0u, c.x), sy = size_at(1u, c.y);
    vec4 sz = sizes_z(k);
    vec4 yz = sy * sz, zx = sz * sx;
    float xy = sx * sy;
    QuadStencil s;
    s.w[0] = yz * link_before(0u, c.x);
    s.w[1] = yz * link_at(0u, c.x);
    s.w[2] = zx * link_before(1u, c.y);
    s.w[3] = zx * link_at(1u, c.y);
    s.w[4] = xy * mix(vec4(0.0), links_z(k - 1u), greaterThan(k, uvec4(0u)));
    s.w[5] = xy * links_z(k);
    s.row = (c.x * d.y + c.y) * pc.zstride;
    uint q = (s.row + c.z) / 4u, slab = d.y * pc.zstride / 4u, row = pc.zstride / 4u;
    s.t[0] = q;
    s.t[1] = c.x > 0u ? q - slab : q;
    s.t[2] = c.x + 1u < d.x ? q + slab : q;
    s.t[3] = c.y > 0u ? q - row : q;
    s.t[4] = c.y + 1u < d.y ? q + row : q;
    return s;
}

// e over the quad (`here`) and at each of its cells' six neighbours, in the stencil's order.
// Across z the neighbours are the quad's own cells but for the two outside it, read as floats
// (any cell where there is none: its coupling is 0).
struct QuadValues {
    vec4 here, beside[6];
};

QuadValues quad_values(QuadStencil s, uvec3 c) {
    QuadValues v;
    v.here = texelFetch(e_quads, int(s.t[0]));
    for (int n = 0; n < 4; ++n) v.beside[n] = texelFetch(e_quads, int(s.t[n + 1]));
    uint first = s.row + c.z;
    float before = texelFetch(e_cells, int(c.z > 0u ? first - 1u : first)).x;
    float after = texelFetch(e_cells, int(c.z + 4u < pc.zstride ? first + 4u : first)).x;
    v.beside[4] = vec4(before, v.here.xyz);
    v.beside[5] = vec4(v.here.yzw, after);
    return v;
}
#endif
