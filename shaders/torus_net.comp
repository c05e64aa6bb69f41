#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#ifdef GSD_SOFTWARE_SHAPED
#extension GL_KHR_shader_subgroup_shuffle : require
#endif
// TorusNet stage 2 (docs/torusnet.md, "GPU kernels"): one workgroup per point. From the K
// tokens written by torus_net_knn.comp (or given neighborhoods), the workgroup builds the token
// features and the scale m, runs the transformer with every activation in a workspace of POOL
// vec4s (shared memory, or a slice of a device buffer when a model is too big for shared
// memory), and writes the six coefficients. Float32 throughout; the CPU reference in double is
// src/pat/torus_net.cpp.
//
// Built twice (cmake/EmbedShaders.cmake). For GPUs, every matrix product is tiled: an
// invocation computes TR rows × 4·TC columns, reading vec4s (4 × 1 on GPUs, where more, smaller
// tiles keep more threads busy). For software devices (GSD_SOFTWARE_SHAPED), the workgroup is
// one subgroup of L lanes, every product, attention and LayerNorm goes row by row, and what a
// lane uses many times (its columns' weights, its tokens' keys and values) stays in its
// registers; rows reach every lane through subgroup shuffles (the section below says why).
// docs/gpu.md ("TorusNet") has the measurements.
//
// Weights come in one buffer in the layout src/pat/torus_net_gpu.cpp packs (offsets below, in
// vec4s): every Linear's weight transposed to [in][out], qkv regrouped per head.

layout(local_size_x_id = 0) in;
layout(constant_id = 1) const int K = 32;      // tokens per point (multiple of 4)
layout(constant_id = 2) const int W = 64;      // width (multiple of 4)
layout(constant_id = 3) const int H = 4;       // heads (W/H a multiple of 4)
layout(constant_id = 4) const int F = 128;     // MLP width (multiple of 4)
layout(constant_id = 5) const int B = 2;       // blocks (≥ 1)
layout(constant_id = 6) const int FC = 64;     // MLP columns per pass (divides F, multiple of 4)
layout(constant_id = 7) const int POOL = 1;    // workspace vec4s per point (layout below)
layout(constant_id = 8) const int GLOBAL = 0;  // 1: the workspace lives in the Scratch buffer
layout(constant_id = 9) const int DEBUG = 0;   // 1: also write features and m (tests)
layout(constant_id = 10) const int SHARED_POOL = 1;  // POOL in shared mode, 1 in global mode
layout(constant_id = 11) const int TR = 4;     // GPU build: matrix-product tile: rows (divides K)
layout(constant_id = 12) const int TC = 2;     // GPU build: matrix-product tile: vec4 columns
layout(constant_id = 13) const int L = 8;      // software build: lanes (the workgroup is one subgroup)

const int D = W / H;  // head dimension
const int W4 = W / 4, D4 = D / 4, K4 = K / 4, F4 = F / 4, FC4 = FC / 4;

// ---- weights layout (vec4s) -----------------------------------------------------------------
const int E_W = 0;                  // embed [8][W] (input 7 is zero)
const int E_B = E_W + 8 * W4;       // [W]
const int EN_G = E_B + W4;          // embed_norm γ, β
const int EN_B = EN_G + W4;
const int BLK0 = EN_B + W4;         // first block
// within a block:
const int N1_G = 0;                 // norm1 γ, β
const int N1_B = N1_G + W4;
const int QKV = N1_B + W4;          // per head h at QKV + h·QKV_HEAD: [W][3D] (q_h | k_h | v_h), bias [3D]
const int QKV_HEAD = W * 3 * D4 + 3 * D4;
const int PR_W = QKV + H * QKV_HEAD;  // proj [W][W]
const int PR_B = PR_W + W * W4;
const int N2_G = PR_B + W4;         // norm2 γ, β
const int N2_B = N2_G + W4;
const int F1_W = N2_B + W4;         // fc1 [W][F]
const int F1_B = F1_W + W * F4;
const int F2_W = F1_B + F4;         // fc2 [F][W]
const int F2_B = F2_W + F * W4;
const int BLK = F2_B + W4;          // vec4s per block
const int FN_G = BLK0 + B * BLK;    // final_norm γ, β
const int FN_B = FN_G + W4;
const int HD_W = FN_B + W4;         // head [6][W] (PyTorch's [out][in])
const int HD_B = HD_W + 6 * W4;     // [6] (+2)

