// gsd on an application's own Vulkan device: the worked example of gsd/vulkan.hpp.
//
//   cmake -S examples/vulkan_interop -B build-example -DCMAKE_PREFIX_PATH=/opt/gsd
//   cmake --build build-example && build-example/vulkan_interop [CLOUD.ply [PICTURE.png]]
//
// Fits tori to a cloud (the demo torus, or a sampled one), then runs interop.cpp: an instance and
// device of the application's own, gsd adopting them, φ and ∇φ evaluated from one of the
// application's buffers into another, and a comparison with gsd's CPU reference; then a picture
// of the field's zero set rendered on the application's device (default interop.png).
#include "interop.hpp"

#include <gsd/io.hpp>
#include <gsd/shapes.hpp>

#include <cstdio>
#include <string>
#include <random>

int main(int argc, char** argv) {
    try {
        const gsd::PointCloud cloud = argc > 1 && std::string(argv[1]) != "-" ? gsd::io::read_point_cloud(argv[1])
                                               : gsd::shapes::torus({0, 0, 0}, 0.6, 0.25)->sample(4000, 1);
        const gsd::FittedTori tori = gsd::JetFitter().fit(cloud);
        gsd::Points queries(20000, 3);
        std::mt19937 rng(2);
        std::uniform_real_distribution<double> u(-1.0, 1.0);
        for (Eigen::Index i = 0; i < queries.rows(); ++i)
            for (int c = 0; c < 3; ++c) queries(i, c) = u(rng);
        return interop_check(tori, queries, argc > 2 ? argv[2] : "interop.png") ? 0 : 1;
    } catch (const gsd::Error& e) {
        std::fprintf(stderr, "vulkan_interop: %s: %s\n", e.where().c_str(), e.what());
        return 1;
    }
}
