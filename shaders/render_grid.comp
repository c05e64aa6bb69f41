#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_vote : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_arithmetic : require
// Sphere-traces a grid of φ (trilinear between nodes) per pixel: the renderer's GPU path for
// grids (src/render/render_gpu.cpp).
layout(local_size_x_id = 0) in;
layout(constant_id = 1) const uint LOOP_CAP = 0u;  // software devices: render_march.glsl's guard; 0: none
uint lane_ticks = 0u, subgroup_ticks = 0u;  // (the field has no loops of its own)
#define TICK_LANE(n) if (LOOP_CAP > 0u) lane_ticks += uint(n)
#define TICK_UNIFORM(n) if (LOOP_CAP > 0u) subgroup_ticks += uint(n)

layout(std430, binding = 0) readonly buffer Values { float values[]; };  // GridSpec order: (i·ny + j)·nz + k

#include "push_constants.h"
layout(push_constant) uniform Push { RenderGridPush pc; };  // push_constants.h

float node(int i, int j, int k) { return values[(uint(i) * pc.ny + uint(j)) * pc.nz + uint(k)]; }

// Trilinear φ and its gradient (the derivative of the trilinear interpolant in its cell).
float field_phi(vec3 x, bool live, bool grad, out vec3 g) {
    vec3 h = vec3(pc.hx, pc.hy, pc.hz);
    vec3 s = (x - vec3(pc.x0, pc.y0, pc.z0)) / h;
    ivec3 n = ivec3(pc.nx, pc.ny, pc.nz);
    ivec3 c = clamp(ivec3(floor(s)), ivec3(0), n - 2);
    vec3 f = clamp(s - vec3(c), 0.0, 1.0);
    float v000 = node(c.x, c.y, c.z), v100 = node(c.x + 1, c.y, c.z);
    float v010 = node(c.x, c.y + 1, c.z), v110 = node(c.x + 1, c.y + 1, c.z);
    float v001 = node(c.x, c.y, c.z + 1), v101 = node(c.x + 1, c.y, c.z + 1);
    float v011 = node(c.x, c.y + 1, c.z + 1), v111 = node(c.x + 1, c.y + 1, c.z + 1);
    float a00 = mix(v000, v100, f.x), a10 = mix(v010, v110, f.x);
    float a01 = mix(v001, v101, f.x), a11 = mix(v011, v111, f.x);
    float b0 = mix(a00, a10, f.y), b1 = mix(a01, a11, f.y);
    g = vec3(0.0);
    if (grad) {
        float dx0 = mix(v100 - v000, v110 - v010, f.y), dx1 = mix(v101 - v001, v111 - v011, f.y);
        g.x = mix(dx0, dx1, f.z) / h.x;
        g.y = mix(a10 - a00, a11 - a01, f.z) / h.y;
        g.z = (b1 - b0) / h.z;
    }
    return mix(b0, b1, f.z);
}

const bool SHADE_HITS = true;  // a trilinear gradient costs little: the march writes it
#define RENDER_PARAMS_BINDING 1
#define RENDER_OUT_BINDING 2
#include "workgroup_order.glsl"  // workgroup_share
#include "render_march.glsl"

void main() { render_main(pc.first_pixel, pc.pixel_count); }
