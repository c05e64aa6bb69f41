#version 450
#extension GL_GOOGLE_include_directive : require
// Restriction (Pᵀ): each coarse cell gathers the finer level's residual t over the product of
// its axes' gather lists (4 slots each; spare slots weigh 0). Rows of coarse cells along z
// (mg_common.glsl); pc.dims is the coarse level, pc.odims the finer.
#include "mg_common.glsl"
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 1) uniform samplerBuffer t_texels;
float t_at(uint q) { return texelFetch(t_texels, int(q)).x; }
#else
layout(std430, binding = 1) readonly buffer T { float t[]; };
float t_at(uint q) { return t[q]; }
#endif
layout(std430, binding = 2) writeonly buffer R { float rc[]; };

// Σ over the z slots of the finer level's row (ix, iy). The software build's z table holds
// where the cells are stored in their row (mg_common.glsl's blocks), not their indices.
float gather_z(uint ix, uint iy, uvec4 iz, vec4 wz) {
    uint row = (ix * pc.odims.y + iy) * pc.ozstride;
    return dot(wz, vec4(t_at(row + iz.x), t_at(row + iz.y), t_at(row + iz.z), t_at(row + iz.w)));
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
#ifdef GSD_SOFTWARE_SHAPED
    uint at = stored_cell((c.x * pc.dims.y + c.y) * pc.zstride, c.z);
#else
    uint at = index_of(c, pc.dims, pc.zstride);
#endif
    if (inside) rc[at] = s;
}
