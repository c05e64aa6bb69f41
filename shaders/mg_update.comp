#version 450
#extension GL_GOOGLE_include_directive : require
// φ += e on the finest level, after a cycle (φ in float64). Rows of cells along z
// (mg_common.glsl; the software build a quad a lane, φ read as two doubles a texel); φ is bound
// twice, read and written (each cell its own). pc.first_sweep: φ starts at 0 (the first cycle;
// φ is not cleared, so not read then).
#define MG_NO_AXIS_TABLE
#include "mg_common.glsl"
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 0) uniform usamplerBuffer phi_pairs;  // two doubles a texel
layout(binding = 1) uniform samplerBuffer e_quads;
layout(std430, binding = 2) writeonly buffer PhiOut { dvec4 phi_out[]; };

void main() {
    bool inside;
    uvec3 c = quad_cell(inside);
    uint q = quad_texel(c);  // φ and e stored alike
    dvec4 phi = pc.first_sweep != 0u ? dvec4(0.0) : double_quad(phi_pairs, q);
    dvec4 updated = phi + dvec4(texelFetch(e_quads, int(q)));
    if (inside) phi_out[q] = updated;  // the padding stays 0: its e is
}
#else
layout(std430, binding = 0) readonly buffer Phi { double phi[]; };
layout(std430, binding = 1) readonly buffer E { float e[]; };
layout(std430, binding = 2) writeonly buffer PhiOut { double phi_out[]; };
void main() {
    bool inside;
    uint p = index_of(row_cell(inside), pc.dims, pc.zstride);
    double updated = (pc.first_sweep != 0u ? 0.0 : phi[p]) + double(e[p]);
    if (inside) phi_out[p] = updated;
}
#endif
