"""The Python module against the gsd CLI (the same library through another door), analytic
answers, and bad input. Run by CTest (test_python) with PYTHONPATH at the build's python/ and
GSD_CLI naming the built `gsd` executable."""
import os
import subprocess
import threading

import numpy as np
import pytest

import gsd

CLI = os.environ.get("GSD_CLI", "gsd")
BOUNDS = (-1.2, -1.2, -1.2, 1.2, 1.2, 1.2)


def cli(*args):
    r = subprocess.run([CLI, "-q", *map(str, args)], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    return r


def bounds_args():
    return ["--bounds", *BOUNDS]


@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    d = tmp_path_factory.mktemp("sphere")
    cloud = d / "s.ply"
    cli("sample", "sphere", "-n", 1500, "--seed", 4, "-o", cloud)
    return d, cloud


def test_version_matches_cli():
    out = subprocess.run([CLI, "--version"], capture_output=True, text=True).stdout.strip()
    assert gsd.version() == out == gsd.__version__


def test_read_point_cloud(sphere):
    _, cloud = sphere
    points, normals = gsd.read_point_cloud(str(cloud))
    assert points.shape == (1500, 3) and normals.shape == (1500, 3)
    assert points.dtype == np.float64
    # `gsd sample sphere` draws the sphere of radius 0.5 at the origin, normals outward.
    np.testing.assert_allclose(np.linalg.norm(points, axis=1), 0.5, atol=1e-6)
    np.testing.assert_allclose(np.einsum("ij,ij->i", points, normals) / 0.5, 1.0, atol=1e-6)


def test_pat_matches_cli_grid_and_gradient(sphere):
    d, cloud = sphere
    cli("pat", "eval", cloud, "--fitter", "jet", "--device", "cpu", "--grid", 24, *bounds_args(),
        "-o", d / "phi.npy", "--gradient", d / "grad.npy")
    points, normals = gsd.read_point_cloud(str(cloud))
    tori = gsd.fit_tori(points.astype(np.float32), normals, fitter="jet")  # float32 in is fine
    assert len(tori) == 1500 and tori.fitter == "jet"
    field = gsd.TorusField(tori, device="cpu")
    (phi, grad), bounds = field.evaluate_grid(24, bounds=BOUNDS, gradient=True)
    assert phi.shape == (24, 24, 24) and grad.shape == (24, 24, 24, 3)
    assert bounds == BOUNDS
    # float32 points in → the fit sees float32-rounded positions: agreement to float32 level.
    np.testing.assert_allclose(phi, np.load(d / "phi.npy"), atol=2e-5)
    np.testing.assert_allclose(grad, np.load(d / "grad.npy"), atol=2e-4)
    # φ is the signed distance to the sphere (radius 0.5) near it.
    queries = np.array([[0.3, 0.0, 0.0], [0.0, 0.6, 0.0], [0.0, 0.0, -0.45], [0.2, 0.2, 0.3]])
    np.testing.assert_allclose(field.evaluate(queries), np.linalg.norm(queries, axis=1) - 0.5, atol=0.01)


def test_tori_round_trip_through_the_cli(sphere):
    d, cloud = sphere
    cli("pat", "fit", cloud, "--fitter", "jet", "-o", d / "s.tori")
    tori = gsd.load_tori(str(d / "s.tori"))
    points, normals = gsd.read_point_cloud(str(cloud))
    mine = gsd.fit_tori(points, normals, fitter="jet")
    q = np.random.default_rng(0).uniform(-1.2, 1.2, size=(300, 3))
    np.testing.assert_allclose(gsd.TorusField(tori, device="cpu").evaluate(q),
                               gsd.TorusField(mine, device="cpu").evaluate(q), atol=1e-6)
    mine.save(str(d / "mine.tori"))
    assert len(gsd.load_tori(str(d / "mine.tori"))) == 1500


def test_gpu_matches_cpu(sphere):
    # The suite requires a Vulkan device, as the C++ suites do (lavapipe in CI).
    _, cloud = sphere
    assert any(dev["usable"] for dev in gsd.devices()), "no usable Vulkan device (install mesa-vulkan-drivers)"
    points, normals = gsd.read_point_cloud(str(cloud))
    tori = gsd.fit_tori(points, normals, fitter="jet")
    q = np.random.default_rng(1).uniform(-1.2, 1.2, size=(2000, 3))
    cpu = gsd.TorusField(tori, device="cpu").evaluate(q)
    gpu = gsd.TorusField(tori, device="gpu").evaluate(q)
    assert np.max(np.abs(cpu - gpu)) < 1e-4


def test_winding_numbers_match_cli_and_are_one_inside(tmp_path):
    mesh = tmp_path / "m.obj"
    cli("mesh", "sphere", "-r", 24, "-o", mesh)
    v, f = gsd.read_mesh(str(mesh))
    assert v.shape[1] == 3 and f.shape[1] == 3 and f.dtype == np.int64
    q = np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 0.1], [3.0, 0.0, 0.0], [0.0, -5.0, 2.0]])
    w = gsd.winding_numbers(q, vertices=v, faces=f, exact=True, device="cpu")
    np.testing.assert_allclose(w, [1, 1, 0, 0], atol=1e-9)
    np.save(tmp_path / "q.npy", q)
    cli("winding", mesh, "--queries", tmp_path / "q.npy", "--exact", "--device", "cpu", "-o", tmp_path / "w.npy")
    np.testing.assert_allclose(w, np.load(tmp_path / "w.npy"), atol=1e-6)
    # Faces as a list of sequences (mixed sizes allowed) give the same numbers.
    w_list = gsd.winding_numbers(q, vertices=v, faces=[list(x) for x in f], exact=True, device="cpu")
    np.testing.assert_allclose(w_list, w, atol=0)


