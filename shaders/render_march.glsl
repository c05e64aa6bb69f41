// Sphere tracing for the field renderer (mirrors src/render/render.cpp's march_ray, which the
// tests hold this to). The including shader defines, before including this,
//   float field_phi(vec3 x, bool live, bool grad, out vec3 g)   the field (called by every lane
//   together, live = false on lanes with nothing to evaluate), and ∇φ into g when `grad`,
// RENDER_PARAMS_BINDING / RENDER_OUT_BINDING, the bindings of the two buffers below (and
// RENDER_EMPTY_BINDING, that of the empty cells, where rays may skip: render.hpp's EmptySpace),
// SHADE_HITS (a constant: true, the kernel writes ∇φ at each hit — a shading turn per hit; false,
// it writes the hit alone and the host evaluates ∇φ there, so that the march's evaluations carry
// no gradient sums: render_gpu.cpp), the specialization constant LOOP_CAP, the counters lane_ticks and subgroup_ticks and the macros
// TICK_LANE / TICK_UNIFORM that its field's loops count into (see past_loop_limit), and enables
// the subgroup vote, ballot and arithmetic extensions.
// Each ray (render_main() says how the lanes of a subgroup share them) is clipped to the box,
// then advanced by step_scale·|φ| (at least min_step) until |φ| < hit_eps, or φ changes sign
// between two steps (then bisected), or it leaves the box or runs out of steps.

struct RenderParams {
    vec4 eye;
    vec4 forward;    // unit, toward the scene
    vec4 right;      // scaled by tan(fov/2)·aspect
    vec4 up;         // scaled by tan(fov/2)
    vec4 box_min;
    vec4 box_max;
    uvec4 size;      // width, height, max_steps, bisection steps
    vec4 march;      // step_scale, hit_eps, min_step, unused
    uvec4 tile;      // rays in tile order: tile width, height (pixels); rays per lane; unused
    vec4 empty;      // the empty-space grid's low corner, cell side
    uvec4 cells;     // its cells along x, y, z; W, the words of empty bits (0: rays skip nothing)
};

layout(std430, binding = RENDER_PARAMS_BINDING) readonly buffer Params { RenderParams rp; };
// Per ray of the chunk, in tile order: (t, ∇φ at the hit; 0 unless SHADE_HITS), t < 0 for a
// miss. The host fills it with t = −2 first: a ray left so was cut short by llvmpipe's loop limit (below), and the
// host marches it on the CPU.
layout(std430, binding = RENDER_OUT_BINDING) writeonly buffer Hits { vec4 hits[]; };
#ifdef RENDER_EMPTY_BINDING
// Two bits per cell, C order: words [0, W) 1 = empty, [W, 2W) 1 = negative (render.hpp's EmptySpace).
layout(std430, binding = RENDER_EMPTY_BINDING) readonly buffer Empty { uint empty_bits[]; };

uint cell_index(ivec3 c) { return (uint(c.x) * rp.cells.y + uint(c.y)) * rp.cells.z + uint(c.z); }

bool empty_cell(ivec3 c) {
    if (any(lessThan(c, ivec3(0))) || any(greaterThanEqual(c, ivec3(rp.cells.xyz)))) return false;
    uint cell = cell_index(c);
    return ((empty_bits[cell >> 5u] >> (cell & 31u)) & 1u) != 0u;
}

bool negative_cell(ivec3 c) {
    uint cell = cell_index(c);
    return ((empty_bits[rp.cells.w + (cell >> 5u)] >> (cell & 31u)) & 1u) != 0u;
}
#endif

// Moves t on past the run of empty cells the ray o + t·d is in (a hair past the last one's
// exit), cell by cell (a 3D DDA), unless its cell's sign is not `sign` (that of φ where the ray
// last sampled it; 0: none yet); false when that takes it past span. render.hpp's
// EmptySpace::skip, which the CPU runs.
bool skip_empty(vec3 o, vec3 d, float span, inout float t, int sign) {
#ifdef RENDER_EMPTY_BINDING
    if (rp.cells.w == 0u) return true;
    float h = rp.empty.w;
    vec3 f = (o + t * d - rp.empty.xyz) / h;
    // A ray starts on the box's face, where f is 0 or n up to rounding (float32: the entry point
    // a few units from the eye is off by ~1e-6, some 3e-5 of a small cell): within a thousandth
    // of a cell of the grid it is in the cell at the face (as EmptySpace::skip; next[] comes
    // from the point itself, so the cell's planes stay right).
    vec3 n = vec3(rp.cells.xyz);
    if (!(all(greaterThanEqual(f, vec3(-1e-3))) && all(lessThanEqual(f, n + 1e-3)))) return true;
    ivec3 c = clamp(ivec3(floor(f)), ivec3(0), ivec3(rp.cells.xyz) - 1);
    if (!empty_cell(c) || (sign != 0 && negative_cell(c) != (sign < 0))) return true;
    vec3 next, delta;
    ivec3 dir;
    for (int a = 0; a < 3; ++a) {
        dir[a] = d[a] > 0.0 ? 1 : -1;
        next[a] = d[a] != 0.0 ? (rp.empty[a] + h * (float(c[a]) + (d[a] > 0.0 ? 1.0 : 0.0)) - o[a]) / d[a] : 3.0e38;
        delta[a] = d[a] != 0.0 ? h / abs(d[a]) : 3.0e38;
    }
    float exit = t;
    for (int i = 0; i < 256; ++i) {  // a ray crosses at most n_x + n_y + n_z ≤ 192 cells
        TICK_LANE(1u);
        int a = next.x <= next.y ? (next.x <= next.z ? 0 : 2) : (next.y <= next.z ? 1 : 2);
        exit = next[a];
        c[a] += dir[a];
        next[a] += delta[a];
        if (!empty_cell(c)) break;
    }
    t = max(exit, t) + 1e-4 * h;
    return t <= span;
#else
    return true;
#endif
}

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

