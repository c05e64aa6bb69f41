// The 7-point stencil of cell c at index p of the level in pc.dims / pc.axes_off, for mg_smooth
// and mg_residual: the couplings to its six neighbours (in the order −x, +x, −y, +y, −z, +z) and
// their indices. A coupling is the face's area (the other two axes' sizes) times the axis's
// factor toward that neighbour. Toward a missing neighbour it is 0 and the index is p itself,
// so that the kernels load all six without a branch.
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
    uint slab = d.y * d.z;
    s.q[0] = c.x > 0u ? p - slab : p;
    s.q[1] = c.x + 1u < d.x ? p + slab : p;
    s.q[2] = c.y > 0u ? p - d.z : p;
    s.q[3] = c.y + 1u < d.y ? p + d.z : p;
    s.q[4] = c.z > 0u ? p - 1u : p;
    s.q[5] = c.z + 1u < d.z ? p + 1u : p;
    return s;
}
