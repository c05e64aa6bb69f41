// PLY reader and writer (hand-written: Debian packages no PLY library).
//
// The header is parsed into elements and properties; the body is then walked element by
// element in header order, reading the vertex (and face) element and skipping every other
// one, in any of the three encodings. Before anything is allocated, the counts in the header
// are checked against the bytes the file actually has, so a header that claims 10^12
// vertices is an error, not an allocation.
#include "io/io_internal.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace gsd::io::detail {

namespace {

enum class Scalar : std::uint8_t { i8, u8, i16, u16, i32, u32, f32, f64 };

std::size_t size_of(Scalar s) {
    switch (s) {
        case Scalar::i8:
        case Scalar::u8: return 1;
        case Scalar::i16:
        case Scalar::u16: return 2;
        case Scalar::i32:
        case Scalar::u32:
        case Scalar::f32: return 4;
        case Scalar::f64: return 8;
    }
    return 1;
}

bool is_integer(Scalar s) { return s != Scalar::f32 && s != Scalar::f64; }

/// PLY type names, both the original ones and the sized aliases.
bool scalar_from_name(std::string_view name, Scalar& out) {
    static constexpr std::array<std::pair<std::string_view, Scalar>, 16> kNames{{
        {"char", Scalar::i8},    {"int8", Scalar::i8},     {"uchar", Scalar::u8},
        {"uint8", Scalar::u8},   {"short", Scalar::i16},   {"int16", Scalar::i16},
        {"ushort", Scalar::u16}, {"uint16", Scalar::u16},  {"int", Scalar::i32},
        {"int32", Scalar::i32},  {"uint", Scalar::u32},    {"uint32", Scalar::u32},
        {"float", Scalar::f32},  {"float32", Scalar::f32}, {"double", Scalar::f64},
        {"float64", Scalar::f64},
    }};
    for (const auto& [n, s] : kNames)
        if (n == name) {
            out = s;
            return true;
        }
    return false;
}

/// One binary value of type t at p, widened to double.
double decode(const char* p, Scalar t, std::endian order) {
    switch (t) {
        case Scalar::i8: return double(static_cast<std::int8_t>(*p));
        case Scalar::u8: return double(static_cast<std::uint8_t>(*p));
        case Scalar::i16: return double(load<std::int16_t>(p, order));
        case Scalar::u16: return double(load<std::uint16_t>(p, order));
        case Scalar::i32: return double(load<std::int32_t>(p, order));
        case Scalar::u32: return double(load<std::uint32_t>(p, order));
        case Scalar::f32: return double(load<float>(p, order));
        case Scalar::f64: return load<double>(p, order);
    }
    return 0;
}

struct PlyProperty {
    std::string name;
    Scalar type = Scalar::f32;  // the item type, for a list
    bool is_list = false;
    Scalar count_type = Scalar::u8;
};

struct PlyElement {
    std::string name;
    std::uint64_t count = 0;
    std::vector<PlyProperty> properties;

    /// Index of the property called `name`, or -1.
    int find(std::string_view prop) const {
        for (std::size_t i = 0; i < properties.size(); ++i)
            if (properties[i].name == prop) return int(i);
        return -1;
    }
    /// Bytes of the smallest binary row (every list empty).
    std::uint64_t min_row_bytes() const {
        std::uint64_t n = 0;
        for (const auto& p : properties) n += size_of(p.is_list ? p.count_type : p.type);
        return n;
    }
    bool has_lists() const {
        for (const auto& p : properties)
            if (p.is_list) return true;
        return false;
    }
};

enum class PlyEncoding { ascii, binary_le, binary_be };

struct PlyHeader {
    PlyEncoding encoding = PlyEncoding::ascii;
    std::vector<PlyElement> elements;
    std::size_t body_offset = 0;  // first byte after the end_header line

