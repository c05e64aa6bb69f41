// The safetensors container (https://github.com/huggingface/safetensors): an 8-byte
// little-endian header length, a JSON header {name: {dtype, shape, data_offsets}, __metadata__},
// then the raw little-endian data. This layer checks the container only (sizes, offsets,
// dtypes it knows); what the tensors must be is the caller's business (torus_net_model.cpp).
// Private to the library; the tests read golden files with it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

namespace gsd::pat {

struct SafeTensor {
    std::string dtype;                   ///< "F32", "F64", "I32", ... as written
    std::vector<std::size_t> shape;      ///< empty for a scalar
    std::span<const std::uint8_t> data;  ///< a view into the parsed bytes
    std::size_t count() const;           ///< product of the shape
};

struct SafeTensors {
    std::map<std::string, SafeTensor> tensors;
    std::map<std::string, std::string> metadata;  ///< __metadata__ (string values only)
};

/// Parses and checks the container: header length against the size, valid JSON, every entry
/// with a known dtype, a shape, and offsets that lie in the data and match the shape's byte
/// count; tensors tile the data without overlap or gaps. The result views into `bytes`.
/// Throws gsd::Error(where, ...) on anything else.
SafeTensors parse_safetensors(std::span<const std::uint8_t> bytes, const std::string& where);

/// The values of an F32 or F64 tensor, converted to double (throws for other dtypes).
std::vector<double> tensor_as_double(const SafeTensor& t, const std::string& where, const std::string& name);

/// Reads a whole regular file (throws gsd::Error(path, ...) if it cannot).
std::vector<std::uint8_t> read_binary_file(const std::string& path);

}  // namespace gsd::pat
