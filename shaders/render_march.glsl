// Sphere tracing for the field renderer (mirrors src/render/render.cpp's march_ray, which the
// tests hold this to). The including shader defines, before including this,
//   float field_phi(vec3 x, bool grad, out vec3 g)   the field, and ∇φ when `grad`,
// and RENDER_PARAMS_BINDING / RENDER_OUT_BINDING, the bindings of the two buffers below.
// One invocation per pixel: its ray from the eye is clipped to the box, then advanced by
// step_scale·|φ| (at least min_step) until |φ| < hit_eps, or φ changes sign between two steps
// (then bisected), or it leaves the box or runs out of steps.

struct RenderParams {
    vec4 eye;
    vec4 forward;    // unit, toward the scene
    vec4 right;      // scaled by tan(fov/2)·aspect
    vec4 up;         // scaled by tan(fov/2)
    vec4 box_min;
    vec4 box_max;
    uvec4 size;      // width, height, max_steps, bisection steps
    vec4 march;      // step_scale, hit_eps, min_step, unused
};

layout(std430, binding = RENDER_PARAMS_BINDING) readonly buffer Params { RenderParams rp; };
// Per pixel: (t, ∇φ at the hit), t < 0 for a miss.
layout(std430, binding = RENDER_OUT_BINDING) writeonly buffer Hits { vec4 hits[]; };

vec3 pixel_ray(uint px, uint py) {
    float u = 2.0 * (float(px) + 0.5) / float(rp.size.x) - 1.0;
    float v = 1.0 - 2.0 * (float(py) + 0.5) / float(rp.size.y);
    return normalize(rp.forward.xyz + u * rp.right.xyz + v * rp.up.xyz);
}

// The ray's parameter range inside the box (slab test); false if it misses the box.
bool clip_to_box(vec3 o, vec3 d, out float t0, out float t1) {
    t0 = 0.0;
    t1 = 3.0e38;
    for (int a = 0; a < 3; ++a) {
        if (abs(d[a]) < 1e-30) {
            if (o[a] < rp.box_min[a] || o[a] > rp.box_max[a]) return false;
            continue;
        }
        float ta = (rp.box_min[a] - o[a]) / d[a], tb = (rp.box_max[a] - o[a]) / d[a];
        t0 = max(t0, min(ta, tb));
        t1 = min(t1, max(ta, tb));
    }
    return t0 <= t1;
}

vec4 march(vec3 eye, vec3 d) {
    float t0, t1;
    if (!clip_to_box(eye, d, t0, t1)) return vec4(-1.0, 0.0, 0.0, 0.0);
    // March from where the ray enters the box, so t stays small and float steps stay exact
    // however far the camera is; t0 is added back at the end.
    vec3 o = eye + t0 * d;
    float span = t1 - t0;
    vec3 g;
    float t = 0.0;
    float phi = field_phi(o, false, g);
    float hit = -1.0;
    if (abs(phi) < rp.march.y) hit = t;
    for (uint s = 0; hit < 0.0 && s < rp.size.z; ++s) {
        float tn = t + max(rp.march.x * abs(phi), rp.march.z);
        if (tn > span) break;
        float pn = field_phi(o + tn * d, false, g);
        if ((pn < 0.0) != (phi < 0.0)) {
            // Crossed the surface within the step: bisect [t, tn].
            float a = t, b = tn, pa = phi;
            for (uint k = 0; k < rp.size.w; ++k) {
                float m = 0.5 * (a + b);
                float pm = field_phi(o + m * d, false, g);
                if ((pm < 0.0) == (pa < 0.0)) { a = m; pa = pm; } else { b = m; }
            }
            hit = 0.5 * (a + b);
        } else if (abs(pn) < rp.march.y) {
            hit = tn;
        }
        t = tn;
        phi = pn;
    }
    if (hit < 0.0) return vec4(-1.0, 0.0, 0.0, 0.0);
    field_phi(o + hit * d, true, g);
    return vec4(t0 + hit, g);
}

void render_main(uint first_pixel, uint pixel_count) {
    uint i = gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    if (i >= pixel_count) return;
    uint p = first_pixel + i;
    uint px = p % rp.size.x, py = p / rp.size.x;
    hits[i] = march(rp.eye.xyz, pixel_ray(px, py));
}