// ---- workspace layout (vec4s; rows padded by one vec4 against shared-memory bank conflicts)
const int XS = W4 + 1;       // row stride of X and Y
const int QS = 3 * D4 + 1;   // row stride of q | k | v
const int SS = K4 + 1;       // row stride of the attention scores
const int HS = FC4 + 1;      // row stride of the MLP hidden rows
const int FS = 2;            // row stride of the features (7 + a zero)
const int X = 0;             // [K][W] the residual stream
const int Y = K * XS;        // [K][W] LayerNorm output
const int T = 2 * K * XS;    // scratch: features [K][8]; per head q|k|v [K][3D] then scores [K][K];
                             // MLP hidden [K][FC] (POOL = T + the largest of these)
const int SC = T + K * QS;   // attention scores

// The weights: a storage buffer, or (built with GSD_SOFTWARE_SHAPED: the kernel software
// devices run, gpu::software_shaped) a uniform texel buffer, which llvmpipe reads with one
// gather where it reads a storage buffer one lane and one float at a time.
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 0) uniform samplerBuffer w4_texels;
#define WEIGHT(i) texelFetch(w4_texels, int(i))
#else
layout(std430, binding = 0) readonly buffer Params4 { vec4 w4[]; };
#define WEIGHT(i) w4[i]
#endif
layout(std430, binding = 1) readonly buffer Fixed { ivec4 fixed_pts[]; };  // position = xyz·2^w (|xyz| ≤ 2^29)
layout(std430, binding = 2) readonly buffer Normals { vec4 nrm[]; };  // unit normal, w: tangent_of's axis
layout(std430, binding = 3) readonly buffer Tokens { uint tokens[]; };  // [count][K]
layout(std430, binding = 4) writeonly buffer Out { float outv[]; };     // [count][6]
layout(std430, binding = 5) coherent buffer Scratch { vec4 gpool[]; };  // GLOBAL: [count][POOL]
layout(std430, binding = 6) writeonly buffer Debug { float dbg[]; };    // DEBUG: [count][7K + 1]

#include "push_constants.h"
layout(push_constant) uniform Push { CountPush pc; };  // push_constants.h

shared vec4 spool[SHARED_POOL];
shared float dist[K];
shared float median_max[2];

int tid = 0;  // gl_LocalInvocationID.x
const int WG = int(gl_WorkGroupSize.x);
uint gbase = 0;  // this point's workspace in gpool (GLOBAL)

vec4 ld(int i) { return GLOBAL == 1 ? gpool[gbase + uint(i)] : spool[i]; }
void st(int i, vec4 v) {
    if (GLOBAL == 1) gpool[gbase + uint(i)] = v;
    else spool[i] = v;
}

// Workgroup barrier that also orders the workspace when it lives in device memory.
void sync() {
    if (GLOBAL == 1) groupMemoryBarrier();
    barrier();
}

// gelu_tanh with tanh(y) = 1 − 2/(e^{2y} + 1): finite for every y (no inf/inf).
vec4 gelu(vec4 x) {
    vec4 y = 0.7978845608028654 * (x + 0.044715 * x * x * x);
    return 0.5 * x * (2.0 - 2.0 / (exp(2.0 * y) + 1.0));
}

// Stores a vec4 of outputs: mode 0 assigns, 1 adds (the residual), 2 assigns gelu.
void put(int o, vec4 v, int mode) {
    if (mode == 1) v += ld(o);
    else if (mode == 2) v = gelu(v);
    st(o, v);
}

