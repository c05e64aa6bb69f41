// gsd field EXPR: a field made of fields (gsd/field_algebra.hpp), named by files and combined
// by operators, evaluated on a grid or at queries (docs/field.md).
//
//   gsd field "union(a.tori, offset(b.npy, 0.05))" --grid 128 -o out.npy
//
// The expression: a leaf is a file — fitted tori (.tori), a grid read back (.npy with its
// sidecar, or an OpenVDB .vdb), a mesh (a file with faces: its exact signed distance, gsd sdf's automatic sign) or
// an oriented point cloud (fitted by the jet fitter and blended as PAT) — and an operator is
// NAME(operand, …): union and intersection of two or more, difference of two, their smooth_
// variants with a radius last, offset and shell with a distance. A path with parentheses,
// commas or spaces at its ends goes in quotes.
#include "cli.hpp"
#include "gpu/field_device.hpp"
#include "gpu/on_device.hpp"

#include <gsd/field_algebra.hpp>
#include <gsd/io.hpp>
#include <gsd/pat.hpp>
#include <gsd/sdf.hpp>

#include <cctype>
#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace gsd::cli {

namespace {

/// What a parsed (sub)expression is: its field, and the box its zero set can reach (the leaves'
/// boxes, grown by outward offsets), for a grid's default bounds.
struct Parsed {
    FieldPtr field;
    Box box;
    Points seeds;  ///< points on the zero set, for a PAT leaf (a cloud or .tori): opening by resampling
};

/// How leaves become fields.
struct LeafOptions {
    std::string device;
    int morphology_grid = kMorphologyGrid;  ///< nodes per axis of opening's and closing's grids
    bool morphology_by_grid = false;        ///< a grid even for a cloud's opening (not resampling)
};

Box merged(const Box& a, const Box& b) { return {a.lo.cwiseMin(b.lo), a.hi.cwiseMax(b.hi)}; }
Box grown(const Box& b, double r) {
    const Eigen::Vector3d d = Eigen::Vector3d::Constant(std::max(r, 0.0));
    return {b.lo - d, b.hi + d};
}

Parsed load_leaf(const std::string& path, const LeafOptions& o) {
    if (!std::filesystem::exists(path)) throw Error(path, "no such file");
    const std::string ext = io::extension(path);
    if (ext == ".tori") {
        FittedTori t = load_tori(path);
        const Box box = bounding_box(t.points);
        Points seeds = t.points;
        BlendOptions b;
        b.device = o.device;
        return {std::make_shared<TorusField>(std::move(t), b), box, std::move(seeds)};
    }
    if (ext == ".npy") {
        const io::NpyArray a = io::read_grid(path);
        const GridSpec g = grid_of(a.shape, path, {});
        std::vector<float> values(a.data.begin(), a.data.end());
        std::shared_ptr<GridField> f;
        naming_file(path, "values", [&] { f = std::make_shared<GridField>(g, std::move(values)); });
        return {f, g.box};
    }
    if (ext == ".vdb") {
        std::pair<GridSpec, std::vector<float>> grid = io::read_vdb(path);
        const Box box = grid.first.box;
        std::shared_ptr<GridField> f;
        naming_file(path, "values", [&] { f = std::make_shared<GridField>(grid.first, std::move(grid.second)); });
        return {f, box};
    }
    if (io::file_has_faces(path)) {
        PolygonMesh mesh = io::read_mesh(path);
        const Box box = bounding_box(mesh.vertices);
        MeshSdfOptions m;
        m.device = o.device;
        std::shared_ptr<MeshSdfField> f;
        naming_file(path, "mesh", [&] { f = std::make_shared<MeshSdfField>(std::move(mesh), m); });
        return {f, box};
    }
    PointCloud cloud = io::read_point_cloud(path);
    // As `pat fit` does by default: a flipped normal's torus has the wrong sign.
    turn_back_normals(cloud, path + ": ", "fit a .tori with `pat fit --keep-normals` to keep them");
    Progress progress("fit " + std::filesystem::path(path).filename().string());
    FittedTori t = JetFitter().fit(cloud, progress.fn());
    progress.finish();
    const Box box = bounding_box(t.points);
    Points seeds = t.points;
    BlendOptions b;
    b.device = o.device;
    return {std::make_shared<TorusField>(std::move(t), b), box, std::move(seeds)};
}

/// A recursive-descent parser of EXPR; errors name the character (1-based) where it went wrong
/// and what it expected there.
class ExpressionParser {
public:
    ExpressionParser(std::string text, LeafOptions options) : text_(std::move(text)), options_(std::move(options)) {}

