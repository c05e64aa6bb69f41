#!/usr/bin/env python3
"""The TorusNet validation set and its evaluation (issue: PAT-net vs PAT-jet vs SSPD vs SHC).

  python3 tools/train/validate.py make --dir val/            # clouds + exact φ on 64³
  python3 tools/train/validate.py run --dir val/ --gsd build/bin/gsd [--model M] [--device cpu]

  python3 tools/train/validate.py make-rows --dir rows/ --shapes 6   # one corruption per row
  python3 tools/train/validate.py make-landscape --dir land/        # sphere/cylinder, radius × corruption
  python3 tools/train/validate.py run --dir rows/ --methods PAT-net,PAT-keep,SPSR,SSPD,SHC,SHM

`make` draws procedural shapes from a stream the training never uses (stream 2), samples each
at 512, 2048 and 8192 points, clean and corrupted (thesis §7.2: Gaussian noise on positions and
normals, outliers uniform in [-1,1]^3 with random normals, flipped normals), and writes the
exact signed distance on a 64³ grid of nodes over [-1,1]^3 (NaN where it can't be certified;
those nodes are skipped). `make-rows` writes the robustness table's clouds instead: each §7.2
corruption alone (noise, flips, holes, outliers 0.5–10 %) at 512 and 2048 points; `make-landscape`
the thesis' sphere and cylinder landscapes. `run` evaluates every method through the `gsd` CLI and prints a
markdown table of mean |φ − φ_true| (rows: density × corruption; mean over shapes).
"""
import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import dataset  # noqa: E402
import shapes  # noqa: E402

VALIDATION_STREAM = 2
DENSITIES = (512, 2048, 8192)
GRID = 64
# Fixed §7.2 corruption of the "corrupted" rows (in [-1,1]^3 units).
NOISE_POSITION = 0.004
NOISE_NORMAL = 0.1
OUTLIER_FRACTION = 0.005
FLIP_FRACTION = 0.02


def corrupt_fixed(rng, pts, nrm, outlier_fraction=OUTLIER_FRACTION):
    n = len(pts)
    pts = pts + rng.normal(size=pts.shape) * NOISE_POSITION
    nrm = nrm + rng.normal(size=nrm.shape) * NOISE_NORMAL
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    flip = rng.choice(n, int(n * FLIP_FRACTION), replace=False)
    nrm[flip] *= -1
    m = int(n * outlier_fraction)
    out = rng.uniform(-1, 1, (m, 3))
    on = rng.normal(size=(m, 3))
    on /= np.linalg.norm(on, axis=-1, keepdims=True)
    return np.concatenate([pts, out]), np.concatenate([nrm, on])


# The corruption rows of the robustness table (issue: PAT that survives outliers), each applied
# alone to a clean sample: label -> (kind, amount). Amounts in [-1,1]^3 units / fractions.
ROWS = {
    'clean': ('clean', 0.0),
    'noise 0.005': ('noise', 0.005),
    'flip 10%': ('flip', 0.10),
    '3 holes': ('holes', 3),
    'outliers 0.5%': ('outliers', 0.005),
    'outliers 2%': ('outliers', 0.02),
    'outliers 5%': ('outliers', 0.05),
    'outliers 10%': ('outliers', 0.10),
}
ROW_DENSITIES = (512, 2048)
HOLE_RADIUS = 0.2
# Thesis §7.2 landscapes: one sphere or cylinder, radius × corruption, at 2048 points.
LANDSCAPE_RADII = (0.2, 0.4, 0.6, 0.8)
LANDSCAPE_ROWS = ('clean', 'noise 0.005', 'outliers 0.5%', 'outliers 2%', 'outliers 5%', 'outliers 10%')
LANDSCAPE_POINTS = 2048


