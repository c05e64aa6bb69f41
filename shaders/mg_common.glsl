// Shared by the multigrid kernels (mirrors src/shm/multigrid.hpp and grid_poisson.cpp).
// A level is a grid of cells nx × ny × nz, C order. Its per-axis tables hold each cell's size
// in finest cells, its prolongation sources on the coarser level (c0, c1, w0, w1) and its
// restriction gather range on the finer level [g_begin, g_end) into `gathers`.

struct AxisEntry {
    float size;
    int c0;
    int c1;
    float w0;
    float w1;
    int g_begin;
    int g_end;
    float center;
};

struct Gather { int index; float weight; };

layout(push_constant) uniform Push {
    uvec3 dims;      // this level
    uint color;      // red-black color for the smoother
    uvec3 axes_off;  // where this level's x, y, z tables start in `axes`
    uint pad0;
    uvec3 odims;     // the other level (coarser for prolongation, finer for restriction)
    uint pad1;
    uvec3 oaxes_off;
    uint pad2;
    vec3 inv_h2;     // 1/Δ² of the finest grid per axis
    uint pad3;
} pc;

// Needs `layout(local_size_x_id = 0) in;` before this file is included.
uint linear_id() { return gl_WorkGroupID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x; }

uvec3 cell_of(uint p, uvec3 d) { return uvec3(p / (d.y * d.z), (p / d.z) % d.y, p % d.z); }
uint index_of(uvec3 c, uvec3 d) { return (c.x * d.y + c.y) * d.z + c.z; }
