#version 450
#extension GL_GOOGLE_include_directive : require
// φ += e on the finest level, after a cycle (φ in float64). Rows of cells along z
// (mg_common.glsl); φ is bound twice, read and written (each cell its own).
#define MG_NO_AXIS_TABLE
#include "mg_common.glsl"
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 0) uniform usamplerBuffer phi_texels;  // a double as two words
layout(binding = 1) uniform samplerBuffer e_texels;
double phi_at(uint q) { return packDouble2x32(texelFetch(phi_texels, int(q)).xy); }
float e_at(uint q) { return texelFetch(e_texels, int(q)).x; }
#else
layout(std430, binding = 0) readonly buffer Phi { double phi[]; };
layout(std430, binding = 1) readonly buffer E { float e[]; };
double phi_at(uint q) { return phi[q]; }
float e_at(uint q) { return e[q]; }
#endif
layout(std430, binding = 2) writeonly buffer PhiOut { double phi_out[]; };

void main() {
    bool inside;
    uint p = index_of(row_cell(inside), pc.dims);
    double updated = phi_at(p) + double(e_at(p));
    if (inside) phi_out[p] = updated;
}
