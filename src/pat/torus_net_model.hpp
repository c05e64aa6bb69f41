// TorusNet weights as the CPU reference and the GPU kernels both see them (docs/torusnet.md):
// one float array holding every tensor, and the offsets of each layer's parameters in it, so
// the GPU path uploads a single buffer. Private to the library.
#pragma once

#include <gsd/core.hpp>

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace gsd::pat {

/// Offsets (in floats) of a Linear layer's weight [out, in] (row-major) and bias [out].
struct NetLinear {
    int in = 0, out = 0;
    std::size_t weight = 0, bias = 0;
};

/// Offsets of a LayerNorm's γ and β (both [width]).
struct NetNorm {
    int width = 0;
    std::size_t weight = 0, bias = 0;
};

struct NetBlock {
    NetNorm norm1;
    NetLinear qkv;   ///< W → 3W, output rows [q | k | v]
    NetLinear proj;  ///< W → W
    NetNorm norm2;
    NetLinear fc1;   ///< W → F
    NetLinear fc2;   ///< F → W
};

inline constexpr int kTorusNetInputs = 7;   ///< features per token
inline constexpr int kTorusNetOutputs = 6;  ///< a00, a10, a01, a11, a20, a02

struct TorusNetModel {
    int k = 0, width = 0, blocks = 0, heads = 0, mlp = 0;
    std::string description;
    std::vector<float> params;  ///< every tensor, at the offsets below

    NetLinear embed;
    NetNorm embed_norm;
    std::vector<NetBlock> block;
    NetNorm final_norm;
    NetLinear head;

    /// Parses and validates a .safetensors file (names, shapes, dtype, offsets, metadata).
    /// `where` names the source in errors.
    static TorusNetModel from_bytes(std::span<const std::uint8_t> bytes, const std::string& where);
    static TorusNetModel load(const std::string& path);
    /// The model shipped in models/ and embedded in the library at build time.
    static const TorusNetModel& shipped();
};

}  // namespace gsd::pat