    Parsed parse() {
        Parsed p = expression();
        skip_space();
        if (pos_ < text_.size()) fail("expected the end of the expression after a complete field");
        return p;
    }

private:
    // An operand is a field or a number; a call's arguments are these.
    struct Operand {
        std::optional<Parsed> field;
        double number = 0;
        std::size_t at = 0;  // where it starts, for errors
    };

    [[noreturn]] void fail(const std::string& what, std::size_t at) const {
        throw Error("expression", "at character " + std::to_string(at + 1) + " of '" + excerpt(at) + "': " + what);
    }
    // The expression, or for a long one the 80 characters about `at`.
    std::string excerpt(std::size_t at) const {
        if (text_.size() <= 100) return text_;
        const std::size_t from = at > 40 ? at - 40 : 0, to = std::min(text_.size(), from + 80);
        return (from > 0 ? "…" : "") + text_.substr(from, to - from) + (to < text_.size() ? "…" : "");
    }
    [[noreturn]] void fail(const std::string& what) const { fail(what, pos_); }

    void skip_space() {
        while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    }

    // A quoted string, or a run of characters other than ( ) , (trimmed).
    std::string token() {
        skip_space();
        if (pos_ < text_.size() && (text_[pos_] == '"' || text_[pos_] == '\'')) {
            const char quote = text_[pos_];
            const std::size_t close = text_.find(quote, pos_ + 1);
            if (close == std::string::npos) fail(std::string("expected the closing ") + quote);
            std::string t = text_.substr(pos_ + 1, close - pos_ - 1);
            pos_ = close + 1;
            return t;
        }
        const std::size_t start = pos_;
        while (pos_ < text_.size() && text_[pos_] != '(' && text_[pos_] != ')' && text_[pos_] != ',') ++pos_;
        std::size_t end = pos_;
        while (end > start && std::isspace(static_cast<unsigned char>(text_[end - 1]))) --end;
        return text_.substr(start, end - start);
    }

    static std::optional<double> as_number(const std::string& t) {
        if (t.empty()) return std::nullopt;
        char* end = nullptr;
        const double v = std::strtod(t.c_str(), &end);
        if (end != t.c_str() + t.size()) return std::nullopt;
        return v;
    }

    Operand operand() {
        skip_space();
        Operand o;
        o.at = pos_;
        const bool quoted = pos_ < text_.size() && (text_[pos_] == '"' || text_[pos_] == '\'');
        const std::string t = token();
        skip_space();
        if (!quoted && pos_ < text_.size() && text_[pos_] == '(') {
            o.field = call(t, o.at);
            return o;
        }
        if (t.empty()) fail("expected a field (a file, or an operator such as union(…)) or a number", o.at);
        if (!quoted)
            if (const auto v = as_number(t)) {
                if (!std::isfinite(*v)) fail("the number '" + t + "' is not finite", o.at);
                o.number = *v;
                return o;
            }
        o.field = load_leaf(t, options_);
        return o;
    }

    Parsed expression() {
        Operand o = operand();
        if (!o.field) fail("expected a field, not a number", o.at);
        return std::move(*o.field);
    }

    // NAME( operands ) — pos_ at the '('.
    Parsed call(const std::string& name, std::size_t at) {
        static const std::map<std::string, std::string> kSignature = {
            {"union", "union(a, b, …)"},
            {"intersection", "intersection(a, b, …)"},
            {"difference", "difference(a, b)"},
            {"smooth_union", "smooth_union(a, b, radius)"},
            {"smooth_intersection", "smooth_intersection(a, b, radius)"},
            {"smooth_difference", "smooth_difference(a, b, radius)"},
            {"offset", "offset(a, distance)"},
            {"shell", "shell(a, half_thickness)"},
            {"erosion", "erosion(a, radius)"},
            {"dilation", "dilation(a, radius)"},
            {"opening", "opening(a, radius)"},
            {"closing", "closing(a, radius)"},
        };
        const auto it = kSignature.find(name);
        if (it == kSignature.end()) {
            std::string known;
            for (const auto& [k, v] : kSignature) known += (known.empty() ? "" : ", ") + k;
            fail("unknown operator '" + name + "' (known: " + known + ")", at);
        }
        // Each level is a frame of this parser and, later, of every evaluation: bounded, so that
        // a runaway expression is an error rather than a stack overflow.
        if (++depth_ > kMaxDepth) fail("operators nested deeper than " + std::to_string(kMaxDepth), at);
        ++pos_;  // '('
        std::vector<Operand> args;
        while (true) {
            args.push_back(operand());
            skip_space();
            if (pos_ < text_.size() && text_[pos_] == ',') {
                ++pos_;
                continue;
            }
            if (pos_ < text_.size() && text_[pos_] == ')') {
                ++pos_;
                break;
            }
            fail("expected ',' or ')' in " + it->second);
        }
        --depth_;
        return apply(name, it->second, args, at);
    }

