#version 450
#extension GL_GOOGLE_include_directive : require
// dst[i] = src[i] for `count` 32-bit words: copies between gsd's buffers and an application's,
// which are storage buffers and need not allow transfers (gpu::evaluate_into's host fallback).
layout(local_size_x_id = 0) in;
layout(std430, binding = 0) readonly buffer Src { uint src[]; };
layout(std430, binding = 1) writeonly buffer Dst { uint dst[]; };
#include "push_constants.h"
layout(push_constant) uniform Push { CountPush pc; };  // push_constants.h

void main() {
    const uint i = gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    if (i < pc.count) dst[i] = src[i];
}
