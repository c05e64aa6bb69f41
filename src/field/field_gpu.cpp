// A composite's device program (composite.hpp): each leaf evaluates into its own region of one
// device buffer (gpu::evaluate_into: its program, or the CPU between two copies), then
// field_combine runs the composite's postfix program over them in one pass. No operator's
// values pass through the host.
#include "field/composite.hpp"

#include "gpu/runtime.hpp"

#include <algorithm>

namespace gsd::field {

namespace {

class CompositeProgram final : public DeviceProgram {
public:
    CompositeProgram(std::vector<CombineOp> ops, std::vector<const Field*> leaves)
        : ops_(std::move(ops)), leaves_(std::move(leaves)) {}

    void evaluate_into(const std::shared_ptr<gpu::Context>& ctx, const gpu::DeviceQueries& job,
                       const gpu::SubmitSync& sync) const override {
        gpu::Context& c = *ctx;
        const std::uint64_t n = job.count, stride = job.gradient ? 16 : 4, L = leaves_.size();
        // Chunks of whole multiples of 256 queries (every offset stays aligned) whose leaf
        // regions, bound together, fit the device's binding range.
        const std::uint64_t by_range = c.max_binding_bytes() / (L * stride) / 256 * 256;
        const std::uint64_t chunk = std::max<std::uint64_t>(256, std::min<std::uint64_t>({by_range, 1u << 22, gpu::round_up(n, 256)}));
        const std::uint64_t region = gpu::round_up(chunk * stride, 256);
        const gpu::Buffer temp(c, L * region, gpu::Memory::Device);
        const gpu::Buffer program = gpu::upload(c, ops_.data(), ops_.size() * sizeof(CombineOp));
        const gpu::Kernel& k = gpu::kernel(c, gpu::kernel_table::field_combine);
        gpu::Recorder rec(c);
        std::uint64_t first = 0;
        do {
            const std::uint64_t m = std::min(chunk, n - first);
            for (std::uint64_t l = 0; l < L && m; ++l) {
                gpu::DeviceQueries leaf;
                leaf.queries = {job.queries.buffer, job.queries.offset + first * 16};
                leaf.results = {temp.handle(), l * region};
                leaf.count = m;
                leaf.gradient = job.gradient;
                gpu::evaluate_into(*leaves_[l], ctx, leaf);  // returns when written
            }
            const bool last = first + m >= n;
            rec.begin();
            rec.barrier_after_external();
            if (m) {
                const kernels::CombinePush push{std::uint32_t(m), std::uint32_t(ops_.size()), std::uint32_t(region / 4),
                                                job.gradient ? 1u : 0u};
                rec.dispatch(k, {{&temp}, {&program}, {job.results.buffer, job.results.offset + first * stride, m * stride}}, &push,
                             sizeof push, std::uint32_t((m + k.workgroup - 1) / k.workgroup));
            }
            rec.barrier_before_external();
            if (last) rec.submit(sync);
            else rec.submit();
            rec.wait();  // `temp` is reused by the next chunk, and freed on return
            first += m;
        } while (first < n);
    }

private:
    std::vector<CombineOp> ops_;
    std::vector<const Field*> leaves_;
};

}  // namespace

std::shared_ptr<const DeviceProgram> make_composite_program(std::vector<CombineOp> ops, std::vector<const Field*> leaves) {
    return std::make_shared<CompositeProgram>(std::move(ops), std::move(leaves));
}

}  // namespace gsd::field