    const PlyElement* find(std::string_view name) const {
        for (const auto& e : elements)
            if (e.name == name) return &e;
        return nullptr;
    }
};

// ---- header -----------------------------------------------------------------------------

/// Header lines end at '\n' ('\r\n' tolerated); returns the line and advances `pos`.
std::string_view next_header_line(std::string_view bytes, std::size_t& pos) {
    const std::size_t end = bytes.find('\n', pos);
    std::string_view line = bytes.substr(pos, end == std::string_view::npos ? bytes.size() - pos : end - pos);
    pos = end == std::string_view::npos ? bytes.size() : end + 1;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    return line;
}

Scalar header_type(const std::string& path, std::size_t line, std::string_view name) {
    Scalar s{};
    if (!scalar_from_name(name, s)) fail(path, at_line(line, "unknown PLY property type " + quoted(name)));
    return s;
}

PlyProperty parse_property_line(const std::string& path, std::size_t line, Tokens tokens) {
    std::string_view t1, t2, t3, extra;
    PlyProperty p;
    if (!tokens.next(t1)) fail(path, at_line(line, "PLY property line has no type"));
    if (t1 == "list") {
        if (!tokens.next(t1) || !tokens.next(t2) || !tokens.next(t3))
            fail(path, at_line(line, "PLY list property needs 'list <count type> <item type> <name>'"));
        p.is_list = true;
        p.count_type = header_type(path, line, t1);
        p.type = header_type(path, line, t2);
        p.name = std::string(t3);
        if (!is_integer(p.count_type))
            fail(path, at_line(line, "PLY list count type must be an integer type, found " + quoted(t1)));
    } else {
        if (!tokens.next(t2)) fail(path, at_line(line, "PLY property line has no name"));
        p.type = header_type(path, line, t1);
        p.name = std::string(t2);
    }
    if (tokens.next(extra)) fail(path, at_line(line, "unexpected " + quoted(extra) + " after PLY property"));
    return p;
}

PlyEncoding parse_format_line(const std::string& path, std::size_t line, Tokens tokens) {
    std::string_view kind, version;
    if (!tokens.next(kind) || !tokens.next(version))
        fail(path, at_line(line, "PLY format line needs '<encoding> 1.0'"));
    if (version != "1.0" && version != "1")
        fail(path, at_line(line, "unsupported PLY version " + quoted(version)));
    if (kind == "ascii") return PlyEncoding::ascii;
    if (kind == "binary_little_endian") return PlyEncoding::binary_le;
    if (kind == "binary_big_endian") return PlyEncoding::binary_be;
    fail(path, at_line(line, "unknown PLY encoding " + quoted(kind) +
                                 " (expected ascii, binary_little_endian or binary_big_endian)"));
}

PlyElement parse_element_line(const std::string& path, std::size_t line, Tokens tokens) {
    std::string_view name, count, extra;
    if (!tokens.next(name) || !tokens.next(count) || tokens.next(extra))
        fail(path, at_line(line, "PLY element line needs 'element <name> <count>'"));
    long long n = 0;
    if (!parse_int(count, n) || n < 0)
        fail(path, at_line(line, "PLY element " + quoted(name) + " has a bad count " + quoted(count)));
    PlyElement e;
    e.name = std::string(name);
    e.count = std::uint64_t(n);
    return e;
}

/// Checks that the body can hold what the header promises (lists counted as empty), with
/// saturating arithmetic so absurd counts cannot overflow past the check.
void check_body_fits(const std::string& path, const PlyHeader& h, std::size_t body_size) {
    std::uint64_t need = 0;
    for (const auto& e : h.elements) {
        // An ascii row is at least one character and one separator per property.
        const std::uint64_t row = h.encoding == PlyEncoding::ascii ? 2 * e.properties.size() : e.min_row_bytes();
        const std::uint64_t bytes = mul_sat(e.count, row);
        need = add_sat(need, bytes);
        // +1: the last ascii value may lack a trailing separator.
        if (need > std::uint64_t(body_size) + (h.encoding == PlyEncoding::ascii ? 1 : 0))
            fail(path, "PLY header promises " + std::to_string(e.count) + " '" + e.name +
                           "' elements, but the file is too short to hold them (" +
                           std::to_string(body_size) + " bytes of data; truncated or corrupt)");
    }
}

PlyHeader parse_ply_header(const std::string& path, std::string_view bytes) {
    std::size_t pos = 0;
    if (next_header_line(bytes, pos) != "ply") fail(path, "not a PLY file (first line is not 'ply')");
    PlyHeader h;
    bool have_format = false, ended = false;
    std::size_t line_no = 1;
    while (pos < bytes.size()) {
        const std::string_view line = next_header_line(bytes, pos);
        ++line_no;
        Tokens tokens(line);
        std::string_view key;
        if (!tokens.next(key)) continue;  // blank line: tolerated
        if (key == "end_header") {
            ended = true;
            break;
        }
        if (key == "comment" || key == "obj_info") continue;
        if (key == "format") {
            h.encoding = parse_format_line(path, line_no, tokens);
            have_format = true;
        } else if (key == "element") {
            h.elements.push_back(parse_element_line(path, line_no, tokens));
        } else if (key == "property") {
            if (h.elements.empty()) fail(path, at_line(line_no, "PLY property before any element"));
            h.elements.back().properties.push_back(parse_property_line(path, line_no, tokens));
        } else {
            fail(path, at_line(line_no, "unexpected PLY header line starting with " + quoted(key)));
        }
    }
    if (!ended) fail(path, "PLY header has no 'end_header' line (truncated or not a PLY file)");
    if (!have_format) fail(path, "PLY header has no 'format' line");
    h.body_offset = pos;
    check_body_fits(path, h, bytes.size() - pos);
    return h;
}

// ---- body -------------------------------------------------------------------------------

/// Reads values from the body in any encoding. Knows which element and row it is in, so that
/// a truncated or malformed body gets an error naming where it broke.
class PlyBodyReader {
public:
    PlyBodyReader(const std::string& path, const PlyHeader& h, std::string_view bytes)
        : path_(path), bytes_(bytes), pos_(h.body_offset), encoding_(h.encoding) {}

