// push_constants.h — every compute kernel's push constants, declared once for both sides: the
// shaders include this file and declare `layout(push_constant) uniform Push { NamePush pc; };`,
// the host includes it and fills the same struct (namespace gsd::kernels). A field added on one
// side is there on the other; the sizes and offsets below are checked when the host compiles.
//
// Rules that keep the two layouts one: scalars (uint, float) only, except GSD_ALIGNED_VEC3
// members (a 3-vector on a 16-byte boundary followed by a 4-byte scalar, as std430 places a
// uvec3/vec3; the host's alignas says the same) and arrays of scalars (std430 strides them 4
// bytes, as C++ does). No bool (GLSL's is 4 bytes, C++'s 1). At most 128 bytes (Vulkan's
// guaranteed push-constant range).
#ifndef GSD_PUSH_CONSTANTS_H
#define GSD_PUSH_CONSTANTS_H

#ifdef __cplusplus
#include <cstddef>
#include <cstdint>
namespace gsd::kernels {
using uint = std::uint32_t;
// GLSL's 3-vectors, with [a] for axis a as the host fills them.
template <class T>
struct Vec3Of {
    T x, y, z;
    T& operator[](int a) { return a == 0 ? x : a == 1 ? y : z; }
    const T& operator[](int a) const { return a == 0 ? x : a == 1 ? y : z; }
};
using uvec3 = Vec3Of<uint>;
using vec3 = Vec3Of<float>;
#define GSD_ALIGNED_VEC3 alignas(16)
#else
#define GSD_ALIGNED_VEC3
#endif

// A kernel that takes only how many items it has: torus_from_jet, torus_net, mg_add, mg_coarse.
struct CountPush {
    uint count;
};

// sums_winding.comp
struct WindingPush {
    uint count;
    uint first_leaf;
    uint group_cap;   // loop iterations one subgroup may run (0: no limit): llvmpipe's limit
    uint node_count;  // where the 7-vec4 node records start
};

// blend_eval.comp (and, as the first fields of RenderPatPush, render_pat.comp: blend_field.glsl
// reads these by name)
struct BlendPush {
    uint query_count;
    uint point_count;
    uint first_leaf;  // nodes at or past this index are leaves
    uint k_fallback;
    float r_eval;
    float C;
    float dmin;  // smallest distance used by the SHC kernel (1e-6 h)
};

// render_pat.comp: BlendPush's fields (first_pixel in query_count's place), then the chunk's size
struct RenderPatPush {
    uint first_pixel;
    uint point_count;
    uint first_leaf;
    uint k_fallback;
    float r_eval;
    float C;
    float dmin;
    uint pixel_count;
};

// render_grid.comp
struct RenderGridPush {
    uint first_pixel;
    uint pixel_count;
    uint nx, ny, nz;
    float x0, y0, z0;  // the first node
    float hx, hy, hz;  // node spacing
};

// shm_diffuse.comp
struct DiffusePush {
    uint count;
    uint first_leaf;
    float lambda;
    float cutoff;
    float r_floor;
    float budget;    // tolerance · 2π/λ
    uint group_cap;  // loop iterations one subgroup may run (0: no limit): llvmpipe's limit
};

// sdf_nearest.comp
struct SdfNearestPush {
    uint count;
    uint first_leaf;
    uint group_cap;  // loop iterations one subgroup may run (0: no limit): llvmpipe's limit
};

// torus_net_knn.comp
struct TorusNetKnnPush {
    uint count;       // points in this chunk
    uint first_leaf;  // nodes at or past this index are leaves
};

// The multigrid's level kernels (mg_common.glsl)
struct MultigridPush {
    GSD_ALIGNED_VEC3 uvec3 dims;  // this level
    uint color;                   // red-black color: the smoother's; mg_prolong's cells; mg_residual's computed cells; mg_restrict: t's zero cells
    GSD_ALIGNED_VEC3 uvec3 axes_off;  // where this level's x, y, z tables start, in cells
    uint zstride;                     // cells stored per row of this level (≥ dims.z)
    GSD_ALIGNED_VEC3 uvec3 odims;  // the other level (coarser for prolongation, finer for restriction)
    uint ozstride;                 // cells stored per row of the other level
    GSD_ALIGNED_VEC3 uvec3 oaxes_off;
    uint first_sweep;  // 1: the smoother takes e as 0 (a level's first half-sweep); mg_refine: what it does (poisson_gpu.cpp's Refine)
    GSD_ALIGNED_VEC3 vec3 inv_h2;  // 1/Δ² of the finest grid per axis
    uint pad3;
    // This level's axes (x, y, z) for the software build's stencils: every cell of an axis has
    // cell_size and every link (Hierarchy's AxisLevel::link) is `link`, except the last cell's
    // size and the last link (between the last two cells).
    float cell_size[3];
    float link[3];
    float last_size[3];
    float last_link[3];
};
// field_combine.comp (src/field/field_gpu.cpp)
struct CombinePush {
    uint count;        // queries
    uint ops;          // program length
    uint leaf_stride;  // floats from one leaf's results to the next's
    uint gradient;     // 1: results are (φ, ∇φ) records
};

// sharpen_dual.comp, sharpen_primal.comp, sharpen_restart.comp (src/shm/sharpen.hpp)
struct SharpenPush {
    GSD_ALIGNED_VEC3 uvec3 dims;  // nodes per axis
    uint nodes;
    GSD_ALIGNED_VEC3 vec3 inv_h;  // 1/spacing per axis
    uint rows;                    // zero-set rows
    float sigma_d;                // the gradient blocks' dual step
    float row_scale;              // β
    float damping;                // the soft zero set's dual damping (1: exact)
    float sign_floor;             // keep_sign: s·φ ≥ this (0: eq. 4.13 as written, no bound)
    uint keep_sign;               // 1: bound φ to φ₀'s side
    float inv_count;              // sharpen_restart: 1 / iterations averaged
    uint pad0, pad1;
};

#ifdef __cplusplus
// std430 offsets, as the shaders see them.
static_assert(sizeof(CountPush) == 4);
static_assert(sizeof(WindingPush) == 16);
static_assert(sizeof(BlendPush) == 28);
static_assert(sizeof(RenderPatPush) == 32 && offsetof(RenderPatPush, dmin) == offsetof(BlendPush, dmin));
static_assert(sizeof(RenderGridPush) == 44);
static_assert(sizeof(DiffusePush) == 28);
static_assert(sizeof(TorusNetKnnPush) == 8);
static_assert(sizeof(SdfNearestPush) == 12);
static_assert(sizeof(CombinePush) == 16);
static_assert(sizeof(SharpenPush) == 64 && offsetof(SharpenPush, inv_h) == 16 && offsetof(SharpenPush, rows) == 28 &&
              offsetof(SharpenPush, keep_sign) == 48 && offsetof(SharpenPush, inv_count) == 52);
static_assert(sizeof(MultigridPush) == 128 && offsetof(MultigridPush, color) == 12 &&
              offsetof(MultigridPush, axes_off) == 16 && offsetof(MultigridPush, zstride) == 28 &&
              offsetof(MultigridPush, odims) == 32 && offsetof(MultigridPush, ozstride) == 44 &&
              offsetof(MultigridPush, oaxes_off) == 48 && offsetof(MultigridPush, inv_h2) == 64 &&
              offsetof(MultigridPush, cell_size) == 80 && offsetof(MultigridPush, link) == 92 &&
              offsetof(MultigridPush, last_size) == 104 && offsetof(MultigridPush, last_link) == 116);
}  // namespace gsd::kernels
#endif

#undef GSD_ALIGNED_VEC3
#endif  // GSD_PUSH_CONSTANTS_H