// The pixel of ray p (tile order, src/render/render.cpp's tile_pixel): the image is cut into
// tiles of tile.x × tile.y pixels (narrower in the last column, shorter in the last row), taken
// row of tiles by row of tiles, each tile's pixels row by row. A subgroup's rays are a tile: the
// rays of its lanes start and end near one another, and their tree walks open the same nodes.
uvec2 tile_pixel(uint p) {
    uint W = rp.size.x, H = rp.size.y, TW = rp.tile.x, TH = rp.tile.y;
    uint ty = p / (W * TH), r = p - ty * (W * TH);
    uint h = min(TH, H - ty * TH);           // this row of tiles' height
    uint tiles_x = (W + TW - 1u) / TW;
    uint tx = min(r / (TW * h), tiles_x - 1u);
    uint w = tx + 1u < tiles_x ? TW : W - tx * TW;  // the last column's width
    uint off = r - tx * TW * h;
    return uvec2(tx * TW + off % w, ty * TH + off / w);
}

// A ray's march as a state machine (render.cpp's march_ray does the same arithmetic as a plain
// loop, which the tests hold this to):
const uint IDLE = 0u, FIRST = 1u, MARCH = 2u, BISECT = 3u, SHADE = 4u;
struct Ray {
    uint phase, index, s, k;  // index: the ray's place in the chunk
    bool fresh;               // the next sample follows a skip through empty cells
    vec3 o, d;                // from where it enters the box
    float t0, span, t, phi, tn, a, b, pa, hit;
};

// Starts ray `index` of the chunk; a ray that misses the box is written at once, its lane left
// idle.
void start_ray(inout Ray r, uint index, uint first_pixel) {
    uvec2 px = tile_pixel(first_pixel + index);
    vec3 d = pixel_ray(px.x, px.y);
    float t0, t1;
    bool in_box = clip_to_box(rp.eye.xyz, d, t0, t1);
    // March from where the ray enters the box, so t stays small and float steps stay exact
    // however far the camera is; t0 is added back at the end.
    r.index = index;
    r.o = rp.eye.xyz + t0 * d;
    r.d = d;
    r.t0 = t0;
    r.span = t1 - t0;
    r.t = 0.0;
    r.s = 0u;
    r.hit = -1.0;
    r.fresh = false;
    in_box = in_box && skip_empty(r.o, d, r.span, r.t, 0);
    r.phase = in_box ? FIRST : IDLE;
    if (!in_box) hits[index] = vec4(-1.0, 0.0, 0.0, 0.0);
}

// Where the ray samples φ next.
float next_sample(Ray r) {
    if (r.phase == FIRST) return r.t;
    if (r.phase == MARCH) return r.tn;
    if (r.phase == BISECT) return 0.5 * (r.a + r.b);
    if (r.phase == SHADE) return r.hit;
    return 0.0;
}

