#version 450
// φ += e on the finest level (float64 += float32).
layout(local_size_x_id = 0) in;
layout(std430, binding = 0) buffer Phi { double phi[]; };
layout(std430, binding = 1) readonly buffer E { float e[]; };
layout(push_constant) uniform Push { uint count; } pc;

void main() {
    uint p = gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    if (p < pc.count) phi[p] += double(e[p]);
}
