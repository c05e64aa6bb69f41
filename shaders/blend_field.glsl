// The blend engine's per-query sums (mirrors src/blend/blend_cpu.cpp), shared by blend_eval.comp
// and the renderer (render_pat.comp). The including shader declares, before including this:
// the KIND specialization constant (0 PAT, 1 SSPD, 2 SHC), the tree's buffers through
// box_tree_buffers.glsl (points in tree order, terms — PAT: 3 per point; else (n, area) — and
// nodes), and the push constants `pc`
// (point_count, first_leaf, k_fallback, r_eval, C, dmin) and the SHARED_KNN specialization
// constant, and enables GL_KHR_shader_subgroup_vote and GL_KHR_shader_subgroup_ballot.
const int K_MAX = 32;     // largest fallback_k the kernel supports
const int STACK = 48;     // kd-tree depth bound (2^48 leaves)
const float PI = 3.14159265358979;
// PAT's terms that cannot count are left out (KIND 0): a point's weight is
// e^(−λ(d − σ))·T(d/ρ) with λ = 2C/ρ and T decreasing, so against the nearest summed point's
// (at d₁) it is at most e^(−λ(d − d₁)); past d₁ + PRUNE/λ a term weighs under e^(−PRUNE) of the
// largest, below float32's resolution of the sums even with thousands of them (φ = G/W is a
// weighted mean: each term moves it by at most its weight share times |g − φ|, and ∇φ's sums
// carry the same factor e^(−λd); its taper-derivative terms too, and they are left out only
// where d₁ + PRUNE/λ < ρ, i.e. T(d₁/ρ) ≥ 0.017 at C ≤ 87, so each stays under 5e-9 of the
// nearest's weight). With C = 64 that is d₁ + 0.19ρ: a handful of tori where the ball of
// r_eval (8 spacings) holds tens to hundreds and the fallback 32. Where the walk meets the
// nearest point late (the subgroup's shared walk on GPUs) fewer are left out, never one that
// counts. Not SSPD (area weights scale its terms) nor SHC (a signed sum whose scale is its value).
const float PRUNE = 24.0;

#define KNN_MAX K_MAX
#include "box_tree_knn.glsl"
// TICK_UNIFORM(n), if the includer defines it, counts the subgroup's loop iterations in uniform
// control flow, TICK_LANE(n) a lane's own (render_march.glsl: llvmpipe's loop limit).
#ifndef TICK_UNIFORM
#define TICK_UNIFORM(n)
#endif

// Running sums, as in src/blend/blend_cpu.cpp: w = e·T(d/ρ), q = e·T'(d/ρ), e = A·exp(−λ(d − ref))
// (ref: weight_ref; the CPU's σ).
struct Acc { float W, G, D, GD, QD, QGD, shc; vec3 Gg, U, GU, QU, QGU; };

Acc acc_zero() { return Acc(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0)); }

// Where the weights' exponent is 0 (add_term's `ref`). SHC's value depends on the scale of its
// sum, so its terms are e^(−λ(d − σ)) as the thesis writes them. PAT's and SSPD's φ and ∇φ are
// ratios of sums linear in the weights, so any common factor cancels, and they take the
// nearest summed point's distance: every weight is then at most 1 (no sum of e^C, near 3.4e38
// at the largest C, overflows float32) and the nearest's is not below its taper's floor (where
// every weight is tapered to nothing, e^(−C) of it would have underflowed).
float weight_ref(float sigma, float nearest) { return KIND == 2 ? sigma : nearest; }

// The sums times f (the reference moved: e^(−λ(d − ref)) → e^(−λ(d − ref'))·…).
void acc_scale(inout Acc a, float f) {
    a.W *= f; a.G *= f; a.D *= f; a.GD *= f; a.QD *= f; a.QGD *= f; a.shc *= f;
    a.Gg *= f; a.U *= f; a.GU *= f; a.QU *= f; a.QGU *= f;
}