def corrupt_one(rng, pts, nrm, kind, amount):
    """One §7.2 corruption alone: Gaussian position noise (σ = amount), flipped normals (a
    fraction), holes (`amount` balls of radius HOLE_RADIUS around surface points removed), or
    outliers (a fraction of the count added, uniform in [-1,1]^3 with random normals)."""
    pts, nrm = pts.copy(), nrm.copy()
    n = len(pts)
    if kind == 'noise':
        pts += rng.normal(size=pts.shape) * amount
    elif kind == 'flip':
        nrm[rng.choice(n, int(n * amount), replace=False)] *= -1
    elif kind == 'holes':
        centers = pts[rng.choice(n, int(amount), replace=False)]
        d = np.linalg.norm(pts[:, None, :] - centers[None, :, :], axis=-1).min(axis=1)
        pts, nrm = pts[d > HOLE_RADIUS], nrm[d > HOLE_RADIUS]
    elif kind == 'outliers':
        m = max(1, int(round(n * amount)))
        out = rng.uniform(-1, 1, (m, 3))
        on = rng.normal(size=(m, 3))
        on /= np.linalg.norm(on, axis=-1, keepdims=True)
        pts, nrm = np.concatenate([pts, out]), np.concatenate([nrm, on])
    return pts, nrm


def save_cloud(dir_, name, p, q):
    np.save(os.path.join(dir_, name + '.npy'), np.concatenate([p, q], 1).astype(np.float32))


def validation_shapes(args):
    """Yields (index, rng, shape, φ) for the validation stream's shapes, φ (exact SDF on the
    grid) saved as s{index}_phi.npy in args.dir."""
    os.makedirs(args.dir, exist_ok=True)
    nodes = grid_nodes()
    for s in range(args.shapes):
        rng = dataset.example_rng(args.seed, VALIDATION_STREAM, s)
        shape = shapes.random_shape(rng)
        phi = shape.exact_sdf(nodes).reshape(GRID, GRID, GRID).astype(np.float32)
        np.save(os.path.join(args.dir, f's{s}_phi.npy'), phi)
        yield s, rng, shape, phi


def make_rows(args):
    """The robustness table's clouds: every ROWS corruption alone, at ROW_DENSITIES."""
    index = []
    for s, rng, shape, _ in validation_shapes(args):
        for n in ROW_DENSITIES:
            pts, nrm = shape.sample_surface(rng, n)
            for label, (kind, amount) in ROWS.items():
                p, q = corrupt_one(rng, pts, nrm, kind, amount)
                name = f's{s}_n{n}_{label.replace(" ", "").replace("%", "pc")}'
                save_cloud(args.dir, name, p, q)
                index.append(dict(name=name, shape=s, points=n, row=label))
        print(f'shape {s}: {len(shape.prims)} primitives', flush=True)
    json.dump(index, open(os.path.join(args.dir, 'index.json'), 'w'), indent=1)


def make_landscape(args):
    """Thesis §7.2's landscapes: a sphere and a capped cylinder (half height 0.8) of each
    LANDSCAPE_RADII radius under each LANDSCAPE_ROWS corruption."""
    os.makedirs(args.dir, exist_ok=True)
    nodes = grid_nodes()
    index = []
    rng = np.random.default_rng(args.seed)
    for kind in ('sphere', 'cylinder'):
        for r in LANDSCAPE_RADII:
            prim = (shapes.Sphere(np.eye(3), np.zeros(3), r) if kind == 'sphere'
                    else shapes.Cylinder(np.eye(3), np.zeros(3), r, 0.8))
            shape = shapes.Shape([prim])
            key = f'{kind}_r{r}'
            np.save(os.path.join(args.dir, f'{key}_phi.npy'), shape.exact_sdf(nodes).reshape((GRID,) * 3).astype(np.float32))
            pts, nrm = shape.sample_surface(rng, LANDSCAPE_POINTS)
            for label in LANDSCAPE_ROWS:
                p, q = corrupt_one(rng, pts, nrm, *ROWS[label])
                name = f'{key}_{label.replace(" ", "").replace("%", "pc")}'
                save_cloud(args.dir, name, p, q)
                index.append(dict(name=name, shape=key, landscape=kind, radius=r, points=LANDSCAPE_POINTS, row=label))
    json.dump(index, open(os.path.join(args.dir, 'index.json'), 'w'), indent=1)


def grid_nodes():
    t = np.linspace(-1, 1, GRID)
    X, Y, Z = np.meshgrid(t, t, t, indexing='ij')  # z fastest: gsd's GridSpec order
    return np.stack([X, Y, Z], -1).reshape(-1, 3)


