#version 450
#extension GL_GOOGLE_include_directive : require
// SHM step 1–2 at a batch of points (mirrors CpuEvaluator in src/shm/diffuse.cpp): find the
// nearest source (r_min), then sum A_j N_j exp(−λ(r_j − r_min)) / max(r_j, r_floor) over the
// sources with r_j ≤ r_min + cutoff/λ, and normalize.
#include "box_tree.glsl"

layout(local_size_x_id = 0) in;

const int STACK = 48;

layout(std430, binding = 0) readonly buffer Points { vec4 pts[]; };    // source positions, tree order
layout(std430, binding = 1) readonly buffer Vectors { vec4 vecs[]; };  // A_j N_j, tree order
layout(std430, binding = 2) readonly buffer Nodes { Node nodes[]; };
layout(std430, binding = 3) readonly buffer Queries { vec4 qs[]; };
layout(std430, binding = 4) writeonly buffer Out { vec4 outv[]; };     // (Y, r_min), (terms, 0, 0, 0)

layout(push_constant) uniform Push {
    uint count;
    uint first_leaf;
    float lambda;
    float cutoff;
    float r_floor;
} pc;

float nearest_distance(vec3 x) {
    float best2 = 3.0e38;
    uint stack[STACK];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        uint i = stack[--top];
        if (box_distance2(x, nodes[i].lo, nodes[i].hi) >= best2) continue;
        if (i >= pc.first_leaf) {
            for (uint j = nodes[i].begin; j < nodes[i].end; ++j) {
                vec3 d = x - pts[j].xyz;
                best2 = min(best2, dot(d, d));
            }
        } else {
            uint l = 2 * i + 1, r = 2 * i + 2;
            bool left_first = box_distance2(x, nodes[l].lo, nodes[l].hi) <= box_distance2(x, nodes[r].lo, nodes[r].hi);
            stack[top++] = left_first ? r : l;
            stack[top++] = left_first ? l : r;
        }
    }
    return sqrt(best2);
}

void main() {
    uint q = gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    if (q >= pc.count) return;
    vec3 x = qs[q].xyz;
    float rmin = nearest_distance(x);
    float R = rmin + pc.cutoff / pc.lambda;
    float R2 = R * R;
    vec3 X = vec3(0.0);
    uint terms = 0;
    uint stack[STACK];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        uint i = stack[--top];
        if (box_distance2(x, nodes[i].lo, nodes[i].hi) > R2) continue;
        if (i >= pc.first_leaf) {
            for (uint j = nodes[i].begin; j < nodes[i].end; ++j) {
                vec3 d = x - pts[j].xyz;
                float r2 = dot(d, d);
                if (r2 > R2) continue;
                float r = sqrt(r2);
                X += vecs[j].xyz * (exp(-pc.lambda * (r - rmin)) / max(r, pc.r_floor));
                ++terms;
            }
        } else {
            stack[top++] = 2 * i + 1;
            stack[top++] = 2 * i + 2;
        }
    }
    float len = length(X);
    outv[2 * q] = vec4(len > 0.0 ? X / len : vec3(0.0), rmin);
    outv[2 * q + 1] = vec4(float(terms), 0.0, 0.0, 0.0);
}