// Moves the sums' reference down to `nearest` when it is nearer than `ref` (PAT, SSPD: a lane's
// running nearest summed point; a reference of +∞ scales sums of nothing by 0).
void acc_rebase(inout Acc a, inout float ref, float nearest, float lambda) {
    if (KIND == 2) return;
    bool moves = nearest < ref;
    float f = exp(-lambda * (ref - nearest));
    acc_scale(a, moves ? f : 1.0);
    ref = moves ? nearest : ref;
}

// The taper T(v) = (1 − v²)³ + 1e-9 and its derivative (blend_taper in blend.hpp).
float taper(float v) { float a = 1.0 - min(v * v, 1.0); return a * a * a + 1e-9; }
float taper_derivative(float v) { float a = 1.0 - min(v * v, 1.0); return -6.0 * v * a * a; }

// Adds point p with term data t0..t2 (PAT: the torus; else t0 = (n, area)) at distance d, with
// e = e^(−λ(d − ref)) (ref: weight_ref).
void add_term(inout Acc a, vec3 x, vec3 p, vec4 t0, vec4 t1, vec4 t2, float d, float lambda, float ref,
              float rho, bool tapered, bool grad) {
    float v = d / rho;
    float t = tapered ? taper(v) : 1.0;
    if (KIND == 2) {  // not tapered: SHC depends on the scale of its sum (blend_cpu.cpp)
        float dd = max(d, pc.dmin);
        a.shc += t0.w * (lambda * dd + 1.0) * dot(x - p, t0.xyz) / (2.0 * PI * dd * dd * dd) *
                 exp(-lambda * (dd - ref));
        return;
    }
    float g, scale;
    vec3 gg;
    if (KIND == 0) {
        g = torus_sdf(t0, t1, t2, x, gg);
        scale = 1.0;
    } else {
        g = dot(x - p, t0.xyz);
        gg = t0.xyz;
        scale = t0.w;
    }
    float e = scale * exp(-lambda * (d - ref));
    float w = e * t;
    a.W += w;
    a.G += w * g;
    if (grad) {
        vec3 u = d > 0.0 ? (x - p) / d : vec3(0.0);
        a.Gg += w * gg;
        a.U += w * u;
        a.GU += w * g * u;
        a.D += w * d;
        a.GD += w * g * d;
        if (tapered) {
            float q = e * taper_derivative(v);
            a.QU += q * u;
            a.QGU += q * g * u;
            a.QD += q * d;
            a.QGD += q * g * d;
        }
    }
}

// Point j's term data (PAT: its torus in t0..t2; else t0 = (n, area)).
void point_terms(uint j, out vec4 t0, out vec4 t1, out vec4 t2) {
    t1 = vec4(0.0);
    t2 = vec4(0.0);
    if (KIND == 0) { t0 = term_at(3 * j); t1 = term_at(3 * j + 1); t2 = term_at(3 * j + 2); }
    else t0 = term_at(j);
}

void add_point(inout Acc a, vec3 x, uint j, float d, float lambda, float ref, float rho, bool tapered, bool grad) {
    vec4 t0, t1, t2;
    point_terms(j, t0, t1, t2);
    add_term(a, x, point_at(j).xyz, t0, t1, t2, d, lambda, ref, rho, tapered, grad);
}

