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
    w = gsd.winding_numbers(queries, vertices=v, faces=f)
    phi = gsd.mesh_sdf(v, f, queries)                 # exact distance to a broken mesh, signed by w
    phi_v = gsd.signed_heat_surface(v, f, "curves.txt")            # distance along a surface
    labels, w = gsd.surface_winding_numbers(v, f, "curves.txt")    # inside/outside on a surface
    image = field.render(640, 480)                    # (480, 640, 3) uint8: φ = 0 sphere-traced
    image = gsd.render_grid(grid, bounds)             # the same for a grid

Errors in the input raise gsd.Error (a ValueError) naming the argument or file at fault.
"""
from ._gsd import (  # noqa: F401
    Error,
    OutlierOptions,
    Tori,
    TorusField,
    devices,
    fit_tori,
    load_tori,
    mesh_sdf,
    point_confidence,
    read_mesh,
    read_point_cloud,
    render_grid,
    signed_heat_grid,
    signed_heat_surface,
    surface_winding_numbers,
    version,
    winding_numbers,
    write_mesh,
)

__version__ = version()
