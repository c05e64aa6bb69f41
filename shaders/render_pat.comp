#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_vote : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_EXT_control_flow_attributes : require
// Sphere-traces a blended field (PAT, SSPD, SHC; the accelerated sum) per pixel: the renderer's
// GPU path (src/render/render_gpu.cpp): the hits (t), at which the host then has blend_eval.comp
// evaluate ∇φ. Bindings 0–2 and the first push constants are those of blend_eval.comp, so the
// field's device data serves both.
#include "box_tree.glsl"
#include "torus.glsl"

layout(local_size_x_id = 0) in;
layout(constant_id = 1) const int KIND = 0;  // 0 PAT, 1 SSPD, 2 SHC
layout(constant_id = 2) const int SHARED_KNN = 0;  // 1: the k-nearest fallback walked per subgroup (blend_field.glsl)
layout(constant_id = 3) const uint LOOP_CAP = 0u;  // software devices: render_march.glsl's guard; 0: none

// As blend_eval.comp's: storage buffers, or texel buffers in render_pat_software, built with
// GSD_SOFTWARE_SHAPED (box_tree_buffers.glsl).
#define POINTS_BINDING 0
#define TERMS_BINDING 1
#define NODES_BINDING 2
#include "box_tree_buffers.glsl"

#include "push_constants.h"
layout(push_constant) uniform Push { RenderPatPush pc; };  // push_constants.h

// The loop iterations the walks take, for render_march.glsl's guard against llvmpipe's limit.
uint lane_ticks = 0u, subgroup_ticks = 0u;
#define TICK_LANE(n) if (LOOP_CAP > 0u) lane_ticks += uint(n)
#define TICK_UNIFORM(n) if (LOOP_CAP > 0u) subgroup_ticks += uint(n)
#include "blend_field.glsl"

float field_phi(vec3 x, bool live, bool grad, out vec3 g) { return blend_field(x, live, grad, g); }

// The march evaluates φ alone (the blend's gradient sums would be paid at every step, the
// condition being a lane's own); the host evaluates ∇φ at the hits (render_gpu.cpp).
const bool SHADE_HITS = false;
#define RENDER_PARAMS_BINDING 3
#define RENDER_OUT_BINDING 4
#define RENDER_EMPTY_BINDING 5
#include "workgroup_order.glsl"  // workgroup_share
#include "render_march.glsl"

void main() { render_main(pc.first_pixel, pc.pixel_count); }