// Sums the ball of radius r_eval with ρ = r_eval (constant λ); returns how many points it held.
// The subgroup walks the tree together (as sums_winding.comp does): a node is opened when any
// lane's ball meets its box, and a leaf's points are read once for the subgroup, each lane
// adding those within its own ball. With queries in Morton order (blend_gpu.cpp) the lanes are
// neighbours and their balls open nearly the same nodes; no lane waits on another's branch, and
// no stack is needed: the tree is complete, so the next node in depth-first order comes from the
// node's index (climb while it is a right child, then step to its sibling).
// Call it from uniform control flow (every lane of the subgroup), with live = false on lanes
// that have nothing to evaluate: subgroup votes in divergent control flow are where llvmpipe
// (Mesa 22.3) went wrong, and a walk taken together needs every lane anyway.
#ifdef GSD_SOFTWARE_SHAPED
// sum_ball shaped for llvmpipe (the kernels software devices run: docs/gpu.md, "Kernels shaped
// for software devices"), which runs a loop's body at least once and an if's body whatever the
// lanes decide: the walk above paid a leaf's point at every node it visited. Here each lane
// walks the tree on its own (stackless, the nearer child first: nearer_first_step) and only
// lists the leaves its ball meets, every lane writing its entry (the count says which hold);
// every BALL_ROUND steps the listed leaves' points are summed in loops of their own. The same
// set as the walk above up to PAT's pruning, whose running nearest comes sooner in this order;
// the order of the sums differs. Needs GL_KHR_shader_subgroup_arithmetic.
// PAT's walk stops opening the ball's far side once the ball is known to hold k points: past
// the reach of the terms that count a leaf adds nothing to the sums, and the count only decides
// the fallback; φ is bit-identical. Short rounds let that reach close in sooner. With rounds of
// 8 steps (32 before): the kernel a third faster on the queries of a picture of snail.ply's
// PAT field, 12–15 % on holey-bunny's, 2–5 % on tooth's (half of whose time is the fallback's).
const uint BALL_ROUND = 8u;

// Points [first, first + n) of a leaf's `count` from `begin` whose squared distance to x is at
// most bound2, as bits by their offset from `first` (n ≤ 32). A lane with fewer points reads its
// last one again.
uint mark_points(vec3 x, uint begin, uint count, uint first, uint n, float bound2) {
    uint bits = 0u;
    for (uint j = 0u; j < n; ++j) {
        vec3 dv = x - point_at(begin + min(first + j, max(count, 1u) - 1u)).xyz;
        bits |= first + j < count && dot(dv, dv) <= bound2 ? 1u << j : 0u;
    }
    return bits;
}

// mark_points for sum_ball: the points within the ball (bits, returned) and, of those, the ones
// within `cut` of the nearest point the lane has met so far (summed), its squared distance
// kept in near2 and the bound's square in reach2 (KIND 0; else cut is +∞ and every point in
// the ball is summed). Points met before a nearer one stay summed: the bound only ever shrinks.
uint mark_ball(vec3 x, uint begin, uint count, uint first, uint n, float r2, float cut, inout float near2,
               inout float reach2, out uint summed) {
    uint bits = 0u;
    summed = 0u;
    for (uint j = 0u; j < n; ++j) {
        vec3 dv = x - point_at(begin + min(first + j, max(count, 1u) - 1u)).xyz;
        float d2 = dot(dv, dv);
        bool in_ball = first + j < count && d2 <= r2;
        bool nearer = in_ball && d2 < near2;
        float reach = KIND == 0 ? sqrt(d2) + cut : 3.0e38;  // (no root where nothing is pruned)
        near2 = nearer ? d2 : near2;
        reach2 = nearer ? reach * reach : reach2;
        bits |= in_ball ? 1u << j : 0u;
        summed |= in_ball && d2 <= reach2 ? 1u << j : 0u;
    }
    return bits;
}

// The offset of a lane's next marked point, taken off its mask; −1 when it has no more.
int take_next(inout uint bits) {
    int j = findLSB(bits);
    bits &= bits - 1u;
    return j;
}

