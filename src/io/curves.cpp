// Curves on triangle meshes, read as raw records: the curve text format (point records v/e/f,
// polylines l, the `#offset` directive) and the l/p lines of an .obj. Nothing here knows the
// mesh the curve lies on, so element indices are checked only for syntax and size; the
// surface module checks them against a mesh.
#include "io/io_internal.hpp"

#include <algorithm>
#include <limits>

namespace gsd::io {

namespace {

using detail::at_line;
using detail::fail;
using detail::LineScanner;
using detail::quoted;
using detail::Tokens;

/// Meshes index vertices, edges and triangles with uint32, so no larger index names anything
/// (and `Line::points` holds uint32 record numbers).
constexpr long long kIndexLimit = std::numeric_limits<std::uint32_t>::max();
/// Barycentric weights are written with a few digits; u + v may round to just over 1.
constexpr double kWeightSlack = 1e-9;

/// An optionally signed run of digits: an integer token, even one too long to parse.
bool is_integer_text(std::string_view token) {
    if (!token.empty() && (token.front() == '+' || token.front() == '-')) token.remove_prefix(1);
    return !token.empty() && token.find_first_not_of("0123456789") == std::string_view::npos;
}

/// What both readers share: the file, the current line, the result and the error text.
struct RecordReader {
    const std::string& path;
    std::size_t line = 0;
    CurveFile out;
    std::uint8_t base = 1;  // how the file numbers what it reads now: 1 until an `#offset 0` (.obj: always 1)

    [[noreturn]] void error(const std::string& what) const { fail(path, at_line(line, what)); }

    std::uint32_t add_point(CurveFile::Point p) {
        // Only a file of many gigabytes gets here; record numbers must still fit Line::points.
        if (out.points.size() >= std::size_t(kIndexLimit)) error("too many points (at most 4294967295)");
        p.line = line;
        p.base = base;
        out.points.push_back(p);
        return std::uint32_t(out.points.size() - 1);
    }
};

// ---- the curve text format --------------------------------------------------------------

class CurveTextReader : RecordReader {
public:
    explicit CurveTextReader(const std::string& file) : RecordReader{file} {}

    CurveFile read(std::string_view bytes) {
        LineScanner lines(bytes);
        std::string_view text, key;
        while (lines.next(text)) {
            line = lines.line_number();
            Tokens tokens(text);
            if (tokens.next(key))
                record(key, tokens);
            else
                directive(lines.comment());
        }
        check_references();
        return std::move(out);
    }

private:
    /// An `l` that names a point record not yet read (files may list a polyline before its
    /// last point); checked once the whole file is read.
    struct ForwardReference {
        std::uint32_t record;
        long long base;
        std::size_t line;
    };

    std::vector<ForwardReference> forward_;

    void record(std::string_view key, Tokens tokens) {
        if (key == "v") return vertex_point(tokens);
        if (key == "e") return edge_point(tokens);
        if (key == "f") return triangle_point(tokens);
        if (key == "l") return polyline(tokens);
        // `n` separates curve components in the published example files; it carries nothing
        // a curve needs (their reference reader skips it too).
        if (key == "n") return;
        if (key == "c")
            error("'c' records (dual 1-chains) are not supported: give the curve as points and 'l' lines");
        error("unknown record " + quoted(key) + " (expected v, e, f or l)");
    }

    /// A whole-line comment: `#offset 0` / `#offset 1` set the index base for what follows;
    /// any other comment (a commented-out `#l 3 4`) is ignored.
    void directive(std::string_view comment) {
        Tokens tokens(comment);
        std::string_view word, value;
        if (!tokens.next(word) || word != "offset") return;
        if (!tokens.next(value) || tokens.count_left() != 0 || (value != "0" && value != "1"))
            error("'#offset' must be followed by 0 or 1 alone");
        base = value == "0" ? 0 : 1;
    }

    void expect_values(const Tokens& tokens, std::size_t n, const char* key, const char* needs) const {
        const std::size_t found = tokens.count_left();
        if (found != n)
            error("'" + std::string(key) + "' needs " + needs + ", found " + std::to_string(found) + " values");
    }

    /// An index in the file's convention (0- or 1-based), returned 0-based.
    std::uint64_t index(std::string_view token, const char* what) const {
        long long i = 0;
        const bool parsed = detail::parse_int(token, i);
        if (parsed && i >= base && i - base < kIndexLimit) return std::uint64_t(i - base);
        const std::string name = std::string(what) + " " + quoted(token);
        if (!parsed && !is_integer_text(token))
            error("expected an integer " + std::string(what) + ", found " + quoted(token));
        if (token.front() == '-' && (!parsed || i < 0)) error("negative " + name);
        if (!parsed || i >= base) error(name + " is too large (mesh indices are 32-bit)");
        error(name + ", but indices are 1-based here (a '#offset 0' line before it makes them 0-based)");
    }

    void vertex_point(Tokens tokens) {
        expect_values(tokens, 1, "v", "a vertex index");
        std::string_view t;
        tokens.next(t);
        add_point({'v', index(t, "vertex index")});
    }