def make(args):
    index = []
    for s, rng, shape, phi in validation_shapes(args):
        for n in DENSITIES:
            pts, nrm = shape.sample_surface(rng, n)
            for corrupted in (False, True):
                p, q = corrupt_fixed(rng, pts, nrm, args.outliers) if corrupted else (pts, nrm)
                name = f's{s}_n{n}_{"corrupt" if corrupted else "clean"}'
                save_cloud(args.dir, name, p, q)
                index.append(dict(name=name, shape=s, points=n, corrupted=corrupted,
                                  primitives=[type(pr).__name__ for pr in shape.prims]))
        print(f'shape {s}: {len(shape.prims)} primitives, certified nodes {np.isfinite(phi).mean():.3f}', flush=True)
    json.dump(index, open(os.path.join(args.dir, 'index.json'), 'w'), indent=1)


def spsr(cloud, out, depth=8):
    """Screened Poisson surface reconstruction (Open3D, Debian's python3-open3d) at octree depth
    `depth`, then the signed distance to its mesh on the grid. The mesh is usually not watertight
    (Open3D trims it to the input's box), so ray parity can't sign it: the sign is that of
    (x − closest point)·(normal of the closest triangle)."""
    import open3d as o3d
    a = np.load(cloud).astype(np.float64)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(a[:, :3]))
    pcd.normals = o3d.utility.Vector3dVector(a[:, 3:])
    mesh, _ = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(pcd, depth=depth)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    x = grid_nodes().astype(np.float32)
    hit = scene.compute_closest_points(o3d.core.Tensor(x))
    off = x - hit['points'].numpy()
    side = np.sign((off * hit['primitive_normals'].numpy()).sum(-1))
    sd = np.linalg.norm(off, axis=-1) * np.where(side == 0, 1.0, side)
    np.save(out, sd.reshape(GRID, GRID, GRID).astype(np.float32))


METHODS = {
    'PAT-net': lambda a: ['pat', 'eval', '--fitter', 'net'] + (['--model', a.model] if a.model else []),
    'PAT-keep': lambda a: ['pat', 'eval', '--fitter', 'net', '--keep-outliers'] + (['--model', a.model] if a.model else []),
    'PAT-jet': lambda a: ['pat', 'eval', '--fitter', 'jet'],
    'SHM': lambda a: ['shm', 'grid'],
    'SSPD': lambda a: ['baseline', 'sspd'],
    'SHC': lambda a: ['baseline', 'shc'],
    'SPSR': None,  # in Python, through Open3D
}


def run(args):
    index = json.load(open(os.path.join(args.dir, 'index.json')))
    methods = args.methods.split(',')
    out_dir = os.path.join(args.dir, 'out')
    os.makedirs(out_dir, exist_ok=True)
    # Results of earlier runs (other methods) are kept and merged by cloud name.
    res_path = os.path.join(args.dir, 'results.json')
    earlier = {r['name']: r for r in json.load(open(res_path))} if os.path.exists(res_path) else {}
    results = []
    bounds = ['--bounds', '-1', '-1', '-1', '1', '1', '1']
    for e in index:
        shape_key = e['shape'] if isinstance(e['shape'], str) else f's{e["shape"]}'
        truth = np.load(os.path.join(args.dir, f'{shape_key}_phi.npy'))
        ok = np.isfinite(truth)
        row = dict(earlier.get(e['name'], e))
        for m in methods:
            cloud = os.path.join(args.dir, e['name'] + '.npy')
            out = os.path.join(out_dir, f'{e["name"]}_{m}.npy')
            t = time.time()
            if METHODS[m] is None:
                # Its own process: Open3D aborts on some inputs (an Eigen assertion).
                done = subprocess.run([sys.executable, os.path.abspath(__file__), 'spsr', '--dir', args.dir,
                                       '--cloud', cloud, '--out', out, '--spsr-depth', str(args.spsr_depth)],
                                      stderr=subprocess.DEVNULL)
                if done.returncode != 0:
                    row[m] = float('nan')
                    print(f'{e["name"]}: {m} failed (exit {done.returncode})', flush=True)
                    continue
            else:
                cmd = [args.gsd] + METHODS[m](args) + [cloud, '-o', out, '--grid', str(GRID)] + bounds
                if args.device:
                    cmd += ['--device', args.device]
                subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            phi = np.load(out)
            row[m] = float(np.abs(phi[ok] - truth[ok]).mean())
            row[m + ' s'] = time.time() - t
        results.append(row)
        print(e['name'], ' '.join(f'{m}={row[m]:.5f}' for m in methods), flush=True)
    json.dump(results, open(res_path, 'w'), indent=1)
    print(report(results, [m for m in METHODS if m in results[0]]))