// One step of the stackless walk that takes the nearer child first (sum_ball and knn_listed on
// software devices): into the nearer child when `descend`, else past the children it took
// second (`trail`: a bit per level of the path, aligned with the bits of the node's 1-based
// index, set where it took the right child first) to the sibling of the first one it meets.
// node_d2 becomes the new node's squared box distance; false when the walk is over.
bool nearer_first_step(vec3 x, bool descend, inout uint node, inout uint trail, inout float node_d2) {
    uint k1 = node + 1u;
    int depth = findMSB(k1);
    uint second = (k1 ^ trail) & ((1u << uint(depth)) - 1u);
    int up = descend ? 0 : findLSB(~second);
    bool walking = descend || up < depth;
    uint next = walking ? ((k1 >> uint(up)) ^ 1u) - 1u : 0u;
    // The boxes of the children, or twice that of the next node.
    uint a = descend ? 2u * node + 1u : next, b = descend ? a + 1u : next;
    float da = node_distance2(x, a), db = node_distance2(x, b);
    bool right_first = db < da;
    node = descend && right_first ? b : a;
    node_d2 = descend && right_first ? db : da;
    trail = descend ? 2u * trail + (right_first ? 1u : 0u) : trail >> uint(up);
    return walking;
}

uint sum_ball(vec3 x, bool live, inout Acc a, bool grad) {
    const float r_eval = pc.r_eval, r2 = r_eval * r_eval;  // push constants: read outside the loops
    const float sigma = 0.5 * r_eval, lambda = pc.C / sigma;
    const uint first_leaf = pc.first_leaf;
    // PAT prunes (PRUNE above), so the walk takes the nearer child first, as knn_listed's does
    // (`trail`: which levels of the path took the right child first): the first leaves it
    // lists hold the nearest points, and the bound is tight from the start.
    const float cut = KIND == 0 ? PRUNE / lambda : 3.0e38;
    const uint k = pc.k_fallback;
    float near2 = 3.0e38, reach2 = 3.0e38, ref = weight_ref(sigma, 3.0e38);
    uint found = 0u, node = 0u, trail = 0u;
    float node_d2 = node_distance2(x, 0u);
    bool walking = live;
    uint opened[BALL_ROUND];
    while (true) {
        TICK_UNIFORM(BALL_ROUND + 2u);
        uint n_opened = 0u;
        // Once the ball is known to hold k points (no fallback), only the nodes within the
        // reach of the terms that count can add to the sums: the walk skips the rest of the ball.
        const float open2 = found >= k ? min(r2, reach2) : r2;
        // Every lane takes every step, a lane whose walk is over idly: under a lane mask
        // llvmpipe would store `opened` lane by lane, reloading each masked-off lane's old value
        // first (docs/gpu.md, "Kernels shaped for software devices"). Its store goes past its count.
        for (uint step = 0u; step < BALL_ROUND; ++step) {
            bool near = walking && node_d2 <= open2;
            bool leaf = node >= first_leaf;
            opened[n_opened] = node;
            n_opened += near && leaf ? 1u : 0u;
            walking = nearer_first_step(x, near && !leaf, node, trail, node_d2) && walking;
        }
        uint passes = subgroupMax(n_opened);
        TICK_UNIFORM(passes + 1u);
        for (uint i = 0u; i < passes; ++i) {
            uint leaf = i < n_opened ? opened[min(i, BALL_ROUND - 1u)] : 0u;  // (unset past the count)
            uint begin = node_begin(leaf), count = i < n_opened ? node_end(leaf) - begin : 0u;
            uint longest = subgroupMax(count);
            TICK_UNIFORM((longest + 31u) / 32u + 1u);
            // 32 points at a time: the ones in the ball as bits, then those summed in a loop
            // that runs to the most any lane has (a point's terms are read only if it counts).
            for (uint first = 0u; first < longest; first += 32u) {
                uint n = min(longest - first, 32u);
                TICK_UNIFORM(n + 1u);
                uint bits;
                found += uint(bitCount(mark_ball(x, begin, count, first, n, r2, cut, near2, reach2, bits)));
                acc_rebase(a, ref, sqrt(near2), lambda);
                uint rounds = subgroupMax(uint(bitCount(bits)));
                TICK_UNIFORM(rounds + 1u);
                for (uint r = 0u; r < rounds; ++r) {
                    int j = take_next(bits);
                    uint p = begin + first + uint(max(j, 0));
                    vec3 pp = point_at(p).xyz, dv = x - pp;
                    vec4 t0, t1, t2;
                    point_terms(p, t0, t1, t2);
                    if (j >= 0) {
                        add_term(a, x, pp, t0, t1, t2, sqrt(dot(dv, dv)), lambda, ref, r_eval, true, grad);
                    }
                }
            }
        }
        if (!subgroupAny(walking)) break;
    }
    return found;
}
#else
uint sum_ball(vec3 x, bool live, inout Acc a, bool grad) {
    float r2 = pc.r_eval * pc.r_eval;
    float sigma = 0.5 * pc.r_eval, lambda = pc.C / sigma;
    float ref = weight_ref(sigma, 3.0e38), cut = PRUNE / lambda;
    const uint k_points = pc.k_fallback;
    uint found = 0;
    uint node = 0u;
    while (true) {
        TICK_UNIFORM(1u);
        // PAT, once the ball holds k points: only nodes within the reach can add to the sums
        // (as the software build's walk above). The points are tested against the reach itself
        // (d = sqrt(d²), not correctly rounded on every GPU), the nodes against its square: a
        // margin far above their roundings keeps every point the test sums in a node opened.
        float reach = ref + cut, open2 = KIND == 0 && found >= k_points ? min(r2, reach * reach * 1.0001) : r2;
        bool near = live && node_distance2(x, node) <= open2;
        if (subgroupAny(near)) {
            if (node < pc.first_leaf) {
                node = 2u * node + 1u;
                continue;
            }
            TICK_UNIFORM(node_end(node) - node_begin(node) + 1u);
            for (uint j = node_begin(node); j < node_end(node); ++j) {
                vec3 dv = x - point_at(j).xyz;
                float d2 = dot(dv, dv);
                if (near && d2 <= r2) {
                    float d = sqrt(d2);
                    if (d < ref) acc_rebase(a, ref, d, lambda);  // (divergent here anyway)
                    // PAT: past the nearest point so far + PRUNE/λ a term cannot count.
                    if (KIND != 0 || d <= ref + cut) add_point(a, x, j, d, lambda, ref, pc.r_eval, true, grad);
                    ++found;
                }
            }
        }
        uint k = node + 1u;  // 1-based: right children odd
        k >>= uint(findLSB(~k));
        if (k == 0u) break;
        node = k;
    }
    return found;
}
#endif