    Parsed apply(const std::string& name, const std::string& signature, std::vector<Operand>& args, std::size_t at) const {
        auto field_at = [&](std::size_t k) -> Parsed& {
            if (!args[k].field) fail(signature + " takes a field here, not a number", args[k].at);
            return *args[k].field;
        };
        auto number_at = [&](std::size_t k) {
            if (args[k].field) fail(signature + " takes a number here, not a field", args[k].at);
            return args[k].number;
        };
        auto arity = [&](std::size_t least, std::size_t most) {
            if (args.size() < least || args.size() > most)
                fail(signature + ": " + std::to_string(args.size()) + " operand" + (args.size() == 1 ? "" : "s") + " given", at);
        };
        Parsed out;
        try {
            if (name == "union" || name == "intersection") {
                arity(2, std::size_t(-1));
                out = field_at(0);
                for (std::size_t k = 1; k < args.size(); ++k) {
                    const Parsed& b = field_at(k);
                    out.field = name == "union" ? field_union(out.field, b.field) : field_intersection(out.field, b.field);
                    out.box = merged(out.box, b.box);
                }
            } else if (name == "difference") {
                arity(2, 2);
                out = {field_difference(field_at(0).field, field_at(1).field), field_at(0).box};
            } else if (name.rfind("smooth_", 0) == 0) {
                arity(3, 3);
                const Parsed &a = field_at(0), &b = field_at(1);
                const double k = number_at(2);
                if (name == "smooth_union") out = {field_union(a.field, b.field, k), grown(merged(a.box, b.box), k / 4)};
                else if (name == "smooth_intersection") out = {field_intersection(a.field, b.field, k), merged(a.box, b.box)};
                else out = {field_difference(a.field, b.field, k), a.box};
            } else if (name == "opening" || name == "closing") {
                arity(2, 2);
                const Parsed& a = field_at(0);
                const double r = number_at(1);
                if (a.seeds.rows() > 0 && !options_.morphology_by_grid) {
                    // A cloud's (or .tori's) own points sample its zero set: no grid, no mesh.
                    out = {name == "opening" ? field_opening(a.field, r, a.seeds) : field_closing(a.field, r, a.seeds), a.box};
                } else {
                    // The grid covers what the first offset can reach (a closing grows by r first) and
                    // room for the distances beyond it.
                    const GridSpec g = GridSpec::cube(options_.morphology_grid, padded_cube(grown(a.box, 2 * std::abs(r))));
                    out = {name == "opening" ? field_opening(a.field, r, g) : field_closing(a.field, r, g), a.box};
                }
            } else {  // offset, shell, erosion, dilation
                arity(2, 2);
                const Parsed& a = field_at(0);
                const double r = number_at(1);
                if ((name == "erosion" || name == "dilation") && !(r > 0))
                    fail(signature + ": the radius must be > 0", args[1].at);
                if (name == "offset") out = {field_offset(a.field, r), grown(a.box, r)};
                else if (name == "shell") out = {field_shell(a.field, r), grown(a.box, r)};
                else if (name == "dilation") out = {field_offset(a.field, r), grown(a.box, r)};
                else out = {field_offset(a.field, -r), a.box};
            }
        } catch (const Error& e) {
            if (e.where() == "expression") throw;
            // An operator's own check (a negative radius, …).
            fail(signature + ": " + (e.where().empty() ? "" : e.where() + ": ") + e.what(), at);
        }
        return out;
    }

    static constexpr int kMaxDepth = 64;
    std::string text_;
    LeafOptions options_;
    std::size_t pos_ = 0;
    int depth_ = 0;
};

}  // namespace

// φ (and ∇φ) at points through a field's device program, 2²⁰ points a submission.
template <class Context>
FieldValues on_device_in_chunks(const Field& field, const std::shared_ptr<Context>& ctx, const Points& x, bool gradient,
                                const ProgressFn& progress) {
    constexpr Eigen::Index kChunk = Eigen::Index(1) << 20;
    FieldValues out;
    out.phi.reserve(std::size_t(x.rows()));
    for (Eigen::Index first = 0; first < x.rows(); first += kChunk) {
        const Eigen::Index n = std::min(kChunk, x.rows() - first);
        FieldValues v = gpu::evaluate_points(field, ctx, x.middleRows(first, n), gradient);
        out.phi.insert(out.phi.end(), v.phi.begin(), v.phi.end());
        out.gradient.insert(out.gradient.end(), v.gradient.begin(), v.gradient.end());
        out.device = v.device;
        if (progress) progress("evaluate", double(first + n) / double(x.rows()));
    }
    return out;
}