def test_mesh_sdf_is_the_sphere_distance_and_matches_cli(tmp_path):
    mesh = tmp_path / "m.obj"
    cli("mesh", "sphere", "-r", 32, "-o", mesh)
    v, f = gsd.read_mesh(str(mesh))
    q = np.random.default_rng(5).uniform(-1.0, 1.0, (500, 3))
    phi = gsd.mesh_sdf(v, f, q, device="cpu")
    exact = np.linalg.norm(q, axis=1) - 0.5  # the "sphere" shape: radius 0.5
    far = np.abs(exact) > 0.05
    assert far.sum() > 250
    np.testing.assert_allclose(phi[far], exact[far], atol=0.02)
    phi_again, grad = gsd.mesh_sdf(v, f, q, device="cpu", gradient=True)
    np.testing.assert_array_equal(phi_again, phi)
    assert grad.shape == (500, 3)
    np.testing.assert_allclose(np.sum(grad[far] * q[far], axis=1) / np.linalg.norm(q[far], axis=1), 1.0, atol=0.02)
    unsigned = gsd.mesh_sdf(v, f, q, sign="none", device="cpu")
    np.testing.assert_array_equal(unsigned, np.abs(phi))
    np.save(tmp_path / "q.npy", q)
    cli("sdf", mesh, "--queries", tmp_path / "q.npy", "--device", "cpu", "-o", tmp_path / "s.npy")
    np.testing.assert_allclose(phi, np.load(tmp_path / "s.npy"), atol=1e-6)
    with pytest.raises(Exception):
        gsd.mesh_sdf(v, f, q, sign="maybe")


def test_field_algebra_matches_cli(sphere, tmp_path):
    d, cloud = sphere
    mesh = tmp_path / "t.obj"
    cli("mesh", "torus", "-r", 24, "-o", mesh)
    cli("pat", "fit", cloud, "--fitter", "jet", "-o", tmp_path / "s.tori")
    v, f = gsd.read_mesh(str(mesh))
    pat = gsd.TorusField(gsd.load_tori(str(tmp_path / "s.tori")), device="cpu")
    torus = gsd.MeshSdfField(v, f, device="cpu")
    q = np.random.default_rng(6).uniform(-1.0, 1.0, (300, 3))
    a, b = pat.evaluate(q), torus.evaluate(q)
    # The operators are what they say, on any two fields.
    np.testing.assert_allclose((pat | torus).evaluate(q), np.minimum(a, b), atol=1e-6)
    np.testing.assert_allclose((pat & torus).evaluate(q), np.maximum(a, b), atol=1e-6)
    np.testing.assert_allclose((pat - torus).evaluate(q), np.maximum(a, -b), atol=1e-6)
    np.testing.assert_allclose(torus.offset(0.1).shell(0.02).evaluate(q), np.abs(b - 0.1) - 0.02, atol=1e-6)
    smooth = gsd.union(pat, torus, smooth=0.2).evaluate(q)
    assert np.all(smooth <= np.minimum(a, b) + 1e-6) and np.all(smooth >= np.minimum(a, b) - 0.05 - 1e-6)
    phi, grad = (pat | torus).evaluate(q, gradient=True)
    assert grad.shape == (300, 3)
    # A grid read back is a field; the composite on a grid is the CLI's.
    grid = (pat | torus.offset(0.05)).evaluate_on_grid(12, BOUNDS)
    cli("field", f"union({tmp_path / 's.tori'}, offset({mesh}, 0.05))", "--grid", 12, *bounds_args(),
        "--device", "cpu", "-o", tmp_path / "u.npy")
    np.testing.assert_allclose(grid, np.load(tmp_path / "u.npy"), atol=1e-5)
    g = gsd.GridField(grid, BOUNDS)
    np.testing.assert_allclose(g.evaluate_on_grid(12, BOUNDS), grid, atol=1e-6)
    with pytest.raises(gsd.Error):
        gsd.union(pat, torus, smooth=-1.0)
    # Morphology: an opening by r keeps a shape much thicker than 2r where it was.
    # (The tube's radius is 0.125: deeper than 0.08 in it is deeper than r.)
    opened = gsd.opening(torus, 0.05, 48, BOUNDS)
    deep = np.random.default_rng(7).uniform(-1.0, 1.0, (3000, 3))
    inside = torus.evaluate(deep) < -0.08
    assert inside.sum() > 20 and np.all(opened.evaluate(deep)[inside] < 0)


