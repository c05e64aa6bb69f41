// Sphere tracing for the field renderer (mirrors src/render/render.cpp's march_ray, which the
// tests hold this to). The including shader defines, before including this,
//   float field_phi(vec3 x, bool grad, out vec3 g)   the field, and ∇φ when `grad`,
// and RENDER_PARAMS_BINDING / RENDER_OUT_BINDING, the bindings of the two buffers below.
// One invocation per pixel (march() says how a subgroup keeps its lanes together): its ray from
// the eye is clipped to the box, then advanced by
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

// The march as a state machine per lane — first sample, marching, bisecting, done — in a loop
// that runs while any lane of the subgroup has work: every lane calls field_phi at every turn
// (live = false once its ray is done), so the field is always evaluated in uniform control
// flow and its tree walks are taken by the subgroup together. Each lane does the arithmetic the
// plain loop did (render.cpp's march_ray): the same samples, the same hits.
vec4 march(vec3 eye, vec3 d, bool valid) {
    const uint FIRST = 0u, MARCH = 1u, BISECT = 2u, DONE = 3u;
    float t0 = 0.0, t1 = 0.0;
    bool inside = valid && clip_to_box(eye, d, t0, t1);
    // March from where the ray enters the box, so t stays small and float steps stay exact
    // however far the camera is; t0 is added back at the end.
    vec3 o = eye + t0 * d;
    float span = t1 - t0;
    vec3 g;
    uint phase = inside ? FIRST : DONE;
    float t = 0.0, phi = 0.0, tn = 0.0, a = 0.0, b = 0.0, pa = 0.0, hit = -1.0;
    uint s = 0u, k = 0u;
    while (subgroupAny(phase != DONE)) {
        float at = phase == FIRST ? 0.0 : (phase == MARCH ? tn : 0.5 * (a + b));
        float p = field_phi(o + at * d, phase != DONE, false, g);
        if (phase == FIRST || phase == MARCH) {
            bool next = false;  // take another step from (t, phi)
            if (phase == FIRST) {
                phi = p;
                if (abs(phi) < rp.march.y) hit = 0.0;
                else next = true;
            } else if ((p < 0.0) != (phi < 0.0)) {
                // Crossed the surface within the step: bisect [t, tn].
                a = t;
                b = tn;
                pa = phi;
                k = 0u;
                if (rp.size.w == 0u) hit = 0.5 * (a + b);
                else phase = BISECT;
            } else if (abs(p) < rp.march.y) {
                hit = tn;
            } else {
                t = tn;
                phi = p;
                ++s;
                next = true;
            }
            if (next) {
                tn = t + max(rp.march.x * abs(phi), rp.march.z);
                phase = (s < rp.size.z && tn <= span) ? MARCH : DONE;
            } else if (phase != BISECT) {
                phase = DONE;
            }
        } else if (phase == BISECT) {
            if ((p < 0.0) == (pa < 0.0)) { a = 0.5 * (a + b); pa = p; } else { b = 0.5 * (a + b); }
            if (++k >= rp.size.w) {
                hit = 0.5 * (a + b);
                phase = DONE;
            }
        }
    }
    bool got = hit >= 0.0;
    field_phi(o + max(hit, 0.0) * d, got, true, g);  // ∇φ at the hit, again by every lane
    if (!got) return vec4(-1.0, 0.0, 0.0, 0.0);
    return vec4(t0 + hit, g);
}

void render_main(uint first_pixel, uint pixel_count) {
    uint i = gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    bool valid = i < pixel_count;  // lanes past the end take part in the walks, idle
    uint p = first_pixel + min(i, pixel_count - 1u);
    uint px = p % rp.size.x, py = p / rp.size.x;
    vec4 h = march(rp.eye.xyz, pixel_ray(px, py), valid);
    if (valid) hits[i] = h;
}