// Takes φ = p at next_sample(r); returns true when the ray has ended (hit or not).
bool advance(inout Ray r, float p) {
    if (r.phase == FIRST || r.phase == MARCH) {
        bool next = false;  // take another step from (t, phi)
        if (r.phase == FIRST) {
            r.phi = p;
            if (abs(r.phi) < rp.march.y) r.hit = r.t;
            else next = true;
        } else if (r.fresh) {
            // After a skip through empty cells, which hold no surface: a fresh start at tn.
            if (abs(p) < rp.march.y) r.hit = r.tn;
            else {
                r.t = r.tn;
                r.phi = p;
                ++r.s;
                next = true;
            }
        } else if ((p < 0.0) != (r.phi < 0.0)) {
            // Crossed the surface within the step: bisect [t, tn].
            r.a = r.t;
            r.b = r.tn;
            r.pa = r.phi;
            r.k = 0u;
            if (rp.size.w == 0u) r.hit = 0.5 * (r.a + r.b);
            else { r.phase = BISECT; return false; }
        } else if (abs(p) < rp.march.y) {
            r.hit = r.tn;
        } else {
            r.t = r.tn;
            r.phi = p;
            ++r.s;
            next = true;
        }
        if (next) {
            r.tn = r.t + max(rp.march.x * abs(r.phi), rp.march.z);
            float stepped = r.tn;
            if (r.s < rp.size.z && r.tn <= r.span && skip_empty(r.o, r.d, r.span, r.tn, r.phi < 0.0 ? -1 : 1)) {
                r.fresh = r.tn != stepped;
                r.phase = MARCH;
                return false;
            }
        }
        return true;
    }
    // BISECT
    if ((p < 0.0) == (r.pa < 0.0)) { r.a = 0.5 * (r.a + r.b); r.pa = p; } else { r.b = 0.5 * (r.a + r.b); }
    if (++r.k < rp.size.w) return false;
    r.hit = 0.5 * (r.a + r.b);
    return true;
}

// llvmpipe ends every loop of a shader, silently, once the SIMD group running it has iterated
// 65 535 times in all (docs/gpu.md): a subgroup whose rays march long through a dense tree gets
// there, and its walks would return wrong sums. On software devices (LOOP_CAP > 0) every loop
// counts its iterations — uniform ones once for the subgroup, a lane's own per lane, their sum
// over the lanes bounding what the SIMD group iterated — and the subgroup stops, writing
// nothing more, once the count passes LOOP_CAP: the rays it had not finished keep the host's
// t = −2, and the host marches them on the CPU.
bool past_loop_limit() {
    if (LOOP_CAP == 0u) return false;
    subgroup_ticks += subgroupAdd(lane_ticks) + 1u;
    lane_ticks = 0u;
    return subgroup_ticks > LOOP_CAP;
}

// A subgroup owns a block of rays (tile.z per lane: a tile, in tile order) and runs one loop
// while any of them is left: at every turn each lane without a ray takes the block's next one,
// every lane calls field_phi — live = false on an idle lane — so the field is always evaluated
// in uniform control flow and its tree walks are taken by the subgroup together, and a lane
// whose ray ended shades it (∇φ at the hit, one more turn) and takes another. With one ray a
// lane (the default, render_gpu.cpp says why) that is the tile marched together; with more, a
// lane never waits for its neighbours' longer rays while the block has rays left.
void render_main(uint first_pixel, uint pixel_count) {
    uint group = workgroup_share();  // workgroup_order.glsl: the including shader's
    uint lane0 = group * gl_WorkGroupSize.x + subgroupBroadcastFirst(gl_LocalInvocationIndex);
    uint lanes = subgroupBallotBitCount(subgroupBallot(true));
    uint next = min(lane0 * rp.tile.z, pixel_count);                // the block's next ray
    uint end = min((lane0 + lanes) * rp.tile.z, pixel_count);
    Ray r;
    r.phase = IDLE;
    r.o = vec3(0.0);
    r.d = vec3(0.0);
    vec3 g;
    while (true) {
        // Idle lanes take the next rays, in lane order; a ray that misses the box is done at once.
        while (subgroupAny(r.phase == IDLE) && next < end) {
            TICK_LANE(4u);  // clip_to_box's loop
            bool want = r.phase == IDLE;
            uvec4 wanting = subgroupBallot(want);
            uint index = next + subgroupBallotBitCount(wanting & gl_SubgroupLtMask);
            next = min(next + subgroupBallotBitCount(wanting), end);
            if (want && index < end) start_ray(r, index, first_pixel);
        }
        if (past_loop_limit() || !subgroupAny(r.phase != IDLE)) break;
        float p = field_phi(r.o + next_sample(r) * r.d, r.phase != IDLE, SHADE_HITS && r.phase == SHADE, g);
        if (past_loop_limit()) break;  // p may be cut short: this turn writes nothing
        if (r.phase == SHADE) {
            hits[r.index] = vec4(r.t0 + r.hit, g);
            r.phase = IDLE;
        } else if (r.phase != IDLE && advance(r, p)) {
            if (r.hit >= 0.0 && SHADE_HITS) r.phase = SHADE;
            else if (r.hit >= 0.0) {
                hits[r.index] = vec4(r.t0 + r.hit, 0.0, 0.0, 0.0);
                r.phase = IDLE;
            } else {
                hits[r.index] = vec4(-1.0, 0.0, 0.0, 0.0);
                r.phase = IDLE;
            }
        }
    }
}