    void at(const PlyElement& e, std::uint64_t row) {
        element_ = &e;
        row_ = row;
    }

    double scalar(Scalar t) { return encoding_ == PlyEncoding::ascii ? ascii_scalar() : binary_scalar(t); }

    /// A list count; checks that the items it announces can still be in the file.
    std::uint64_t list_count(const PlyProperty& p) {
        const double v = scalar(p.count_type);
        if (!(v >= 0) || v != std::floor(v)) broken("list count " + std::to_string(v) + " is not a count");
        // Compared in double before the cast: an ascii count such as 1e300 must not overflow it.
        const double item = encoding_ == PlyEncoding::ascii ? 2 : double(size_of(p.type));
        if (v * item > double(bytes_.size() - pos_) + 1)
            broken("list '" + p.name + "' announces " + std::to_string(std::llround(std::min(v, 1e18))) +
                   " items; the file ends first (truncated)");
        return std::uint64_t(v);
    }

    void skip_property(const PlyProperty& p) {
        if (!p.is_list) {
            skip_scalar(p.type);
            return;
        }
        const std::uint64_t n = list_count(p);
        for (std::uint64_t i = 0; i < n; ++i) skip_scalar(p.type);
    }

    void skip_element(const PlyElement& e) {
        if (e.properties.empty()) return;
        if (fixed_binary_rows(e)) {
            take_rows(e);
            return;
        }
        for (std::uint64_t r = 0; r < e.count; ++r) {
            at(e, r);
            for (const auto& p : e.properties) skip_property(p);
            end_row();
        }
    }

    /// Ascii rows are lines: what is left on a row's line means the row has more values than
    /// the header declares (reading on would silently shift every later value).
    void end_row() {
        if (encoding_ != PlyEncoding::ascii) return;
        while (pos_ < bytes_.size() && (bytes_[pos_] == ' ' || bytes_[pos_] == '\t' || bytes_[pos_] == '\r')) ++pos_;
        if (pos_ < bytes_.size() && bytes_[pos_] != '\n')
            broken("more values on the line than the header's " + std::to_string(element_->properties.size()) +
                   " properties");
        if (pos_ < bytes_.size()) ++pos_;
    }

    /// Binary rows without lists all have the same size, so whole elements can be addressed
    /// directly instead of value by value.
    bool fixed_binary_rows(const PlyElement& e) const { return encoding_ != PlyEncoding::ascii && !e.has_lists(); }

    /// Start of an element of fixed-size binary rows; moves past all of its rows.
    const char* take_rows(const PlyElement& e) {
        at(e, 0);
        const std::uint64_t bytes = mul_sat(e.count, e.min_row_bytes());
        if (bytes > bytes_.size() - pos_) broken("the file ends early (truncated)");
        const char* start = bytes_.data() + pos_;
        pos_ += std::size_t(bytes);
        return start;
    }

    std::endian byte_order() const {
        return encoding_ == PlyEncoding::binary_be ? std::endian::big : std::endian::little;
    }

    [[noreturn]] void broken(const std::string& what) const {
        std::string where = element_ ? "PLY element '" + element_->name + "' row " + std::to_string(row_) : "PLY body";
        if (encoding_ == PlyEncoding::ascii) where = at_line(line_of(pos_), where);
        fail(path_, where + ": " + what);
    }

private:
    std::size_t line_of(std::size_t pos) const {
        std::size_t line = 1;
        for (std::size_t i = 0; i < pos && i < bytes_.size(); ++i) line += bytes_[i] == '\n';
        return line;
    }

