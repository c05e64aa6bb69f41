// Object File Format (.off): "OFF", counts "nv nf ne", nv vertex lines, nf face lines
// "n i1 ... in [color]". Read line by line so that what follows the indices on a face line
// (colors) and what follows x y z on a vertex line (COFF/NOFF extras) can be ignored.
#include "io/io_internal.hpp"

namespace gsd::io::detail {

namespace {

/// Next line with a token on it; false at the end of the file.
bool next_content_line(LineScanner& lines, Tokens& tokens) {
    std::string_view line;
    while (lines.next(line)) {
        tokens = Tokens(line);
        if (tokens.count_left() > 0) return true;
    }
    return false;
}

/// Accepts OFF and the 3-D variants whose vertex lines start with x y z (COFF, NOFF, CNOFF,
/// STOFF, ...). 4OFF/nOFF (other dimensions) and binary OFF are rejected.
void check_off_keyword(const std::string& path, std::string_view key) {
    if (key.size() < 3 || key.substr(key.size() - 3) != "OFF")
        fail(path, "not an OFF file (first keyword is " + quoted(key) + ", expected 'OFF')");
    const std::string_view prefix = key.substr(0, key.size() - 3);
    if (prefix.find_first_not_of("STCN") != std::string_view::npos)
        fail(path, "unsupported OFF variant " + quoted(key) + " (only 3-D OFF, COFF, NOFF, STOFF are read)");
}

std::uint64_t count_token(const std::string& path, std::size_t line, std::string_view t, const char* what) {
    long long v = 0;
    if (!parse_int(t, v) || v < 0)
        fail(path, at_line(line, std::string("bad ") + what + " count " + quoted(t)));
    return std::uint64_t(v);
}

}  // namespace

PolygonMesh read_off_mesh(const std::string& path, std::string_view bytes) {
    LineScanner lines(bytes);
    Tokens tokens{{}};
    std::string_view key, t;
    if (!next_content_line(lines, tokens)) fail(path, "file has no content");
    tokens.next(key);
    check_off_keyword(path, key);
    if (tokens.count_left() == 1) {  // "OFF BINARY", or a stray token where counts belong
        tokens.next(t);
        if (t == "BINARY") fail(path, "binary OFF is not supported");
        fail(path, at_line(lines.line_number(), "OFF header line needs the counts 'nv nf ne'"));
    }
    if (tokens.count_left() == 0 && !next_content_line(lines, tokens))
        fail(path, "OFF file ends before its counts line");
    const std::size_t counts_line = lines.line_number();
    std::string_view snv, snf;
    if (tokens.count_left() < 2 || !tokens.next(snv) || !tokens.next(snf))
        fail(path, at_line(counts_line, "OFF counts line needs 'nv nf ne'"));
    const std::uint64_t nv = count_token(path, counts_line, snv, "vertex");
    const std::uint64_t nf = count_token(path, counts_line, snf, "face");
    // The shortest vertex line is "0 0 0\n" (6 bytes), the shortest face "3 0 1 2\n" (8):
    // counts the file cannot hold are a lie, caught before anything is allocated.
    if (add_sat(mul_sat(nv, 6), mul_sat(nf, 8)) > std::uint64_t(bytes.size()) + 1)
        fail(path, "OFF header promises " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
                       " faces, but the file has only " + std::to_string(bytes.size()) +
                       " bytes (truncated or corrupt)");

    PolygonMesh mesh;
    mesh.vertices.resize(Eigen::Index(nv), 3);
    for (std::uint64_t i = 0; i < nv; ++i) {
        if (!next_content_line(lines, tokens))
            fail(path, "OFF file ends after " + std::to_string(i) + " of " + std::to_string(nv) + " vertices (truncated)");
        if (tokens.count_left() < 3)
            fail(path, at_line(lines.line_number(), "vertex line needs 3 numbers (x y z)"));
        for (int k = 0; k < 3; ++k) {
            tokens.next(t);
            mesh.vertices(Eigen::Index(i), k) = finite_number(t, path, lines.line_number(), "a coordinate");
        }
    }
    mesh.offsets.reserve(std::size_t(nf) + 1);
    mesh.indices.reserve(std::size_t(nf) * 3);
    for (std::uint64_t f = 0; f < nf; ++f) {
        if (!next_content_line(lines, tokens))
            fail(path, "OFF file ends after " + std::to_string(f) + " of " + std::to_string(nf) + " faces (truncated)");
        const std::size_t line = lines.line_number();
        tokens.next(t);
        const std::uint64_t n = count_token(path, line, t, "face vertex");
        if (n < 3) fail(path, at_line(line, "face has " + std::to_string(n) + " vertices (needs at least 3)"));
        if (n > tokens.count_left())
            fail(path, at_line(line, "face announces " + std::to_string(n) + " vertices but lists fewer"));
        for (std::uint64_t k = 0; k < n; ++k) {
            tokens.next(t);
            long long index = 0;
            if (!parse_int(t, index)) fail(path, at_line(line, "bad face vertex index " + quoted(t)));
            if (index < 0 || std::uint64_t(index) >= nv)
                fail(path, at_line(line, "face vertex index " + std::to_string(index) + " is out of range (" +
                                             std::to_string(nv) + " vertices)"));
            mesh.indices.push_back(std::uint32_t(index));
        }
        // Anything after the indices (a face color) is ignored.
        mesh.offsets.push_back(std::uint32_t(mesh.indices.size()));
    }
    return mesh;
}

std::string off_mesh_bytes(const PolygonMesh& mesh) {
    std::string out = "OFF\n" + std::to_string(mesh.vertices.rows()) + " " + std::to_string(mesh.face_count()) + " 0\n";
    out.reserve(std::size_t(mesh.vertices.rows()) * 40 + mesh.indices.size() * 8);
    for (Eigen::Index i = 0; i < mesh.vertices.rows(); ++i) {
        for (int k = 0; k < 3; ++k) {
            append_number(out, mesh.vertices(i, k));
            out += k < 2 ? ' ' : '\n';
        }
    }
    for (std::size_t f = 0; f < mesh.face_count(); ++f) {
        out += std::to_string(mesh.face_size(f));
        for (auto k = mesh.offsets[f]; k < mesh.offsets[f + 1]; ++k) {
            out += ' ';
            out += std::to_string(mesh.indices[k]);
        }
        out += '\n';
    }
    return out;
}

}  // namespace gsd::io::detail