def test_sample_sdf_matches_cli_and_the_folder_iterator(tmp_path):
    folder = tmp_path / "meshes"
    folder.mkdir()
    cli("mesh", "sphere", "-r", 24, "-o", folder / "a.obj")
    cli("mesh", "torus", "-r", 24, "-o", folder / "b.ply")
    (folder / "notes.txt").write_text("not a mesh")
    v, f = gsd.read_mesh(str(folder / "a.obj"))
    s, center, radius = gsd.sample_sdf(v, f, 4000, near_sigma=[0.05], uniform=0.25, seed=3, device="cpu")
    assert s.shape == (4000, 4) and s.dtype == np.float32
    assert radius == pytest.approx(0.5, rel=1e-6)
    exact = np.linalg.norm(s[:, :3] - center, axis=1) - 0.5  # the "sphere" shape: radius 0.5
    np.testing.assert_allclose(s[:, 3], exact, atol=0.01)
    assert np.all(np.abs(s[3000:, :3] - center) <= radius + 1e-6)  # the uniform quarter, in the cube
    cli("sdf", folder / "a.obj", "--samples", 4000, "--near-sigma", 0.05, "--uniform", 0.25, "--seed", 3,
        "--device", "cpu", "-o", tmp_path / "s.npy")
    np.testing.assert_array_equal(s, np.load(tmp_path / "s.npy"))
    seen = [(os.path.basename(p), smp.shape) for p, smp, _, _ in
            gsd.sdf_samples_in_folder(str(folder), 100, normalize=True, device="cpu")]
    assert seen == [("a.obj", (100, 4)), ("b.ply", (100, 4))]
    with pytest.raises(Exception):
        gsd.sample_sdf(v, f, 10, near_sigma=[-1.0])


def test_winding_opening_criterion_matches_cli(tmp_path):
    mesh = tmp_path / "m.obj"
    cli("mesh", "torus", "-r", 24, "--holes", 2, "--flip", 0.1, "-o", mesh)
    v, f = gsd.read_mesh(str(mesh))
    q = np.random.default_rng(3).uniform(-1.2, 1.2, (2000, 3))
    np.save(tmp_path / "q.npy", q)
    exact = gsd.winding_numbers(q, vertices=v, faces=f, exact=True, device="cpu")
    # libigl's criterion (β = 2 alone) through both doors gives the same numbers.
    w = gsd.winding_numbers(q, vertices=v, faces=f, beta=2.0, tolerance=0.0, device="cpu")
    cli("winding", mesh, "--queries", tmp_path / "q.npy", "--beta", 2, "--tolerance", 0, "--device", "cpu",
        "-o", tmp_path / "w.npy")
    np.testing.assert_allclose(w, np.load(tmp_path / "w.npy"), atol=1e-6)
    # A looser criterion is cheaper and less exact: the options reach the sums.
    loose = gsd.winding_numbers(q, vertices=v, faces=f, beta=1.1, tolerance=0.0, device="cpu")
    assert np.abs(loose - exact).max() > np.abs(w - exact).max()
    with pytest.raises(gsd.Error, match="beta"):
        gsd.winding_numbers(q, vertices=v, faces=f, beta=1.0)
    with pytest.raises(gsd.Error, match="tolerance"):
        gsd.winding_numbers(q, vertices=v, faces=f, tolerance=-1.0)


def test_signed_heat_grid_matches_cli(tmp_path):
    mesh = tmp_path / "b.obj"
    cli("mesh", "sphere", "-r", 16, "--holes", 2, "--hole-area", 0.1, "-o", mesh)
    cli("shm", "grid", mesh, "--grid", 20, *bounds_args(), "--device", "cpu", "-o", tmp_path / "shm.npy")
    v, f = gsd.read_mesh(str(mesh))
    phi, bounds = gsd.signed_heat_grid(20, vertices=v, faces=f, bounds=BOUNDS, device="cpu")
    assert phi.shape == (20, 20, 20) and bounds == BOUNDS
    np.testing.assert_allclose(phi, np.load(tmp_path / "shm.npy"), atol=1e-6)
    assert phi[10, 10, 10] < 0 < phi[0, 0, 0]  # inside the broken sphere, outside at the corner


