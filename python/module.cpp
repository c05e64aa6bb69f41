// gsd's Python module (pybind11): NumPy arrays in and out, the GIL released while gsd works.
//
// Arrays come in as any (N, 3) float array and are converted once to gsd's row-major double
// matrices; results (std::vector) are handed to NumPy without a copy (the array owns them).
// gsd::Error becomes gsd.Error, a ValueError. python/gsd/__init__.py documents the API.
#include <gsd/adaptive_shm.hpp>
#include <gsd/baselines.hpp>
#include <gsd/field_algebra.hpp>
#include <gsd/gpu.hpp>
#include <gsd/io.hpp>
#include <gsd/pat.hpp>
#include <gsd/render.hpp>
#include <gsd/shm.hpp>
#include <gsd/spatial.hpp>
#include <gsd/sums.hpp>
#include <gsd/sdf.hpp>
#include <gsd/surface.hpp>
#include <gsd/swn.hpp>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <optional>
#include <utility>

namespace py = pybind11;
using namespace gsd;

namespace {

using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;
using IndexArray = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>;

// An (N, 3) array of any float dtype → gsd::Points; `name` is the argument, for errors.
void check_points_shape(const DoubleArray& a, const char* name) {
    if (a.ndim() == 2 && a.shape(1) == 3) return;
    std::string shape;
    for (py::ssize_t d = 0; d < a.ndim(); ++d) shape += (d ? ", " : "") + std::to_string(a.shape(d));
    throw Error(name, "must be an (N, 3) array, not (" + shape + ")");
}

Points points_from(const DoubleArray& a, const char* name) {
    check_points_shape(a, name);
    Points p(a.shape(0), 3);
    std::copy(a.data(), a.data() + a.size(), p.data());
    return p;
}

// An (N, 3) float64 C-order array read in place (forcecast made one if the caller's was not).
Eigen::Map<const Points> points_view(const DoubleArray& a, const char* name) {
    check_points_shape(a, name);
    return Eigen::Map<const Points>(a.data(), a.shape(0), 3);
}

// Moves a vector into a NumPy array of the given shape (no copy: a capsule owns the vector).
template <class T>
py::array_t<T> to_numpy(std::vector<T>&& v, std::vector<py::ssize_t> shape) {
    auto* owned = new std::vector<T>(std::move(v));
    py::capsule free_when_done(owned, [](void* p) { delete static_cast<std::vector<T>*>(p); });
    return py::array_t<T>(shape, owned->data(), free_when_done);
}

py::array_t<double> to_numpy(const Points& p) {
    py::array_t<double> out({py::ssize_t(p.rows()), py::ssize_t(3)});
    std::copy(p.data(), p.data() + p.size(), out.mutable_data());
    return out;
}

// A polygon mesh from vertices (V, 3) and faces: an (F, k) integer array (all faces k-gons) or
// a sequence of index sequences (mixed sizes).
PolygonMesh mesh_from(const DoubleArray& vertices, const py::object& faces) {
    PolygonMesh m;
    m.vertices = points_from(vertices, "vertices");
    auto add = [&](const std::int64_t* f, std::size_t n) {
        std::vector<std::uint32_t> idx(n);
        for (std::size_t k = 0; k < n; ++k) {
            if (f[k] < 0 || f[k] >= std::int64_t(m.vertices.rows()))
                throw Error("faces", "index " + std::to_string(f[k]) + " is not a vertex (there are " +
                                         std::to_string(m.vertices.rows()) + ")");
            idx[k] = std::uint32_t(f[k]);
        }
        m.add_face(idx.data(), n);
    };
    if (py::isinstance<py::array>(faces)) {
        const IndexArray f = faces.cast<IndexArray>();
        if (f.ndim() != 2 || f.shape(1) < 3) throw Error("faces", "must be an (F, k) integer array with k ≥ 3");
        for (py::ssize_t i = 0; i < f.shape(0); ++i) add(f.data(i, 0), std::size_t(f.shape(1)));
    } else {
        for (const py::handle face : faces) {
            const IndexArray f = py::reinterpret_borrow<py::object>(face).cast<IndexArray>();
            if (f.ndim() != 1) throw Error("faces", "each face must be a sequence of vertex indices");
            add(f.data(), std::size_t(f.size()));
        }
    }
    validate(m, "mesh");
    return m;
}

py::object faces_of(const PolygonMesh& m) {
    bool uniform = true;
    for (std::size_t f = 1; f < m.face_count() && uniform; ++f) uniform = m.face_size(f) == m.face_size(0);
    if (uniform && m.face_count() > 0) {
        const std::size_t k = m.face_size(0);
        py::array_t<std::int64_t> out({py::ssize_t(m.face_count()), py::ssize_t(k)});
        for (std::size_t i = 0; i < m.indices.size(); ++i) out.mutable_data()[i] = m.indices[i];
        return out;
    }
    py::list out;
    for (std::size_t f = 0; f < m.face_count(); ++f)
        out.append(py::array_t<std::int64_t>(py::ssize_t(m.face_size(f)), std::vector<std::int64_t>(
            m.indices.begin() + m.offsets[f], m.indices.begin() + m.offsets[f + 1]).data()));
    return out;
}

PointCloud cloud_from(const DoubleArray& points, const DoubleArray& normals) {
    PointCloud c{points_from(points, "points"), points_from(normals, "normals")};
    validate(c, "cloud");
    normalize_normals(c, "cloud");
    return c;
}

GridSpec grid_from(int n, const std::optional<std::array<double, 6>>& bounds, const Box& fallback) {
    const Box box = bounds ? Box{{(*bounds)[0], (*bounds)[1], (*bounds)[2]}, {(*bounds)[3], (*bounds)[4], (*bounds)[5]}}
                           : padded_cube(fallback);
    GridSpec g = GridSpec::cube(n, box);
    g.validate();
    return g;
}

py::tuple bounds_tuple(const Box& b) { return py::make_tuple(b.lo.x(), b.lo.y(), b.lo.z(), b.hi.x(), b.hi.y(), b.hi.z()); }

py::object field_result(FieldValues&& v, bool gradient, std::vector<py::ssize_t> shape) {
    py::array_t<float> phi = to_numpy(std::move(v.phi), shape);
    if (!gradient) return phi;
    shape.push_back(3);
    return py::make_tuple(phi, to_numpy(std::move(v.gradient), shape));
}

FieldRenderOptions render_options(int width, int height, const std::optional<std::array<double, 3>>& view_from,
                                  const std::optional<std::array<double, 3>>& camera,
                                  const std::optional<std::array<double, 3>>& up, double fov, int supersample,
                                  const std::string& device) {
    FieldRenderOptions o;
    o.width = width;
    o.height = height;
    if (view_from) o.view_from = {(*view_from)[0], (*view_from)[1], (*view_from)[2]};
    if (camera) o.eye = Eigen::Vector3d((*camera)[0], (*camera)[1], (*camera)[2]);
    if (up) o.up = {(*up)[0], (*up)[1], (*up)[2]};
    o.fov_degrees = fov;
    o.supersample = supersample;
    o.device = device;
    return o;
}

py::array_t<std::uint8_t> image_array(Image&& image) {
    return to_numpy(std::move(image.rgb), {image.height, image.width, 3});
}

// The options mesh_sdf and sample_sdf share.
void set_sdf_options(MeshSdfOptions& o, const std::string& sign, double inside, const std::string& device) {
    o.sign = sdf_sign_from_name(sign);
    o.inside_threshold = inside;
    o.device = device;
}

// The Signed Heat Method's source from a cloud, a mesh or both, as `gsd shm` loads them: a
// cloud's outliers left out, then its flipped normals turned back (each unless asked not to).
ShmSource shm_source_from(const std::optional<DoubleArray>& points, const std::optional<DoubleArray>& normals,
                          const std::optional<DoubleArray>& vertices, const py::object& faces, bool drop_outliers,
                          bool reorient) {
    if (points.has_value() != normals.has_value()) throw Error("normals", "points and normals go together");
    if (vertices.has_value() == faces.is_none()) throw Error("faces", "vertices and faces go together");
    if (!points && !vertices) throw Error("points", "give a cloud (points, normals), a mesh (vertices, faces), or both");
    std::optional<PointCloud> cloud;
    std::optional<PolygonMesh> mesh;
    if (points) cloud = cloud_from(*points, *normals);
    if (vertices) mesh = mesh_from(*vertices, faces);
    py::gil_scoped_release nogil;
    if (cloud && drop_outliers) cloud = without_outliers(*cloud);
    if (cloud && reorient) reorient_normals(*cloud);
    ShmSource src;
    if (mesh) src = shm_source(*mesh);
    if (cloud) src = mesh ? combine(src, shm_source(*cloud)) : shm_source(*cloud);
    return src;
}

}  // namespace