    static bool is_space(char c) { return c == ' ' || c == '\n' || c == '\r' || c == '\t' || c == '\v' || c == '\f'; }

    std::string_view ascii_token() {
        while (pos_ < bytes_.size() && is_space(bytes_[pos_])) ++pos_;
        if (pos_ == bytes_.size()) broken("the file ends early (truncated)");
        const std::size_t start = pos_;
        while (pos_ < bytes_.size() && !is_space(bytes_[pos_])) ++pos_;
        return bytes_.substr(start, pos_ - start);
    }

    double ascii_scalar() {
        const std::string_view tok = ascii_token();
        double v = 0;
        if (!parse_double(tok, v)) {
            pos_ -= tok.size();
            broken("expected a number, found " + quoted(tok));
        }
        return v;
    }

    void take(std::size_t n) {
        if (bytes_.size() - pos_ < n) broken("the file ends early (truncated)");
    }

    double binary_scalar(Scalar t) {
        take(size_of(t));
        const char* p = bytes_.data() + pos_;
        pos_ += size_of(t);
        return decode(p, t, byte_order());
    }

    void skip_scalar(Scalar t) {
        if (encoding_ == PlyEncoding::ascii) {
            ascii_token();
        } else {
            take(size_of(t));
            pos_ += size_of(t);
        }
    }

    const std::string& path_;
    std::string_view bytes_;
    std::size_t pos_;
    PlyEncoding encoding_;
    const PlyElement* element_ = nullptr;
    std::uint64_t row_ = 0;
};

/// Which column of a vertex row each property fills: 0..2 = x y z, 3..5 = nx ny nz, -1 none.
std::vector<int> vertex_slots(const PlyElement& vertex) {
    std::vector<int> slots(vertex.properties.size(), -1);
    static constexpr std::array<std::pair<std::string_view, int>, 9> kNames{{
        {"x", 0}, {"y", 1}, {"z", 2}, {"nx", 3}, {"ny", 4}, {"nz", 5},
        {"normal_x", 3}, {"normal_y", 4}, {"normal_z", 5},  // some exporters' spelling
    }};
    for (std::size_t i = 0; i < vertex.properties.size(); ++i) {
        const auto& p = vertex.properties[i];
        if (p.is_list) continue;
        for (const auto& [name, slot] : kNames)
            if (p.name == name) slots[i] = slot;
    }
    return slots;
}

bool has_slots(const std::vector<int>& slots, int first, int last) {
    for (int s = first; s <= last; ++s)
        if (std::find(slots.begin(), slots.end(), s) == slots.end()) return false;
    return true;
}

/// Where vertex values go: slots 0..2 into `points`, 3..5 into `normals` (row-major N×3,
/// already sized); with no `normals`, slots 3..5 are skipped. Filling the result directly
/// avoids a second copy of a large cloud.
struct VertexTarget {
    double* points;
    double* normals = nullptr;