def test_signed_heat_grid_options_match_cli(tmp_path):
    mesh = tmp_path / "b.obj"
    cli("mesh", "sphere", "-r", 16, "--holes", 3, "--hole-area", 0.2, "--flip", 0.1, "-o", mesh)
    v, f = gsd.read_mesh(str(mesh))
    default, _ = gsd.signed_heat_grid(20, vertices=v, faces=f, bounds=BOUNDS, device="cpu")
    # The mean shift alone, no outside veto: the CLI's --fit-zero-set 0 --veto-winding 0.
    cli("shm", "grid", mesh, "--grid", 20, *bounds_args(), "--device", "cpu", "--fit-zero-set", 0,
        "--veto-winding", 0, "-o", tmp_path / "shift.npy")
    shift, _ = gsd.signed_heat_grid(20, vertices=v, faces=f, bounds=BOUNDS, fit_zero_set=0, veto_winding=0,
                                    device="cpu")
    np.testing.assert_allclose(shift, np.load(tmp_path / "shift.npy"), atol=1e-6)
    assert np.abs(shift - default).max() > 1e-4  # the fit moves φ
    cli("shm", "grid", mesh, "--grid", 20, *bounds_args(), "--device", "cpu", "--veto-margin", 0.3,
        "--veto-winding", 0.5, "-o", tmp_path / "veto.npy")
    veto, _ = gsd.signed_heat_grid(20, vertices=v, faces=f, bounds=BOUNDS, veto_margin=0.3, veto_winding=0.5,
                                   device="cpu")
    np.testing.assert_allclose(veto, np.load(tmp_path / "veto.npy"), atol=1e-6)
    with pytest.raises(gsd.Error, match="veto_margin"):
        gsd.signed_heat_grid(20, vertices=v, faces=f, veto_margin=0)
    with pytest.raises(gsd.Error, match="fit_zero_set"):
        gsd.signed_heat_grid(20, vertices=v, faces=f, fit_zero_set=-1)


def test_reorient_normals_and_the_grid_default_match_cli(tmp_path):
    cloud = tmp_path / "t.ply"
    cli("sample", "torus", "-n", 1024, "--flip", 0.1, "--seed", 3, "-o", cloud)
    p, n = gsd.read_point_cloud(str(cloud))
    turned_normals, turned = gsd.reorient_normals(p, n)
    flips = (turned_normals * n).sum(1) < 0
    assert turned == flips.sum() and 80 < turned < 130  # about the 10 % flipped
    assert np.allclose(np.abs((turned_normals * n).sum(1)), (n * n).sum(1))  # turned, not tilted
    again, none = gsd.reorient_normals(p, turned_normals)
    assert none == 0 and np.allclose(again, turned_normals, atol=1e-12)
    # shm grid turns them by default (as signed_heat_grid), --keep-normals keeps them.
    for flag, reorient in (([], True), (["--keep-normals"], False)):
        out = tmp_path / f"g{len(flag)}.npy"
        cli("shm", "grid", cloud, "--grid", 16, *bounds_args(), "--device", "cpu", *flag, "-o", out)
        phi, _ = gsd.signed_heat_grid(16, points=p, normals=n, bounds=BOUNDS, device="cpu", reorient_normals=reorient)
        np.testing.assert_allclose(phi, np.load(out), atol=1e-6)
    turned_phi, _ = gsd.signed_heat_grid(16, points=p, normals=turned_normals, bounds=BOUNDS, device="cpu",
                                         reorient_normals=False)
    np.testing.assert_allclose(turned_phi, np.load(tmp_path / "g0.npy"), atol=1e-6)
    with pytest.raises(gsd.Error, match="neighbors"):
        gsd.reorient_normals(p, n, neighbors=1)
    # A cloud's outliers: left out by default, kept by drop_outliers=False (--keep-outliers).
    stray = tmp_path / "o.ply"
    cli("sample", "torus", "-n", 1024, "--outliers", 0.03, "--seed", 3, "-o", stray)
    sp, sn = gsd.read_point_cloud(str(stray))
    for flag, drop in (([], True), (["--keep-outliers"], False)):
        out = tmp_path / f"o{len(flag)}.npy"
        cli("shm", "grid", stray, "--grid", 16, *bounds_args(), "--device", "cpu", *flag, "-o", out)
        phi, _ = gsd.signed_heat_grid(16, points=sp, normals=sn, bounds=BOUNDS, device="cpu", drop_outliers=drop)
        np.testing.assert_allclose(phi, np.load(out), atol=1e-6)
    assert np.abs(np.load(tmp_path / "o0.npy") - np.load(tmp_path / "o1.npy")).max() > 1e-3
    # The default box is the source's once the outliers are left out, in both: a stray far off
    # does not stretch it.
    far_p, far_n = np.vstack([sp, [[3.0, 3.0, 3.0]]]), np.vstack([sn, [[0.0, 0.0, 1.0]]])
    np.save(tmp_path / "far.npy", np.hstack([far_p, far_n]))
    cli("shm", "grid", tmp_path / "far.npy", "--grid", 16, "--device", "cpu", "-o", tmp_path / "ob.npy")
    phi, bounds = gsd.signed_heat_grid(16, points=far_p, normals=far_n, device="cpu")
    np.testing.assert_allclose(phi, np.load(tmp_path / "ob.npy"), atol=1e-6)
    import json
    side = json.load(open(tmp_path / "ob.npy.json"))["bounds"]
    np.testing.assert_allclose([*side["lo"], *side["hi"]], bounds, rtol=1e-6)
    assert max(bounds[3:]) < 1.5  # not stretched to the stray at (3, 3, 3)
    # PAT too: fit_tori turns them back by default (pat fit), reorient_normals=False keeps them.
    q = np.array([[0.5, 0.0, 0.0], [0.7, 0.0, 0.1], [0.0, 0.0, 0.0], [0.9, 0.9, 0.9]])
    turned_field = gsd.TorusField(gsd.fit_tori(p, n, fitter="jet"), device="cpu")
    np.testing.assert_allclose(
        turned_field.evaluate(q),
        gsd.TorusField(gsd.fit_tori(p, turned_normals, fitter="jet", reorient_normals=False), device="cpu").evaluate(q),
        atol=1e-6)
    kept_field = gsd.TorusField(gsd.fit_tori(p, n, fitter="jet", reorient_normals=False), device="cpu")
    assert np.abs(kept_field.evaluate(q) - turned_field.evaluate(q)).max() > 1e-3