// Features [K][8] at T and the scale m of this point's neighborhood (docs/torusnet.md).
float features(uint g) {
    uint c = tokens[g * uint(K)];
    ivec4 pc_fixed = fixed_pts[c];
    vec4 nc = nrm[c];
    vec3 n = nc.xyz;
    vec3 axis = nc.w == 0.0 ? vec3(1.0, 0.0, 0.0) : (nc.w == 1.0 ? vec3(0.0, 1.0, 0.0) : vec3(0.0, 0.0, 1.0));
    vec3 s = normalize(cross(n, axis));  // tangent_of(n): the axis is chosen on the host in double
    vec3 t = cross(n, s);
    for (int j = tid; j < K; j += WG) {
        uint tj = tokens[g * uint(K) + uint(j)];
        // d = p_j − p from fixed-point positions: the integer difference is exact, so d has
        // float32 precision relative to |d| however far the cloud is from the origin (float
        // tricks like hi/lo splits do not survive compilers that reassociate; lavapipe's does).
        vec3 d = ldexp(vec3(fixed_pts[tj].xyz - pc_fixed.xyz), ivec3(pc_fixed.w));
        dist[j] = length(d);
        vec3 nj = nrm[tj].xyz;
        st(T + FS * j, vec4(dot(d, s), dot(d, t), dot(d, n), dot(nj, s)));
        st(T + FS * j + 1, vec4(dot(nj, t), dot(nj, n), j == 0 ? 1.0 : 0.0, 0.0));
    }
    barrier();
    // The lower median (rank (K − 2)/2) and the largest (rank K − 2) of the K − 1 distances.
    for (int j = 1 + tid; j < K; j += WG) {
        float dj = dist[j];
        int rank = 0;
        [[dont_unroll]] for (int i = 1; i < K; ++i) rank += (dist[i] < dj || (dist[i] == dj && i < j)) ? 1 : 0;
        if (rank == (K - 2) / 2) median_max[0] = dj;
        if (rank == K - 2) median_max[1] = dj;
    }
    barrier();
    float m = median_max[0], dmax = median_max[1];
    if (m <= 1e-3 * dmax) m = 1e-3 * dmax;
    if (dmax == 0.0) m = 1.0;
    for (int j = tid; j < K; j += WG) {
        vec4 f0 = ld(T + FS * j);
        f0.xyz /= m;
        st(T + FS * j, f0);
        if (DEBUG == 1) {
            vec4 f1 = ld(T + FS * j + 1);
            uint at = g * uint(7 * K + 1) + uint(7 * j);
            dbg[at] = f0.x; dbg[at + 1] = f0.y; dbg[at + 2] = f0.z; dbg[at + 3] = f0.w;
            dbg[at + 4] = f1.x; dbg[at + 5] = f1.y; dbg[at + 6] = f1.z;
        }
    }
    if (DEBUG == 1 && tid == 0) dbg[g * uint(7 * K + 1) + uint(7 * K)] = m;
    sync();
    return m;
}

#ifdef GSD_SOFTWARE_SHAPED
// ---- the kernel for software devices (gpu::software_shaped): a point's workgroup is one
// subgroup of L lanes (L ≥ 8, K % L == 0, D4 ≤ L; torus_net_gpu.cpp checks) ---------------
//
// llvmpipe runs a subgroup as one SIMD thread and reads memory at lane-varying addresses one
// lane at a time, so a tile loop that reads an activation and a weight for every few products
// spends its time in those reads. Here the data a lane uses many times lives in its registers:
// in a product with weights, lane l owns the vec4 columns c = l + L·m and loads their weights
// once (the indices are constants after unrolling, so they stay SSA values: spilled vectors,
// not gathers); then, row by row, the L lanes load the row together (one vec4 each) and
// subgroupShuffle hands each vec4 to every lane (on Mesa 22.3's llvmpipe a third of what
// subgroupBroadcast costs, and a shared-memory row read at constant addresses costs as much as
// the broadcast). Attention, softmax and LayerNorm work row by row the same way,
// their sums and maxima butterflies of shuffles. docs/gpu.md ("TorusNet") has the measurements.

