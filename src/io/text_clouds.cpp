// Plain-text point clouds: .xyz/.xyzn/.txt (six numbers a line) and .pc ("v" / "vn" lines).
#include "io/io_internal.hpp"

#include <algorithm>

namespace gsd::io::detail {

namespace {

/// An upper bound on the number of data lines, to reserve once instead of regrowing a large
/// vector. Capped by the shortest possible data line, so a file of blank lines cannot make
/// the reservation large.
std::size_t max_data_lines(std::string_view bytes, std::size_t shortest_line) {
    const auto lines = std::size_t(std::count(bytes.begin(), bytes.end(), '\n')) + 1;
    return std::min(lines, bytes.size() / shortest_line + 1);
}

/// Parses exactly three finite numbers from `tokens` (the rest of a "v"/"vn" line).
void three_numbers(const std::string& path, std::size_t line, Tokens tokens, const char* what,
                   std::vector<double>& out) {
    const std::size_t n = tokens.count_left();
    if (n != 3)
        fail(path, at_line(line, std::string("'") + what + "' needs 3 numbers, found " + std::to_string(n)));
    std::string_view t;
    while (tokens.next(t)) out.push_back(finite_number(t, path, line, "a number"));
}

}  // namespace

PointCloud read_xyz_cloud(const std::string& path, std::string_view bytes) {
    std::vector<double> rows;
    rows.reserve(max_data_lines(bytes, 6) * 3);  // "0 0 0\n"
    LineScanner lines(bytes);
    std::string_view line;
    std::size_t width = 0;  // 6 (x y z nx ny nz) or 3 (x y z, no normals), set by the first row
    while (lines.next(line)) {
        Tokens tokens(line, /*commas=*/true);
        const std::size_t n = tokens.count_left();
        if (n == 0) continue;
        if (width == 0 && (n == 3 || n == 6)) width = n;
        if (n != width)
            fail(path, at_line(lines.line_number(),
                               width == 0 ? "expected 6 numbers (x y z nx ny nz) or 3 (x y z), found " + std::to_string(n) + " values"
                                          : "expected " + std::to_string(width) + " numbers like the first row, found " +
                                                std::to_string(n) + " values"));
        std::string_view t;
        while (tokens.next(t)) rows.push_back(finite_number(t, path, lines.line_number(), "a number"));
    }
    return cloud_from_rows(rows.data(), width ? rows.size() / width : 0, width != 3);
}

PointCloud read_pc_cloud(const std::string& path, std::string_view bytes) {
    std::vector<double> points, normals;
    const std::size_t reserve = max_data_lines(bytes, 8) / 2 * 3 + 3;  // "v 0 0 0\n"
    points.reserve(reserve);
    normals.reserve(reserve);
    LineScanner lines(bytes);
    std::string_view line, key;
    while (lines.next(line)) {
        Tokens tokens(line);
        if (!tokens.next(key)) continue;
        if (key == "v") {
            three_numbers(path, lines.line_number(), tokens, "v", points);
        } else if (key == "vn") {
            three_numbers(path, lines.line_number(), tokens, "vn", normals);
        } else {
            fail(path, at_line(lines.line_number(), "unexpected " + quoted(key) +
                                                        " (a .pc file has only 'v' and 'vn' lines)"));
        }
    }
    if (!normals.empty() && points.size() != normals.size())
        fail(path, std::to_string(points.size() / 3) + " 'v' lines but " + std::to_string(normals.size() / 3) +
                       " 'vn' lines (the counts must match)");
    PointCloud c;
    c.points = Eigen::Map<const Points>(points.data(), Eigen::Index(points.size() / 3), 3);
    c.normals = Eigen::Map<const Points>(normals.data(), Eigen::Index(normals.size() / 3), 3);
    return c;
}

std::string xyz_cloud_bytes(const PointCloud& cloud) {
    std::string out;
    out.reserve(std::size_t(cloud.size()) * 6 * 12);
    for (Eigen::Index i = 0; i < cloud.size(); ++i) {
        for (int k = 0; k < 6; ++k) {
            append_number(out, k < 3 ? cloud.points(i, k) : cloud.normals(i, k - 3));
            out += k < 5 ? ' ' : '\n';
        }
    }
    return out;
}

std::string pc_cloud_bytes(const PointCloud& cloud) {
    std::string out;
    out.reserve(std::size_t(cloud.size()) * 6 * 12 + std::size_t(cloud.size()) * 6);
    for (Eigen::Index i = 0; i < cloud.size(); ++i) {
        out += "v";
        for (int k = 0; k < 3; ++k) {
            out += ' ';
            append_number(out, cloud.points(i, k));
        }
        out += "\nvn";
        for (int k = 0; k < 3; ++k) {
            out += ' ';
            append_number(out, cloud.normals(i, k));
        }
        out += '\n';
    }
    return out;
}

}  // namespace gsd::io::detail
