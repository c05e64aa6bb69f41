// Streams a large batch of independent items through a kernel in chunks, with three chunks in
// flight: while chunk i computes, chunk i+1 is written into its upload buffer and chunk i−1 is
// read back. Each chunk is one submission (copy in → kernels → copy out). Results do not depend
// on the chunk size as long as items are independent.
#pragma once

#include "gpu/runtime.hpp"

#include <functional>
#include <vector>

namespace gsd::gpu {

struct StreamJob {
    std::size_t count = 0;       ///< items
    std::size_t in_bytes = 0;    ///< per item, uploaded
    std::size_t out_bytes = 0;   ///< per item, read back
    std::size_t chunk = 65536;   ///< items per chunk (capped by the device's binding range)
    /// Chunks hold a multiple of this many items (rounded down, at least one granule): for
    /// kernels whose workgroups take items in fixed groups, so that results do not depend on
    /// the chunk size.
    std::size_t granule = 1;
    /// Writes items [first, first + n) into dst (host memory of n·in_bytes).
    std::function<void(std::size_t first, std::size_t n, void* dst)> fill;
    /// Records the kernels that read `in` and write `out` for n items (ranges are bound whole).
    std::function<void(Recorder& rec, const Buffer& in, const Buffer& out, std::size_t n)> record;
    /// Reads items [first, first + n) from src.
    std::function<void(std::size_t first, std::size_t n, const void* src)> drain;
    const char* stage = "evaluate";  ///< progress label
};

void stream(Context& ctx, const StreamJob& job, const ProgressFn& progress);

/// Items per chunk for a device: a GPU wants millions of queries in flight (2^20), a software
/// device's few cores 65 536 (progress and the first results come sooner).
/// Whether the memory the host writes and reads (Memory::Upload, Memory::Download) is the
/// device's own (DEVICE_LOCAL: software devices, integrated GPUs): stream() then binds those
/// buffers to the kernels and copies nothing. $GSD_STREAM_COPIES=1 copies anyway (tests).
bool host_buffers_are_device_local(const Context& ctx);
std::size_t default_chunk(const Context& ctx);

/// A StreamJob::fill for query points: items [first, first + n) as float vec4 (w = 0), item i
/// being row order[i] of `points` (row i when `order` is empty: spatial::morton_order's, or
/// none).
void fill_vec4(PointsView points, const std::vector<std::uint32_t>& order, std::size_t first, std::size_t n, void* dst);

}  // namespace gsd::gpu
