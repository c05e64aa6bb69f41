// The couplings of cell (i, j, k) to its six neighbours on the level of pc.dims / pc.axes_off
// (mg_common.glsl's coupling(), in the order −x, +x, −y, +y, −z, +z), for the kernels that take
// a row of cells along z per workgroup (mg_smooth, mg_residual). A coupling across a face is the
// face's area (the other two axes' sizes) over the distance between the two cells' centers,
// times 1/Δ² of its axis. Couplings to missing neighbours are left unset; callers test bounds.
// Requires `AxisEntry axes[]` declared by the including shader.
struct Couplings { float w[6]; };

float axis_size(uint a, uint c) { return axes[pc.axes_off[a] + c].size; }

Couplings couplings(uint i, uint j, uint k) {
    uvec3 d = pc.dims;
    float sx = axis_size(0u, i), sy = axis_size(1u, j), sz = axis_size(2u, k);
    Couplings c;
    if (i > 0u) c.w[0] = sy * sz / (0.5 * (axis_size(0u, i - 1u) + sx)) * pc.inv_h2.x;
    if (i + 1u < d.x) c.w[1] = sy * sz / (0.5 * (sx + axis_size(0u, i + 1u))) * pc.inv_h2.x;
    if (j > 0u) c.w[2] = sz * sx / (0.5 * (axis_size(1u, j - 1u) + sy)) * pc.inv_h2.y;
    if (j + 1u < d.y) c.w[3] = sz * sx / (0.5 * (sy + axis_size(1u, j + 1u))) * pc.inv_h2.y;
    if (k > 0u) c.w[4] = sx * sy / (0.5 * (axis_size(2u, k - 1u) + sz)) * pc.inv_h2.z;
    if (k + 1u < d.z) c.w[5] = sx * sy / (0.5 * (sz + axis_size(2u, k + 1u))) * pc.inv_h2.z;
    return c;
}