void add_morphology_grid(CLI::App& app, MorphologyArgs& m) {
    app.add_option("--morphology-grid", m.grid,
                   "Nodes per axis of the grid an opening or closing re-distances on (the leaves' cube, grown by 2r, + 10 %), "
                   "where its operand is not a cloud or .tori (those are resampled: no grid)")
        ->check(CLI::Range(8, 1024))
        ->capture_default_str();
    app.add_flag("--morphology-by-grid", m.by_grid, "Re-distance on the grid even for a cloud's or .tori's opening and closing");
}

ParsedField parse_field_expression(const std::string& expression, const std::string& device, const MorphologyArgs& morphology) {
    LeafOptions leaves;
    leaves.device = device;
    leaves.morphology_grid = morphology.grid;
    leaves.morphology_by_grid = morphology.by_grid;
    const Parsed p = ExpressionParser(expression, leaves).parse();
    return {p.field, p.box};
}

void add_field(CLI::App& app) {
    auto* cmd = app.add_subcommand(
        "field", "A field made of fields: Booleans, offsets, shells, opening and closing of fitted tori, grids, meshes and clouds, on a grid "
                 "or at queries (docs/field.md)");
    struct Args {
        std::string expression, output, gradient, device;
        MorphologyArgs morphology;
        Domain domain;
    };
    auto a = std::make_shared<Args>();
    cmd->add_option("EXPR", a->expression,
                    "The expression, e.g. \"union(a.tori, offset(b.npy, 0.05))\": leaves are files (.tori, a .npy grid "
                    "with its sidecar or a .vdb, a mesh, an oriented cloud); operators union, intersection, difference, "
                    "smooth_union, smooth_intersection, smooth_difference (radius last), offset, shell, erosion, "
                    "dilation, opening, closing")
        ->required();
    cmd->add_option("-o,--output", a->output,
                    "Output .npy: (N,N,N) for a grid, (M,) for queries; or .vdb (a grid: φ as an OpenVDB level set)")
        ->required()
        ->check(output_file({".npy", ".vdb"}));
    cmd->add_option("--gradient", a->gradient, "Also write ∇φ: (N,N,N,3) or (M,3) .npy")->check(output_file({".npy"}));
    cmd->add_option("--device", a->device,
                    "Where the leaves evaluate: auto | gpu | cpu | device index | name substring (default: $GSD_DEVICE "
                    "or auto); a composite whose leaves include one with a device program is combined there too");
    add_morphology_grid(*cmd, a->morphology);
    a->domain.add_to(*cmd, true);
    cmd->callback([a] {
        if (!a->domain.is_grid() && a->domain.queries.empty()) throw CLI::RequiredError("--grid or --queries");
        if (!a->domain.bounds.empty()) bounds_from(a->domain.bounds, "--bounds");  // before any costly fit
        const DevicePrefetch prefetch(a->device);  // while the leaves are read and fitted
        const ParsedField p = parse_field_expression(a->expression, a->device, a->morphology);
        const bool want_gradient = !a->gradient.empty();
        if (want_gradient && !p.field->has_gradient())
            throw Error("--gradient", "a field of this expression offers no gradient");
        // A composite with a device program evaluates there in one pass per chunk (its leaves
        // into device buffers, field_combine over them); otherwise each leaf where --device says
        // and the operators on the CPU.
        std::function<FieldValues(const Points&, const ProgressFn&)> at_points = [&](const Points& q, const ProgressFn& pr) {
            return p.field->evaluate(q, want_gradient, pr);
        };
        std::function<FieldValues(const GridSpec&, const ProgressFn&)> on_grid = [&](const GridSpec& g, const ProgressFn& pr) {
            return p.field->evaluate(g, want_gradient, pr);
        };
        gpu::on_device(a->device, [&](const auto& ctx, std::string&) {
            if (!p.field->device_program()) return false;
            at_points = [&, ctx](const Points& q, const ProgressFn& pr) { return on_device_in_chunks(*p.field, ctx, q, want_gradient, pr); };
            on_grid = [&, ctx](const GridSpec& g, const ProgressFn& pr) {
                return on_device_in_chunks(*p.field, ctx, g.nodes(), want_gradient, pr);
            };
            return true;
        });
        evaluate_and_write(a->domain, p.box, a->output, a->gradient, at_points, on_grid, "field", "field", kSdfGridBytesPerNode);
    });
}

}  // namespace gsd::cli
