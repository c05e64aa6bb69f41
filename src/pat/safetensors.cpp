// The safetensors container: parse and check the header, view the tensors (safetensors.hpp).
#include "pat/safetensors.hpp"

#include <gsd/core.hpp>

#include "io/io_internal.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <utility>

namespace gsd::pat {

namespace {

using Json = nlohmann::json;

// The reference implementation refuses headers over 100 MB; so do we (a corrupt length must
// not make us allocate gigabytes).
constexpr std::uint64_t kMaxHeaderBytes = 100'000'000;

template <class T>
T load_le(const std::uint8_t* p) {
    std::array<std::uint8_t, sizeof(T)> b;
    std::memcpy(b.data(), p, sizeof(T));
    if constexpr (std::endian::native == std::endian::big) std::reverse(b.begin(), b.end());
    T v;
    std::memcpy(&v, b.data(), sizeof(T));
    return v;
}

std::size_t dtype_bytes(const std::string& dtype) {
    static const std::pair<const char*, std::size_t> known[] = {
        {"F64", 8}, {"F32", 4}, {"F16", 2}, {"BF16", 2}, {"I64", 8}, {"I32", 4}, {"I16", 2}, {"I8", 1},
        {"U64", 8}, {"U32", 4}, {"U16", 2}, {"U8", 1},  {"BOOL", 1}};
    for (const auto& [name, bytes] : known)
        if (dtype == name) return bytes;
    return 0;
}

std::size_t as_size(const Json& v, const std::string& where, const std::string& what) {
    if (!v.is_number_unsigned()) throw Error(where, what + " must be a non-negative integer");
    const auto u = v.get<std::uint64_t>();
    if (u > std::numeric_limits<std::size_t>::max()) throw Error(where, what + " is too large");
    return std::size_t(u);
}

std::map<std::string, std::string> parse_metadata(const Json& m, const std::string& where) {
    if (!m.is_object()) throw Error(where, "__metadata__ must be an object of strings");
    std::map<std::string, std::string> out;
    for (const auto& [key, value] : m.items()) {
        if (!value.is_string()) throw Error(where, "__metadata__ value '" + key + "' is not a string");
        out[key] = value.get<std::string>();
    }
    return out;
}

// One header entry; `data` is the data section its offsets index.
SafeTensor parse_entry(const std::string& name, const Json& e, std::span<const std::uint8_t> data,
                       const std::string& where) {
    const std::string at = "tensor '" + name + "'";
    if (!e.is_object()) throw Error(where, at + ": entry is not an object");
    for (const char* key : {"dtype", "shape", "data_offsets"})
        if (!e.contains(key)) throw Error(where, at + ": missing '" + key + "'");
    SafeTensor t;
    if (!e["dtype"].is_string()) throw Error(where, at + ": dtype is not a string");
    t.dtype = e["dtype"].get<std::string>();
    const std::size_t elem = dtype_bytes(t.dtype);
    if (elem == 0) throw Error(where, at + ": unknown dtype '" + t.dtype + "'");

    const Json& shape = e["shape"];
    if (!shape.is_array()) throw Error(where, at + ": shape is not an array");
    std::size_t count = 1;
    for (const Json& d : shape) {
        const std::size_t n = as_size(d, where, at + ": shape entry");
        // Every byte must lie in the data, so a count beyond it is an error, not an overflow.
        if (n != 0 && count > data.size() / n) throw Error(where, at + ": shape is larger than the file");
        count *= n;
        t.shape.push_back(n);
    }

    const Json& off = e["data_offsets"];
    if (!off.is_array() || off.size() != 2) throw Error(where, at + ": data_offsets must be [begin, end]");
    const std::size_t begin = as_size(off[0], where, at + ": data offset");
    const std::size_t end = as_size(off[1], where, at + ": data offset");
    if (begin > end || end > data.size())
        throw Error(where, at + ": data_offsets [" + std::to_string(begin) + ", " + std::to_string(end) +
                               "] out of range (data holds " + std::to_string(data.size()) + " bytes)");
    if (count > data.size() / elem || end - begin != count * elem)
        throw Error(where, at + ": data_offsets span " + std::to_string(end - begin) + " bytes but its shape and " +
                               t.dtype + " need " + std::to_string(count) + " × " + std::to_string(elem));
    t.data = data.subspan(begin, end - begin);
    return t;
}

// Tensors must tile the data section exactly, as the format requires: overlapping tensors
// alias each other, gaps hide bytes nobody checks.
void check_tiling(const SafeTensors& st, std::span<const std::uint8_t> data, const std::string& where) {
    std::vector<std::pair<std::size_t, std::size_t>> spans;
    for (const auto& [name, t] : st.tensors)
        spans.push_back({std::size_t(t.data.data() - data.data()), t.data.size()});
    std::sort(spans.begin(), spans.end());
    std::size_t at = 0;
    for (const auto& [begin, size] : spans) {
        if (begin != at) throw Error(where, begin < at ? "tensors overlap" : "data has bytes no tensor covers");
        at = begin + size;
    }
    if (at != data.size()) throw Error(where, "data has bytes no tensor covers (trailing bytes)");
}

}  // namespace

std::size_t SafeTensor::count() const {
    std::size_t n = 1;
    for (std::size_t d : shape) n *= d;
    return n;
}

SafeTensors parse_safetensors(std::span<const std::uint8_t> bytes, const std::string& where) {
    if (bytes.size() < 8) throw Error(where, "not a safetensors file (shorter than its 8-byte header length)");
    const auto header_bytes = load_le<std::uint64_t>(bytes.data());
    if (header_bytes > kMaxHeaderBytes || header_bytes > bytes.size() - 8)
        throw Error(where, "not a safetensors file or truncated (header length " + std::to_string(header_bytes) +
                               ", file size " + std::to_string(bytes.size()) + ")");
    const auto text = bytes.subspan(8, std::size_t(header_bytes));
    const auto data = bytes.subspan(8 + std::size_t(header_bytes));

    Json header;
    try {
        header = Json::parse(text.begin(), text.end());
    } catch (const Json::exception& e) {
        throw Error(where, std::string("bad safetensors JSON header: ") + e.what());
    }
    if (!header.is_object()) throw Error(where, "bad safetensors JSON header: not an object");

    SafeTensors st;
    for (const auto& [name, entry] : header.items()) {
        if (name == "__metadata__") st.metadata = parse_metadata(entry, where);
        else st.tensors.emplace(name, parse_entry(name, entry, data, where));
    }
    check_tiling(st, data, where);
    return st;
}

std::vector<double> tensor_as_double(const SafeTensor& t, const std::string& where, const std::string& name) {
    const std::size_t n = t.count();
    std::vector<double> out(n);
    if (t.dtype == "F32")
        for (std::size_t i = 0; i < n; ++i) out[i] = load_le<float>(t.data.data() + 4 * i);
    else if (t.dtype == "F64")
        for (std::size_t i = 0; i < n; ++i) out[i] = load_le<double>(t.data.data() + 8 * i);
    else throw Error(where, "tensor '" + name + "' is " + t.dtype + ", expected F32 or F64");
    return out;
}

std::vector<std::uint8_t> read_binary_file(const std::string& path) {
    // The shared reader: regular files only (a FIFO or device could block or never end).
    const std::string bytes = io::detail::read_whole_file(path);
    return std::vector<std::uint8_t>(bytes.begin(), bytes.end());
}

}  // namespace gsd::pat