// Sums (and maxima) over the L lanes, every lane getting the result.
float lanes_sum(float v) {
    [[unroll]] for (int k = 0; k < 6; ++k)
        if ((1 << k) < L) v += subgroupShuffleXor(v, 1u << k);
    return v;
}
vec4 lanes_sum(vec4 v) {
    [[unroll]] for (int k = 0; k < 6; ++k)
        if ((1 << k) < L) v += subgroupShuffleXor(v, 1u << k);
    return v;
}
float lanes_max(float v) {
    [[unroll]] for (int k = 0; k < 6; ++k)
        if ((1 << k) < L) v = max(v, subgroupShuffleXor(v, 1u << k));
    return v;
}

// out[r][c] (=, +=, = gelu) bias[c] + Σ_i A[r][i]·B[i][c] for r < R, c < N: A in the
// workspace (row stride lda; I4 = inputs / 4), B in the weights (row stride ldb), bias in the
// weights (< 0: none), out in the workspace (row stride ldo); all in vec4s. I4 and NL (a lane's
// vec4 columns, ⌈N/4L⌉ or more) must be constants at every call: they size the unrolled code.
// The rest may vary, so products of one shape share a call site: llvmpipe compiles every copy
// of the unrolled code at pipeline creation, in every run.
const int GI4 = (W + F) / 4;           // bound on a product's inputs in vec4s (2, W4, D4, FC4)
const int GN4 = ((2 * W + F) / 4 + 7) / 8;  // bound on NL for L ≥ 8 (q | k v: 2·D4 ≤ 2·W4 columns)
void gemm_lanes(int a, int lda, int R, const int I4, const int NL, int b, int ldb, int bias, int N, int o, int ldo,
                int mode) {
    int n4 = N / 4;
    vec4 wreg[GI4][4][GN4];
    vec4 breg[GN4];
    [[unroll]] for (int m = 0; m < NL; ++m) {
        int c = tid + L * m, cc = min(c, n4 - 1);
        breg[m] = c < n4 && bias >= 0 ? WEIGHT(bias + cc) : vec4(0.0);
        // Nested: Mesa 22.3 left a loop of 64 passes rolled despite [[unroll]] (llvmpipe's
        // max_unroll_iterations is 32), its arrays in memory.
        [[unroll]] for (int i4 = 0; i4 < I4; ++i4)
            [[unroll]] for (int k = 0; k < 4; ++k)
                wreg[i4][k][m] = c < n4 ? WEIGHT(b + (4 * i4 + k) * ldb + cc) : vec4(0.0);
    }
    [[dont_unroll]] for (int r = 0; r < R; ++r) {
        vec4 acc[GN4];
        [[unroll]] for (int m = 0; m < NL; ++m) acc[m] = breg[m];
        [[unroll]] for (int m4 = 0; m4 < (I4 + L - 1) / L; ++m4) {
            vec4 xv = tid + L * m4 < I4 ? ld(a + r * lda + tid + L * m4) : vec4(0.0);
            [[unroll]] for (int s = 0; s < L; ++s) {
                const int i4 = s + L * m4;
                if (i4 >= I4) break;
                vec4 xs = subgroupShuffle(xv, uint(s));
                [[unroll]] for (int m = 0; m < NL; ++m)
                    acc[m] += xs.x * wreg[i4][0][m] + xs.y * wreg[i4][1][m] + xs.z * wreg[i4][2][m] + xs.w * wreg[i4][3][m];
            }
        }
        [[unroll]] for (int m = 0; m < NL; ++m)
            if (tid + L * m < n4) put(o + r * ldo + tid + L * m, acc[m], mode);
    }
}

// gemm with the GPU build's signature, so both builds share main(): a product with weights
// (`weights` is true at every call here) whose N is a constant, the lane's columns following.
void gemm(int a, int lda, int R, const int I4, bool weights, int b, int ldb, int bias, const int N, int o, int ldo,
          int mode) {
    gemm_lanes(a, lda, R, I4, (N / 4 + L - 1) / L, b, ldb, bias, N, o, ldo, mode);
}

