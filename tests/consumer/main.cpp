// Consumer of an installed gsd (tests/consumer/run.sh): links libgsd and libvulkan together,
// calls the Vulkan loader directly, then evaluates a cloud's PAT field on the CPU and on a
// Vulkan device through gsd and compares them, and again on a device it created itself and
// handed to gsd (examples/vulkan_interop/interop.cpp). Exit 0 only if everything agrees.
#include <gsd/pat.hpp>
#include <gsd/shapes.hpp>
#include <gsd/gpu.hpp>
#include <gsd/io.hpp>

#include "interop.hpp"

#include <vulkan/vulkan.h>

#include <cmath>
#include <cstdio>
#include <random>

int main(int argc, char** argv) {
    // The application's own use of the loader: these resolve to libvulkan, not to anything in
    // libgsd (which keeps its loader's function pointers to itself).
    std::uint32_t api = 0;
    if (vkEnumerateInstanceVersion(&api) != VK_SUCCESS) {
        std::fprintf(stderr, "consumer: vkEnumerateInstanceVersion failed\n");
        return 1;
    }
    std::printf("consumer: loader Vulkan %u.%u, gsd %s\n", VK_API_VERSION_MAJOR(api),
                VK_API_VERSION_MINOR(api), std::string(gsd::version()).c_str());

    gsd::PointCloud cloud = gsd::shapes::torus({0, 0, 0}, 0.6, 0.25)->sample(2000, 7);
    gsd::validate(cloud, "torus sample");
    gsd::FittedTori tori = gsd::JetFitter().fit(cloud);

    gsd::Points queries(500, 3);
    std::mt19937 rng(1);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (Eigen::Index i = 0; i < queries.rows(); ++i)
        for (int c = 0; c < 3; ++c) queries(i, c) = u(rng);

    gsd::BlendOptions cpu_options;
    cpu_options.device = "cpu";
    gsd::BlendOptions gpu_options;
    gpu_options.device = "gpu";
    auto cpu = gsd::TorusField(tori, cpu_options).evaluate(queries, true);
    auto gpu = gsd::TorusField(tori, gpu_options).evaluate(queries, true);
    std::printf("consumer: evaluated on %s and %s\n", cpu.device.c_str(), gpu.device.c_str());
    if (gpu.device == "cpu") {
        std::fprintf(stderr, "consumer: no Vulkan device reached through gsd\n");
        return 1;
    }
    double worst = 0;
    for (std::size_t i = 0; i < cpu.phi.size(); ++i) worst = std::max(worst, double(std::abs(cpu.phi[i] - gpu.phi[i])));
    std::printf("consumer: max |phi_gpu - phi_cpu| = %.3g\n", worst);
    // The sign of φ at the torus's center hole (outside) and in its tube (inside).
    gsd::Points probes(2, 3);
    probes << 0, 0, 0, 0.6, 0, 0;
    auto at = gsd::TorusField(tori, cpu_options).evaluate(probes);
    std::printf("consumer: phi(hole) = %.4f, phi(tube) = %.4f\n", at.phi[0], at.phi[1]);
    bool ok = worst <= 1e-4 && at.phi[0] > 0 && at.phi[1] < 0;
    try {
        gsd::BlendOptions bad;
        bad.device = "no such device";
        (void)gsd::TorusField(tori, bad).evaluate(queries);
        std::fprintf(stderr, "consumer: an unknown device was accepted\n");
        ok = false;
    } catch (const gsd::Error& e) {  // gsd's exception type crosses the library boundary
        std::printf("consumer: caught gsd::Error: %s\n", e.what());
    }
    // A level set through the shared library's OpenVDB writer (when built with it).
    if (gsd::io::vdb_available()) {
        const gsd::GridSpec g = gsd::GridSpec::cube(24, gsd::Box{{-1, -1, -1}, {1, 1, 1}});
        const std::vector<float> phi = gsd::TorusField(tori, cpu_options).evaluate(g).phi;
        const std::string out = argc > 1 ? std::string(argv[1]) + "/consumer.vdb" : "consumer.vdb";
        gsd::io::write_vdb(out, g, phi);
        std::FILE* f = std::fopen(out.c_str(), "rb");
        char magic[4] = {};
        const bool read = f && std::fread(magic, 1, 4, f) == 4;
        if (f) std::fclose(f);
        if (!read || std::string(magic, 4) != " BDV") {
            std::fprintf(stderr, "consumer: %s is not a VDB file\n", out.c_str());
            ok = false;
        } else {
            std::printf("consumer: wrote %s\n", out.c_str());
        }
    }
    // The engine path: gsd on the application's own device and buffers (examples/vulkan_interop/interop.cpp).
    ok = interop_check(tori, queries) && ok;
    return ok ? 0 : 1;
}