    void edge_point(Tokens tokens) {
        expect_values(tokens, 2, "e", "an edge index and a parameter t");
        std::string_view i, t;
        tokens.next(i);
        tokens.next(t);
        const std::uint64_t edge = index(i, "edge index");
        const double param = detail::finite_number(t, path, line, "an edge parameter t");
        if (param < 0 || param > 1) error("edge parameter t = " + quoted(t) + " is outside [0, 1]");
        add_point({'e', edge, param});
    }

    void triangle_point(Tokens tokens) {
        expect_values(tokens, 3, "f", "a triangle index and barycentric weights u v");
        std::string_view i, u_text, v_text;
        tokens.next(i);
        tokens.next(u_text);
        tokens.next(v_text);
        const std::uint64_t triangle = index(i, "triangle index");
        const double u = detail::finite_number(u_text, path, line, "a barycentric weight u");
        const double v = detail::finite_number(v_text, path, line, "a barycentric weight v");
        if (u < -kWeightSlack || v < -kWeightSlack || u + v > 1 + kWeightSlack)
            error("barycentric weights u = " + quoted(u_text) + ", v = " + quoted(v_text) +
                  " do not satisfy u >= 0, v >= 0, u + v <= 1");
        add_point({'f', triangle, u, v});
    }

    void polyline(Tokens tokens) {
        CurveFile::Line polyline{{}, line};
        std::uint32_t largest = 0;
        std::string_view t;
        while (tokens.next(t)) {
            const auto record = std::uint32_t(index(t, "point record"));
            largest = std::max(largest, record);
            polyline.points.push_back(record);
        }
        if (polyline.points.size() < 2)
            error("'l' needs at least 2 point records, found " + std::to_string(polyline.points.size()));
        if (largest >= out.points.size()) forward_.push_back({largest, base, line});
        out.lines.push_back(std::move(polyline));
    }

    void check_references() const {
        if (out.points.empty()) fail(path, "no point records (v, e or f lines)");
        for (const ForwardReference& f : forward_)
            if (f.record >= out.points.size())
                fail(path, at_line(f.line, "'l' names point record " + std::to_string(f.record + f.base) +
                                               ", but the file has only " + std::to_string(out.points.size()) +
                                               " point records (numbered from " + std::to_string(f.base) + ")"));
    }
};

// ---- l and p lines of an .obj -----------------------------------------------------------

class ObjCurveReader : RecordReader {
public:
    explicit ObjCurveReader(const std::string& file) : RecordReader{file} {}

    CurveFile read(std::string_view bytes) {
        LineScanner lines(bytes);
        std::string_view text, key;
        while (lines.next(text)) {
            line = lines.line_number();
            Tokens tokens(text);
            if (!tokens.next(key)) continue;
            if (key == "v") ++vertices_;
            if (key == "l") polyline(tokens);
            if (key == "p") isolated_points(tokens);
        }
        check_range();
        return std::move(out);
    }

private:
    std::size_t vertices_ = 0;  // `v` lines so far: negative indices count back from here
    std::uint64_t bound_ = 0;   // 1 + the largest vertex index named, checked at the end
    std::size_t bound_line_ = 0;

    /// "i" or "i/t": a 1-based vertex index, or a negative one relative to the last vertex.
    std::uint32_t vertex_point(std::string_view token) {
        const std::string_view text = token.substr(0, token.find('/'));
        long long i = 0;
        const bool parsed = detail::parse_int(text, i);
        if (!parsed && !is_integer_text(text))
            error("bad vertex " + quoted(token) + " (expected an integer index)");
        if (parsed && i == 0) error("vertex index 0 (OBJ indices start at 1)");
        const long long zero_based = !parsed ? 0 : i > 0 ? i - 1 : static_cast<long long>(vertices_) + i;
        if (text.front() == '-' && (!parsed || zero_based < 0))
            error("relative vertex index " + quoted(text) + " points before the first vertex");
        if (!parsed || zero_based >= kIndexLimit)
            error("vertex index " + quoted(text) + " is too large (mesh indices are 32-bit)");
        if (std::uint64_t(zero_based) >= bound_) {  // a new largest: keep where it first appears
            bound_ = std::uint64_t(zero_based) + 1;
            bound_line_ = line;
        }
        return add_point({'v', std::uint64_t(zero_based)});
    }

    void polyline(Tokens tokens) {
        CurveFile::Line polyline{{}, line};
        std::string_view t;
        while (tokens.next(t)) polyline.points.push_back(vertex_point(t));
        if (polyline.points.size() < 2)
            error("'l' needs at least 2 vertices, found " + std::to_string(polyline.points.size()));
        out.lines.push_back(std::move(polyline));
    }

    void isolated_points(Tokens tokens) {
        std::string_view t;
        std::size_t n = 0;
        for (; tokens.next(t); ++n) vertex_point(t);
        if (n == 0) error("'p' needs at least 1 vertex");
    }

    void check_range() const {
        if (out.points.empty()) fail(path, "no curves ('l' or 'p' lines) in the .obj");
        if (bound_ > vertices_)
            fail(path, at_line(bound_line_, "vertex index " + std::to_string(bound_) +
                                                " is out of range (the file has " + std::to_string(vertices_) +
                                                " vertices)"));
    }
};

}  // namespace

CurveFile read_curve_file(const std::string& path) {
    const std::string bytes = detail::read_whole_file(path);
    if (extension(path) == ".obj") return ObjCurveReader(path).read(bytes);
    return CurveTextReader(path).read(bytes);
}

}  // namespace gsd::io