// LayerNorm (biased variance, eps 1e-5) of rows [0, R) of src into dst (row stride XS), γ at
// g, β at g + W4: lane l normalizes the row's vec4s l + L·m.
const int LN4 = (W4 + L - 1) / L;
void layer_norm(int src, int dst, int R, int g) {
    vec4 gamma[LN4], beta[LN4];
    [[unroll]] for (int m = 0; m < LN4; ++m) {
        int c = min(tid + L * m, W4 - 1);
        gamma[m] = WEIGHT(g + c);
        beta[m] = WEIGHT(g + W4 + c);
    }
    [[dont_unroll]] for (int r = 0; r < R; ++r) {
        vec4 v[LN4];
        vec4 s = vec4(0.0);
        [[unroll]] for (int m = 0; m < LN4; ++m) {
            v[m] = tid + L * m < W4 ? ld(src + r * XS + tid + L * m) : vec4(0.0);
            s += v[m];
        }
        float mean = lanes_sum(s.x + s.y + s.z + s.w) / float(W);
        vec4 q = vec4(0.0);
        [[unroll]] for (int m = 0; m < LN4; ++m) {
            vec4 e = tid + L * m < W4 ? v[m] - mean : vec4(0.0);
            q += e * e;
        }
        float rstd = inversesqrt(lanes_sum(q.x + q.y + q.z + q.w) / float(W) + 1e-5);
        [[unroll]] for (int m = 0; m < LN4; ++m)
            if (tid + L * m < W4) st(dst + r * XS + tid + L * m, (v[m] - mean) * rstd * gamma[m] + beta[m]);
    }
    sync();
}

// One head's attention for rows r < R: scores q_r·k_j / √D, softmax over j, o_r = Σ_j a_rj v_j,
// row by row in registers. Lane l holds the keys and values of tokens j = l + L·c (loaded
// once); a row's query comes in one vec4 a lane (D4 ≤ L) and is shuffled to all; the max, the
// sum and o_r's partial sums are butterflies. o_r goes to q_r's place: lane l < D4 writes the
// vec4 it read, so no lane overwrites what another still reads.
const int KL = K / L;  // tokens a lane holds
void attention(int R, float scale) {
    vec4 kreg[KL][D4], vreg[KL][D4];
    [[unroll]] for (int c = 0; c < KL; ++c)
        [[unroll]] for (int x4 = 0; x4 < D4; ++x4) {
            kreg[c][x4] = ld(T + (tid + L * c) * QS + D4 + x4);
            vreg[c][x4] = ld(T + (tid + L * c) * QS + 2 * D4 + x4);
        }
    [[dont_unroll]] for (int r = 0; r < R; ++r) {
        vec4 qv = tid < D4 ? ld(T + r * QS + tid) : vec4(0.0);
        vec4 q[D4];
        [[unroll]] for (int x4 = 0; x4 < D4; ++x4) q[x4] = subgroupShuffle(qv, uint(x4));
        float e[KL];
        float mx = -3.0e38;
        [[unroll]] for (int c = 0; c < KL; ++c) {
            float d = 0.0;
            [[unroll]] for (int x4 = 0; x4 < D4; ++x4) d += dot(q[x4], kreg[c][x4]);
            e[c] = scale * d;
            mx = max(mx, e[c]);
        }
        mx = lanes_max(mx);
        float sum = 0.0;
        [[unroll]] for (int c = 0; c < KL; ++c) {
            e[c] = exp(e[c] - mx);
            sum += e[c];
        }
        float inv = 1.0 / lanes_sum(sum);
        vec4 mine = vec4(0.0);
        [[unroll]] for (int x4 = 0; x4 < D4; ++x4) {
            vec4 part = vec4(0.0);
            [[unroll]] for (int c = 0; c < KL; ++c) part += e[c] * vreg[c][x4];
            part = lanes_sum(part) * inv;
            if (tid == x4) mine = part;
        }
        if (tid < D4) st(T + r * QS + tid, mine);
    }
}

