// kernel_table.hpp — every compute kernel gsd ships, in one table (as ggml-vulkan's pipeline
// list): its shader, its bindings, its push constants (shaders/push_constants.h) and, for a
// shader also built for software devices (NAME_software, GSD_SOFTWARE_SHAPED), the bindings that
// build reads as texel buffers. Call sites name an entry (gpu::kernel(ctx, kernel_table::X, …))
// instead of repeating counts and sizes; Context::kernel checks the binding count against the
// SPIR-V, and test_gpu builds every entry and checks that every embedded shader has one.
//
// Adding a kernel: shaders/NAME.comp (its push struct in push_constants.h, with a size check),
// the shader in shaders/CMakeLists (EmbedShaders), a row here and in `all` below.
#pragma once

#include <gsd/vulkan.hpp>

#include "push_constants.h"

#include <cstdint>

namespace gsd::gpu {

struct KernelSpec {
    const char* shader;        ///< shaders/<shader>.comp
    std::uint32_t bindings;    ///< buffers at set 0, bindings 0..n−1
    std::uint32_t push_bytes;  ///< sizeof its push struct
    /// Its software build's texel-buffer bindings; none: one build serves every device.
    TexelBindings texels = {};
    /// Its software build's binding count where it differs (0: `bindings`).
    std::uint32_t software_bindings = 0;
    constexpr bool has_software_build() const { return texels.all() != 0; }
    constexpr std::uint32_t bindings_of(bool software) const {
        return software && software_bindings ? software_bindings : bindings;
    }
};

namespace kernel_table {
using namespace kernels;
// Sums over oriented elements (src/sums): winding numbers; SHM step 1's screened sum.
inline constexpr KernelSpec sums_winding{"sums_winding", 4, sizeof(WindingPush), {0b11u}};
inline constexpr KernelSpec shm_diffuse{"shm_diffuse", 5, sizeof(DiffusePush), {0b111u}};
// The signed distance's nearest triangle (src/sdf).
inline constexpr KernelSpec sdf_nearest{"sdf_nearest", 4, sizeof(SdfNearestPush), {0b11u}};
// The PAT blend (src/blend): tori from jets, evaluation, the sphere-traced render.
inline constexpr KernelSpec torus_from_jet{"torus_from_jet", 2, sizeof(CountPush)};
inline constexpr KernelSpec blend_eval{"blend_eval", 5, sizeof(BlendPush), {0b111u}};
inline constexpr KernelSpec render_pat{"render_pat", 6, sizeof(RenderPatPush), {0b111u}};
// Rendering a sampled grid (src/render).
inline constexpr KernelSpec render_grid{"render_grid", 3, sizeof(RenderGridPush)};
// TorusNet (src/pat): neighbours, then the network.
inline constexpr KernelSpec torus_net_knn{"torus_net_knn", 4, sizeof(TorusNetKnnPush)};
inline constexpr KernelSpec torus_net{"torus_net", 7, sizeof(CountPush), {0b1u}};
// The multigrid (src/shm/poisson_gpu.cpp). GPUs: the stencils read the axis table (binding 0)
// and the grids as storage buffers. The software builds of the stencils take a quad (4 cells) a
// lane (the rows stored in blocks of even and odd cells, shaders/mg_common.glsl) and read the
// grids as vec4s, φ and b as pairs of doubles; the smoother and the residual need no axis
// table (3 bindings). The prolongation takes a quad a lane too and reads all as vec4s; the
// restriction reads the axis table as vec4s and the grid as floats.
inline constexpr KernelSpec mg_smooth{"mg_smooth", 4, sizeof(MultigridPush), {0b11u}, 3};
inline constexpr KernelSpec mg_residual{"mg_residual", 4, sizeof(MultigridPush), {0b11u}, 3};
inline constexpr KernelSpec mg_restrict{"mg_restrict", 3, sizeof(MultigridPush), {0b11u}};
inline constexpr KernelSpec mg_prolong{"mg_prolong", 4, sizeof(MultigridPush), {0b111u}};
inline constexpr KernelSpec mg_refine{"mg_refine", 7, sizeof(MultigridPush), {0b1u, 0u, 0u, 0b110u}};
inline constexpr KernelSpec mg_coarse{"mg_coarse", 3, sizeof(CountPush)};
inline constexpr KernelSpec mg_add{"mg_add", 2, sizeof(CountPush)};
// Any field on a device (src/gpu/field_device.cpp, src/field/field_gpu.cpp): copies between
// gsd's buffers and an application's; a composite's leaves combined in one pass.
inline constexpr KernelSpec copy_words{"copy_words", 2, sizeof(CountPush)};
inline constexpr KernelSpec field_combine{"field_combine", 3, sizeof(CombinePush)};
// Distance sharpening (src/shm/sharpen_gpu.cpp): PDHG's dual and primal steps.
inline constexpr KernelSpec sharpen_dual{"sharpen_dual", 7, sizeof(SharpenPush)};
inline constexpr KernelSpec sharpen_primal{"sharpen_primal", 8, sizeof(SharpenPush)};
inline constexpr KernelSpec sharpen_restart{"sharpen_restart", 7, sizeof(SharpenPush)};

inline constexpr const KernelSpec* all[] = {&sums_winding, &shm_diffuse, &sdf_nearest, &torus_from_jet, &blend_eval, &render_pat,
                                            &render_grid,  &torus_net_knn, &torus_net,    &mg_smooth,  &mg_residual,
                                            &mg_restrict,  &mg_prolong,  &mg_refine,  &mg_coarse,
                                            &mg_add,       &sharpen_dual, &sharpen_primal,
                                            &sharpen_restart, &copy_words,   &field_combine};
}  // namespace kernel_table

}  // namespace gsd::gpu