def test_signed_heat_adaptive_matches_cli(tmp_path):
    mesh = tmp_path / "b.obj"
    cli("mesh", "sphere", "-r", 16, "--holes", 2, "--hole-area", 0.1, "-o", mesh)
    q = np.array([[0.0, 0.0, 0.0], [0.9, 0.9, 0.9], [0.5, 0.125, -0.25]], dtype=np.float32)
    np.save(tmp_path / "q.npy", q)
    cli("shm", "adaptive", mesh, "--depth", 5, *bounds_args(), "--device", "cpu", "--queries", tmp_path / "q.npy",
        "-o", tmp_path / "phi.npy")
    v, f = gsd.read_mesh(str(mesh))
    field = gsd.signed_heat_adaptive(5, vertices=v, faces=f, bounds=BOUNDS, device="cpu")
    assert isinstance(field, gsd.Field) and field.depth == 5
    phi = field.evaluate(q.astype(np.float64))
    np.testing.assert_allclose(phi, np.load(tmp_path / "phi.npy"), atol=1e-6)
    assert phi[0] < 0 < phi[1]  # inside the broken sphere, outside at the corner
    nodes, values = field.nodes(), field.node_values()
    assert nodes.shape == (field.node_count, 3) and values.shape == (field.node_count,)
    np.testing.assert_allclose(field.evaluate(nodes[:50]), values[:50], atol=1e-6)
    with pytest.raises(gsd.Error, match="depth"):
        gsd.signed_heat_adaptive(0, vertices=v, faces=f)


def test_adaptive_vdb_is_a_sparse_level_set_on_the_finest_lattice(tmp_path):
    """`gsd shm adaptive -o X.vdb`: python3-openvdb reads a level set whose voxel (i, j, k) sits at
    lo + (i, j, k)·h (h the finest cell), holding the field's φ in the band; inactive voxels inside
    read −background (the signed flood fill), outside +background."""
    import pyopenvdb as vdb

    mesh = tmp_path / "s.obj"
    cli("mesh", "sphere", "-r", 16, "-o", mesh)
    cli("shm", "adaptive", mesh, "--depth", 6, *bounds_args(), "--device", "cpu", "-o", tmp_path / "s.vdb")
    grids, _ = vdb.readAll(str(tmp_path / "s.vdb"))
    g = grids[0]
    assert g.name == "surface" and g.gridClass == "level set" and g.metadata["gsd_method"] == "shm"
    lo, side = np.array(BOUNDS[:3]), BOUNDS[3] - BOUNDS[0]
    h = side / 64
    np.testing.assert_allclose(g.transform.voxelSize(), [h, h, h], rtol=1e-12)
    for ijk in [(0, 0, 0), (64, 64, 64), (3, 17, 9)]:
        np.testing.assert_allclose(g.transform.indexToWorld(ijk), lo + np.array(ijk) * h, rtol=0, atol=1e-12)
    assert g.activeVoxelCount() > 1000
    v, f = gsd.read_mesh(str(mesh))
    field = gsd.signed_heat_adaptive(6, vertices=v, faces=f, bounds=BOUNDS, device="cpu")
    acc = g.getConstAccessor()
    center, corner = (32, 32, 32), (1, 1, 1)  # the sphere's center, the cube's corner
    assert acc.getValue(center) == pytest.approx(-g.background) and acc.getValue(corner) == pytest.approx(g.background)
    # Active voxels hold the field's φ at their lattice point.
    on_surface = [(32 + int(round(0.5 / h)), 32, 32), (32, 32 - int(round(0.5 / h)), 32)]
    for ijk in on_surface:
        value, active = acc.probeValue(ijk)
        assert active
        expect = field.evaluate(np.array([lo + np.array(ijk) * h]))[0]
        assert value == pytest.approx(float(expect), abs=1e-6)


