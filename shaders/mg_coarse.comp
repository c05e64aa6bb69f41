#version 450
// The coarsest level: e = A⁺ r with the dense pseudo-inverse (at most 64 cells).
layout(local_size_x_id = 0) in;
layout(std430, binding = 0) readonly buffer Pinv { float pinv[]; };
layout(std430, binding = 1) readonly buffer R { float r[]; };
layout(std430, binding = 2) writeonly buffer E { float e[]; };
layout(push_constant) uniform Push { uint m; } pc;

void main() {
    uint p = gl_GlobalInvocationID.x;
    if (p >= pc.m) return;
    float s = 0.0;
    for (uint q = 0; q < pc.m; ++q) s += pinv[p * pc.m + q] * r[q];
    e[p] = s;
}
