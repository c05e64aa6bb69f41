// Any gsd::Field on a device: gpu::evaluate_into runs the field's device program, or evaluates
// a field without one on the CPU between two copies; evaluate_points serves host points through
// it (the renderer's wavefront march).
#include "gpu/field_device.hpp"

#include "gpu/runtime.hpp"

#include <algorithm>
#include <cstring>

namespace gsd::gpu {

void check_span(const Context& c, const BufferSpan& span, const char* what) {
    if (span.buffer == VK_NULL_HANDLE) throw Error(what, "no buffer given");
    const VkDeviceSize align = c.limits().minStorageBufferOffsetAlignment;
    if (align && span.offset % align)
        throw Error(what, "offset " + std::to_string(span.offset) + " is not a multiple of " + c.info().name +
                              "'s minStorageBufferOffsetAlignment (" + std::to_string(align) + ")");
}

namespace {

// Records copy_words over `words` words from one range to another, in dispatches that fit the
// device's binding range (whole multiples of 256 bytes, so every offset stays aligned).
void record_copy(Recorder& rec, Context& c, VkBuffer src, VkDeviceSize src_offset, VkBuffer dst, VkDeviceSize dst_offset,
                 std::uint64_t words) {
    const Kernel& k = kernel(c, kernel_table::copy_words);
    const std::uint64_t chunk = std::max<std::uint64_t>(64, std::min<std::uint64_t>(words, c.max_binding_bytes() / 4) / 64 * 64);
    for (std::uint64_t first = 0; first < words; first += chunk) {
        const std::uint64_t n = std::min(chunk, words - first);
        const kernels::CountPush push{std::uint32_t(n)};
        rec.dispatch(k, {Binding(src, src_offset + first * 4, n * 4), Binding(dst, dst_offset + first * 4, n * 4)}, &push,
                     sizeof push, std::uint32_t((n + k.workgroup - 1) / k.workgroup));
    }
}

// A field without a device program: its queries copied to the host, evaluate(), its results
// copied into the caller's buffer. Returns when they are written.
void evaluate_on_host(const Field& field, const std::shared_ptr<Context>& ctx, const DeviceQueries& job,
                      const SubmitSync& sync) {
    log_once("a field without a device program is evaluated by its CPU evaluate(): evaluate_into copies its queries "
             "back and its results in");
    Context& c = *ctx;
    const std::uint64_t n = job.count, out_floats = job.gradient ? 4 : 1;
    Points x(Eigen::Index(n), 3);
    if (n) {
        Buffer down(c, n * 16, Memory::Download);
        Recorder rec(c);
        rec.begin();
        rec.barrier_after_external();
        record_copy(rec, c, job.queries.buffer, job.queries.offset, down.handle(), 0, n * 4);
        rec.barrier();
        rec.submit();
        rec.wait();
        const auto* q = static_cast<const float*>(down.mapped());
        for (std::uint64_t i = 0; i < n; ++i)
            for (int a = 0; a < 3; ++a) x(Eigen::Index(i), a) = q[4 * i + std::uint64_t(a)];
        if (!x.allFinite()) throw Error("DeviceQueries::queries", "query points must be finite");
    }
    const FieldValues v = n ? field.evaluate(x, job.gradient) : FieldValues{};
    Buffer up(c, std::max<std::uint64_t>(n * out_floats * 4, 4), Memory::Upload);
    auto* r = static_cast<float*>(up.mapped());
    for (std::uint64_t i = 0; i < n; ++i) {
        r[out_floats * i] = v.phi[i];
        if (job.gradient)
            for (std::uint64_t a = 0; a < 3; ++a) r[4 * i + 1 + a] = v.gradient[3 * i + a];
    }
    Recorder rec(c);
    rec.begin();
    rec.barrier_after_external();
    if (n) record_copy(rec, c, up.handle(), 0, job.results.buffer, job.results.offset, n * out_floats);
    rec.barrier_before_external();
    rec.submit(sync);
    rec.wait();  // `up` must outlive the copy
}

}  // namespace

void evaluate_into(const Field& field, const std::shared_ptr<Context>& ctx, const DeviceQueries& job, const SubmitSync& sync) {
    if (!ctx) throw Error("context", "no device context given");
    check_span(*ctx, job.queries, "DeviceQueries::queries");
    check_span(*ctx, job.results, "DeviceQueries::results");
    if (job.count >= (1ull << 31)) throw Error("DeviceQueries::count", "at most 2^31 − 1 queries per call");
    if (job.gradient && !field.has_gradient()) throw Error("DeviceQueries::gradient", "the field offers no gradient");
    if (const DeviceProgram* program = field.device_program()) {
        program->evaluate_into(ctx, job, sync);
        return;
    }
    evaluate_on_host(field, ctx, job, sync);
}

FieldValues evaluate_points(const Field& field, const std::shared_ptr<Context>& ctx, const Points& x, bool gradient) {
    Context& c = *ctx;
    const auto n = std::uint64_t(x.rows());
    const std::uint64_t out_floats = gradient ? 4 : 1;
    FieldValues v;
    v.device = device_name(c);
    if (n == 0) return v;
    Buffer q(c, n * 16, Memory::Upload), r(c, n * out_floats * 4, Memory::Download);
    auto* qp = static_cast<float*>(q.mapped());
    for (std::uint64_t i = 0; i < n; ++i) {
        for (int a = 0; a < 3; ++a) qp[4 * i + std::uint64_t(a)] = float(x(Eigen::Index(i), a));
        qp[4 * i + 3] = 0;
    }
    DeviceQueries job;
    job.queries = {q.handle(), 0};
    job.results = {r.handle(), 0};
    job.count = n;
    job.gradient = gradient;
    evaluate_into(field, ctx, job);
    const auto* rp = static_cast<const float*>(r.mapped());
    v.phi.resize(n);
    if (gradient) v.gradient.resize(3 * n);
    for (std::uint64_t i = 0; i < n; ++i) {
        v.phi[i] = rp[out_floats * i];
        if (gradient)
            for (std::uint64_t a = 0; a < 3; ++a) v.gradient[3 * i + a] = rp[4 * i + 1 + a];
    }
    return v;
}

}  // namespace gsd::gpu