// The k ≤ K_MAX nearest points to x (distances kd, tree-order indices ki, nearest first) for
// the fallback, the subgroup walking together (SHARED_KNN = 1, hardware GPUs): a node is opened
// when any lane's current k-th distance reaches it, children in the order most of the lanes
// that search prefer, and each lane keeps its own list (a node a lane's list has passed holds
// nothing nearer for it: the boxes nest). Each lane ends with its own k nearest; only points
// tied at the k-th distance may differ from box_tree_knn.glsl's, and those weigh T(1) ≈ 1e-9.
// Not on software devices: lanes far apart walk the union of their searches, which on
// llvmpipe can pass its loop limit of 65 535 iterations. Uniform control flow, as sum_ball.
void knn_together(vec3 x, bool live, uint k, out float kd[K_MAX], out uint ki[K_MAX]) {
    for (int m = 0; m < K_MAX; ++m) { kd[m] = 3.0e38; ki[m] = 0u; }
    uint stack[STACK];
    int top = 0;
    stack[top++] = 0u;
    while (top > 0) {
        TICK_UNIFORM(1u);
        uint i = stack[--top];
        float worst = kd[k - 1u];
        bool need = live && node_distance2(x, i) <= worst * worst;
        if (!subgroupAny(need)) continue;
        if (i >= pc.first_leaf) {
            TICK_UNIFORM(node_end(i) - node_begin(i) + 1u);
            for (uint j = node_begin(i); j < node_end(i); ++j) {
                float d = distance(x, point_at(j).xyz);
                if (!need || d >= kd[k - 1u]) continue;
                TICK_LANE(1);
                int m = int(k) - 1;
                while (m > 0 && kd[m - 1] > d) { TICK_LANE(1); kd[m] = kd[m - 1]; ki[m] = ki[m - 1]; --m; }
                kd[m] = d;
                ki[m] = j;
            }
        } else {
            uint l = 2u * i + 1u, r = 2u * i + 2u;
            bool prefers_left = node_distance2(x, l) <= node_distance2(x, r);
            uint left = subgroupBallotBitCount(subgroupBallot(need && prefers_left));
            uint right = subgroupBallotBitCount(subgroupBallot(need && !prefers_left));
            bool left_first = left >= right;
            stack[top++] = left_first ? r : l;  // the nearer child is popped first
            stack[top++] = left_first ? l : r;
        }
    }
}

