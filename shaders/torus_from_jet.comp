#version 450
#extension GL_GOOGLE_include_directive : require
// Builds tori from per-point frames and jet coefficients (mirrors gsd::torus_from_jet).
// In:  4 vec4 per point: (p, a00), (n, a10), (s, a01), (a11, a20, a02, 0)
// Out: 3 vec4 per point: (q, k1), (e1, k2), (n*, 0)
layout(local_size_x_id = 0) in;

layout(std430, binding = 0) readonly buffer Jets { vec4 jets[]; };
layout(std430, binding = 1) writeonly buffer Tori { vec4 tori[]; };
#include "push_constants.h"
layout(push_constant) uniform Push { CountPush pc; };  // push_constants.h

void main() {
    uint i = gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    if (i >= pc.count) return;
    vec4 j0 = jets[4 * i], j1 = jets[4 * i + 1], j2 = jets[4 * i + 2], j3 = jets[4 * i + 3];
    vec3 p = j0.xyz, n = j1.xyz, s = j2.xyz;
    vec3 t = cross(n, s);
    float a00 = j0.w, a10 = j1.w, a01 = j2.w, a11 = j3.x, a20 = j3.y, a02 = j3.z;

    float A = sqrt(1.0 + a10 * a10 + a01 * a01);
    float I11 = 1.0 + a10 * a10, I12 = a10 * a01;
    float B11 = 2.0 * a20 / A, B12 = a11 / A, B22 = 2.0 * a02 / A;
    float l11 = sqrt(I11);
    float la = 1.0 / l11, lb = -I12 / (l11 * A), ld = l11 / A;
    float C11 = la * la * B11;
    float C12 = la * (lb * B11 + ld * B12);
    float C22 = lb * lb * B11 + 2.0 * lb * ld * B12 + ld * ld * B22;
    float mean = 0.5 * (C11 + C22), half_diff = 0.5 * (C11 - C22);
    float gap = sqrt(half_diff * half_diff + C12 * C12);
    float big = mean >= 0.0 ? mean + gap : mean - gap;
    float small = mean >= 0.0 ? mean - gap : mean + gap;

    float w0 = C12, w1 = big - C11;
    float u0 = big - C22, u1 = C12;
    if (u0 * u0 + u1 * u1 > w0 * w0 + w1 * w1) { w0 = u0; w1 = u1; }
    if (w0 * w0 + w1 * w1 <= 1e-30) { w0 = 1.0; w1 = 0.0; }
    float v0 = la * w0 + lb * w1, v1 = ld * w1;
    vec3 el = normalize(vec3(v0, v1, v0 * a10 + v1 * a01));
    vec3 nl = vec3(-a10, -a01, 1.0) / A;

    vec3 q = p + a00 * n;
    vec3 e1 = normalize(el.x * s + el.y * t + el.z * n);
    vec3 nn = normalize(nl.x * s + nl.y * t + nl.z * n);
    tori[3 * i] = vec4(q, big);
    tori[3 * i + 1] = vec4(e1, small);
    tori[3 * i + 2] = vec4(nn, 0.0);
}
