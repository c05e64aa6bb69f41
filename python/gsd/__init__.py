"""gsd — generalized signed distance and winding numbers from imperfect geometry.

NumPy arrays in and out; gsd releases the GIL while it works. Point arrays are (N, 3) of any
float dtype. Devices: "" ($GSD_DEVICE, else "auto"), "auto", "gpu", "cpu", an index or a name.

    import gsd
    points, normals = gsd.read_point_cloud("scan.ply")
    tori = gsd.fit_tori(points, normals)              # TorusNet; fitter="jet" for the classic fit
    field = gsd.TorusField(tori)
    phi = field.evaluate(queries)                     # (M,) float32, negative inside
    phi, grad = field.evaluate(queries, gradient=True)
    grid, bounds = field.evaluate_grid(64)            # (64, 64, 64) on the cloud's cube + 10%
    grid, bounds = gsd.signed_heat_grid(64, vertices=v, faces=f)   # broken meshes, clouds, both
    octree = gsd.signed_heat_adaptive(9, points=p, normals=n)      # …on an adaptive octree: a Field
    w = gsd.winding_numbers(queries, vertices=v, faces=f)
    phi = gsd.mesh_sdf(v, f, queries)                 # exact distance to a broken mesh, signed by w
    samples, center, radius = gsd.sample_sdf(v, f, 500000)         # (N,4) x y z sdf, for training
    for path, samples, center, radius in gsd.sdf_samples_in_folder("meshes/", 500000): ...
    phi_v = gsd.signed_heat_surface(v, f, "curves.txt")            # distance along a surface
    labels, w = gsd.surface_winding_numbers(v, f, "curves.txt")    # inside/outside on a surface
    phi_p = gsd.signed_heat_surface(points, None, "curves.txt")    # …on a point cloud: per point
    phi_v, corner_phi, jumps = gsd.discontinuous_distance(v, f, "loop.txt")  # around a handle: φ jumps
    faces, normals = gsd.cloud_surface(points)        # a cloud's triangulation, oriented normals
    image = field.render(640, 480)                    # (480, 640, 3) uint8: φ = 0 sphere-traced
    image = gsd.render_grid(grid, bounds)             # the same for a grid
    both = field | gsd.MeshSdfField(v, f).offset(0.05)           # fields made of fields (docs/field.md):
    phi = both.evaluate(queries)                      #   | & - offset shell, gsd.union(a, b, smooth=k)

Errors in the input raise gsd.Error (a ValueError) naming the argument or file at fault.
"""
from ._gsd import (  # noqa: F401
    Error,
    Field,
    GridField,
    MeshSdfField,
    OctreeField,
    OutlierOptions,
    Tori,
    TorusField,
    closing,
    cloud_surface,
    devices,
    difference,
    discontinuous_distance,
    intersection,
    opening,
    union,
    fit_tori,
    load_tori,
    mesh_sdf,
    point_confidence,
    read_mesh,
    read_point_cloud,
    sample_sdf,
    render_grid,
    reorient_normals,
    signed_heat_adaptive,
    signed_heat_grid,
    signed_heat_surface,
    surface_winding_numbers,
    version,
    winding_numbers,
    write_mesh,
)

__version__ = version()


_MESH_SUFFIXES = (".obj", ".ply", ".off", ".stl")


def sdf_samples_in_folder(folder, count, **options):
    """Yields (path, samples, center, radius) for each mesh file in `folder` (.obj .ply .off .stl,
    in sorted order), sample_sdf's result with `options` (near_sigma, uniform, normalize, seed,
    sign, inside, device): a training loop can take meshes one at a time. A mesh that cannot be
    read or sampled raises gsd.Error naming it; wrap the loop to skip such files."""
    import os

    names = sorted(n for n in os.listdir(folder) if n.lower().endswith(_MESH_SUFFIXES))
    for name in names:
        path = os.path.join(folder, name)
        vertices, faces = read_mesh(path)
        samples, center, radius = sample_sdf(vertices, faces, count, **options)
        yield path, samples, center, radius