#ifdef GSD_SOFTWARE_SHAPED
// The k-nearest fallback shaped for llvmpipe (docs/gpu.md, "Kernels shaped for software
// devices"). knn() keeps its stack and its list in private arrays indexed per lane, which
// llvmpipe reads and writes one lane at a time, and shifts the list at each lane's own place.
// Here the list lives in registers: K_MAX slots, sorted, with constant indices only; a k < K_MAX
// list takes the last k slots, the first ones holding −1 (nothing passes them). Each lane walks
// the tree on its own, depth first and the nearer child first as knn() does, but with no stack:
// `trail` holds, for each level of its path (aligned with the bits of the node's 1-based index),
// whether it took the right child first, so the walk climbs past the children it took second
// and steps to the sibling of the first one it meets. It lists the leaves that its current k-th
// distance reaches; every KNN_ROUND steps the listed leaves' points nearer than it are
// inserted, in loops of their own. The same k nearest as knn(), out in kd, ki from index
// K_MAX − k on, nearest first; only points tied at the k-th distance may differ, and those weigh
// T(1) ≈ 1e-9.

// The k-nearest walk's round is shorter than the ball's: a leaf is listed against the k-th
// distance as the last round left it, so short rounds list fewer leaves the list no longer
// needs (8 against 32: the kernel 10 % faster on far queries of a 2048-point cloud).
const uint KNN_ROUND = 8u;

// Inserts distance c of point ci into the sorted list (d, id): from the first slot it goes
// before, every later entry moves down one, as knn() shifts them (so among equal distances the
// entry found first stays first, and the one pushed out is the last). A candidate at +∞
// changes nothing.
void list_insert(inout float d[K_MAX], inout uint id[K_MAX], float c, uint ci) {
    [[unroll]] for (int s = 0; s < K_MAX; ++s) {
        // c carries the entry being placed: the candidate, then each one it moved down.
        float ds = d[s];
        uint is = id[s];
        bool before = c < ds;
        d[s] = min(c, ds);
        c = max(c, ds);
        id[s] = before ? ci : is;
        ci = before ? is : ci;
    }
}

// Inserts the points [begin, begin + count) nearer to x than the list's k-th, in index order,
// 32 at a time: a lane marks its candidates in a bit mask (no private array), then inserts them
// in loops that run to the most any lane has. TICK_UNIFORM: the renderer's loop guard.
void insert_nearer(vec3 x, uint begin, uint count, inout float d[K_MAX], inout uint id[K_MAX]) {
    uint longest = subgroupMax(count);
    TICK_UNIFORM((longest + 31u) / 32u + 1u);
    for (uint first = 0u; first < longest; first += 32u) {
        uint n = min(longest - first, 32u);
        TICK_UNIFORM(n + 1u);
        // Marked by squared distance with a margin of a few float steps, so that every point
        // nearer than the list's k-th is marked; one marked but not nearer changes nothing.
        float worst = d[K_MAX - 1];
        uint bits = mark_points(x, begin, count, first, n, worst * worst * 1.000001);
        uint rounds = subgroupMax(uint(bitCount(bits)));
        TICK_UNIFORM(rounds + 1u);
        for (uint r = 0u; r < rounds; ++r) {
            int j = take_next(bits);
            uint p = begin + first + uint(max(j, 0));
            float c = j >= 0 ? distance(x, point_at(p).xyz) : 3.0e38;
            list_insert(d, id, c, p);
        }
    }
}

