// Which share of a dispatch's work a workgroup takes, so that every thread of a software device
// gets an even share of it (gpu::dispatch_threads, src/gpu/runtime.hpp).
//
// llvmpipe splits a dispatch of N workgroups between its T threads in T contiguous blocks of
// N / T (the last N mod T one at a time). gsd's queries come in Morton order, and the work per
// query is anything but even along it: near the input a query sums leaves exactly, far from it
// a few expansions. In contiguous blocks one thread got the near half of a chunk and the other
// waited for it: measured with perf on lavapipe, 2 cores, winding numbers of 10⁶ queries, each
// of llvmpipe's two threads busy 67-71 % of the kernel's time. So workgroup w of the first T·B
// (B = N / T) takes share (w mod B)·T + w / B: thread t's block is every T-th share from t on,
// spread over the whole dispatch, and its consecutive workgroups stay neighbours T shares apart
// (the tree nodes they read stay in its cache). The rest, and every workgroup on other devices
// (DISPATCH_THREADS = 1), take their own index.
//
// Include it after the shader's `layout(local_size_x_id = ...) in;`: before it, glslang reads
// gl_WorkGroupSize as 1.

layout(constant_id = 63) const uint DISPATCH_THREADS = 1u;  // gpu::kDispatchThreadsConstant

// The share of the work this workgroup takes: a permutation of the dispatch's linear workgroup
// indices (x fastest, as llvmpipe numbers them).
uint workgroup_share() {
    uint w = (gl_WorkGroupID.z * gl_NumWorkGroups.y + gl_WorkGroupID.y) * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (DISPATCH_THREADS <= 1u) return w;
    uint per_thread = (gl_NumWorkGroups.x * gl_NumWorkGroups.y * gl_NumWorkGroups.z) / DISPATCH_THREADS;
    if (per_thread == 0u) return w;  // fewer workgroups than threads: one each
    return w < per_thread * DISPATCH_THREADS ? (w % per_thread) * DISPATCH_THREADS + w / per_thread : w;
}

// The item this invocation takes where a workgroup takes gl_WorkGroupSize.x consecutive items.
uint workgroup_share_item() { return workgroup_share() * gl_WorkGroupSize.x + gl_LocalInvocationID.x; }