    bool wants(int slot) const { return slot >= 0 && (slot < 3 || normals != nullptr); }
    double& at(std::uint64_t row, int slot) const {
        return slot < 3 ? points[3 * row + std::uint64_t(slot)] : normals[3 * row + std::uint64_t(slot - 3)];
    }
};

/// The fast path for the common case (binary, no lists): each wanted column is read at its
/// fixed offset in the row, with no per-value bounds checks (take_rows checked the whole span).
void read_fixed_vertex_rows(PlyBodyReader& body, const PlyElement& e, const std::vector<int>& slots,
                            const VertexTarget& out) {
    struct Column {
        std::size_t offset;
        Scalar type;
        int slot;
    };
    std::vector<Column> columns;
    std::size_t offset = 0;
    for (std::size_t i = 0; i < e.properties.size(); ++i) {
        const Scalar t = e.properties[i].type;
        if (out.wants(slots[i])) columns.push_back({offset, t, slots[i]});
        offset += size_of(t);
    }
    const std::size_t row_bytes = offset;
    const std::endian order = body.byte_order();
    const char* data = body.take_rows(e);
    for (std::uint64_t r = 0; r < e.count; ++r) {
        const char* row = data + r * row_bytes;
        for (const Column& c : columns) out.at(r, c.slot) = decode(row + c.offset, c.type, order);
    }
}

/// Reads the vertex element into `out`, in any encoding.
void read_vertex_rows(PlyBodyReader& body, const PlyElement& e, const std::vector<int>& slots,
                      const VertexTarget& out) {
    if (body.fixed_binary_rows(e)) {
        read_fixed_vertex_rows(body, e, slots, out);
        return;
    }
    for (std::uint64_t r = 0; r < e.count; ++r) {
        body.at(e, r);
        for (std::size_t i = 0; i < e.properties.size(); ++i) {
            const auto& p = e.properties[i];
            if (p.is_list || !out.wants(slots[i])) {
                body.skip_property(p);
            } else {
                out.at(r, slots[i]) = body.scalar(p.type);
            }
        }
        body.end_row();
    }
}

int face_index_property(const std::string& path, const PlyElement& face) {
    for (const char* name : {"vertex_indices", "vertex_index"}) {
        const int i = face.find(name);
        if (i >= 0) {
            if (!face.properties[std::size_t(i)].is_list)
                fail(path, std::string("PLY face property '") + name + "' is not a list");
            return i;
        }
    }
    fail(path, "PLY face element has no 'vertex_indices' (or 'vertex_index') list property");
}

void read_faces(PlyBodyReader& body, const PlyElement& e, int index_prop, PolygonMesh& mesh) {
    mesh.indices.reserve(std::size_t(e.count) * 3);
    mesh.offsets.reserve(std::size_t(e.count) + 1);
    for (std::uint64_t r = 0; r < e.count; ++r) {
        body.at(e, r);
        for (std::size_t i = 0; i < e.properties.size(); ++i) {
            const auto& p = e.properties[i];
            if (int(i) != index_prop) {
                body.skip_property(p);
                continue;
            }
            const std::uint64_t n = body.list_count(p);
            if (n < 3) body.broken("face has " + std::to_string(n) + " vertices (needs at least 3)");
            for (std::uint64_t k = 0; k < n; ++k) {
                const double v = body.scalar(p.type);
                if (!(v >= 0 && v <= double(UINT32_MAX - 1)) || v != std::floor(v))
                    body.broken("vertex index " + std::to_string(v) + " is not a valid index");
                mesh.indices.push_back(std::uint32_t(v));
            }
            mesh.offsets.push_back(std::uint32_t(mesh.indices.size()));
        }
        body.end_row();
    }
}

const PlyElement& vertex_element(const std::string& path, const PlyHeader& h) {
    const PlyElement* v = h.find("vertex");
    if (!v) fail(path, "PLY file has no 'vertex' element");
    if (v->count > UINT32_MAX) fail(path, "PLY vertex count " + std::to_string(v->count) + " is too large");
    return *v;
}

void require_xyz(const std::string& path, const std::vector<int>& slots) {
    if (!has_slots(slots, 0, 2)) fail(path, "PLY vertex element lacks x, y and z properties");
}

// ---- writers ----------------------------------------------------------------------------

std::string header_start(std::size_t vertices) {
    return "ply\nformat binary_little_endian 1.0\ncomment written by gsd\nelement vertex " +
           std::to_string(vertices) + "\nproperty float x\nproperty float y\nproperty float z\n";
}

/// uchar counts are what most tools expect; faces past 255 corners need a wider count.
bool wide_face_counts(const PolygonMesh& mesh) {
    for (std::size_t f = 0; f < mesh.face_count(); ++f)
        if (mesh.face_size(f) > 255) return true;
    return false;
}

/// The face element's header lines, through end_header.
std::string face_header(const PolygonMesh& mesh) {
    return "element face " + std::to_string(mesh.face_count()) + "\nproperty list " +
           (wide_face_counts(mesh) ? "uint" : "uchar") + " int vertex_indices\nend_header\n";
}

void append_faces(std::string& out, const PolygonMesh& mesh) {
    const bool wide = wide_face_counts(mesh);
    for (std::size_t f = 0; f < mesh.face_count(); ++f) {
        const auto n = std::uint32_t(mesh.face_size(f));
        if (wide) append_le(out, n);
        else append_le(out, std::uint8_t(n));
        for (auto k = mesh.offsets[f]; k < mesh.offsets[f + 1]; ++k) append_le(out, std::int32_t(mesh.indices[k]));
    }
}

}  // namespace