// A bound on the distance from x to its k-th nearest point: the farthest corner of a node that
// holds k points or more (its points are all within it), the smallest such node on the way down
// toward the child whose bound is smaller, with a margin for float rounding. The list starts
// full of it instead of +∞, so the walk's first round (KNN_ROUND steps before any insertion)
// lists and inserts only points within it, not every point of every leaf it meets: a far query's
// first round used to insert a hundred points or more, each an unrolled pass over the list.
float kth_bound(vec3 x, uint k, uint first_leaf) {
    uint node = 0u;
    vec3 e = max(abs(x - node_lo(0u)), abs(x - node_hi(0u)));
    float best = dot(e, e);
    while (node < first_leaf) {
        TICK_LANE(1u);
        uint l = 2u * node + 1u, r = l + 1u;
        vec3 el = max(abs(x - node_lo(l)), abs(x - node_hi(l))), er = max(abs(x - node_lo(r)), abs(x - node_hi(r)));
        float bl = node_end(l) - node_begin(l) >= k ? dot(el, el) : 3.0e38;
        float br = node_end(r) - node_begin(r) >= k ? dot(er, er) : 3.0e38;
        if (min(bl, br) >= 3.0e38) break;
        node = bl <= br ? l : r;
        best = min(best, min(bl, br));
    }
    return sqrt(best) * 1.00001 + 1e-30;
}

void knn_listed(vec3 x, bool live, uint k, out float kd[K_MAX], out uint ki[K_MAX]) {
    const uint first_leaf = pc.first_leaf;  // push constants: read outside the loops
    const float bound = live ? kth_bound(x, k, first_leaf) : 3.0e38;
    float d[K_MAX];
    uint id[K_MAX];
    [[unroll]] for (int s = 0; s < K_MAX; ++s) {
        d[s] = s < K_MAX - int(k) ? -1.0 : bound;
        id[s] = 0u;
    }
    uint node = 0u, trail = 0u;
    float node_d2 = node_distance2(x, 0u);  // carried from step to step: two boxes read a step
    bool walking = live;
    uint listed[KNN_ROUND];
    while (true) {
        TICK_UNIFORM(KNN_ROUND + 2u);
        float worst = d[K_MAX - 1];
        float w2 = worst * worst;
        uint n_listed = 0u;
        for (uint step = 0u; step < KNN_ROUND; ++step) {  // every lane every step (sum_ball's)
            bool near = walking && node_d2 <= w2;
            bool leaf = node >= first_leaf;
            listed[n_listed] = node;
            n_listed += near && leaf ? 1u : 0u;
            walking = nearer_first_step(x, near && !leaf, node, trail, node_d2) && walking;
        }
        uint passes = subgroupMax(n_listed);
        TICK_UNIFORM(passes + 1u);
        for (uint i = 0u; i < passes; ++i) {
            uint leaf = i < n_listed ? listed[min(i, KNN_ROUND - 1u)] : 0u;  // (unset past the count)
            uint begin = node_begin(leaf);
            insert_nearer(x, begin, i < n_listed ? node_end(leaf) - begin : 0u, d, id);
        }
        if (!subgroupAny(walking)) break;
    }
    // Out as the registers hold them: nearest first from slot K_MAX − k (constant indices on both
    // sides; the caller reads from there).
    [[unroll]] for (int s = 0; s < K_MAX; ++s) {
        kd[s] = d[s];
        ki[s] = id[s];
    }
}
#endif

