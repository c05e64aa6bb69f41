#include <gsd/core.hpp>
#include <gsd/field.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <sstream>

#include <unistd.h>

namespace gsd {

std::string_view version() { return GSD_VERSION; }

void PolygonMesh::add_face(std::initializer_list<std::uint32_t> f) { add_face(f.begin(), f.size()); }

void PolygonMesh::add_face(const std::uint32_t* f, std::size_t n) {
    if (offsets.empty()) offsets.push_back(0);
    indices.insert(indices.end(), f, f + n);
    offsets.push_back(static_cast<std::uint32_t>(indices.size()));
}

Eigen::Vector3d GridSpec::node(int i, int j, int k) const {
    const Eigen::Vector3d e = box.extent();
    return box.lo + Eigen::Vector3d(nx > 1 ? e.x() * i / (nx - 1) : 0.0,
                                    ny > 1 ? e.y() * j / (ny - 1) : 0.0,
                                    nz > 1 ? e.z() * k / (nz - 1) : 0.0);
}

Points GridSpec::nodes() const {
    Points out(static_cast<Eigen::Index>(node_count()), 3);
    Eigen::Index row = 0;
    for (int i = 0; i < nx; ++i)
        for (int j = 0; j < ny; ++j)
            for (int k = 0; k < nz; ++k) out.row(row++) = node(i, j, k).transpose();
    return out;
}

void GridSpec::validate() const {
    if (nx < 2 || ny < 2 || nz < 2)
        throw Error("GridSpec", "grid needs at least 2 nodes per axis");
    // 2^31 nodes is 8 GiB of float32: far past what one .npy grid on this library's path can hold.
    if (double(nx) * double(ny) * double(nz) > double(1u << 31))
        throw Error("GridSpec", "grid has more than 2^31 nodes");
    validate_box(box, "GridSpec::box");
    // Cells that double precision still resolves at the box's coordinates (and whose squares
    // and inverses stay normal numbers): past that, node positions coincide and the Poisson
    // operator's 1/h² overflows.
    const int n[3] = {nx, ny, nz};
    for (int a = 0; a < 3; ++a) {
        const double cell = (box.hi[a] - box.lo[a]) / (n[a] - 1);
        const double at = std::max(std::abs(box.lo[a]), std::abs(box.hi[a]));
        if (!(cell >= 1e-100) || !(cell >= 1e-12 * at)) {
            std::ostringstream s;
            s.precision(3);
            s << "grid cells of " << cell << " are too small for the box's coordinates (" << at
              << "): at least 1e-12 of them, and 1e-100";
            throw Error("GridSpec::box", s.str());
        }
    }
}

Box bounding_box(PointsView p) {
    if (p.rows() == 0) throw Error("bounding box of an empty point set");
    Box b;
    b.lo = p.colwise().minCoeff().transpose();
    b.hi = p.colwise().maxCoeff().transpose();
    return b;
}

Box padded_cube(const Box& b, double margin) {
    const Eigen::Vector3d c = 0.5 * (b.lo + b.hi);
    const double half = 0.5 * (1 + margin) * std::max(b.extent().maxCoeff(), 1e-12);
    return Box{c.array() - half, c.array() + half};
}

namespace {
std::string at_row(const char* what, Eigen::Index i) {
    std::ostringstream s;
    s << what << " (element " << i << ")";
    return s.str();
}

std::string gib(double bytes) {
    std::ostringstream s;
    s.precision(3);
    s << bytes / double(1ull << 30) << " GiB";
    return s.str();
}

}  // namespace

void check_coordinates(const Points& p, const std::string& where, const char* element) {
    for (Eigen::Index i = 0; i < p.rows(); ++i)
        if (!(p.row(i).cwiseAbs().maxCoeff() <= kMaxCoordinate))
            throw Error(where, at_row((std::string(element) + " coordinate beyond ±1e30").c_str(), i));
    if (p.rows() < 4) return;
    Eigen::Vector3d median, iqr;
    std::vector<double> v(std::size_t(p.rows()));
    for (int a = 0; a < 3; ++a) {
        for (Eigen::Index i = 0; i < p.rows(); ++i) v[std::size_t(i)] = p(i, a);
        const auto at = [&](double q) {
            auto it = v.begin() + std::ptrdiff_t(q * double(v.size() - 1));
            std::nth_element(v.begin(), it, v.end());
            return *it;
        };
        const double q1 = at(0.25), q2 = at(0.5), q3 = at(0.75);
        median[a] = q2;
        iqr[a] = q3 - q1;
    }
    const double bulk = iqr.maxCoeff();
    if (!(bulk > 0)) return;  // most elements coincide: no scale to compare with
    Eigen::Index far = 0;
    double farthest = 0;
    for (Eigen::Index i = 0; i < p.rows(); ++i) {
        const double d = (p.row(i).transpose() - median).cwiseAbs().maxCoeff();
        if (d > farthest) farthest = d, far = i;
    }
    if (farthest > kMaxExtentRatio * bulk) {
        std::ostringstream s;
        s.precision(3);
        s << element << " " << far << " lies " << farthest / bulk
          << "x the size of the bulk (interquartile range) away from it: the input's extent makes a grid, "
             "tree or quadrature over it meaningless (limit 1e12x); remove the stray element";
        throw Error(where, s.str());
    }
}

std::size_t memory_budget() {
    if (const char* env = std::getenv("GSD_MEMORY_LIMIT"); env && *env) {
        char* end = nullptr;
        const double v = std::strtod(env, &end);
        double scale = 1;
        switch (end && *end ? std::toupper(static_cast<unsigned char>(*end)) : 0) {
            case 0: break;
            case 'K': scale = 1024.0; break;
            case 'M': scale = 1024.0 * 1024; break;
            case 'G': scale = 1024.0 * 1024 * 1024; break;
            case 'T': scale = 1024.0 * 1024 * 1024 * 1024; break;
            default: throw Error("GSD_MEMORY_LIMIT", "expects bytes or a number with K, M, G or T, not '" + std::string(env) + "'");
        }
        if (!(v > 0) || !std::isfinite(v * scale))
            throw Error("GSD_MEMORY_LIMIT", "expects a positive size, not '" + std::string(env) + "'");
        return std::size_t(std::min(v * scale, 1e18));
    }
    const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
    if (pages <= 0 || page <= 0) return std::size_t(8) << 30;  // unknown: 8 GiB
    return std::size_t(double(pages) * double(page) * 0.75);
}

void check_memory(double bytes, const std::string& where, const std::string& what) {
    const std::size_t budget = memory_budget();
    if (!(bytes <= double(budget)))
        throw Error(where, what + " needs about " + gib(bytes) + ", over the memory budget of " + gib(double(budget)) +
                               (std::getenv("GSD_MEMORY_LIMIT") ? " (GSD_MEMORY_LIMIT)"
                                                                : " (3/4 of this machine's memory; GSD_MEMORY_LIMIT changes it)"));
}

void validate_box(const Box& box, const std::string& where) {
    for (int a = 0; a < 3; ++a) {
        if (!std::isfinite(box.lo[a]) || !std::isfinite(box.hi[a])) throw Error(where, "bounds must be finite numbers");
        if (!(box.hi[a] > box.lo[a])) throw Error(where, "bounds must satisfy x0 < x1, y0 < y1, z0 < z1");
        if (std::abs(box.lo[a]) > kMaxCoordinate || std::abs(box.hi[a]) > kMaxCoordinate)
            throw Error(where, "bounds must lie within ±1e30");
        if (!std::isfinite(box.hi[a] - box.lo[a])) throw Error(where, "bounds are too far apart (x1 − x0 overflows)");
    }
}

void validate(const PointCloud& cloud, const std::string& where) {
    if (cloud.points.rows() == 0) throw Error(where, "point cloud is empty");
    if (cloud.normals.rows() == 0) throw Error(where, "point cloud has no normals");
    if (cloud.normals.rows() != cloud.points.rows())
        throw Error(where, "point and normal counts differ");
    if (cloud.points.rows() < 2) throw Error(where, "point cloud needs at least 2 points");
    for (Eigen::Index i = 0; i < cloud.points.rows(); ++i) {
        if (!cloud.points.row(i).allFinite())
            throw Error(where, at_row("non-finite coordinate", i));
        if (!cloud.normals.row(i).allFinite())
            throw Error(where, at_row("non-finite normal", i));
        if (!(cloud.normals.row(i).norm() > 1e-30)) throw Error(where, at_row("zero-length normal", i));
    }
    check_coordinates(cloud.points, where, "point");
    const Box b = bounding_box(cloud.points);
    if (!(b.diagonal() > 0)) throw Error(where, "all points coincide");
}

void normalize_normals(PointCloud& cloud, const std::string& where) {
    for (Eigen::Index i = 0; i < cloud.normals.rows(); ++i) {
        const double len = cloud.normals.row(i).norm();
        if (!(len > 1e-30) || !std::isfinite(len)) throw Error(where, at_row("zero-length or non-finite normal", i));
        cloud.normals.row(i) /= len;
    }
}

double robust_mean(std::vector<double> values) {
    if (values.empty()) return 0.0;
    const auto mid = values.begin() + std::ptrdiff_t(values.size() / 2);
    std::nth_element(values.begin(), mid, values.end());
    const double cap = kRobustMeanCap * *mid;
    double sum = 0;
    for (const double v : values) sum += std::min(v, cap);
    return sum / double(values.size());
}

double mean_edge_length(const PolygonMesh& mesh) {
    std::vector<double> lengths;
    lengths.reserve(mesh.indices.size());
    for (std::size_t f = 0; f < mesh.face_count(); ++f)
        for (auto k = mesh.offsets[f]; k < mesh.offsets[f + 1]; ++k) {
            const auto next = k + 1 < mesh.offsets[f + 1] ? k + 1 : mesh.offsets[f];
            lengths.push_back((mesh.vertices.row(mesh.indices[k]) - mesh.vertices.row(mesh.indices[next])).norm());
        }
    return robust_mean(std::move(lengths));
}

void validate(const PolygonMesh& mesh, const std::string& where) {
    if (mesh.vertices.rows() == 0) throw Error(where, "mesh has no vertices");
    if (mesh.face_count() == 0) throw Error(where, "mesh has no faces");
    if (mesh.offsets.front() != 0 || mesh.offsets.back() != mesh.indices.size())
        throw Error(where, "mesh face offsets are inconsistent");
    for (Eigen::Index i = 0; i < mesh.vertices.rows(); ++i)
        if (!mesh.vertices.row(i).allFinite())
            throw Error(where, at_row("non-finite vertex coordinate", i));
    check_coordinates(mesh.vertices, where, "vertex");
    const auto nv = static_cast<std::uint32_t>(mesh.vertices.rows());
    for (std::size_t f = 0; f < mesh.face_count(); ++f) {
        if (mesh.offsets[f + 1] < mesh.offsets[f] + 3)
            throw Error(where, at_row("face with fewer than 3 vertices", Eigen::Index(f)));
        for (auto k = mesh.offsets[f]; k < mesh.offsets[f + 1]; ++k)
            if (mesh.indices[k] >= nv)
                throw Error(where, at_row("vertex index out of range in face", Eigen::Index(f)));
    }
}

Field::~Field() = default;  // the key function: Field's vtable lives in the library
DeviceProgram::~DeviceProgram() = default;

void Field::refuse_gradient(bool with_gradient, const char* field_kind) {
    if (with_gradient) throw Error("with_gradient", std::string(field_kind) + " offer no gradient");
}

FieldValues Field::evaluate(PointsFView queries, bool with_gradient, const ProgressFn& progress) const {
    const Points q = queries.cast<double>();
    return evaluate(PointsView(q), with_gradient, progress);
}

}  // namespace gsd
