// The .tori file: a fitted cloud, so it is fitted once. Layout (little endian), docs/formats.md:
//   0  char[8]  "GSDTORI1"
//   8  uint32   version (1)
//  12  uint32   header size in bytes (64)
//  16  uint64   point count N
//  24  float64  mean spacing h
//  32  char[32] fitter name, NUL padded
//  64  N records of 15 float64: p(3) n(3) s(3) a00 a10 a01 a11 a20 a02
#include <gsd/io.hpp>
#include <gsd/pat.hpp>

#include "io/io_internal.hpp"

#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

namespace gsd {

namespace {

static_assert(std::endian::native == std::endian::little, "the .tori writer assumes a little-endian host");

constexpr char kMagic[8] = {'G', 'S', 'D', 'T', 'O', 'R', 'I', '1'};
constexpr std::uint32_t kVersion = 1;
constexpr std::uint32_t kHeaderBytes = 64;
constexpr std::size_t kRecordDoubles = 15;

template <class T>
void put(std::string& out, const T& v) {
    out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

template <class T>
T get(const std::string& in, std::size_t offset) {
    T v;
    std::memcpy(&v, in.data() + offset, sizeof(T));
    return v;
}

}  // namespace

void save_tori(const std::string& path, const FittedTori& t) {
    const auto n = std::size_t(t.size());
    if (n == 0) throw Error(path, "no tori to save");
    if (std::size_t(t.normals.rows()) != n || std::size_t(t.tangents.rows()) != n || t.jets.size() != n)
        throw Error(path, "fitted tori have inconsistent counts");
    std::string out;
    out.reserve(kHeaderBytes + n * kRecordDoubles * 8);
    out.append(kMagic, 8);
    put(out, kVersion);
    put(out, kHeaderBytes);
    put(out, std::uint64_t(n));
    put(out, t.spacing);
    char name[32] = {};
    std::strncpy(name, t.fitter.c_str(), sizeof(name) - 1);
    out.append(name, sizeof(name));
    for (std::size_t i = 0; i < n; ++i) {
        const auto r = Eigen::Index(i);
        for (int c = 0; c < 3; ++c) put(out, t.points(r, c));
        for (int c = 0; c < 3; ++c) put(out, t.normals(r, c));
        for (int c = 0; c < 3; ++c) put(out, t.tangents(r, c));
        const Jet& j = t.jets[i];
        for (double a : {j.a00, j.a10, j.a01, j.a11, j.a20, j.a02}) put(out, a);
    }
    io::write_file_atomic(path, out);
}

FittedTori load_tori(const std::string& path) {
    // The shared reader: regular files only (a FIFO or /dev/zero would block or never end).
    const std::string in = io::detail::read_whole_file(path);
    if (in.size() < kHeaderBytes || std::memcmp(in.data(), kMagic, 8) != 0)
        throw Error(path, "not a .tori file (bad magic)");
    if (get<std::uint32_t>(in, 8) != kVersion)
        throw Error(path, "unsupported .tori version " + std::to_string(get<std::uint32_t>(in, 8)));
    if (get<std::uint32_t>(in, 12) != kHeaderBytes) throw Error(path, "bad .tori header size");
    const auto n = get<std::uint64_t>(in, 16);
    if (n == 0) throw Error(path, ".tori file holds no points");
    if (n > (in.size() - kHeaderBytes) / (kRecordDoubles * 8) ||
        in.size() != kHeaderBytes + n * kRecordDoubles * 8)
        throw Error(path, "truncated or oversized .tori file (size does not match its point count)");

    FittedTori t;
    t.spacing = get<double>(in, 24);
    t.fitter.assign(in.data() + 32, strnlen(in.data() + 32, 32));
    if (!(std::isfinite(t.spacing) && t.spacing >= 0)) throw Error(path, "bad spacing in .tori header");
    const auto rows = Eigen::Index(n);
    t.points.resize(rows, 3);
    t.normals.resize(rows, 3);
    t.tangents.resize(rows, 3);
    t.jets.resize(n);
    std::size_t off = kHeaderBytes;
    auto next = [&] { const double v = get<double>(in, off); off += 8; return v; };
    for (Eigen::Index r = 0; r < rows; ++r) {
        for (int c = 0; c < 3; ++c) t.points(r, c) = next();
        for (int c = 0; c < 3; ++c) t.normals(r, c) = next();
        for (int c = 0; c < 3; ++c) t.tangents(r, c) = next();
        Jet& j = t.jets[std::size_t(r)];
        j.a00 = next(); j.a10 = next(); j.a01 = next(); j.a11 = next(); j.a20 = next(); j.a02 = next();
        const bool finite = t.points.row(r).allFinite() && t.normals.row(r).allFinite() &&
                            t.tangents.row(r).allFinite() && std::isfinite(j.a00 + j.a10 + j.a01 + j.a11 + j.a20 + j.a02);
        if (!finite) throw Error(path, "non-finite value in record " + std::to_string(r));
        if (std::abs(t.normals.row(r).norm() - 1) > 1e-6 || std::abs(t.tangents.row(r).norm() - 1) > 1e-6 ||
            std::abs(t.normals.row(r).dot(t.tangents.row(r))) > 1e-6)
            throw Error(path, "record " + std::to_string(r) + " has a frame that is not orthonormal");
    }
    // The same limits as a cloud's: points squared in the blend and the trees must not overflow.
    check_coordinates(t.points, path, "torus");
    return t;
}

}  // namespace gsd
