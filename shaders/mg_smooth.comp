#version 450
#extension GL_GOOGLE_include_directive : require
// One red-black Gauss–Seidel sweep of one color: e_p = (r_p + Σ c e_q) / Σ c.
// A workgroup takes a row of cells along z (gl_WorkGroupID.z = i, .y = j) and its lanes the
// row's cells of this color (k = 2·x + parity): no division finds a cell, no lane idles on the
// other color, and the row's x and y factors of the couplings are the same on every lane (read
// once there, where llvmpipe reads an address that differs across lanes one lane at a time).
// The workgroup size must be declared before mg_common.glsl uses gl_WorkGroupSize.
layout(local_size_x_id = 0) in;
#include "mg_common.glsl"
layout(std430, binding = 0) readonly buffer Axes { AxisEntry axes[]; };
layout(std430, binding = 1) readonly buffer R { float r[]; };
layout(std430, binding = 2) buffer E { float e[]; };
#include "mg_row.glsl"

void main() {
    uvec3 d = pc.dims;
    uint i = gl_WorkGroupID.z, j = gl_WorkGroupID.y;
    uint k = 2u * gl_GlobalInvocationID.x + ((i + j + pc.color) & 1u);
    if (k >= d.z) return;
    uint p = (i * d.y + j) * d.z + k;
    Couplings c = couplings(i, j, k);
    uint slab = d.y * d.z;
    float s = r[p], diag = 0.0;
    if (i > 0u) { s += c.w[0] * e[p - slab]; diag += c.w[0]; }
    if (i + 1u < d.x) { s += c.w[1] * e[p + slab]; diag += c.w[1]; }
    if (j > 0u) { s += c.w[2] * e[p - d.z]; diag += c.w[2]; }
    if (j + 1u < d.y) { s += c.w[3] * e[p + d.z]; diag += c.w[3]; }
    if (k > 0u) { s += c.w[4] * e[p - 1u]; diag += c.w[4]; }
    if (k + 1u < d.z) { s += c.w[5] * e[p + 1u]; diag += c.w[5]; }
    if (diag > 0.0) e[p] = s / diag;
}