def report(results, methods):
    if 'landscape' in results[0]:
        return landscape_tables(results, methods)
    if 'row' in results[0]:
        return row_table(results, methods)
    return table(results, methods)


def cells(vals, methods):
    best = min(methods, key=lambda m: vals[m] if np.isfinite(vals[m]) else np.inf)
    return ['**%.5f**' % vals[m] if m == best else '%.5f' % vals[m] for m in methods]


def row_table(results, methods):
    lines = ['| points | input | ' + ' | '.join(methods) + ' |', '|---|---|' + '---|' * len(methods)]
    for n in ROW_DENSITIES:
        for label in ROWS:
            rows = [r for r in results if r['points'] == n and r['row'] == label]
            if rows:
                vals = {m: float(np.nanmean([r[m] for r in rows])) for m in methods}
                lines.append(f'| {n} | {label} | ' + ' | '.join(cells(vals, methods)) + ' |')
    return '\n'.join(lines)


def landscape_tables(results, methods):
    out = []
    for kind in ('sphere', 'cylinder'):
        if not any(r['landscape'] == kind for r in results):
            continue
        out.append(f'\n{kind} ({LANDSCAPE_POINTS} points), mean |φ − φ_true|:\n')
        out.append(f'| {kind}: input | radius | ' + ' | '.join(methods) + ' |')
        out.append('|---|---|' + '---|' * len(methods))
        for label in LANDSCAPE_ROWS:
            rows = [r for r in results if r['landscape'] == kind and r['row'] == label]
            for r in LANDSCAPE_RADII:
                rr = [x for x in rows if x['radius'] == r]
                if rr:
                    vals = {m: float(np.nanmean([x[m] for x in rr])) for m in methods}
                    out.append(f'| {label} | {r} | ' + ' | '.join(cells(vals, methods)) + ' |')
    return '\n'.join(out)


def table(results, methods):
    lines = ['| points | input | ' + ' | '.join(methods) + ' |', '|---|---|' + '---|' * len(methods)]
    for n in DENSITIES:
        for corrupted in (False, True):
            rows = [r for r in results if r['points'] == n and r['corrupted'] == corrupted]
            if not rows:
                continue
            vals = {m: np.nanmean([r[m] for r in rows]) for m in methods}
            best = min(vals, key=vals.get)
            cells = [f'**{vals[m]:.5f}**' if m == best else f'{vals[m]:.5f}' for m in methods]
            lines.append(f'| {n} | {"corrupted" if corrupted else "clean"} | ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('command', choices=['make', 'make-rows', 'make-landscape', 'run', 'table', 'spsr'])
    ap.add_argument('--cloud', help='spsr: input cloud .npy')
    ap.add_argument('--out', help='spsr: output grid .npy')
    ap.add_argument('--dir', required=True)
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--shapes', type=int, default=8)
    ap.add_argument('--outliers', type=float, default=OUTLIER_FRACTION,
                    help='outlier fraction of the corrupted clouds (make)')
    ap.add_argument('--gsd', default='build/bin/gsd')
    ap.add_argument('--model', default='')
    ap.add_argument('--spsr-depth', type=int, default=8, help='screened Poisson octree depth')
    ap.add_argument('--device', default='cpu')
    ap.add_argument('--methods', default='PAT-net,PAT-jet,SSPD,SHC',
                    help='comma-separated, of: ' + ', '.join(METHODS))
    args = ap.parse_args()
    if args.command == 'make':
        make(args)
    elif args.command == 'make-rows':
        make_rows(args)
    elif args.command == 'make-landscape':
        make_landscape(args)
    elif args.command == 'spsr':
        spsr(args.cloud, args.out, args.spsr_depth)
    elif args.command == 'run':
        run(args)
    else:
        results = json.load(open(os.path.join(args.dir, 'results.json')))
        print(report(results, args.methods.split(',')))


if __name__ == '__main__':
    main()