// One block; in the last block only token 0 leaves, so its query row, attention row and MLP are
// computed for row 0 only (R = 1); keys and values still come from every token.
void block(int base, int R) {
    layer_norm(X, Y, K, base + N1_G);
    float scale = inversesqrt(float(D));
    [[dont_unroll]] for (int h = 0; h < H; ++h) {
        int qkv = base + QKV + h * QKV_HEAD, qkv_b = qkv + W * 3 * D4;
        // q of head h for rows < R, then k | v for every row ([K][3D] at T): one call site.
        [[dont_unroll]] for (int p = 0; p < 2; ++p)
            gemm_lanes(Y, XS, p == 0 ? R : K, W4, (2 * D4 + L - 1) / L, qkv + p * D4, 3 * D4, qkv_b + p * D4, (p + 1) * D,
                       T + p * D4, QS, 0);
        sync();
        attention(R, scale);
        sync();
        // x += o_h · proj[hD … hD+D) (the bias once, with head 0).
        gemm(T, QS, R, D4, true, base + PR_W + h * D * W4, W4, h == 0 ? base + PR_B : -1, W, X, XS, 1);
        sync();
    }
    layer_norm(X, Y, R, base + N2_G);
    [[dont_unroll]] for (int c0 = 0; c0 < F; c0 += FC) {
        if (FC == W) {  // fc1 and fc2 have one shape: one call site
            [[dont_unroll]] for (int p = 0; p < 2; ++p) {
                bool fc1 = p == 0;
                gemm_lanes(fc1 ? Y : T, fc1 ? XS : HS, R, W4, (W4 + L - 1) / L, base + (fc1 ? F1_W + c0 / 4 : F2_W + c0 * W4),
                           fc1 ? F4 : W4, fc1 ? base + F1_B + c0 / 4 : (c0 == 0 ? base + F2_B : -1), W, fc1 ? T : X,
                           fc1 ? HS : XS, fc1 ? 2 : 1);
                sync();
            }
        } else {
            gemm(Y, XS, R, W4, true, base + F1_W + c0 / 4, F4, base + F1_B + c0 / 4, FC, T, HS, 2);
            sync();
            gemm(T, HS, R, FC4, true, base + F2_W + c0 * W4, W4, c0 == 0 ? base + F2_B : -1, W, X, XS, 1);
            sync();
        }
    }
}
const int LAST_ROWS = 1;  // rows the last block computes

#else
// ---- the kernel for GPUs (and software devices the one above does not fit) ------------------

// out[r][c] (=, +=, = gelu) bias[c] + Σ_i A[r][i]·B[i][c] for r < R, c < N; all in vec4s:
// A in the workspace (row stride lda), I4 = inputs / 4; B in the weights (weights = true) or
// the workspace, row-major (row stride ldb); bias in the weights (bias < 0: none); out in the
// workspace (row stride ldo). An invocation computes TR rows × TC vec4 columns (a constant, so
// the tile loops unroll into registers); R is a multiple of TR; N % 4 == 0.