def test_surface_methods_match_cli(tmp_path):
    mesh = tmp_path / "s.obj"
    curves = tmp_path / "c.txt"
    cli("mesh", "sphere", "-r", 20, "-o", mesh)
    cli("curve", mesh, "--plane", 0, 0, 1, 0.3, "-o", curves)
    v, f = gsd.read_mesh(str(mesh))
    cli("swn", mesh, "--curves", curves, "-o", tmp_path / "labels.npy")
    labels, w = gsd.surface_winding_numbers(v, f, str(curves))
    assert labels.dtype == np.int32 and labels.shape == (f.shape[0],)
    np.testing.assert_array_equal(labels, np.load(tmp_path / "labels.npy"))
    cli("shm", "surface", mesh, "--curves", curves, "-o", tmp_path / "phi.npy")
    phi = gsd.signed_heat_surface(v, f, str(curves))
    np.testing.assert_allclose(phi, np.load(tmp_path / "phi.npy"), atol=1e-6)
    # The plane's curve n·x = d has n·x < d on its left (inside): the cap z > 0.3 is outside,
    # so at the north pole φ > 0, at the south pole φ < 0.
    assert phi[np.argmax(v[:, 2])] > 0 > phi[np.argmin(v[:, 2])]


def test_discontinuous_distance_matches_cli(tmp_path):
    # A loop around the tube of a torus bounds nothing: φ jumps along one loop, at the antipode.
    mesh = tmp_path / "t.obj"
    curves = tmp_path / "m.txt"
    cli("mesh", "torus", "-r", 24, "-o", mesh)
    cli("curve", mesh, "--plane", 0, 1, 0, 0, "--near", 0.5, 0, 0, "-o", curves)
    v, f = gsd.read_mesh(str(mesh))
    cli("shm", "surface", mesh, "--curves", curves, "--integrate", "l1", "-o", tmp_path / "phi.npy",
        "--corners", tmp_path / "corners.npy")
    phi, corners, jumps = gsd.discontinuous_distance(v, f, str(curves))
    np.testing.assert_allclose(phi, np.load(tmp_path / "phi.npy"), atol=1e-5)
    np.testing.assert_allclose(corners, np.load(tmp_path / "corners.npy"), atol=1e-5)
    assert corners.shape == (f.shape[0], 3)
    assert len(jumps) == 1 and jumps[0].shape[1] == 3
    assert np.all(jumps[0][:, 0] < -0.2)  # the curve is at x = 0.5: the jump on the far side
    # The other remedy: leave the loop out (with a small loop beside it, the distance to that).
    loop = tmp_path / "loop.txt"
    cli("curve", mesh, "--sphere", -0.7, 0, 0, 0.15, "-o", loop)
    both = tmp_path / "both.txt"  # one file: the second file's l records renumbered after the first's
    lines, records = ["#offset 0"], 0
    for path in (curves, loop):
        start = records
        for line in path.read_text().splitlines():
            if line[:2] in ("v ", "e ", "f "):
                lines.append(line)
                records += 1
            elif line.startswith("l "):
                lines.append("l " + " ".join(str(int(i) + start) for i in line.split()[1:]))
    both.write_text("\n".join(lines) + "\n")
    cli("shm", "surface", mesh, "--curves", curves, loop, "--filter-nonbounding", "-o", tmp_path / "f.npy")
    filtered = gsd.signed_heat_surface(v, f, str(both), filter_nonbounding=True)
    np.testing.assert_allclose(filtered, np.load(tmp_path / "f.npy"), atol=1e-5)
    np.testing.assert_allclose(filtered, gsd.signed_heat_surface(v, f, str(loop)), atol=1e-5)
    with pytest.raises(gsd.Error, match="bounds nothing"):
        gsd.signed_heat_surface(v, f, str(curves), filter_nonbounding=True)


def test_surface_winding_options_match_cli(tmp_path):
    # A torus with two holes (a surface with boundary, not simply connected) and a broken loop
    # around its tube: every option changes w here.
    mesh, curves = tmp_path / "t.obj", tmp_path / "c.txt"
    cli("mesh", "torus", "-r", 24, "--holes", 2, "--hole-area", 0.1, "-o", mesh)
    cli("curve", mesh, "--plane", 0, 1, 0, 0, "--near", 0.6, 0, 0, "--break", 0.3, "-o", curves)
    v, f = gsd.read_mesh(str(mesh))
    _, w_default = gsd.surface_winding_numbers(v, f, str(curves))
    cli("swn", mesh, "--curves", curves, "--lp", "full", "--lp-solver", "clp", "--curve-weight", 0.5,
        "--boundary-aware", "--no-close-gaps", "-o", tmp_path / "l.npy", "--w", tmp_path / "w.npy")
    labels, w = gsd.surface_winding_numbers(v, f, str(curves), lp="full", lp_solver="clp", curve_weight=0.5,
                                            boundary_aware=True, close_gaps=False)
    np.testing.assert_array_equal(labels, np.load(tmp_path / "l.npy"))
    np.testing.assert_allclose(w, np.load(tmp_path / "w.npy"), atol=1e-5)
    assert np.abs(w - w_default).max() > 0.1
    with pytest.raises(gsd.Error, match="curve_weight"):
        gsd.surface_winding_numbers(v, f, str(curves), curve_weight=2.0)
    with pytest.raises(gsd.Error):
        gsd.surface_winding_numbers(v, f, str(curves), lp_solver="simplex")


