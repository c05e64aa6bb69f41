// The accuracy measures of gsd/accuracy.hpp, over a SurfaceMesh's triangulation and areas.
#include <gsd/accuracy.hpp>
#include <gsd/surface.hpp>

#include "mesh/topology.hpp"

#include <algorithm>
#include <cmath>
#include <map>

namespace gsd {

std::vector<double> vertex_areas(const SurfaceMesh& mesh) {
    const mesh::Topology& t = mesh.topology();
    std::vector<double> a(t.mesh.vertex_count, 0.0);
    for (std::size_t f = 0; f < t.mesh.face_count(); ++f)
        for (std::uint32_t v : t.mesh.faces[f]) a[v] += t.face_areas[f] / 3;
    return a;
}

double surface_distance_error(const SurfaceMesh& mesh, const std::vector<double>& phi,
                              const std::vector<double>& phi_true) {
    if (phi.size() != mesh.vertex_count() || phi_true.size() != mesh.vertex_count())
        throw Error("surface_distance_error", "expected one value per vertex");
    const std::vector<double> A = vertex_areas(mesh);
    double lo = INFINITY, hi = -INFINITY, sum = 0, area = 0;
    for (std::size_t i = 0; i < A.size(); ++i) {
        if (!std::isfinite(phi[i]) || !std::isfinite(phi_true[i])) continue;
        lo = std::min(lo, phi_true[i]);
        hi = std::max(hi, phi_true[i]);
        sum += A[i] * (phi[i] - phi_true[i]) * (phi[i] - phi_true[i]);
        area += A[i];
    }
    if (!(hi > lo) || !(area > 0)) throw Error("surface_distance_error", "the true distance is constant or undefined");
    return std::sqrt(sum) / ((hi - lo) * std::sqrt(area));
}

double surface_sign_agreement(const SurfaceMesh& mesh, const std::vector<double>& phi,
                              const std::vector<double>& phi_true) {
    if (phi.size() != mesh.vertex_count() || phi_true.size() != mesh.vertex_count())
        throw Error("surface_sign_agreement", "expected one value per vertex");
    const std::vector<double> A = vertex_areas(mesh);
    double agree = 0, area = 0;
    for (std::size_t i = 0; i < A.size(); ++i) {
        if (!std::isfinite(phi_true[i])) continue;
        area += A[i];
        if (phi_true[i] == 0 || (std::isfinite(phi[i]) && (phi[i] < 0) == (phi_true[i] < 0))) agree += A[i];
    }
    return area > 0 ? agree / area : 0.0;
}

double mislabeled_area(const SurfaceMesh& mesh, const std::vector<int>& labels, const std::vector<int>& truth,
                       bool up_to_shift) {
    if (labels.size() != mesh.face_count() || truth.size() != mesh.face_count())
        throw Error("mislabeled_area", "expected one label per face");
    const mesh::Topology& t = mesh.topology();
    std::vector<double> area(mesh.face_count(), 0.0);
    for (std::size_t f = 0; f < t.mesh.face_count(); ++f) area[t.triangle_face[f]] += t.face_areas[f];
    double total = 0;
    for (double a : area) total += a;
    std::map<int, double> agree;  // shift → area that agrees under it
    for (std::size_t f = 0; f < area.size(); ++f) agree[truth[f] - labels[f]] += area[f];
    const double right = up_to_shift ? std::max_element(agree.begin(), agree.end(), [](const auto& a, const auto& b) {
                                           return a.second < b.second;
                                       })->second
                                     : agree[0];
    return total > 0 ? 1.0 - right / total : 0.0;
}

}  // namespace gsd