// Uniform control flow (sum_ball); a lane with live = false gets sums of nothing.
void blend_accelerated(vec3 x, bool live, bool grad, out Acc a, out float rho, out bool rho_varies, out vec3 far_p) {
    a = acc_zero();
    rho = pc.r_eval;
    rho_varies = false;
    far_p = vec3(0.0);
    uint found = sum_ball(x, live, a, grad);
    bool fallback = live && found < pc.k_fallback;
    // The fallback's loops with a fixed count, once for the subgroup (the list's setup, the sum).
    if (subgroupAny(fallback)) TICK_UNIFORM(uint(K_MAX) + pc.k_fallback + 2u);
    // Fewer than k points within r_eval: the k nearest, ρ = d_k.
    float kd[K_MAX];
    uint ki[K_MAX];
    uint first = 0u;  // where the k nearest start in kd, ki
    if (SHARED_KNN == 1) {
        if (!subgroupAny(fallback)) return;
        knn_together(x, fallback, pc.k_fallback, kd, ki);
        if (!fallback) return;
    } else {
#ifdef GSD_SOFTWARE_SHAPED
        // Each lane on its own, its list in registers (uniform control flow: subgroup maxima).
        if (!subgroupAny(fallback)) return;
        knn_listed(x, fallback, pc.k_fallback, kd, ki);
        first = uint(K_MAX) - pc.k_fallback;
        if (!fallback) return;
#else
        // Each lane on its own, best first from its own position.
        if (!fallback) return;
        knn(x, pc.k_fallback, 0xffffffffu, pc.first_leaf, kd, ki);  // (its first loop: counted below)
#endif
    }
    a = acc_zero();
    uint k = pc.k_fallback;
    rho = max(kd[first + k - 1], 1e-30);
    rho_varies = true;
    far_p = point_at(ki[first + k - 1]).xyz;
    float sigma = 0.5 * rho, lambda = pc.C / sigma;
    float ref = weight_ref(sigma, kd[first]);  // the list is nearest first
    // PAT: only the list's points within d₁ + PRUNE/λ can count (PRUNE above), a prefix of it.
    // (A loop of at most k iterations, as the loop guard's count above has it.)
    const float reach = KIND == 0 ? kd[first] + PRUNE / lambda : 3.0e38;
    for (uint m = first; m < first + k; ++m) {
        if (kd[m] > reach) break;
        add_point(a, x, ki[m], kd[m], lambda, ref, rho, true, grad);
    }
}

// φ from the sums (and ∇φ into g when `grad`; SHC has none).
float blend_finish(Acc a, vec3 x, float rho, bool rho_varies, vec3 far_p, bool grad, out vec3 g) {
    float sigma = 0.5 * rho, lambda = pc.C / sigma;
    g = vec3(0.0);
    if (KIND == 2) {
        float mag = max(abs(a.shc), 1e-37);
        return (a.shc < 0.0 ? -1.0 : 1.0) * (-log(mag) / lambda + sigma);
    }
    float phi = a.G / a.W;
    if (!grad) return phi;
    g = a.Gg - lambda * (a.GU - phi * a.U) + (a.QGU - phi * a.QU) / rho;
    if (rho_varies) {
        vec3 xf = x - far_p;
        float dfar = length(xf);
        if (dfar > 0.0)
            g += (xf / dfar) * ((lambda / rho) * (a.GD - phi * a.D) - (a.QGD - phi * a.QD) / (rho * rho));
    }
    g /= a.W;
    return phi;
}

// The accelerated field at x; uniform control flow, live = false on lanes with nothing to do.
float blend_field(vec3 x, bool live, bool grad, out vec3 g) {
    Acc a;
    float rho;
    bool rho_varies;
    vec3 far_p;
    blend_accelerated(x, live, grad, a, rho, rho_varies, far_p);
    return blend_finish(a, x, rho, rho_varies, far_p, grad, g);
}