def test_threads_share_a_field(sphere):
    _, cloud = sphere
    points, normals = gsd.read_point_cloud(str(cloud))
    field = gsd.TorusField(gsd.fit_tori(points, normals, fitter="jet"), device="cpu")
    q = np.random.default_rng(2).uniform(-1, 1, size=(4000, 3))
    expect = field.evaluate(q)
    results = [None] * 4

    def work(i):
        results[i] = field.evaluate(q)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for r in results:
        np.testing.assert_array_equal(r, expect)


def test_bad_input_raises_gsd_error(tmp_path):
    with pytest.raises(gsd.Error, match="points: must be an \\(N, 3\\) array"):
        gsd.fit_tori(np.zeros((5, 2)), np.zeros((5, 2)))
    with pytest.raises(ValueError, match="missing.ply"):
        gsd.read_point_cloud(str(tmp_path / "missing.ply"))
    with pytest.raises(gsd.Error, match="fitter"):
        p = np.random.default_rng(0).normal(size=(50, 3))
        gsd.fit_tori(p, p, fitter="magic")
    with pytest.raises(gsd.Error, match="non-finite|NaN|finite"):
        p = np.random.default_rng(0).normal(size=(50, 3))
        p[3, 1] = np.nan
        gsd.fit_tori(p, p)
    with pytest.raises(gsd.Error, match="faces"):
        gsd.winding_numbers(np.zeros((1, 3)), vertices=np.eye(3), faces=np.array([[0, 1, 7]]))
    with pytest.raises(gsd.Error):
        gsd.signed_heat_grid(16)


def test_outlier_defence_matches_cli(tmp_path):
    cloud = tmp_path / "o.npy"
    cli("sample", "torus", "-n", 1500, "--outliers", 0.05, "--seed", 2, "-o", cloud)
    cli("pat", "fit", cloud, "-o", tmp_path / "o.tori", "--confidence", tmp_path / "c.npy", "--device", "cpu")
    tori = gsd.load_tori(str(tmp_path / "o.tori"))
    field = gsd.TorusField(tori, device="cpu")
    conf = np.load(tmp_path / "c.npy")
    np.testing.assert_array_equal(field.confidence, conf)
    assert field.blended_count == int((conf >= 0.5).sum()) < len(tori)
    c, residual, sparsity = gsd.point_confidence(tori)
    np.testing.assert_array_equal(c, conf)
    # Disabled: every point blended, nothing scored; a stricter residual threshold drops more.
    kept = gsd.TorusField(tori, device="cpu", keep_outliers=True)
    assert kept.blended_count == len(tori) and len(kept.confidence) == 0
    strict = gsd.OutlierOptions()
    strict.min_score = 0.02
    strict.mad_factor = 0
    assert gsd.TorusField(tori, device="cpu", outliers=strict).blended_count < field.blended_count
    bad = gsd.OutlierOptions()
    bad.k = 1
    with pytest.raises(gsd.Error, match="OutlierOptions::k"):
        gsd.point_confidence(tori, bad)


def test_vdb_output_opens_in_openvdb_with_the_nodes_transform(sphere, tmp_path):
    """`-o X.vdb`: Debian's python3-openvdb reads a level set named "surface" whose voxel
    (i, j, k) sits on the grid's node (i, j, k), holding φ in the narrow band and ±background
    by φ's sign outside; winding numbers go in as a plain float grid."""
    import pyopenvdb as vdb

    _, cloud = sphere
    cli("pat", "eval", cloud, "--fitter", "jet", "--device", "cpu", "--grid", 24, *bounds_args(), "-o", tmp_path / "p.npy")
    cli("pat", "eval", cloud, "--fitter", "jet", "--device", "cpu", "--grid", 24, *bounds_args(), "-o", tmp_path / "p.vdb")
    phi = np.load(tmp_path / "p.npy")
    grids, _ = vdb.readAll(str(tmp_path / "p.vdb"))
    assert len(grids) == 1
    g = grids[0]
    assert g.name == "surface" and g.gridClass == "level set" and g.metadata["gsd_method"] == "pat"
    lo, hi = np.array(BOUNDS[:3]), np.array(BOUNDS[3:])
    step = (hi - lo) / 23
    np.testing.assert_allclose(g.transform.voxelSize(), step, rtol=1e-12)
    for ijk in [(0, 0, 0), (23, 23, 23), (3, 17, 9)]:
        np.testing.assert_allclose(g.transform.indexToWorld(ijk), lo + np.array(ijk) * step, rtol=0, atol=1e-12)
    assert g.background == pytest.approx(3 * step[0], rel=1e-6)
    values = np.zeros(phi.shape, np.float32)
    g.copyToArray(values)
    band = np.abs(phi) < g.background
    assert band.sum() > 100
    np.testing.assert_array_equal(values[band], phi[band])
    assert np.all(np.sign(values[~band]) == np.sign(phi[~band]))
    assert np.all(np.abs(values[~band]) == np.float32(g.background))

    mesh = tmp_path / "m.obj"
    cli("mesh", "sphere", "-r", 16, "-o", mesh)
    cli("winding", mesh, "--grid", 12, *bounds_args(), "-o", tmp_path / "w.npy")
    cli("winding", mesh, "--grid", 12, *bounds_args(), "-o", tmp_path / "w.vdb")
    w = vdb.readAll(str(tmp_path / "w.vdb"))[0][0]
    assert w.name == "winding" and w.gridClass == "unknown"
    values = np.zeros((12, 12, 12), np.float32)
    w.copyToArray(values)
    np.testing.assert_array_equal(values, np.load(tmp_path / "w.npy"))


