// Tests of read_curve_file: the curve text format (v/e/f/l records, #offset, comments) and
// the l/p lines of an .obj, every malformed case throwing gsd::Error that names the line, very
// long lines, and the real curve files in ../shared/data/surface-curves.
#include <doctest/doctest.h>

#include <gsd/io.hpp>

#include "support.hpp"

#include <filesystem>
#include <string>
#include <vector>

using namespace gsd;
using gsd::test::ScratchDir;
using gsd::test::write_bytes;

namespace {

/// The message of the gsd::Error that `f` throws, or "<no error>".
template <class F>
std::string error_of(F&& f) {
    try {
        f();
    } catch (const Error& e) {
        return e.what();
    }
    return "<no error>";
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

/// Writes `text` to a scratch file with the given name and reads it back.
io::CurveFile read_text(const ScratchDir& dir, const std::string& text, const std::string& name = "c.txt") {
    write_bytes(dir.file(name), text);
    return io::read_curve_file(dir.file(name));
}

/// The error reading `text` gives, or "<no error>".
std::string text_error(const ScratchDir& dir, const std::string& text, const std::string& name = "c.txt") {
    return error_of([&] { read_text(dir, text, name); });
}

std::vector<std::uint32_t> points_of(const io::CurveFile::Line& l) { return l.points; }

}  // namespace

// ---- the text format --------------------------------------------------------------------

TEST_CASE("indices are 1-based without #offset and 0-based after '#offset 0'") {
    ScratchDir dir("curves");
    const io::CurveFile one = read_text(dir, "v 1\nv 7\nl 1 2\n");
    REQUIRE(one.points.size() == 2);
    CHECK(one.points[0].index == 0);
    CHECK(one.points[1].index == 6);
    REQUIRE(one.lines.size() == 1);
    CHECK(points_of(one.lines[0]) == std::vector<std::uint32_t>{0, 1});
    CHECK(one.lines[0].line == 3);

    const io::CurveFile zero = read_text(dir, "#offset 0\nv 0\nv 7\nl 0 1 0\n");
    REQUIRE(zero.points.size() == 2);
    CHECK(zero.points[0].index == 0);
    CHECK(zero.points[1].index == 7);
    CHECK(points_of(zero.lines[0]) == std::vector<std::uint32_t>{0, 1, 0});

    // Any spacing; '#offset 1' is the default spelled out; a directive applies to what follows.
    const io::CurveFile spaced = read_text(dir, "  #   offset \t 0  \r\nv 0\r\n#offset 1\nv 1\nl 1 2\n");
    REQUIRE(spaced.points.size() == 2);
    CHECK(spaced.points[0].index == 0);
    CHECK(spaced.points[1].index == 0);
    CHECK(points_of(spaced.lines[0]) == std::vector<std::uint32_t>{0, 1});

    // A UTF-8 byte-order mark before '#offset 0' does not hide the directive.
    const io::CurveFile bom = read_text(dir, "\xEF\xBB\xBF#offset 0\nv 0\nv 7\nl 0 1\n");
    REQUIRE(bom.points.size() == 2);
    CHECK(bom.points[0].index == 0);
    CHECK(bom.points[1].index == 7);
    CHECK(bom.lines.size() == 1);
}

TEST_CASE("each point record kind keeps its values and line") {
    ScratchDir dir("curves");
    const io::CurveFile c = read_text(dir,
                                      "#offset 0\n"
                                      "v 5\n"
                                      "e 12 0.25\n"
                                      "f 3 0.2 0.5\n"
                                      "e 4 +1\n"
                                      "f 9 0 0\n"
                                      "l 0 1 2 3 4\n");
    REQUIRE(c.points.size() == 5);
    CHECK(c.points[0].kind == 'v');
    CHECK(c.points[0].index == 5);
    CHECK(c.points[0].line == 2);
    CHECK(c.points[1].kind == 'e');
    CHECK(c.points[1].index == 12);
    CHECK(c.points[1].a == 0.25);
    CHECK(c.points[1].line == 3);
    CHECK(c.points[2].kind == 'f');
    CHECK(c.points[2].index == 3);
    CHECK(c.points[2].a == 0.2);
    CHECK(c.points[2].b == 0.5);
    CHECK(c.points[2].line == 4);
    CHECK(c.points[3].a == 1.0);
    CHECK(c.points[4].a == 0.0);
    CHECK(c.points[4].b == 0.0);
    REQUIRE(c.lines.size() == 1);
    CHECK(points_of(c.lines[0]) == std::vector<std::uint32_t>{0, 1, 2, 3, 4});
    CHECK(c.lines[0].line == 7);
}

TEST_CASE("comments, commented-out l lines, n separators and forward references") {
    ScratchDir dir("curves");
    const io::CurveFile c = read_text(dir,
                                      "# a curve\n"
                                      "#offset 0\n"
                                      "\n"
                                      "v 1\n"
                                      "l 0 1   # the next point comes later\n"
                                      "v 2\n"
                                      "#l 1 2\n"
                                      "# l 1 5\n"
                                      "n\n"
                                      "v 3\n"
                                      "n 1\n"
                                      "v 4\n"
                                      "l 2 3");  // no newline at the end
    CHECK(c.points.size() == 4);
    REQUIRE(c.lines.size() == 2);
    CHECK(points_of(c.lines[0]) == std::vector<std::uint32_t>{0, 1});
    CHECK(points_of(c.lines[1]) == std::vector<std::uint32_t>{2, 3});
    CHECK(c.lines[1].line == 13);
}

TEST_CASE("barycentric weights may exceed their bounds by rounding slack only") {
    ScratchDir dir("curves");
    CHECK(read_text(dir, "f 1 0.6 0.4000000005\n").points.size() == 1);
    CHECK(read_text(dir, "f 1 -0.0000000005 1\n").points.size() == 1);
    CHECK(contains(text_error(dir, "f 1 0.6 0.41\n"), "line 1: barycentric weights"));
    CHECK(contains(text_error(dir, "v 1\nf 1 -0.01 0.5\n"), "line 2: barycentric weights"));
    CHECK(contains(text_error(dir, "v 1\nf 1 0.5 -0.01\n"), "line 2: barycentric weights"));
}

TEST_CASE("malformed curve text files throw gsd::Error naming the file and line") {
    ScratchDir dir("curves");
    const auto err = [&](const std::string& text) { return text_error(dir, text); };
    // Every message starts with the path (gsd::Error's where()) and names the line.
    try {
        read_text(dir, "v 1\nq 2\n");
        FAIL("no error");
    } catch (const Error& e) {
        CHECK(e.where() == dir.file("c.txt"));
        CHECK(std::string(e.what()) == "line 2: unknown record 'q' (expected v, e, f or l)");
    }
    CHECK(contains(err("v 1\nc 1 2\n"), "line 2: 'c' records (dual 1-chains) are not supported"));
    CHECK(contains(err("V 1\n"), "line 1: unknown record 'V'"));

    // Token counts.
    CHECK(contains(err("v\n"), "line 1: 'v' needs a vertex index, found 0 values"));
    CHECK(contains(err("v 1 2\n"), "line 1: 'v' needs a vertex index, found 2 values"));
    CHECK(contains(err("v 1\ne 1\n"), "line 2: 'e' needs an edge index and a parameter t, found 1 values"));
    CHECK(contains(err("e 1 0.5 0.5\n"), "line 1: 'e' needs an edge index and a parameter t, found 3 values"));
    CHECK(contains(err("f 1 0.2\n"), "line 1: 'f' needs a triangle index and barycentric weights u v, found 2"));
    CHECK(contains(err("f 1 0.2 0.3 0.5\n"), "line 1: 'f' needs a triangle index"));

    // Indices.
    CHECK(contains(err("v 1.5\n"), "line 1: expected an integer vertex index, found '1.5'"));
    CHECK(contains(err("v x\n"), "line 1: expected an integer vertex index, found 'x'"));
    CHECK(contains(err("e 1e3 0.5\n"), "line 1: expected an integer edge index, found '1e3'"));
    CHECK(contains(err("v 1\nv -3\n"), "line 2: negative vertex index '-3'"));
    CHECK(contains(err("#offset 0\nf -1 0 0\n"), "line 2: negative triangle index '-1'"));
    CHECK(contains(err("v -99999999999999999999\n"), "line 1: negative vertex index"));
    CHECK(contains(err("v 0\n"), "line 1: vertex index '0', but indices are 1-based here"));
    CHECK(contains(err("#offset 0\nv 4294967295\n"), "line 2: vertex index '4294967295' is too large"));
    CHECK(read_text(dir, "v 4294967295\n").points[0].index == 4294967294u);  // 1-based: the largest
    CHECK(contains(err("v 99999999999999999999\n"), "line 1: vertex index '99999999999999999999' is too large"));
    CHECK(contains(err("v 1\nv 2\nl 1 x\n"), "line 3: expected an integer point record, found 'x'"));
    CHECK(contains(err("v 1\nv 2\nl 1 -2\n"), "line 3: negative point record '-2'"));
    CHECK(contains(err("v 1\nv 2\nl 0 1\n"), "line 3: point record '0', but indices are 1-based here"));

    // Numbers.
    CHECK(contains(err("v 1\n\ne 1 1.5\n"), "line 3: edge parameter t = '1.5' is outside [0, 1]"));
    CHECK(contains(err("e 1 -0.25\n"), "line 1: edge parameter t = '-0.25' is outside [0, 1]"));
    CHECK(contains(err("e 1 nan\n"), "line 1: non-finite value 'nan'"));
    CHECK(contains(err("e 1 inf\n"), "line 1: non-finite value 'inf'"));
    CHECK(contains(err("f 1 0.5 nan\n"), "line 1: non-finite value 'nan'"));
    CHECK(contains(err("f 1 -inf 0.5\n"), "line 1: non-finite value '-inf'"));
    CHECK(contains(err("e 1 half\n"), "line 1: expected an edge parameter t, found 'half'"));

    // Polylines.
    CHECK(contains(err("v 1\nl 1\n"), "line 2: 'l' needs at least 2 point records, found 1"));
    CHECK(contains(err("v 1\nl\n"), "line 2: 'l' needs at least 2 point records, found 0"));
    CHECK(contains(err("v 1\nv 2\nl 1 2\nl 2 3\nv 3\nl 3 5\nl 9 1\n"),
                   "line 6: 'l' names point record 5, but the file has only 3 point records (numbered from 1)"));
    CHECK(contains(err("#offset 0\nv 1\nl 0 1\n"),
                   "line 3: 'l' names point record 1, but the file has only 1 point records (numbered from 0)"));

    // The directive.
    CHECK(contains(err("#offset 2\nv 1\n"), "line 1: '#offset' must be followed by 0 or 1 alone"));
    CHECK(contains(err("v 1\n#offset\n"), "line 2: '#offset' must be followed by 0 or 1 alone"));
    CHECK(contains(err("#offset 0 1\nv 1\n"), "line 1: '#offset' must be followed by 0 or 1 alone"));
    CHECK(read_text(dir, "#offsets 0\nv 1 # offset 0 here is a comment\n").points[0].index == 0);

    // Nothing to read.
    CHECK(contains(err("#offset 0\n# nothing\n\n"), "no point records (v, e or f lines)"));
    CHECK(contains(err("#offset 0\nl 0 1\n"), "no point records"));
    CHECK(contains(err(""), "file is empty"));
    CHECK(contains(error_of([&] { io::read_curve_file(dir.file("missing.txt")); }), "file not found"));
    CHECK(contains(error_of([&] { io::read_curve_file(dir.path().string()); }), "is a directory"));
}

TEST_CASE("the text format is read from any extension but .obj") {
    ScratchDir dir("curves");
    CHECK(read_text(dir, "v 2\nv 3\nl 1 2\n", "curve.curves").points.size() == 2);
    CHECK(read_text(dir, "v 2\nv 3\nl 1 2\n", "curve").lines.size() == 1);
    CHECK(read_text(dir, "v 1 2 3\nl 1 1\n", "mesh.OBJ").points.size() == 2);  // .OBJ is an obj
}

// ---- .obj l and p lines -------------------------------------------------------------------

TEST_CASE("obj l and p lines become vertex points; negative and v/vt indices") {
    ScratchDir dir("curves");
    const std::string obj =
        "# a mesh with a curve\n"
        "#offset 0\n"  // a curve-text directive means nothing in an .obj
        "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
        "vt 0 0\nvn 0 0 1\ng part\nusemtl red\ns off\n"
        "f 1 2 3\n"
        "l 1 2 3 1\n"
        "l -1 -3/1\n"
        "v 1 1 0\n"
        "p 4 -2\n"
        "l 4/2 -4\n";
    const io::CurveFile c = read_text(dir, obj, "m.obj");
    REQUIRE(c.points.size() == 10);
    const std::vector<std::uint64_t> expected{0, 1, 2, 0, 2, 0, 3, 2, 3, 0};
    for (std::size_t i = 0; i < expected.size(); ++i) {
        CAPTURE(i);
        CHECK(c.points[i].kind == 'v');
        CHECK(c.points[i].index == expected[i]);
    }
    CHECK(c.points[0].line == 12);
    CHECK(c.points[6].line == 15);
    REQUIRE(c.lines.size() == 3);
    CHECK(points_of(c.lines[0]) == std::vector<std::uint32_t>{0, 1, 2, 3});
    CHECK(points_of(c.lines[1]) == std::vector<std::uint32_t>{4, 5});
    CHECK(points_of(c.lines[2]) == std::vector<std::uint32_t>{8, 9});  // points 6, 7 came from 'p'
    CHECK(c.lines[2].line == 16);

    // Only p lines: points and no polylines.
    const io::CurveFile p = read_text(dir, "v 0 0 0\nv 1 0 0\np 2\n", "p.obj");
    CHECK(p.points.size() == 1);
    CHECK(p.lines.empty());
}

TEST_CASE("malformed obj curves throw gsd::Error naming the line") {
    ScratchDir dir("curves");
    const auto err = [&](const std::string& text) { return text_error(dir, text, "m.obj"); };
    const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    CHECK(contains(err(tri + "l 1 0\n"), "line 4: vertex index 0 (OBJ indices start at 1)"));
    CHECK(contains(err(tri + "l 1 -4\n"), "line 4: relative vertex index '-4' points before the first vertex"));
    CHECK(contains(err(tri + "l 1 a/2\n"), "line 4: bad vertex 'a/2' (expected an integer index)"));
    CHECK(contains(err(tri + "l 1 1.5\n"), "line 4: bad vertex '1.5'"));
    CHECK(contains(err(tri + "l 1 99999999999999999999\n"),
                   "line 4: vertex index '99999999999999999999' is too large"));
    CHECK(contains(err(tri + "p -99999999999999999999\n"), "line 4: relative vertex index '-9999"));
    CHECK(contains(err(tri + "l 1 4294967296\n"), "line 4: vertex index '4294967296' is too large"));
    CHECK(contains(err(tri + "l 2\n"), "line 4: 'l' needs at least 2 vertices, found 1"));
    CHECK(contains(err(tri + "p\n"), "line 4: 'p' needs at least 1 vertex"));
    // Out of range is known only at the end (positive indices may name later vertices).
    CHECK(contains(err(tri + "l 1 5\nl 1 2\nl 5 1\nv 0 0 1\n"),
                   "line 4: vertex index 5 is out of range (the file has 4 vertices)"));
    CHECK(read_text(dir, "l 1 4\n" + tri + "v 0 0 1\n", "m.obj").points[1].index == 3);
    CHECK(contains(err(tri + "f 1 2 3\n"), "no curves ('l' or 'p' lines) in the .obj"));
    CHECK(contains(err(""), "file is empty"));
}

// ---- large inputs -----------------------------------------------------------------------

TEST_CASE("a line with millions of point references reads without trouble") {
    ScratchDir dir("curves");
    constexpr std::uint32_t n = 2'000'000;
    std::string text = "#offset 0\nv 0\nv 1\nl";
    for (std::uint32_t i = 0; i < n; ++i) text += i % 2 ? " 1" : " 0";
    text += '\n';
    const io::CurveFile c = read_text(dir, text);
    REQUIRE(c.lines.size() == 1);
    CHECK(c.lines[0].points.size() == n);
    CHECK(c.lines[0].points.back() == 1);

    std::string obj = "v 0 0 0\nv 1 0 0\nl";
    for (std::uint32_t i = 0; i < n; ++i) obj += i % 2 ? " -1" : " 1";
    obj += "\np";
    for (std::uint32_t i = 0; i < n; ++i) obj += " 2";
    obj += '\n';
    const io::CurveFile o = read_text(dir, obj, "big.obj");
    CHECK(o.points.size() == 2 * std::size_t(n));
    REQUIRE(o.lines.size() == 1);
    CHECK(o.lines[0].points.size() == n);
    CHECK(o.points[1].index == 1);
}

TEST_CASE("a 10 MB curve file with every record kind reads completely") {
    // Load time is measured by hand (docs/formats.md), not asserted: tests check results.
    ScratchDir dir("curves");
    std::string text = "#offset 0\n";
    std::size_t records = 0, lines = 0;
    while (text.size() < 10'000'000) {
        text += "v 123456\ne 234567 0.123456789\nf 345678 0.25 0.5\n";
        text += "l " + std::to_string(records) + " " + std::to_string(records + 1) + " " +
                std::to_string(records + 2) + "\n";
        records += 3;
        ++lines;
    }
    const io::CurveFile c = read_text(dir, text);
    CHECK(c.points.size() == records);
    CHECK(c.lines.size() == lines);
    CHECK(c.points.back().kind == 'f');
    CHECK(c.points.back().b == 0.5);
}

// ---- the real files ---------------------------------------------------------------------

#if GSD_HAVE_SHARED_DATA
namespace {

struct Expected {
    const char* name;
    std::size_t points, lines, edge_points;
};

}  // namespace

TEST_CASE("every real curve file parses with the counts grep finds") {
    // Counts from grep: point records are the lines starting "v ", "e " or "f "; polylines
    // the lines starting "l " (commented-out "#l" lines excluded).
    const Expected text_files[] = {
        {"S.txt", 236, 232, 187},          {"annulus.txt", 386, 193, 0},
        {"asymmetric-torus.txt", 112, 112, 0}, {"bunny-brokenheart.txt", 97, 92, 31},
        {"bunny-heart.txt", 97, 97, 31},   {"double-torus.txt", 90, 90, 87},
        {"spots-on-spot.txt", 520, 260, 0}, {"torus-phi.txt", 114, 88, 0},
        {"twirl.txt", 2912, 1456, 0},
    };
    std::size_t checked = 0;
    for (const Expected& e : text_files) {
        CAPTURE(e.name);
        const std::string path = test::shared_data(std::string("surface-curves/") + e.name);
        const io::CurveFile c = io::read_curve_file(path);
        CHECK(c.points.size() == e.points);
        CHECK(c.lines.size() == e.lines);
        std::size_t edges = 0;
        for (const auto& p : c.points) edges += p.kind == 'e';
        CHECK(edges == e.edge_points);
        for (const auto& l : c.lines) CHECK(l.points.size() == 2);
        ++checked;
    }
    // Every .txt in the folder is listed above.
    std::size_t in_folder = 0;
    for (const auto& entry : std::filesystem::directory_iterator(test::shared_data("surface-curves")))
        in_folder += entry.path().extension() == ".txt";
    CHECK(in_folder == checked);

    // The first records of S.txt, 0-based.
    const io::CurveFile s = io::read_curve_file(test::shared_data("surface-curves/S.txt"));
    CHECK(s.points[0].kind == 'v');
    CHECK(s.points[0].index == 9289);
    CHECK(s.points[1].kind == 'e');
    CHECK(s.points[1].index == 24420);
    CHECK(s.points[1].a == 0.609275);
    CHECK(s.points[1].line == 4);
    CHECK(points_of(s.lines[0]) == std::vector<std::uint32_t>{0, 1});
    CHECK(points_of(s.lines.back()) == std::vector<std::uint32_t>{234, 235});
}

TEST_CASE("every real .obj with l lines parses with the counts grep finds") {
    // Points: the tokens of all l lines; polylines: the l lines (awk/grep on the files).
    const Expected obj_files[] = {
        {"DoubleTorusWithLoops.obj", 1093, 7, 0},
        {"DoubleTorusWithBrokenLoops.obj", 992, 15, 0},
    };
    for (const Expected& e : obj_files) {
        CAPTURE(e.name);
        const std::string path = test::shared_data(std::string("surface-curves/") + e.name);
        const io::CurveFile c = io::read_curve_file(path);
        CHECK(c.points.size() == e.points);
        CHECK(c.lines.size() == e.lines);
        for (const auto& p : c.points) CHECK(p.index < 17476);  // the files have 17476 vertices
    }
    const io::CurveFile loops = io::read_curve_file(test::shared_data("surface-curves/DoubleTorusWithLoops.obj"));
    REQUIRE(loops.lines[0].points.size() == 180);
    CHECK(loops.lines[0].line == 52433);
    CHECK(loops.points[0].index == 16588);
    CHECK(loops.points[179].index == 16582);

    // The other .obj files carry no curves, and say so.
    for (const auto& entry : std::filesystem::directory_iterator(test::shared_data("surface-curves"))) {
        const std::string name = entry.path().filename().string();
        if (entry.path().extension() != ".obj" || name.rfind("DoubleTorus", 0) == 0) continue;
        CAPTURE(name);
        CHECK(contains(error_of([&] { io::read_curve_file(entry.path().string()); }), "no curves"));
    }
}
#endif
