// The JSON sidecar of a grid (GRID.npy.json): shape, bounds, method, options, version.
#include "io/io_internal.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>

namespace gsd::io {

std::string grid_metadata_path(const std::string& grid_path) { return grid_path + ".json"; }

void write_grid_metadata(const std::string& grid_path, const GridMetadata& meta) {
    const std::string path = grid_metadata_path(grid_path);
    meta.grid.validate();
    if (meta.components != 1 && meta.components != 3) throw Error(path, "components must be 1 (values) or 3 (a gradient)");
    nlohmann::json options;
    try {
        options = nlohmann::json::parse(meta.options_json.empty() ? "{}" : meta.options_json);
    } catch (const nlohmann::json::exception& e) {
        throw Error(path, std::string("options_json is not valid JSON: ") + e.what());
    }
    if (!options.is_object()) throw Error(path, "options_json must be a JSON object");
    const Box& b = meta.grid.box;
    nlohmann::ordered_json j;  // fields in the order a reader wants them
    j["format"] = "gsd-grid";
    j["shape"] = {meta.grid.nx, meta.grid.ny, meta.grid.nz};
    j["components"] = meta.components;
    j["bounds"] = {{"lo", {b.lo.x(), b.lo.y(), b.lo.z()}}, {"hi", {b.hi.x(), b.hi.y(), b.hi.z()}}};
    j["layout"] = "C order: index = (i*ny + j)*nz + k; node (i,j,k) at lo + (i,j,k)*(hi-lo)/(shape-1)";
    j["method"] = meta.method;
    j["options"] = nlohmann::ordered_json(options);
    j["command"] = meta.command;
    j["gsd_version"] = meta.version.empty() ? std::string(version()) : meta.version;
    // dump(2): humans read these; the bounds keep every digit (nlohmann writes doubles exactly).
    write_file_atomic(path, j.dump(2) + "\n");
}

namespace {

const nlohmann::json& field(const nlohmann::json& j, const char* name, const std::string& path) {
    auto it = j.find(name);
    if (it == j.end()) detail::fail(path, std::string("missing \"") + name + "\"");
    return *it;
}

Eigen::Vector3d vec3(const nlohmann::json& j, const char* what, const std::string& path) {
    if (!j.is_array() || j.size() != 3) detail::fail(path, std::string(what) + " must be an array of 3 numbers");
    Eigen::Vector3d v;
    for (int a = 0; a < 3; ++a) {
        if (!j[a].is_number()) detail::fail(path, std::string(what) + " must be an array of 3 numbers");
        v[a] = j[a].get<double>();
    }
    return v;
}

}  // namespace

std::optional<GridMetadata> read_grid_metadata(const std::string& grid_path) {
    const std::string path = grid_metadata_path(grid_path);
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) return std::nullopt;
    const std::string text = detail::read_whole_file(path);
    nlohmann::json j;
    try {
        j = nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception& e) {
        detail::fail(path, std::string("not valid JSON: ") + e.what());
    }
    if (!j.is_object()) detail::fail(path, "not a JSON object");
    GridMetadata m;
    try {
        const auto& shape = field(j, "shape", path);
        if (!shape.is_array() || shape.size() != 3) detail::fail(path, "\"shape\" must be an array of 3 integers");
        int n[3];
        for (int a = 0; a < 3; ++a) {
            if (!shape[a].is_number_integer() || shape[a].get<long long>() < 2 || shape[a].get<long long>() > (1ll << 31))
                detail::fail(path, "\"shape\" must hold 3 integers of at least 2");
            n[a] = int(shape[a].get<long long>());
        }
        const auto& bounds = field(j, "bounds", path);
        if (!bounds.is_object()) detail::fail(path, "\"bounds\" must be an object with \"lo\" and \"hi\"");
        m.grid = GridSpec{n[0], n[1], n[2], Box{vec3(field(bounds, "lo", path), "\"bounds.lo\"", path),
                                                vec3(field(bounds, "hi", path), "\"bounds.hi\"", path)}};
        try {
            m.grid.validate();
        } catch (const Error& e) {
            detail::fail(path, e.what());
        }
        // Required, and 1 or 3: the only grids gsd writes are values and gradients (found by
        // fuzz/grid_metadata.cpp: 2 used to pass).
        const auto comp = j.find("components");
        if (comp == j.end()) detail::fail(path, "lacks \"components\"");
        if (!comp->is_number_integer() || (comp->get<long long>() != 1 && comp->get<long long>() != 3))
            detail::fail(path, "\"components\" must be 1 (values) or 3 (a gradient)");
        m.components = int(comp->get<long long>());
        if (auto it = j.find("method"); it != j.end() && it->is_string()) m.method = it->get<std::string>();
        if (auto it = j.find("options"); it != j.end() && it->is_object()) m.options_json = it->dump();
        if (auto it = j.find("command"); it != j.end() && it->is_array())
            for (const auto& a : *it)
                if (a.is_string()) m.command.push_back(a.get<std::string>());
        if (auto it = j.find("gsd_version"); it != j.end() && it->is_string()) m.version = it->get<std::string>();
    } catch (const nlohmann::json::exception& e) {
        detail::fail(path, e.what());
    }
    return m;
}

}  // namespace gsd::io
