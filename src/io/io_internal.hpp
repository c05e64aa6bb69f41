// io_internal.hpp — what the io module's format files share: whole-file reading, error text,
// text scanning with std::from_chars, byte-order helpers, and the per-format entry points
// that io.cpp dispatches to by extension. Private to src/io.
#pragma once

#include <gsd/io.hpp>

#include <array>
#include <bit>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <string>
#include <string_view>

namespace gsd::io::detail {

// ---- files ----------------------------------------------------------------------------

/// The whole file in memory (one read). Throws gsd::Error for a missing file, a directory,
/// a non-regular file (FIFO, device: reading those could hang or never end), a read error,
/// or an empty file.
std::string read_whole_file(const std::string& path);

/// Throws like read_whole_file, without reading the contents.
void require_regular_file(const std::string& path);

// ---- error text -------------------------------------------------------------------------

[[noreturn]] void fail(const std::string& path, const std::string& what);
/// "line N: what".
std::string at_line(std::size_t line, const std::string& what);
/// A token as it may appear in an error message: quoted, non-printable bytes escaped,
/// long tokens cut (garbage files have garbage tokens).
std::string quoted(std::string_view token);

// ---- text scanning ----------------------------------------------------------------------

/// The text without a leading UTF-8 byte-order mark (some Windows editors write one).
inline std::string_view without_byte_order_mark(std::string_view text) {
    return text.substr(0, 3) == "\xEF\xBB\xBF" ? text.substr(3) : text;
}

/// Walks the lines of a text file: strips "\r", and everything from '#' on (every text
/// format here uses '#' for comments). Line numbers count from 1. A UTF-8 byte-order mark
/// at the start (some Windows editors write one) is skipped.
class LineScanner {
public:
    explicit LineScanner(std::string_view text) : rest_(without_byte_order_mark(text)) {}
    /// Next line (possibly blank after comment stripping); false at the end of the text.
    bool next(std::string_view& line);
    std::size_t line_number() const { return line_; }
    /// What followed '#' on the current line ("" if none): for formats that put directives
    /// in comments (`#offset 0` in curve files).
    std::string_view comment() const { return comment_; }

private:
    std::string_view rest_;
    std::string_view comment_;
    std::size_t line_ = 0;
};

/// Splits a line into tokens at whitespace (and at commas when `commas` is set).
class Tokens {
public:
    explicit Tokens(std::string_view line, bool commas = false) : rest_(line), commas_(commas) {}
    bool next(std::string_view& token);
    /// Tokens left, without consuming them.
    std::size_t count_left() const;

private:
    bool is_separator(char c) const;
    std::string_view rest_;
    bool commas_;
};

/// Parses a whole token as a double (a leading '+' allowed). NaN and Inf parse; callers
/// that need finite values check. False if the token is not entirely a number.
bool parse_double(std::string_view token, double& out);
/// Parses a whole token as a signed integer.
bool parse_int(std::string_view token, long long& out);
/// Parses a finite double or throws "line N: expected <what>, found 'token'".
double finite_number(std::string_view token, const std::string& path, std::size_t line,
                     const char* what);

/// Appends the shortest text that reads back as exactly `v`.
void append_number(std::string& out, double v);

// ---- binary helpers -------------------------------------------------------------------

template <class T>
T byteswapped(T v) {
    unsigned char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
    std::memcpy(&v, b, sizeof(T));
    return v;
}

/// Loads a T stored at p (any alignment) in the given byte order.
template <class T>
T load(const char* p, std::endian order) {
    T v;
    std::memcpy(&v, p, sizeof(T));
    return order == std::endian::native ? v : byteswapped(v);
}

/// Appends T in little-endian byte order.
template <class T>
void append_le(std::string& out, T v) {
    if constexpr (std::endian::native != std::endian::little) v = byteswapped(v);
    out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

/// a·b and a+b, saturating at UINT64_MAX: size checks on counts from untrusted headers.
std::uint64_t mul_sat(std::uint64_t a, std::uint64_t b);
std::uint64_t add_sat(std::uint64_t a, std::uint64_t b);

/// Copies N×6 values (x y z nx ny nz per row), or N×3 (x y z) without normals, into a cloud.
PointCloud cloud_from_rows(const double* xyzn, std::size_t n, bool with_normals = true);

// ---- formats (readers return unvalidated data; io.cpp validates) ---------------------
// Cloud readers return `normals` empty when the file has none; io.cpp decides whether that
// is an error.

PointCloud read_ply_cloud(const std::string& path, std::string_view bytes);
PolygonMesh read_ply_mesh(const std::string& path, std::string_view bytes);
bool ply_has_faces(const std::string& path, std::string_view bytes);
std::string ply_cloud_bytes(const PointCloud& cloud);
std::string ply_mesh_bytes(const PolygonMesh& mesh);
/// A mesh with per-vertex uchar colors and, if `values` is non-empty, a float property
/// `value_name` (both already checked against the vertex count).
std::string ply_colored_mesh_bytes(const PolygonMesh& mesh, const std::vector<std::array<std::uint8_t, 3>>& colors,
                                   const std::vector<double>& values, const std::string& value_name);

PointCloud read_xyz_cloud(const std::string& path, std::string_view bytes);
std::string xyz_cloud_bytes(const PointCloud& cloud);

PointCloud read_pc_cloud(const std::string& path, std::string_view bytes);
std::string pc_cloud_bytes(const PointCloud& cloud);

PointCloud read_obj_cloud(const std::string& path, std::string_view bytes);
PolygonMesh read_obj_mesh(const std::string& path, std::string_view bytes);
bool obj_has_faces(std::string_view bytes);
std::string obj_cloud_bytes(const PointCloud& cloud);
std::string obj_mesh_bytes(const PolygonMesh& mesh);

PolygonMesh read_off_mesh(const std::string& path, std::string_view bytes);
std::string off_mesh_bytes(const PolygonMesh& mesh);

PolygonMesh read_stl_mesh(const std::string& path, std::string_view bytes);
std::string stl_mesh_bytes(const PolygonMesh& mesh);

NpyArray parse_npy(const std::string& path, std::string_view bytes);
/// parse_npy into storage the caller provides: `storage(count)` returns room for count doubles
/// (called once, after the header is checked); `shape` gets the array's shape.
void parse_npy_into(const std::string& path, std::string_view bytes, std::vector<std::size_t>& shape,
                    const std::function<double*(std::size_t count)>& storage);
std::string npy_bytes(const std::string& path, const std::vector<std::size_t>& shape,
                      const float* values, std::size_t count);
std::string npy_bytes(const std::string& path, const std::vector<std::size_t>& shape,
                      const std::int32_t* values, std::size_t count);
/// "(3,)", "(4, 6)": a shape as numpy prints it.
std::string npy_shape_text(const std::vector<std::size_t>& shape);
PointCloud read_npy_cloud(const std::string& path, std::string_view bytes);
std::string npy_cloud_bytes(const PointCloud& cloud);

}  // namespace gsd::io::detail
