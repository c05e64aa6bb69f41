#include <gsd/shapes.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace gsd::shapes {

namespace {

using Vec3 = Eigen::Vector3d;
using Rng = std::mt19937_64;

double uniform(Rng& rng, double a = 0, double b = 1) {
    return a + (b - a) * std::uniform_real_distribution<double>(0.0, 1.0)(rng);
}

/// Three draws of `dist` in a fixed order, z then y then x, whatever the compiler: a call like
/// Vec3(g(rng), g(rng), g(rng)) leaves the order unspecified (GCC draws right to left, clang left
/// to right), so the same seed gave different clouds. z-first is GCC's order, which keeps every
/// cloud made before from the same seed.
template <class Distribution>
Vec3 draw3(Distribution& dist, Rng& rng) {
    const double z = dist(rng);
    const double y = dist(rng);
    const double x = dist(rng);
    return {x, y, z};
}

Vec3 unit_vector(Rng& rng) {
    std::normal_distribution<double> g;
    for (;;) {
        const Vec3 v = draw3(g, rng);
        const double n = v.norm();
        if (n > 1e-12) return v / n;
    }
}

PointCloud make_cloud(std::size_t n) {
    PointCloud c;
    c.points.resize(Eigen::Index(n), 3);
    c.normals.resize(Eigen::Index(n), 3);
    return c;
}

class Sphere final : public Shape {
public:
    Sphere(Vec3 c, double r) : c_(c), r_(r) {}
    std::string name() const override { return "sphere"; }
    double sdf(const Vec3& x) const override { return (x - c_).norm() - r_; }
    double area() const override { return 4 * M_PI * r_ * r_; }
    PointCloud sample(std::size_t n, std::uint64_t seed) const override {
        Rng rng(seed);
        PointCloud out = make_cloud(n);
        for (std::size_t i = 0; i < n; ++i) {
            const Vec3 u = unit_vector(rng);
            out.points.row(Eigen::Index(i)) = (c_ + r_ * u).transpose();
            out.normals.row(Eigen::Index(i)) = u.transpose();
        }
        return out;
    }

private:
    Vec3 c_;
    double r_;
};

class Torus final : public Shape {
public:
    Torus(Vec3 c, double R, double r) : c_(c), R_(R), r_(r) {
        if (!(r > 0 && R > r)) throw Error("torus needs 0 < r < R");
    }
    std::string name() const override { return "torus"; }
    double sdf(const Vec3& x) const override {
        const Vec3 p = x - c_;
        const double q = std::hypot(p.x(), p.y()) - R_;
        return std::hypot(q, p.z()) - r_;
    }
    double area() const override { return 4 * M_PI * M_PI * R_ * r_; }
    PointCloud sample(std::size_t n, std::uint64_t seed) const override {
        Rng rng(seed);
        PointCloud out = make_cloud(n);
        for (std::size_t i = 0; i < n;) {
            // Area element ∝ (R + r cos v): rejection on the tube angle v.
            const double v = uniform(rng, 0, 2 * M_PI);
            if (uniform(rng) * (R_ + r_) > R_ + r_ * std::cos(v)) continue;
            const double u = uniform(rng, 0, 2 * M_PI);
            const Vec3 radial(std::cos(u), std::sin(u), 0);
            const Vec3 nrm = std::cos(v) * radial + std::sin(v) * Vec3::UnitZ();
            out.points.row(Eigen::Index(i)) = (c_ + R_ * radial + r_ * nrm).transpose();
            out.normals.row(Eigen::Index(i)) = nrm.transpose();
            ++i;
        }
        return out;
    }

private:
    Vec3 c_;
    double R_, r_;
};

class Capsule final : public Shape {
public:
    Capsule(Vec3 a, Vec3 b, double r) : a_(a), b_(b), r_(r) {
        if (!(r > 0) || (b - a).norm() <= 0) throw Error("capsule needs a radius > 0 and a ≠ b");
    }
    std::string name() const override { return "capsule"; }
    double sdf(const Vec3& x) const override {
        const Vec3 ab = b_ - a_;
        const double t = std::clamp((x - a_).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
        return (x - (a_ + t * ab)).norm() - r_;
    }
    double area() const override { return 2 * M_PI * r_ * (b_ - a_).norm() + 4 * M_PI * r_ * r_; }
    PointCloud sample(std::size_t n, std::uint64_t seed) const override {
        Rng rng(seed);
        PointCloud out = make_cloud(n);
        const Vec3 ab = b_ - a_;
        const double len = ab.norm();
        const Vec3 axis = ab / len;
        const double p_cyl = 2 * M_PI * r_ * len / area();
        for (std::size_t i = 0; i < n; ++i) {
            Vec3 p, nrm;
            if (uniform(rng) < p_cyl) {
                const Vec3 u = unit_vector(rng);
                Vec3 radial = u - u.dot(axis) * axis;
                if (radial.norm() < 1e-9) radial = axis.unitOrthogonal();
                nrm = radial.normalized();
                p = a_ + uniform(rng) * ab + r_ * nrm;
            } else {
                nrm = unit_vector(rng);
                p = (nrm.dot(axis) >= 0 ? b_ : a_) + r_ * nrm;
            }
            out.points.row(Eigen::Index(i)) = p.transpose();
            out.normals.row(Eigen::Index(i)) = nrm.transpose();
        }
        return out;
    }

private:
    Vec3 a_, b_;
    double r_;
};

class RoundedBox final : public Shape {
public:
    RoundedBox(Vec3 c, Vec3 h, double r) : c_(c), h_(h), r_(r) {
        if (!(r > 0) || (h.array() < 0).any()) throw Error("rounded box needs radius > 0 and half extents ≥ 0");
    }
    std::string name() const override { return "rounded-box"; }
    double sdf(const Vec3& x) const override {
        const Vec3 d = (x - c_).cwiseAbs() - h_;
        const double outside = d.cwiseMax(0.0).norm();
        const double inside = std::min(d.maxCoeff(), 0.0);
        return outside + inside - r_;
    }
    double area() const override {
        return face_area_total() + edge_area_total() + 4 * M_PI * r_ * r_;
    }
    PointCloud sample(std::size_t n, std::uint64_t seed) const override {
        Rng rng(seed);
        PointCloud out = make_cloud(n);
        const double total = area();
        const double p_face = face_area_total() / total;
        const double p_edge = edge_area_total() / total;
        for (std::size_t i = 0; i < n; ++i) {
            const double pick = uniform(rng);
            Vec3 core, nrm;
            if (pick < p_face) {
                // Faces ⟂ axis a have area 4 h_b h_c each; choose an axis by area, then a side.
                const double w[3] = {h_.y() * h_.z(), h_.x() * h_.z(), h_.x() * h_.y()};
                const int a = pick_index(rng, w);
                const double s = uniform(rng) < 0.5 ? -1 : 1;
                for (int k = 0; k < 3; ++k) core[k] = k == a ? s * h_[k] : uniform(rng, -h_[k], h_[k]);
                nrm = Vec3::Zero();
                nrm[a] = s;
            } else if (pick < p_face + p_edge) {
                // Quarter cylinders along axis a have area π r h_a each (4 per axis).
                const double w[3] = {h_.x(), h_.y(), h_.z()};
                const int a = pick_index(rng, w);
                const int b = (a + 1) % 3, c = (a + 2) % 3;
                const double sb = uniform(rng) < 0.5 ? -1 : 1, sc = uniform(rng) < 0.5 ? -1 : 1;
                const double th = uniform(rng, 0, M_PI / 2);
                core[a] = uniform(rng, -h_[a], h_[a]);
                core[b] = sb * h_[b];
                core[c] = sc * h_[c];
                nrm = Vec3::Zero();
                nrm[b] = sb * std::cos(th);
                nrm[c] = sc * std::sin(th);
            } else {
                nrm = unit_vector(rng);
                for (int k = 0; k < 3; ++k) core[k] = (nrm[k] >= 0 ? 1 : -1) * h_[k];
            }
            out.points.row(Eigen::Index(i)) = (c_ + core + r_ * nrm).transpose();
            out.normals.row(Eigen::Index(i)) = nrm.transpose();
        }
        return out;
    }

private:
    double face_area_total() const { return 8 * (h_.x() * h_.y() + h_.y() * h_.z() + h_.x() * h_.z()); }
    double edge_area_total() const { return 4 * M_PI * r_ * (h_.x() + h_.y() + h_.z()); }
    static int pick_index(Rng& rng, const double (&w)[3]) {
        const double u = uniform(rng) * (w[0] + w[1] + w[2]);
        return u < w[0] ? 0 : (u < w[0] + w[1] ? 1 : 2);
    }
    Vec3 c_, h_;
    double r_;
};

}  // namespace

std::unique_ptr<Shape> sphere(const Eigen::Vector3d& c, double r) {
    if (!(r > 0)) throw Error("sphere radius must be > 0");
    return std::make_unique<Sphere>(c, r);
}
std::unique_ptr<Shape> torus(const Eigen::Vector3d& c, double R, double r) {
    return std::make_unique<Torus>(c, R, r);
}
std::unique_ptr<Shape> capsule(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r) {
    return std::make_unique<Capsule>(a, b, r);
}
std::unique_ptr<Shape> rounded_box(const Eigen::Vector3d& c, const Eigen::Vector3d& h, double r) {
    return std::make_unique<RoundedBox>(c, h, r);
}

std::unique_ptr<Shape> by_name(const std::string& name) {
    if (name == "sphere") return sphere(Vec3::Zero(), 0.5);
    if (name == "torus") return torus(Vec3::Zero(), 0.5, 0.2);
    if (name == "capsule") return capsule(Vec3(-0.4, 0, 0), Vec3(0.4, 0, 0), 0.3);
    if (name == "rounded-box") return rounded_box(Vec3::Zero(), Vec3(0.35, 0.25, 0.2), 0.15);
    throw Error("shape", "unknown shape '" + name + "' (sphere, torus, capsule, rounded-box)");
}

PointCloud corrupt(const PointCloud& clean, const Corruption& c, std::uint64_t seed) {
    Rng rng(seed);
    std::normal_distribution<double> g;
    const Box box = bounding_box(clean.points);
    const double diag = box.diagonal();
    const Eigen::Index n = clean.size();

    std::vector<char> keep(std::size_t(n), 1);
    for (int h = 0; h < c.holes && n > 0; ++h) {
        const Eigen::Index center = Eigen::Index(uniform(rng) * double(n)) % n;
        const Vec3 pc = clean.points.row(center).transpose();
        for (Eigen::Index i = 0; i < n; ++i)
            if ((clean.points.row(i).transpose() - pc).norm() < c.hole_radius * diag) keep[std::size_t(i)] = 0;
    }
    std::vector<Eigen::Index> kept;
    for (Eigen::Index i = 0; i < n; ++i)
        if (keep[std::size_t(i)]) kept.push_back(i);
    for (Eigen::Index i = 0; kept.size() < 2 && i < n; ++i)
        if (!keep[std::size_t(i)]) kept.push_back(i);  // never fewer than two points

    PointCloud out = make_cloud(kept.size());
    for (std::size_t r = 0; r < kept.size(); ++r) {
        Vec3 p = clean.points.row(kept[r]).transpose();
        Vec3 nn = clean.normals.row(kept[r]).transpose().normalized();
        if (c.position_noise > 0) p += c.position_noise * diag * draw3(g, rng);
        if (c.normal_noise > 0) {
            const Vec3 m = nn + c.normal_noise * draw3(g, rng);
            if (m.norm() > 1e-9) nn = m.normalized();
        }
        if (c.flip_fraction > 0 && uniform(rng) < c.flip_fraction) nn = -nn;
        if (c.outlier_fraction > 0 && uniform(rng) < c.outlier_fraction) {
            for (int k = 0; k < 3; ++k) p[k] = uniform(rng, box.lo[k], box.hi[k]);
            nn = unit_vector(rng);
        }
        out.points.row(Eigen::Index(r)) = p.transpose();
        out.normals.row(Eigen::Index(r)) = nn.transpose();
    }
    return out;
}

}  // namespace gsd::shapes