PointCloud read_ply_cloud(const std::string& path, std::string_view bytes) {
    const PlyHeader h = parse_ply_header(path, bytes);
    const PlyElement& vertex = vertex_element(path, h);
    const std::vector<int> slots = vertex_slots(vertex);
    require_xyz(path, slots);
    const bool with_normals = has_slots(slots, 3, 5);
    PlyBodyReader body(path, h, bytes);
    for (const auto& e : h.elements) {
        if (&e != &vertex) {
            body.skip_element(e);
            continue;
        }
        PointCloud cloud;
        cloud.points.resize(Eigen::Index(e.count), 3);
        if (with_normals) cloud.normals.resize(Eigen::Index(e.count), 3);
        read_vertex_rows(body, e, slots, {cloud.points.data(), with_normals ? cloud.normals.data() : nullptr});
        return cloud;
    }
    fail(path, "PLY vertex element not found");  // unreachable: vertex_element found it
}

PolygonMesh read_ply_mesh(const std::string& path, std::string_view bytes) {
    const PlyHeader h = parse_ply_header(path, bytes);
    const PlyElement& vertex = vertex_element(path, h);
    const std::vector<int> slots = vertex_slots(vertex);
    require_xyz(path, slots);
    const PlyElement* face = h.find("face");
    if (!face) fail(path, "PLY file has no 'face' element (a point cloud, not a mesh)");
    const int index_prop = face_index_property(path, *face);

    PolygonMesh mesh;
    PlyBodyReader body(path, h, bytes);
    bool have_vertices = false, have_faces = false;
    for (const auto& e : h.elements) {
        if (have_vertices && have_faces) break;
        if (&e == &vertex) {
            mesh.vertices.resize(Eigen::Index(e.count), 3);
            read_vertex_rows(body, e, slots, {mesh.vertices.data()});
            have_vertices = true;
        } else if (&e == face) {
            read_faces(body, e, index_prop, mesh);
            have_faces = true;
        } else {
            body.skip_element(e);
        }
    }
    return mesh;
}

bool ply_has_faces(const std::string& path, std::string_view bytes) {
    const PlyHeader h = parse_ply_header(path, bytes);
    const PlyElement* face = h.find("face");
    return face && face->count > 0;
}

std::string ply_cloud_bytes(const PointCloud& cloud) {
    const auto n = std::size_t(cloud.size());
    std::string out = header_start(n) + "property float nx\nproperty float ny\nproperty float nz\nend_header\n";
    out.reserve(out.size() + n * 24);
    for (Eigen::Index i = 0; i < cloud.size(); ++i) {
        for (int k = 0; k < 3; ++k) append_le(out, float(cloud.points(i, k)));
        for (int k = 0; k < 3; ++k) append_le(out, float(cloud.normals(i, k)));
    }
    return out;
}

std::string ply_mesh_bytes(const PolygonMesh& mesh) {
    std::string out = header_start(std::size_t(mesh.vertices.rows())) + face_header(mesh);
    out.reserve(out.size() + std::size_t(mesh.vertices.rows()) * 12 + mesh.face_count() + mesh.indices.size() * 4);
    for (Eigen::Index i = 0; i < mesh.vertices.rows(); ++i)
        for (int k = 0; k < 3; ++k) append_le(out, float(mesh.vertices(i, k)));
    append_faces(out, mesh);
    return out;
}

std::string ply_colored_mesh_bytes(const PolygonMesh& mesh, const std::vector<std::array<std::uint8_t, 3>>& colors,
                                   const std::vector<double>& values, const std::string& value_name) {
    const bool with_values = !values.empty();
    std::string out = header_start(std::size_t(mesh.vertices.rows())) +
                      "property uchar red\nproperty uchar green\nproperty uchar blue\n" +
                      (with_values ? "property float " + value_name + "\n" : "") + face_header(mesh);
    const std::size_t row = 15 + (with_values ? 4 : 0);
    out.reserve(out.size() + std::size_t(mesh.vertices.rows()) * row + mesh.face_count() + mesh.indices.size() * 4);
    for (Eigen::Index i = 0; i < mesh.vertices.rows(); ++i) {
        for (int k = 0; k < 3; ++k) append_le(out, float(mesh.vertices(i, k)));
        for (std::uint8_t c : colors[std::size_t(i)]) append_le(out, c);
        if (with_values) append_le(out, float(values[std::size_t(i)]));
    }
    append_faces(out, mesh);
    return out;
}

}  // namespace gsd::io::detail