def read_png(path):
    """A PNG as written by gsd (8-bit RGB, not interlaced) → (H, W, 3) uint8, with zlib alone."""
    import struct
    import zlib
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, width, height = 8, b"", 0, 0
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            width, height, depth, color = struct.unpack(">IIBB", body[:10])
            assert (depth, color) == (8, 2)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    raw = zlib.decompress(idat)
    stride = 3 * width
    out = np.zeros((height, stride), dtype=np.int32)
    for y in range(height):
        f, row = raw[y * (stride + 1)], np.frombuffer(raw, np.uint8, stride, y * (stride + 1) + 1).astype(np.int32)
        prev = out[y - 1] if y else np.zeros(stride, np.int32)
        cur = np.zeros(stride, np.int32)
        for x in range(stride):
            a = cur[x - 3] if x >= 3 else 0
            b, c = prev[x], (prev[x - 3] if x >= 3 else 0)
            if f == 0:
                p = 0
            elif f == 1:
                p = a
            elif f == 2:
                p = b
            elif f == 3:
                p = (a + b) // 2
            else:
                pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                p = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            cur[x] = (row[x] + p) & 255
        out[y] = cur
    return out.reshape(height, width, 3).astype(np.uint8)


def test_render_matches_cli_and_gpu(sphere, tmp_path):
    d, cloud = sphere
    cli("pat", "fit", cloud, "--fitter", "jet", "-o", tmp_path / "s.tori")
    cli("render", "--tori", tmp_path / "s.tori", "--size", 48, 36, "--supersample", 1, "--device", "cpu",
        "-o", tmp_path / "s.png")
    tori = gsd.load_tori(str(tmp_path / "s.tori"))
    field = gsd.TorusField(tori, device="cpu")
    image = field.render(48, 36, device="cpu")
    assert image.shape == (36, 48, 3) and image.dtype == np.uint8
    assert np.array_equal(image, read_png(tmp_path / "s.png"))
    assert tuple(image[0, 0]) == (255, 255, 255)          # background
    assert (image.sum(axis=2) < 3 * 255).mean() > 0.1     # the sphere fills part of the frame
    on_gpu = field.render(48, 36, device="gpu")
    assert (np.abs(on_gpu.astype(int) - image.astype(int)) > 8).mean() <= 0.01
    grid, bounds = field.evaluate_grid(24)
    assert gsd.render_grid(grid, bounds, 40, 30, view_from=(0, 0, 1), device="cpu").shape == (30, 40, 3)
    with pytest.raises(gsd.Error, match="FieldRenderOptions::supersample"):
        field.render(10, 10, supersample=9)
    with pytest.raises(gsd.Error, match="values"):
        gsd.render_grid(np.zeros((4, 4)), bounds)



def test_point_cloud_surfaces_match_cli(tmp_path):
    # An unoriented cloud (x y z only): SHM per point and SWN labels per point, as the CLI.
    cloud, curves = tmp_path / "s.xyz", tmp_path / "c.txt"
    cli("sample", "sphere", "-n", 2000, "-o", tmp_path / "s.ply")
    v, _ = gsd.read_point_cloud(str(tmp_path / "s.ply"))
    np.savetxt(cloud, v)
    cli("curve", cloud, "--plane", 0, 0, 1, 0.3, "-o", curves)
    cli("shm", "surface", cloud, "--curves", curves, "-o", tmp_path / "phi.npy")
    phi = gsd.signed_heat_surface(v, None, str(curves))
    np.testing.assert_allclose(phi, np.load(tmp_path / "phi.npy"), atol=1e-5)
    assert phi[np.argmax(v[:, 2])] > 0 > phi[np.argmin(v[:, 2])]
    cli("swn", cloud, "--curves", curves, "-o", tmp_path / "l.npy")
    labels, _ = gsd.surface_winding_numbers(v, None, str(curves))
    np.testing.assert_array_equal(labels, np.load(tmp_path / "l.npy"))
    faces, normals = gsd.cloud_surface(v)
    assert faces.shape == (2 * len(v) - 4, 3) and normals.shape == v.shape
    assert (np.sum(normals * v, axis=1) > 0).all()  # outward on a closed surface
    (tmp_path / "e.txt").write_text("e 1 0.5\ne 2 0.5\nl 1 2\n")
    with pytest.raises(gsd.Error, match="name cloud points"):
        gsd.signed_heat_surface(v, None, str(tmp_path / "e.txt"))
