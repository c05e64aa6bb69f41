// Shared by the multigrid kernels (mirrors src/shm/multigrid.hpp and poisson_gpu.cpp).
// A level is a grid of cells nx × ny × nz, C order. Binding 0 holds the axis tables of every
// level: four vec4s per cell of each axis (`AxisCell` in poisson_gpu.cpp):
//   [0] the cell's size in finest cells, its coupling factors toward the previous and the next
//       cell (1/(Δ² · the distance between their centers); 0 where there is none), unused
//   [1] prolongation from the coarser level: source cells c0, c1 (as floats) and weights w0, w1
//   [2] restriction from the finer level: the 4 cells gathered (as floats; spare slots weigh 0;
//       the software build's z table: unused, see [3])
//   [3] their weights (the software build's z table: the weights of fine cells 2i − 1 … 2i + 2)
// The build shaped for software devices (GSD_SOFTWARE_SHAPED, gpu::software_shaped) reads the
// tables and the grids through texel buffers: llvmpipe reads a storage buffer one lane and one
// scalar at a time, behind a branch each, and a texel buffer as one gather of all its lanes.
// The kernels have no branch around their loads (llvmpipe runs both sides of every branch).

#include "push_constants.h"
layout(push_constant) uniform Push { MultigridPush pc; };  // push_constants.h

#ifndef MG_NO_AXIS_TABLE
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = 0) uniform samplerBuffer axis_table;
vec4 axis_cell(uint a, uint c, uint part) { return texelFetch(axis_table, int(4u * (pc.axes_off[a] + c) + part)); }
#else
layout(std430, binding = 0) readonly buffer Axes { vec4 axis_table[]; };
vec4 axis_cell(uint a, uint c, uint part) { return axis_table[4u * (pc.axes_off[a] + c) + part]; }
#endif
#endif

// Cell c of a level of d cells whose rows are stored `zstride` cells apart (pc.zstride,
// pc.ozstride; the GPUs' build: the cell's index. The software build pads the rows and orders
// each row's cells in blocks: stored_cell below).
uint index_of(uvec3 c, uvec3 d, uint zstride) { return (c.x * d.y + c.y) * zstride + c.z; }

// The kernels take rows of cells along z: a workgroup's x lanes walk along a row and its y
// lanes take consecutive rows j of one slab i (gl_WorkGroupID.z), so that no division finds a
// cell. GPUs run a row per workgroup; llvmpipe several (specialization constant 1, the rows per
// workgroup), as it pays an allocation for every workgroup. `inside` is false on lanes past the
// grid's end; they work on its last row or cell and store nothing.
layout(local_size_x_id = 0, local_size_y_id = 1) in;

uvec3 row_cell(out bool inside) {
    uvec3 c = uvec3(gl_WorkGroupID.z, gl_GlobalInvocationID.y, gl_GlobalInvocationID.x);
    inside = c.z < pc.dims.z && c.y < pc.dims.y;
    c.yz = min(c.yz, pc.dims.yz - 1u);
    return c;
}

#ifdef GSD_SOFTWARE_SHAPED
// The software build's kernels (all but mg_restrict and mg_coarse) take four cells a lane, a
// quad, read as one vec4 texel. On llvmpipe a vec4 texel fetch is eight 16-byte loads, while a
// float texel fetch is a hardware gather, several times as slow a value (the gathers were a
// third of the solve's samples in perf); and a lane's addressing and couplings are paid once for
// four cells. A quad is four cells of one parity: each row is stored in blocks of 8 cells, the
// even ones first, then the odd ones (`stored_cell`), so that a red-black sweep's lane reads the
// other color's quads whole and updates four cells of its own. The rows are padded to whole
// blocks (pc.zstride), the padding holding zeros. The couplings come from the push constants
// (every axis of every level is regular but for its last cell), not the axis table.

// Where cell k of the row starting at `row` is stored.
uint stored_cell(uint row, uint k) { return row + (k & ~7u) + ((k & 1u) << 2u) + ((k & 7u) >> 1u); }
// The cells of the row's quad at texel tq (of the row): block tq / 2, parity tq & 1.
uvec4 quad_cells(uint tq) { return (tq >> 1u) * 8u + (tq & 1u) + uvec4(0u, 2u, 4u, 6u); }
// A lane's quad: c = (i, j, tq), the lane's row and its texel tq there (quad_cell: the lane's
// x; the smoother: its block's quad of the sweep's color). `inside` is false on lanes past the
// row's stored quads or the level's rows; they work on its last quad and store nothing. A quad
// of the padding alone is stored (zeros), so that no buffer needs clearing first.
uvec3 lane_quad(uint tq, out bool inside) {
    uvec3 c = uvec3(gl_WorkGroupID.z, gl_GlobalInvocationID.y, tq);
    inside = c.z < pc.zstride / 4u && c.y < pc.dims.y;
    c.y = min(c.y, pc.dims.y - 1u);
    c.z = min(c.z, pc.zstride / 4u - 1u);
    return c;
}
uvec3 quad_cell(out bool inside) { return lane_quad(gl_GlobalInvocationID.x, inside); }
// The texel of the lane's quad c.
uint quad_texel(uvec3 c) { return (c.x * pc.dims.y + c.y) * (pc.zstride / 4u) + c.z; }
// The quad at texel q of a float64 grid read two doubles a texel (φ, b).
dvec4 double_quad(usamplerBuffer pairs, uint q) {
    uvec4 a = texelFetch(pairs, int(2u * q)), b = texelFetch(pairs, int(2u * q + 1u));
    return dvec4(packDouble2x32(a.xy), packDouble2x32(a.zw), packDouble2x32(b.xy), packDouble2x32(b.zw));
}
// Cell i's size along axis a, and its link to cell i + 1 (0 from the last cell).
float size_at(uint a, uint i) { return i + 1u == pc.dims[a] ? pc.last_size[a] : pc.cell_size[a]; }
float link_at(uint a, uint i) { return i + 1u < pc.dims[a] ? (i + 2u == pc.dims[a] ? pc.last_link[a] : pc.link[a]) : 0.0; }
float link_before(uint a, uint i) { return i > 0u ? link_at(a, i - 1u) : 0.0; }
// The same along z for the four cells k of a quad.
vec4 sizes_z(uvec4 k) { return mix(vec4(pc.cell_size[2]), vec4(pc.last_size[2]), equal(k + 1u, uvec4(pc.dims.z))); }
vec4 links_z(uvec4 k) {
    vec4 l = mix(vec4(pc.link[2]), vec4(pc.last_link[2]), equal(k + 2u, uvec4(pc.dims.z)));
    return mix(vec4(0.0), l, lessThan(k + 1u, uvec4(pc.dims.z)));
}

#endif
