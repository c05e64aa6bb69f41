// Distance sharpening on a Vulkan device: the PDHG loop of sharpen.hpp as two kernels per
// iteration (sharpen_dual, sharpen_primal), many iterations per submission, φ read back once.
#include "shm/sharpen.hpp"

#include "gpu/runtime.hpp"
#include "push_constants.h"

#include <algorithm>
#include <cstring>

namespace gsd::shm {

namespace {

// Iterations per submission: few enough that progress is reported and a watchdog never sees a
// long one, many enough that the submission's cost is nothing.
constexpr int kIterationsPerSubmit = 32;

}  // namespace

bool sharpen_gpu(const std::shared_ptr<gpu::Context>& ctx, const SharpenProblem& P, bool keep_sign, SharpenState& S,
                 int iterations, const ProgressFn& progress, std::string& why_not) {
    gpu::Context& c = *ctx;
    const std::size_t nodes = P.nodes(), rows = P.row_cell.size(), entries = P.entry_row.size();
    const std::uint64_t largest = std::max<std::uint64_t>({nodes * 12, entries * 8, rows * 32});
    if (largest > c.max_binding_bytes()) {
        why_not = "the grid (" + std::to_string(nodes) + " nodes) exceeds " + c.info().name + "'s storage buffer range";
        return false;
    }
    const std::uint64_t bytes = nodes * (4 + 4 + 12 + 4 + 12 + 8 + 4) + rows * 44 + entries * 8;
    if (c.device_memory_bytes() && bytes > c.device_memory_bytes() / 2) {
        why_not = "the grid does not fit in " + c.info().name + "'s memory";
        return false;
    }
    std::vector<float> tau_sign(2 * nodes);
    for (std::size_t i = 0; i < nodes; ++i) tau_sign[2 * i] = P.tau[i], tau_sign[2 * i + 1] = P.sign[i];
    std::vector<std::uint32_t> entry(2 * entries);
    for (std::size_t e = 0; e < entries; ++e) {
        entry[2 * e] = P.entry_row[e];
        std::memcpy(&entry[2 * e + 1], &P.entry_weight[e], 4);
    }
    gpu::Buffer phi = gpu::upload(c, S.phi.data(), nodes * 4), phi_bar = gpu::upload(c, S.phi_bar.data(), nodes * 4);
    gpu::Buffer p = gpu::upload(c, S.p.data(), nodes * 12), q = gpu::upload(c, S.q.data(), rows * 4);
    gpu::Buffer phi_sum = gpu::upload(c, S.phi_sum.data(), nodes * 4), p_sum = gpu::upload(c, S.p_sum.data(), nodes * 12),
                q_sum = gpu::upload(c, S.q_sum.data(), rows * 4);
    const gpu::Buffer row_cell = gpu::upload(c, P.row_cell.data(), rows * 4);
    const gpu::Buffer row_weight = gpu::upload(c, P.row_weight.data(), rows * 32);
    const gpu::Buffer steps = gpu::upload(c, tau_sign.data(), nodes * 8);
    const gpu::Buffer first = gpu::upload(c, P.node_first.data(), (nodes + 1) * 4);
    const gpu::Buffer entry_buf = gpu::upload(c, entry.data(), entries * 8);

    kernels::SharpenPush push{};
    for (int a = 0; a < 3; ++a) push.dims[a] = std::uint32_t(P.n[a]), push.inv_h[a] = P.inv_h[a];
    push.nodes = std::uint32_t(nodes);
    push.rows = std::uint32_t(rows);
    push.sigma_d = P.sigma_d;
    push.row_scale = P.row_scale;
    push.damping = P.damping;
    push.sign_floor = P.sign_floor;
    push.keep_sign = keep_sign ? 1u : 0u;
    push.inv_count = 1.0f / float(P.restart);  // as restart() in sharpen.cpp: 1/count, then products
    const gpu::Kernel& dual = gpu::kernel(c, gpu::kernel_table::sharpen_dual);
    const gpu::Kernel& primal = gpu::kernel(c, gpu::kernel_table::sharpen_primal);
    const gpu::Kernel& restart = gpu::kernel(c, gpu::kernel_table::sharpen_restart);
    const auto groups = [&](std::size_t items, const gpu::Kernel& k) {
        return std::uint32_t((items + k.workgroup - 1) / k.workgroup);
    };
    gpu::Recorder rec(c);
    int summed = S.summed;  // iterations since the last restart, as the CPU loop counts them
    for (int done = 0; done < iterations;) {
        const int batch = std::min(kIterationsPerSubmit, iterations - done);
        rec.begin();
        for (int it = 0; it < batch; ++it) {
            rec.dispatch(dual, {{&phi_bar}, {&p}, {&q}, {&row_cell}, {&row_weight}, {&p_sum}, {&q_sum}}, &push, sizeof push,
                         groups(nodes + rows, dual));
            rec.barrier();
            rec.dispatch(primal, {{&phi}, {&phi_bar}, {&p}, {&q}, {&steps}, {&first}, {&entry_buf}, {&phi_sum}}, &push,
                         sizeof push, groups(nodes, primal));
            rec.barrier();
            if (++summed == P.restart) {
                rec.dispatch(restart, {{&phi}, {&phi_bar}, {&p}, {&q}, {&phi_sum}, {&p_sum}, {&q_sum}}, &push, sizeof push,
                             groups(nodes + rows, restart));
                rec.barrier();
                summed = 0;
            }
        }
        rec.submit();
        rec.wait();
        done += batch;
        if (progress) progress("sharpen", double(done) / iterations);
    }
    gpu::download(c, phi, S.phi.data(), nodes * 4);  // the rest of the state stays on the device: nothing resumes it
    return true;
}

}  // namespace gsd::shm