PYBIND11_MODULE(_gsd, m) {
    m.doc() = "gsd: generalized signed distance and winding numbers from imperfect geometry";
    static py::exception<Error> error(m, "Error", PyExc_ValueError);
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const Error& e) {
            const std::string where = e.where();
            const std::string message = (where.empty() ? std::string() : where + ": ") + e.what();
            PyErr_SetString(error.ptr(), message.c_str());
        }
    });

    m.def("version", [] { return std::string(version()); });
    m.def("devices", [] {
        py::list out;
        for (const auto& d : gpu::list_devices().devices)
            out.append(py::dict(py::arg("index") = d.index, py::arg("name") = d.name, py::arg("type") = d.type,
                                py::arg("usable") = d.usable));
        return out;
    }, "The Vulkan devices gsd sees (an empty list without a loader).");

    // ---- io ----
    m.def("read_point_cloud", [](const std::string& path) {
        PointCloud c;
        {
            py::gil_scoped_release nogil;
            c = io::read_point_cloud(path);
        }
        return py::make_tuple(to_numpy(c.points), to_numpy(c.normals));
    }, py::arg("path"), "(points (N,3), normals (N,3)) from .ply .xyz .xyzn .txt .pc .obj .npy");
    m.def("read_mesh", [](const std::string& path) {
        PolygonMesh mesh;
        {
            py::gil_scoped_release nogil;
            mesh = io::read_mesh(path);
        }
        return py::make_tuple(to_numpy(mesh.vertices), faces_of(mesh));
    }, py::arg("path"), "(vertices (V,3), faces) from .obj .ply .off .stl; faces (F,k) if all are k-gons, else a list");
    m.def("write_mesh", [](const std::string& path, const DoubleArray& vertices, const py::object& faces) {
        const PolygonMesh mesh = mesh_from(vertices, faces);
        py::gil_scoped_release nogil;
        io::write_mesh(path, mesh);
    }, py::arg("path"), py::arg("vertices"), py::arg("faces"));

    // ---- Points as Tori ----
    py::class_<FittedTori>(m, "Tori", "Tori fitted at every point of a cloud (fit once, evaluate often).")
        .def("__len__", [](const FittedTori& t) { return t.size(); })
        .def_property_readonly("points", [](const FittedTori& t) { return to_numpy(t.points); })
        .def_property_readonly("normals", [](const FittedTori& t) { return to_numpy(t.normals); })
        .def_readonly("spacing", &FittedTori::spacing)
        .def_readonly("fitter", &FittedTori::fitter)
        .def("save", [](const FittedTori& t, const std::string& path) {
            py::gil_scoped_release nogil;
            save_tori(path, t);
        }, py::arg("path"));
    m.def("load_tori", [](const std::string& path) {
        py::gil_scoped_release nogil;
        return load_tori(path);
    }, py::arg("path"));
    m.def("fit_tori", [](const DoubleArray& points, const DoubleArray& normals, const std::string& fitter,
                         const std::string& device, bool reorient) {
        PointCloud cloud = cloud_from(points, normals);
        if (fitter != "net" && fitter != "jet") throw Error("fitter", "must be \"net\" or \"jet\", not \"" + fitter + "\"");
        py::gil_scoped_release nogil;
        if (reorient) reorient_normals(cloud);
        if (fitter == "jet") return JetFitter().fit(cloud);
        TorusNetOptions o;
        o.device = device;
        return TorusNet(o).fit(cloud);
    }, py::arg("points"), py::arg("normals"), py::arg("fitter") = "net", py::arg("device") = "",
       py::arg("reorient_normals") = true,
       "Fits a torus at every point: fitter \"net\" (TorusNet, the default) or \"jet\". reorient_normals: normals "
       "that their neighbours contradict are turned back first (the CLI's default; False: --keep-normals).");

    py::class_<OutlierOptions>(m, "OutlierOptions", "PAT's outlier defence (docs/pat.md, Outliers); defaults as in C++.")
        .def(py::init<>())
        .def_readwrite("enabled", &OutlierOptions::enabled)
        .def_readwrite("k", &OutlierOptions::k)
        .def_readwrite("quantile", &OutlierOptions::quantile)
        .def_readwrite("min_score", &OutlierOptions::min_score)
        .def_readwrite("mad_factor", &OutlierOptions::mad_factor)
        .def_readwrite("sparsity_factor", &OutlierOptions::sparsity_factor);
    m.def("reorient_normals", [](const DoubleArray& points, const DoubleArray& normals, int neighbors, int passes) {
        PointCloud c = cloud_from(points, normals);
        ReorientOptions o;
        o.neighbors = neighbors;
        o.passes = passes;
        std::size_t turned = 0;
        {
            py::gil_scoped_release nogil;
            turned = reorient_normals(c, o);
        }
        return py::make_tuple(to_numpy(c.normals), turned);
    }, py::arg("points"), py::arg("normals"), py::arg("neighbors") = ReorientOptions{}.neighbors,
       py::arg("passes") = ReorientOptions{}.passes,
       "(normals (N,3), how many turned): the normals that their neighbours contradict turned back, as gsd shm "
       "and gsd pat do by default (--keep-normals keeps them). The normals come back of unit length.");
    m.def("point_confidence", [](const FittedTori& tori, std::optional<OutlierOptions> options) {
        const OutlierOptions o = options.value_or(OutlierOptions{});
        PointConfidence c;
        {
            py::gil_scoped_release nogil;
            c = point_confidence(tori, o);
        }
        return py::make_tuple(py::array_t<float>(py::ssize_t(c.confidence.size()), c.confidence.data()),
                              py::array_t<double>(py::ssize_t(c.score.size()), c.score.data()),
                              py::array_t<double>(py::ssize_t(c.sparsity.size()), c.sparsity.data()));
    }, py::arg("tori"), py::arg("options") = py::none(),
       "(confidence (N,) float32, residual (N,), sparsity (N,)): PAT's outlier measures (docs/pat.md, Outliers);\n"
       "a point is an outlier where confidence < 0.5.");

    // ---- fields and their algebra (gsd/field_algebra.hpp, docs/field.md) ----
    // Every field is a gsd.Field held by a shared pointer, so that operators can hold their
    // operands: a | b, a & b, a - b, a.offset(r), a.shell(r), gsd.smooth_union(a, b, k), ….
    py::class_<Field, std::shared_ptr<Field>> field(m, "Field",
        "Any gsd field: PAT, a grid, a mesh's exact distance, or a composite of them (docs/field.md).");
    auto shared = [](FieldPtr f) { return std::const_pointer_cast<Field>(std::move(f)); };
    auto held = [](const std::shared_ptr<Field>& f) { return FieldPtr(f); };
    field
        .def("evaluate", [](const Field& f, const DoubleArray& queries, bool gradient) {
            const Eigen::Map<const Points> q = points_view(queries, "queries");  // no copy
            FieldValues v;
            {
                py::gil_scoped_release nogil;
                v = f.evaluate(q, gradient);
            }
            return field_result(std::move(v), gradient, {py::ssize_t(q.rows())});
        }, py::arg("queries"), py::arg("gradient") = false,
           "φ (M,) float32 at (M,3) queries; with gradient=True, (φ, ∇φ (M,3)).")
        .def("evaluate_on_grid", [](const Field& f, int n, std::array<double, 6> bounds, bool gradient) {
            const GridSpec g = grid_from(n, bounds, Box{});
            FieldValues v;
            {
                py::gil_scoped_release nogil;
                v = f.evaluate(g, gradient);
            }
            return field_result(std::move(v), gradient, {n, n, n});
        }, py::arg("n"), py::arg("bounds"), py::arg("gradient") = false,
           "φ (n,n,n) float32 on the n³ grid of bounds (x0,y0,z0,x1,y1,z1); with gradient=True, (φ, ∇φ (n,n,n,3)).")
        .def_property_readonly("has_gradient", &Field::has_gradient)
        .def("__or__", [=](const std::shared_ptr<Field>& a, const std::shared_ptr<Field>& b) { return shared(field_union(held(a), held(b))); },
             "Union: min(a, b).")
        .def("__and__", [=](const std::shared_ptr<Field>& a, const std::shared_ptr<Field>& b) { return shared(field_intersection(held(a), held(b))); },
             "Intersection: max(a, b).")
        .def("__sub__", [=](const std::shared_ptr<Field>& a, const std::shared_ptr<Field>& b) { return shared(field_difference(held(a), held(b))); },
             "Difference: max(a, −b).")
        .def("offset", [=](const std::shared_ptr<Field>& a, double r) { return shared(field_offset(held(a), r)); }, py::arg("r"),
             "φ − r: grown by r > 0, shrunk by r < 0.")
        .def("shell", [=](const std::shared_ptr<Field>& a, double r) { return shared(field_shell(held(a), r)); }, py::arg("r"),
             "|φ| − r: a shell of thickness 2r.");
    m.def("union", [=](const std::shared_ptr<Field>& a, const std::shared_ptr<Field>& b, double smooth) {
        return shared(field_union(held(a), held(b), smooth));
    }, py::arg("a"), py::arg("b"), py::arg("smooth") = 0.0, "min(a, b); smooth = k > 0: the polynomial smooth minimum.");
    m.def("intersection", [=](const std::shared_ptr<Field>& a, const std::shared_ptr<Field>& b, double smooth) {
        return shared(field_intersection(held(a), held(b), smooth));
    }, py::arg("a"), py::arg("b"), py::arg("smooth") = 0.0, "max(a, b); smooth = k > 0: its smooth variant.");
    m.def("difference", [=](const std::shared_ptr<Field>& a, const std::shared_ptr<Field>& b, double smooth) {
        return shared(field_difference(held(a), held(b), smooth));
    }, py::arg("a"), py::arg("b"), py::arg("smooth") = 0.0, "max(a, −b); smooth = k > 0: its smooth variant.");
    m.def("opening", [=](const std::shared_ptr<Field>& a, double r, int n, std::array<double, 6> bounds) {
        return shared(field_opening(held(a), r, grid_from(n, bounds, Box{})));
    }, py::arg("a"), py::arg("r"), py::arg("n"), py::arg("bounds"),
       "Erosion by r, re-distancing, dilation by r, on the n³ grid of bounds: what is thinner than 2r goes.");
    m.def("opening", [=](const std::shared_ptr<Field>& a, double r, const DoubleArray& seeds) {
        return shared(field_opening(held(a), r, points_from(seeds, "seeds")));
    }, py::arg("a"), py::arg("r"), py::arg("seeds"),
       "The same without a grid: seeds (points on the zero set, a cloud's own) resampled onto the erosion and re-distanced to.");
    m.def("closing", [=](const std::shared_ptr<Field>& a, double r, int n, std::array<double, 6> bounds) {
        return shared(field_closing(held(a), r, grid_from(n, bounds, Box{})));
    }, py::arg("a"), py::arg("r"), py::arg("n"), py::arg("bounds"),
       "Dilation by r, re-distancing, erosion by r, on the n³ grid of bounds: gaps narrower than 2r fill.");
    m.def("closing", [=](const std::shared_ptr<Field>& a, double r, const DoubleArray& seeds) {
        return shared(field_closing(held(a), r, points_from(seeds, "seeds")));
    }, py::arg("a"), py::arg("r"), py::arg("seeds"),
       "The same without a grid: seeds (points on the zero set, a cloud's own) resampled onto the dilation and re-distanced to.");
    py::class_<GridField, Field, std::shared_ptr<GridField>>(m, "GridField",
        "A grid's values as a field: trilinear inside its box, the nearest value plus the distance outside.")
        .def(py::init([](const py::array_t<float, py::array::c_style | py::array::forcecast>& values, std::array<double, 6> bounds) {
                 if (values.ndim() != 3) throw Error("values", "must be an (nx, ny, nz) grid");
                 const GridSpec g{int(values.shape(0)), int(values.shape(1)), int(values.shape(2)),
                                  Box{{bounds[0], bounds[1], bounds[2]}, {bounds[3], bounds[4], bounds[5]}}};
                 return std::make_shared<GridField>(g, std::vector<float>(values.data(), values.data() + values.size()));
             }),
             py::arg("values"), py::arg("bounds"), "values (nx,ny,nz) float; bounds (x0,y0,z0,x1,y1,z1): the first and last nodes.");
    py::class_<MeshSdfField, Field, std::shared_ptr<MeshSdfField>>(m, "MeshSdfField",
        "mesh_sdf as a field: the exact distance to a mesh in any state, signed as `sign` says.")
        .def(py::init([](const DoubleArray& vertices, const py::object& faces, const std::string& sign, double inside,
                         const std::string& device) {
                 MeshSdfOptions o;
                 set_sdf_options(o, sign, inside, device);
                 return std::make_shared<MeshSdfField>(mesh_from(vertices, faces), o);
             }),
             py::arg("vertices"), py::arg("faces"), py::arg("sign") = "auto", py::arg("inside") = 0.5, py::arg("device") = "");

    py::class_<TorusField, Field, std::shared_ptr<TorusField>>(m, "TorusField", "The PAT generalized signed distance of fitted tori.")
        .def(py::init([](const FittedTori& tori, bool exact, const std::string& device, double r_eval,
                         bool keep_outliers, std::optional<OutlierOptions> outliers) {
                 BlendOptions o;
                 o.exact = exact;
                 o.device = device;
                 o.r_eval = r_eval;
                 OutlierOptions out = outliers.value_or(OutlierOptions{});
                 if (keep_outliers) out.enabled = false;
                 py::gil_scoped_release nogil;
                 return std::make_shared<TorusField>(tori, o, out);
             }),
             py::arg("tori"), py::arg("exact") = false, py::arg("device") = "", py::arg("r_eval") = 0.0,
             py::arg("keep_outliers") = false, py::arg("outliers") = py::none(),
             "keep_outliers=True blends every point (disables the outlier defence, for comparison);\n"
             "outliers: an OutlierOptions to tune the defence.")
        .def_property_readonly("confidence", [](const TorusField& f) {
            const std::vector<float>& c = f.confidence().confidence;
            return py::array_t<float>(py::ssize_t(c.size()), c.data());
        }, "Per point confidence (N,) float32; points below 0.5 are outliers left out of the blend (empty with keep_outliers).")
        .def_property_readonly("blended_count", &TorusField::blended_count)  // evaluate: gsd.Field's
        .def("evaluate_grid", [](const TorusField& f, int n, std::optional<std::array<double, 6>> bounds, bool gradient) {
            const GridSpec g = grid_from(n, bounds, bounding_box(f.tori().points));
            FieldValues v;
            {
                py::gil_scoped_release nogil;
                v = f.evaluate(g, gradient);
            }
            return py::make_tuple(field_result(std::move(v), gradient, {n, n, n}), bounds_tuple(g.box));
        }, py::arg("n"), py::arg("bounds") = py::none(), py::arg("gradient") = false,
           "(φ (n,n,n), bounds) on an n³ grid; bounds (x0,y0,z0,x1,y1,z1), default the cloud's cube + 10%.")
        .def_property_readonly("r_eval", &TorusField::r_eval)
        .def("render", [](const TorusField& f, int width, int height, std::optional<std::array<double, 3>> view_from,
                          std::optional<std::array<double, 3>> camera, std::optional<std::array<double, 3>> up, double fov,
                          int supersample, std::optional<std::array<double, 6>> bounds, const std::string& device) {
            const FieldRenderOptions o = render_options(width, height, view_from, camera, up, fov, supersample, device);
            const Box box = bounds ? Box{{(*bounds)[0], (*bounds)[1], (*bounds)[2]}, {(*bounds)[3], (*bounds)[4], (*bounds)[5]}}
                                   : padded_cube(bounding_box(f.tori().points));
            RenderedField r;
            {
                py::gil_scoped_release nogil;
                r = render_field(f, box, o);
            }
            return image_array(std::move(r.image));
        }, py::arg("width") = 800, py::arg("height") = 600, py::arg("view_from") = py::none(), py::arg("camera") = py::none(),
           py::arg("up") = py::none(), py::arg("fov") = 35.0, py::arg("supersample") = 1, py::arg("bounds") = py::none(),
           py::arg("device") = "",
           "A picture of the zero level set, sphere-traced and shaded by ∇φ (gsd render): (height, width, 3) uint8.\n"
           "bounds: the box the rays march in (default: the cloud's cube + 10%); camera: an explicit position.");
    m.def("render_grid", [](const py::array_t<float, py::array::c_style | py::array::forcecast>& values,
                            std::array<double, 6> bounds, int width, int height, std::optional<std::array<double, 3>> view_from,
                            std::optional<std::array<double, 3>> camera, std::optional<std::array<double, 3>> up, double fov,
                            int supersample, const std::string& device) {
        if (values.ndim() != 3) throw Error("values", "must be an (nx, ny, nz) grid");
        const GridSpec g{int(values.shape(0)), int(values.shape(1)), int(values.shape(2)),
                         Box{{bounds[0], bounds[1], bounds[2]}, {bounds[3], bounds[4], bounds[5]}}};
        const std::vector<float> v(values.data(), values.data() + values.size());
        const FieldRenderOptions o = render_options(width, height, view_from, camera, up, fov, supersample, device);
        RenderedField r;
        {
            py::gil_scoped_release nogil;
            r = render_field(g, v, o);
        }
        return image_array(std::move(r.image));
    }, py::arg("values"), py::arg("bounds"), py::arg("width") = 800, py::arg("height") = 600, py::arg("view_from") = py::none(),
       py::arg("camera") = py::none(), py::arg("up") = py::none(), py::arg("fov") = 35.0, py::arg("supersample") = 1,
       py::arg("device") = "",
       "A picture of a grid's zero level set (trilinear), as gsd render draws it: (height, width, 3) uint8.");

    // ---- Signed Heat Method on grids ----
    m.def("signed_heat_grid", [](int n, std::optional<DoubleArray> points, std::optional<DoubleArray> normals,
                                 std::optional<DoubleArray> vertices, py::object faces,
                                 std::optional<std::array<double, 6>> bounds, double t_coef, double fit_zero_set,
                                 double veto_winding, double veto_margin, bool redistance, const std::string& device,
                                 bool reorient_normals, bool drop_outliers) {
        ShmSource src = shm_source_from(points, normals, vertices, faces, drop_outliers, reorient_normals);
        ShmOptions o;  // checked by the solver, whose errors name the option
        o.t_coef = t_coef;
        o.fit_zero_set = fit_zero_set;
        o.veto_winding = veto_winding;
        o.veto_margin = veto_margin;
        o.redistance = redistance;
        o.device = device;
        py::gil_scoped_release nogil;
        const GridSpec g = bounds ? grid_from(n, bounds, {}) : GridSpec::cube(n, shm_default_bounds(src));
        g.validate();
        ShmResult r = SignedHeatGrid(std::move(src), g, o).solve();
        py::gil_scoped_acquire gil;
        return py::make_tuple(to_numpy(std::move(r.phi), {n, n, n}), bounds_tuple(g.box));
    }, py::arg("n"), py::arg("points") = py::none(), py::arg("normals") = py::none(), py::arg("vertices") = py::none(),
       py::arg("faces") = py::none(), py::arg("bounds") = py::none(), py::arg("t_coef") = ShmOptions{}.t_coef,
       py::arg("fit_zero_set") = ShmOptions{}.fit_zero_set, py::arg("veto_winding") = ShmOptions{}.veto_winding,
       py::arg("veto_margin") = ShmOptions{}.veto_margin, py::arg("redistance") = false, py::arg("device") = "",
       py::arg("reorient_normals") = true, py::arg("drop_outliers") = true,
       "(φ (n,n,n), bounds): the Signed Heat Method from a cloud, a mesh, or both. redistance: |φ| made the exact "
       "distance to SHM's zero set (--redistance). drop_outliers: a cloud's points that PAT's outlier scores reject "
       "are left out first; reorient_normals: then normals that their neighbours contradict are turned back (both "
       "the CLI's defaults). fit_zero_set: weight of the "
       "soft fit of φ = 0 on the source (0: the mean shift alone); veto_winding, veto_margin: the outside veto "
       "(veto_winding 0: none), as the CLI's --fit-zero-set, --veto-winding, --veto-margin.");

    py::class_<OctreeField, Field, std::shared_ptr<OctreeField>>(m, "OctreeField",
        "φ on an adaptive octree (signed_heat_adaptive): trilinear in each leaf, continuous across levels.")
        .def_property_readonly("depth", &OctreeField::depth)
        .def_property_readonly("finest_cell", &OctreeField::finest_cell)
        .def_property_readonly("bounds", [](const OctreeField& f) { return bounds_tuple(f.box()); })
        .def_property_readonly("node_count", &OctreeField::node_count)
        .def_property_readonly("leaf_count", &OctreeField::leaf_count)
        .def("nodes", [](const OctreeField& f) {
            const Points p = f.node_positions();
            std::vector<double> flat(p.data(), p.data() + p.size());
            return to_numpy(std::move(flat), {py::ssize_t(p.rows()), 3});
        }, "The nodes' positions (n, 3).")
        .def("node_values", [](const OctreeField& f) {
            std::vector<float> v = f.node_values();
            const auto n = py::ssize_t(v.size());
            return to_numpy(std::move(v), {n});
        }, "φ at the nodes (n,).");
    m.def("signed_heat_adaptive", [](int depth, std::optional<DoubleArray> points, std::optional<DoubleArray> normals,
                                     std::optional<DoubleArray> vertices, py::object faces,
                                     std::optional<std::array<double, 6>> bounds, double band, double grading, double t_coef,
                                     double fit_zero_set, double veto_winding, bool redistance, bool drop_outliers,
                                     const std::string& device, double fit_scale, bool reorient_normals) {
        ShmSource src = shm_source_from(points, normals, vertices, faces, drop_outliers, reorient_normals);
        AdaptiveShmOptions o;  // checked by the solver, whose errors name the option
        o.depth = depth;
        o.band = band;
        o.grading = grading;
        o.t_coef = t_coef;
        o.fit_zero_set = fit_zero_set;
        o.fit_scale = fit_scale;
        o.veto_winding = veto_winding;
        o.redistance = redistance;
        o.device = device;
        if (bounds) o.bounds = Box{{(*bounds)[0], (*bounds)[1], (*bounds)[2]}, {(*bounds)[3], (*bounds)[4], (*bounds)[5]}};
        py::gil_scoped_release nogil;
        return std::make_shared<OctreeField>(SignedHeatOctree(std::move(src), o).solve().field);
    }, py::arg("depth"), py::arg("points") = py::none(), py::arg("normals") = py::none(), py::arg("vertices") = py::none(),
       py::arg("faces") = py::none(), py::arg("bounds") = py::none(), py::arg("band") = AdaptiveShmOptions{}.band,
       py::arg("grading") = AdaptiveShmOptions{}.grading, py::arg("t_coef") = AdaptiveShmOptions{}.t_coef,
       py::arg("fit_zero_set") = AdaptiveShmOptions{}.fit_zero_set, py::arg("veto_winding") = AdaptiveShmOptions{}.veto_winding,
       py::arg("redistance") = false, py::arg("drop_outliers") = true, py::arg("device") = "",
       py::arg("fit_scale") = AdaptiveShmOptions{}.fit_scale, py::arg("reorient_normals") = true,
       "The Signed Heat Method on an adaptive octree (gsd shm adaptive): an OctreeField, a Field to evaluate anywhere. "
       "drop_outliers: a cloud's points that PAT's outlier scores reject are left out first (the CLI's default); "
       "reorient_normals: then normals that their neighbours contradict are turned back (the CLI's default). "
       "depth: finest cell = the cube's side / 2^depth; bounds: the cube's low corner and, by the longest side, its size "
       "(default: the source's cube + 10%); redistance: |φ| made the exact distance to SHM's zero set; "
       "fit_scale: the zero-set fit corrects φ on cells at least this many source spacings wide (0: the finest).");

    // ---- winding numbers ----
    m.def("winding_numbers", [](const DoubleArray& queries, std::optional<DoubleArray> vertices, py::object faces,
                                std::optional<DoubleArray> points, std::optional<DoubleArray> normals, bool exact,
                                double beta, double tolerance, const std::string& device) {
        const Points q = points_from(queries, "queries");
        OrientedElements elements;
        if (vertices && !faces.is_none()) elements = OrientedElements::from_mesh(mesh_from(*vertices, faces));
        else if (points && normals) elements = OrientedElements::from_cloud(cloud_from(*points, *normals));
        else throw Error("vertices", "give a mesh (vertices, faces) or a cloud (points, normals)");
        WindingOptions o;
        o.exact = exact;
        o.beta = beta;
        o.tolerance = tolerance;
        o.device = device;
        WindingResult r;
        {
            py::gil_scoped_release nogil;
            r = fast_winding_numbers(elements, q, o);
        }
        return to_numpy(std::move(r.w), {py::ssize_t(q.rows())});
    }, py::arg("queries"), py::arg("vertices") = py::none(), py::arg("faces") = py::none(), py::arg("points") = py::none(),
       py::arg("normals") = py::none(), py::arg("exact") = false, py::arg("beta") = WindingOptions{}.beta,
       py::arg("tolerance") = WindingOptions{}.tolerance, py::arg("device") = "",
       "Generalized winding number (M,) of a mesh in any state or an oriented cloud at (M,3) queries. beta, "
       "tolerance: the opening criterion, as the CLI's --beta, --tolerance (exact: sum every element).");

    // ---- signed distance to a mesh ----
    m.def("mesh_sdf", [](const DoubleArray& vertices, const py::object& faces, const DoubleArray& queries,
                         const std::string& sign, double inside, const std::string& device, bool gradient) -> py::object {
        const PolygonMesh mesh = mesh_from(vertices, faces);
        const Points q = points_from(queries, "queries");
        MeshSdfOptions o;
        set_sdf_options(o, sign, inside, device);
        o.gradient = gradient;
        MeshSdfResult r;
        {
            py::gil_scoped_release nogil;
            r = mesh_sdf(mesh, q, o);
        }
        py::array_t<double> phi = to_numpy(std::move(r.phi), {py::ssize_t(q.rows())});
        if (!gradient) return phi;
        return py::make_tuple(phi, to_numpy(std::move(r.gradient), {py::ssize_t(q.rows()), 3}));
    }, py::arg("vertices"), py::arg("faces"), py::arg("queries"), py::arg("sign") = "auto",
       py::arg("inside") = MeshSdfOptions{}.inside_threshold, py::arg("device") = "", py::arg("gradient") = false,
       "Signed distance (M,) from (M,3) queries to a mesh in any state: the exact distance to its triangles, negative inside "
       "(sign: 'auto' | 'winding' | 'pseudonormal' | 'shm' | 'none', as `gsd sdf --sign`; inside: the winding number "
       "threshold). gradient=True: (phi, grad (M,3)), grad the unit vector from the nearest point, signed as phi.");
    m.def("sample_sdf", [](const DoubleArray& vertices, const py::object& faces, std::size_t count,
                           const std::vector<double>& near_sigma, double uniform, bool normalize, std::uint64_t seed,
                           const std::string& sign, double inside, const std::string& device) {
        const PolygonMesh mesh = mesh_from(vertices, faces);
        SdfSampleOptions o;
        o.near_sigma = near_sigma;
        o.uniform_fraction = uniform;
        o.normalize = normalize;
        o.seed = seed;
        set_sdf_options(o, sign, inside, device);
        SdfSamples s;
        std::vector<float> rows;
        {
            py::gil_scoped_release nogil;
            s = sample_sdf(mesh, count, o);
            rows = sample_rows(s);
        }
        return py::make_tuple(to_numpy(std::move(rows), {py::ssize_t(count), 4}),
                              to_numpy(std::vector<double>{s.center.x(), s.center.y(), s.center.z()}, {3}), s.radius);
    }, py::arg("vertices"), py::arg("faces"), py::arg("count"), py::arg("near_sigma") = SdfSampleOptions{}.near_sigma,
       py::arg("uniform") = SdfSampleOptions{}.uniform_fraction, py::arg("normalize") = false, py::arg("seed") = 0,
       py::arg("sign") = "auto", py::arg("inside") = MeshSdfOptions{}.inside_threshold, py::arg("device") = "",
       "Training samples of a mesh's signed distance, as `gsd sdf --samples`: (samples (count,4) float32 rows x y z sdf, "
       "center (3,), radius) — near the surface (offsets of each near_sigma × the bounding sphere's radius) and a "
       "`uniform` share in the sphere's cube; normalize: in the unit-sphere frame.");

    // ---- on surfaces ----
    // A surface from (vertices, faces), or from a point cloud when faces is None (its fans for
    // the SHM, its triangulation for SWN); curves on a cloud name points.
    m.def("cloud_surface", [](const DoubleArray& points, std::optional<DoubleArray> normals, int neighbors) {
        const Points p = points_from(points, "points");
        const Points n = normals ? points_from(*normals, "normals") : Points();
        CloudSurfaceOptions o;
        o.neighbors = neighbors;
        PolygonMesh tri;
        Points fitted;
        {
            py::gil_scoped_release nogil;
            CloudSurface s = cloud_surface(p, n, o, "points");
            tri = std::move(s.triangulation);
            fitted = std::move(s.normals);
        }
        return py::make_tuple(faces_of(tri), to_numpy(fitted));
    }, py::arg("points"), py::arg("normals") = py::none(), py::arg("neighbors") = CloudSurfaceOptions{}.neighbors,
       "(faces (F,3), normals (N,3)) of a point cloud as a surface: a manifold triangulation of the points and their "
       "fitted normals, oriented consistently (normals given: their majority sign). As gsd.signed_heat_surface and "
       "gsd.surface_winding_numbers use it with faces=None.");
    m.def("signed_heat_surface", [](const DoubleArray& vertices, const py::object& faces, const std::string& curves,
                                    double t_coef, int neighbors, bool filter_nonbounding) {
        PolygonMesh mesh;
        Points cloud;
        if (faces.is_none()) cloud = points_from(vertices, "vertices");
        else mesh = mesh_from(vertices, faces);
        py::gil_scoped_release nogil;
        CloudSurfaceOptions o;
        o.neighbors = neighbors;
        std::optional<CloudSurface> cs;
        if (faces.is_none()) cs = cloud_surface(cloud, {}, o, "points");
        SurfaceMesh surface = cs ? std::move(cs->mesh) : SurfaceMesh(std::move(mesh), "mesh");
        SurfaceSources sources = read_surface_curves(curves, surface);
        if (cs) require_cloud_points(sources, curves);
        if (filter_nonbounding) {
            // SWN's decomposition (a cloud: on its manifold triangulation, the same vertices).
            const SwnResult w = SurfaceWindingNumbers(cs ? SurfaceMesh(cs->triangulation, "points") : surface).solve(sources);
            if (w.bounding_curves.curves.empty()) throw Error(curves, "every curve bounds nothing: no inside to sign the distance by");
            sources.curves = w.bounding_curves.curves;
        }
        SurfaceShmSetup setup;
        setup.t_coef = t_coef;
        SurfaceShmResult r = SignedHeatSurface(std::move(surface), setup).solve(sources);
        py::gil_scoped_acquire gil;
        const py::ssize_t n = py::ssize_t(r.phi.size());
        return to_numpy(std::move(r.phi), {n});
    }, py::arg("vertices"), py::arg("faces"), py::arg("curves"), py::arg("t_coef") = 1.0,
       py::arg("neighbors") = CloudSurfaceOptions{}.neighbors, py::arg("filter_nonbounding") = false,
       "Signed distance per vertex to the curves in a file (docs/formats.md), by the surface Signed Heat Method. "
       "faces=None: vertices are a point cloud (curves name its points), φ per point. filter_nonbounding: leave out "
       "the parts of the curves that bound nothing (Surface Winding Numbers' decomposition), as the CLI's "
       "--filter-nonbounding.");
    m.def("discontinuous_distance", [](const DoubleArray& vertices, const py::object& faces, const std::string& curves,
                                       double t_coef) {
        PolygonMesh mesh = mesh_from(vertices, faces);
        py::gil_scoped_release nogil;
        SurfaceMesh surface(std::move(mesh), "mesh");
        const SurfaceSources sources = read_surface_curves(curves, surface);
        SurfaceShmSetup setup;
        setup.t_coef = t_coef;
        SurfaceShmOptions o;
        o.integration = SurfaceIntegration::L1;
        SurfaceShmResult r = SignedHeatSurface(std::move(surface), setup).solve(sources, o);
        std::vector<double> corners;
        corners.reserve(3 * r.corner_phi.size());
        for (const auto& c : r.corner_phi) corners.insert(corners.end(), c.begin(), c.end());
        py::gil_scoped_acquire gil;
        const py::ssize_t n = py::ssize_t(r.phi.size()), t = py::ssize_t(r.corner_phi.size());
        py::list jumps;
        for (const Polyline& line : r.jumps) {
            std::vector<double> xyz;
            for (const Eigen::Vector3d& x : line) xyz.insert(xyz.end(), {x.x(), x.y(), x.z()});
            const py::ssize_t k = py::ssize_t(line.size());
            jumps.append(to_numpy(std::move(xyz), {k, 3}));
        }
        return py::make_tuple(to_numpy(std::move(r.phi), {n}), to_numpy(std::move(corners), {t, 3}), jumps);
    }, py::arg("vertices"), py::arg("faces"), py::arg("curves"), py::arg("t_coef") = 1.0,
       "(phi (V,), corner_phi (T,3), jumps: list of (k,3) polylines): the surface Signed Heat Method with L1 "
       "integration (the CLI's --integrate l1): around curves that bound nothing φ jumps along the cheapest loop "
       "instead of warping; corner_phi holds both sides of a jump (T: the mesh's triangles, polygons fanned).");
    m.def("surface_winding_numbers", [](const DoubleArray& vertices, const py::object& faces, const std::string& curves,
                                        const std::string& lp, const std::string& lp_solver, double curve_weight,
                                        bool boundary_aware, bool close_gaps) {
        const bool is_cloud = faces.is_none();
        PolygonMesh mesh;
        if (is_cloud) mesh.vertices = points_from(vertices, "vertices");
        else mesh = mesh_from(vertices, faces);
        SwnOptions o;  // curve_weight is checked by the solver
        o.residual = swn_residual_from_name(lp);
        o.solver = swn_solver_from_name(lp_solver);
        o.curve_weight = curve_weight;
        o.boundary_aware = boundary_aware;
        o.close_gaps = close_gaps;
        py::gil_scoped_release nogil;
        SurfaceMesh surface = is_cloud ? SurfaceMesh(cloud_surface(mesh.vertices, {}, {}, "points").triangulation, "points")
                                       : SurfaceMesh(std::move(mesh), "mesh");
        const SurfaceSources sources = read_surface_curves(curves, surface);
        if (is_cloud) require_cloud_points(sources, curves);
        SwnResult r = SurfaceWindingNumbers(surface).solve(sources, o);
        const std::vector<int> per = is_cloud ? vertex_labels(surface, r.labels) : r.labels;
        std::vector<std::int32_t> labels(per.begin(), per.end());
        std::vector<double> w;
        w.reserve(r.w.size() * 3);
        for (const auto& c : r.w) w.insert(w.end(), c.begin(), c.end());
        py::gil_scoped_acquire gil;
        const py::ssize_t f = py::ssize_t(labels.size()), t = py::ssize_t(r.w.size());
        return py::make_tuple(to_numpy(std::move(labels), {f}), to_numpy(std::move(w), {t, 3}));
    }, py::arg("vertices"), py::arg("faces"), py::arg("curves"), py::arg("lp") = "reduced",
       py::arg("lp_solver") = "network", py::arg("curve_weight") = SwnOptions{}.curve_weight,
       py::arg("boundary_aware") = SwnOptions{}.boundary_aware, py::arg("close_gaps") = SwnOptions{}.close_gaps,
       "(labels (F,) int32 per input face, w (T,3) per triangle corner): Surface Winding Numbers of curves in a file. "
       "faces=None: vertices are a point cloud (curves name its points), labels per point, w on its triangulation. "
       "lp, lp_solver, curve_weight, boundary_aware, close_gaps: as the CLI's --lp, --lp-solver, --curve-weight, "
       "--boundary-aware, --close-gaps.");
}