void gemm(int a, int lda, int R, int I4, bool weights, int b, int ldb, int bias, int N, int o, int ldo,
          int mode) {
    int n4 = N / 4;
    int nct = (n4 + TC - 1) / TC;
    int tiles = (R / TR) * nct;
    for (int tile = tid; tile < tiles; tile += WG) {
        int r0 = (tile / nct) * TR, c0 = (tile % nct) * TC;
        vec4 acc[TR][TC];
        for (int q = 0; q < TC; ++q) {
            vec4 bq = bias >= 0 && c0 + q < n4 ? WEIGHT(bias + c0 + q) : vec4(0.0);
            for (int t = 0; t < TR; ++t) acc[t][q] = bq;
        }
        [[dont_unroll]] for (int i4 = 0; i4 < I4; ++i4) {
            vec4 av[TR];
            for (int t = 0; t < TR; ++t) av[t] = ld(a + (r0 + t) * lda + i4);
            for (int k = 0; k < 4; ++k) {
                int row = b + (4 * i4 + k) * ldb + c0;
                for (int q = 0; q < TC; ++q) {
                    vec4 bv = c0 + q < n4 ? (weights ? WEIGHT(row + q) : ld(row + q)) : vec4(0.0);
                    for (int t = 0; t < TR; ++t) acc[t][q] += av[t][k] * bv;
                }
            }
        }
        for (int t = 0; t < TR; ++t)
            for (int q = 0; q < TC; ++q)
                if (c0 + q < n4) put(o + (r0 + t) * ldo + c0 + q, acc[t][q], mode);
    }
}

// Attention scores S[r][j] = scale · q_r·k_j for r < R, j < K (Q, Kt rows in the workspace,
// row stride QS, D4 vec4s each); TR rows × 8 keys per invocation.
void scores(int R, float scale) {
    int tiles = (R / TR) * (K / 8 + (K % 8 == 0 ? 0 : 1));
    int nct = K / 8 + (K % 8 == 0 ? 0 : 1);
    for (int tile = tid; tile < tiles; tile += WG) {
        int r0 = (tile / nct) * TR, j0 = (tile % nct) * 8;
        float acc[TR][8];
        for (int t = 0; t < TR; ++t)
            for (int q = 0; q < 8; ++q) acc[t][q] = 0.0;
        [[dont_unroll]] for (int x4 = 0; x4 < D4; ++x4) {
            vec4 qv[TR];
            for (int t = 0; t < TR; ++t) qv[t] = ld(T + (r0 + t) * QS + x4);
            for (int q = 0; q < 8; ++q) {
                vec4 kv = j0 + q < K ? ld(T + (j0 + q) * QS + D4 + x4) : vec4(0.0);
                for (int t = 0; t < TR; ++t) acc[t][q] += dot(qv[t], kv);
            }
        }
        for (int t = 0; t < TR; ++t) {
            int s = SC + (r0 + t) * SS + j0 / 4;
            st(s, scale * vec4(acc[t][0], acc[t][1], acc[t][2], acc[t][3]));
            if (j0 + 4 < K) st(s + 1, scale * vec4(acc[t][4], acc[t][5], acc[t][6], acc[t][7]));
        }
    }
}

// LayerNorm (biased variance, eps 1e-5) of rows [0, R) of src into dst (row stride XS), γ at
// g, β at g + W4.
shared float row_mean[K];
shared float row_rstd[K];
void layer_norm(int src, int dst, int R, int g) {
    for (int r = tid; r < R; r += WG) {
        vec4 s = vec4(0.0);
        [[dont_unroll]] for (int c = 0; c < W4; ++c) s += ld(src + r * XS + c);
        float mean = (s.x + s.y + s.z + s.w) / float(W);
        vec4 v = vec4(0.0);
        [[dont_unroll]] for (int c = 0; c < W4; ++c) {
            vec4 e = ld(src + r * XS + c) - mean;
            v += e * e;
        }
        row_mean[r] = mean;
        row_rstd[r] = inversesqrt((v.x + v.y + v.z + v.w) / float(W) + 1e-5);
    }
    barrier();
    for (int e = tid; e < R * W4; e += WG) {
        int r = e / W4, c = e % W4;
        st(dst + r * XS + c, (ld(src + r * XS + c) - row_mean[r]) * row_rstd[r] * WEIGHT(g + c) + WEIGHT(g + W4 + c));
    }
    sync();
}

