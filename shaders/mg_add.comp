#version 450
#extension GL_GOOGLE_include_directive : require
// e += s (the F-cycle adds back the correction it set aside).
layout(local_size_x_id = 0) in;
layout(std430, binding = 0) buffer E { float e[]; };
layout(std430, binding = 1) readonly buffer S { float s[]; };
#include "push_constants.h"
layout(push_constant) uniform Push { CountPush pc; };  // push_constants.h

void main() {
    uint p = gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    if (p < pc.count) e[p] += s[p];
}
