#version 450
#extension GL_GOOGLE_include_directive : require
// Restriction (Pᵀ): each coarse cell gathers the finer level's residual t over the product of
// its axes' gather lists (4 slots each; spare slots weigh 0). pc.dims is the coarse level,
// pc.odims the finer. The GPUs' build takes rows of coarse cells along z (mg_common.glsl), a
// cell a lane; the software build a coarse quad a lane (below).
#include "mg_common.glsl"
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 1) uniform samplerBuffer t_quads;
layout(std430, binding = 2) writeonly buffer R { vec4 rc_quads[]; };

// A coarse quad's cells K = 8B + p + 2m (m = 0 … 3; parity p) gather fine cells 2K − 1 … 2K + 2
// along z, which lie in fine cells 16B − 1 … 16B + 16: the texels 4B − 1 … 4B + 4 of a fine row
// (its blocks 2B and 2B + 1 whole, the last cell before them and the first after). The z table
// of this build holds, for coarse cell K, the weights of fine cells 2K − 1 + j (j = 0 … 3) at
// their fixed places. So a lane sums its 16 fine rows' six texels, weighted in x and y, and
// then combines the six along z for its four cells. Texels outside the fine row are clamped
// into it: the cells there weigh 0 (and t is finite everywhere, its padding 0).
void main() {
    bool inside;
    uvec3 c = quad_cell(inside);
    uint b = c.z >> 1u, quads = pc.ozstride / 4u;
    uvec4 ix = uvec4(axis_cell(0u, c.x, 2u)), iy = uvec4(axis_cell(1u, c.y, 2u));
    vec4 wx = axis_cell(0u, c.x, 3u), wy = axis_cell(1u, c.y, 3u);
    // t is 0 on the fine cells of color pc.color (mg_residual.comp stores them so): in fine row
    // (fi, fj) the quads of cells k with k ≡ fi + fj + pc.color (mod 2). Texel 4b − 1 + s holds
    // cells k ≡ s + 1, so the row's other three texels are s ≡ fi + fj + pc.color: only those
    // are read (the sums are the same, to the bit: the others would add 0).
    vec4 w[6];
    for (int s = 0; s < 6; ++s) w[s] = vec4(0.0);
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            float wij = wx[i] * wy[j];
            uint row = (ix[i] * pc.odims.y + iy[j]) * quads;
            bool odd_first = ((ix[i] + iy[j] + pc.color) & 1u) != 0u;  // s = 1, 3, 5, else 0, 2, 4
            for (int m = 0; m < 3; ++m) {
                int s = 2 * m + (odd_first ? 1 : 0);
                vec4 v = wij * texelFetch(t_quads, int(row + uint(clamp(int(4u * b) - 1 + s, 0, int(quads) - 1))));
                w[2 * m] += odd_first ? vec4(0.0) : v;
                w[2 * m + 1] += odd_first ? v : vec4(0.0);
            }
        }
    // v[d + 1]: fine cell 16B + d (d = −1 … 16) of the summed row.
    float v[18];
    v[0] = w[0].w;
    for (int k = 0; k < 4; ++k) {
        v[1 + 2 * k] = w[1][k];   // block 2B: its even cells, then its odd ones
        v[2 + 2 * k] = w[2][k];
        v[9 + 2 * k] = w[3][k];   // block 2B + 1
        v[10 + 2 * k] = w[4][k];
    }
    v[17] = w[5].x;
    uvec4 k = quad_cells(c.z);
    bool odd = (c.z & 1u) != 0u;
    vec4 r;
    for (int m = 0; m < 4; ++m) {
        vec4 wz = axis_cell(2u, min(k[m], pc.dims.z - 1u), 3u);
        // fine cells 2K − 1 … 2K + 2 = 16B + 2p + 4m − 1 …: v[2p + 4m …]
        float even_sum = dot(wz, vec4(v[4 * m], v[4 * m + 1], v[4 * m + 2], v[4 * m + 3]));
        float odd_sum = dot(wz, vec4(v[4 * m + 2], v[4 * m + 3], v[4 * m + 4], v[4 * m + 5]));
        r[m] = odd ? odd_sum : even_sum;
    }
    if (inside) rc_quads[quad_texel(c)] = mix(vec4(0.0), r, lessThan(k, uvec4(pc.dims.z)));  // the padding: 0
}
#else
layout(std430, binding = 1) readonly buffer T { float t[]; };
layout(std430, binding = 2) writeonly buffer R { float rc[]; };

// Σ over the z slots of the finer level's row (ix, iy).
float gather_z(uint ix, uint iy, uvec4 iz, vec4 wz) {
    uint row = (ix * pc.odims.y + iy) * pc.ozstride;
    return dot(wz, vec4(t[row + iz.x], t[row + iz.y], t[row + iz.z], t[row + iz.w]));
}

// Σ over the y and z slots of the finer level's slab ix.
float gather_yz(uint ix, uvec4 iy, vec4 wy, uvec4 iz, vec4 wz) {
    return dot(wy, vec4(gather_z(ix, iy.x, iz, wz), gather_z(ix, iy.y, iz, wz), gather_z(ix, iy.z, iz, wz),
                        gather_z(ix, iy.w, iz, wz)));
}

void main() {
    bool inside;
    uvec3 c = row_cell(inside);
    uvec4 ix = uvec4(axis_cell(0u, c.x, 2u)), iy = uvec4(axis_cell(1u, c.y, 2u)), iz = uvec4(axis_cell(2u, c.z, 2u));
    vec4 wx = axis_cell(0u, c.x, 3u), wy = axis_cell(1u, c.y, 3u), wz = axis_cell(2u, c.z, 3u);
    float s = dot(wx, vec4(gather_yz(ix.x, iy, wy, iz, wz), gather_yz(ix.y, iy, wy, iz, wz),
                           gather_yz(ix.z, iy, wy, iz, wz), gather_yz(ix.w, iy, wy, iz, wz)));
    if (inside) rc[index_of(c, pc.dims, pc.zstride)] = s;
}
#endif