// One block. In the last block only token 0 leaves, so its query row, attention row and MLP are
// computed for its first TR rows only (R, the rows that go on: one row tile); keys and values
// still come from every token. Both kinds of block are this one code (R a runtime value): the
// pipeline's compile time (llvmpipe's, on every run) grows with the shader's code.
void block(int base, int R) {
    layer_norm(X, Y, K, base + N1_G);
    float scale = inversesqrt(float(D));
    [[dont_unroll]] for (int h = 0; h < H; ++h) {
        int qkv = base + QKV + h * QKV_HEAD, qkv_b = qkv + W * 3 * D4;
        // q of head h for rows < R, k | v for every row: [K][3D] at T.
        gemm(Y, XS, R, W4, true, qkv, 3 * D4, qkv_b, D, T, QS, 0);
        gemm(Y, XS, K, W4, true, qkv + D4, 3 * D4, qkv_b + D4, 2 * D, T + D4, QS, 0);
        sync();
        // Scores q_r·k_j / √D, softmax over j, then o_r = Σ_j a_rj v_j into q's columns.
        scores(R, scale);
        sync();
        for (int r = tid; r < R; r += WG) {
            vec4 mx4 = vec4(-3.0e38);
            [[dont_unroll]] for (int j4 = 0; j4 < K4; ++j4) mx4 = max(mx4, ld(SC + r * SS + j4));
            float mx = max(max(mx4.x, mx4.y), max(mx4.z, mx4.w));
            vec4 sum4 = vec4(0.0);
            [[dont_unroll]] for (int j4 = 0; j4 < K4; ++j4) {
                vec4 e = exp(ld(SC + r * SS + j4) - mx);
                st(SC + r * SS + j4, e);
                sum4 += e;
            }
            float inv = 1.0 / (sum4.x + sum4.y + sum4.z + sum4.w);
            [[dont_unroll]] for (int j4 = 0; j4 < K4; ++j4) st(SC + r * SS + j4, ld(SC + r * SS + j4) * inv);
        }
        sync();
        gemm(SC, SS, R, K4, false, T + 2 * D4, QS, -1, D, T, QS, 0);
        sync();
        // x += o_h · proj[hD … hD+D) (the bias once, with head 0).
        gemm(T, QS, R, D4, true, base + PR_W + h * D * W4, W4, h == 0 ? base + PR_B : -1, W, X, XS, 1);
        sync();
    }
    layer_norm(X, Y, R, base + N2_G);
    [[dont_unroll]] for (int c0 = 0; c0 < F; c0 += FC) {
        gemm(Y, XS, R, W4, true, base + F1_W + c0 / 4, F4, base + F1_B + c0 / 4, FC, T, HS, 2);
        sync();
        gemm(T, HS, R, FC4, true, base + F2_W + c0 * W4, W4, c0 == 0 ? base + F2_B : -1, W, X, XS, 1);
        sync();
    }
}

const int LAST_ROWS = TR;  // rows the last block computes
#endif

void main() {
    uint g = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (g >= pc.count) return;  // uniform over the workgroup
    gbase = g * uint(POOL);
    tid = int(gl_LocalInvocationID.x);

    float m = features(g);
    // x = LayerNorm(embed(features)): the embedding into Y, normalized into X.
    gemm(T, FS, K, 2, true, E_W, W4, E_B, W, Y, XS, 0);
    sync();
    layer_norm(Y, X, K, EN_G);
    [[dont_unroll]] for (int b = 0; b < B; ++b) block(BLK0 + b * BLK, b + 1 < B ? K : LAST_ROWS);
    // z = LayerNorm(x_0), r = head(z), rescaled by m.
    layer_norm(X, Y, 1, FN_G);
    if (tid < 6) {
        vec4 acc = vec4(0.0);
        for (int i4 = 0; i4 < W4; ++i4) acc += ld(Y + i4) * WEIGHT(HD_W + tid * W4 + i4);
        float r = acc.x + acc.y + acc.z + acc.w + WEIGHT(HD_B + tid / 4)[tid % 4];
        // (a00, a10, a01, a11, a20, a02) = (r0·m, r1, r2, r3/m, r4/m, r5/m)
        outv[6 * g + uint(tid)] = tid == 0 ? r * m : (tid < 3 ? r : r / m);
    }
}
