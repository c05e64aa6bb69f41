#version 450
#extension GL_GOOGLE_include_directive : require
// The coarsest level: e = A⁺ r with the dense pseudo-inverse (at most 64 cells).
layout(local_size_x_id = 0) in;
layout(std430, binding = 0) readonly buffer Pinv { float pinv[]; };
layout(std430, binding = 1) readonly buffer R { float r[]; };
layout(std430, binding = 2) writeonly buffer E { float e[]; };
#include "push_constants.h"
layout(push_constant) uniform Push { CountPush pc; };  // push_constants.h

void main() {
    uint p = gl_GlobalInvocationID.x;
    if (p >= pc.count) return;
    float s = 0.0;
    for (uint q = 0; q < pc.count; ++q) s += pinv[p * pc.count + q] * r[q];
    e[p] = s;
}
