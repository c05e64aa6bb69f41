"""Training and validation examples: a procedural cloud, its neighborhoods, and queries with exact
signed distance. Example i of stream `stream` under seed S is a pure function of (S, stream, i).
"""
import numpy as np
from scipy.spatial import cKDTree

import shapes

QUERY_NEIGHBORS = 64  # nearest cloud points gathered per query for the blend (≥ fallback k = 32)
R_EVAL_SPACINGS = 8.0  # BlendOptions::r_eval_spacings


def example_rng(seed, stream, index):
    return np.random.default_rng([seed, stream, index])


def knn_self_first(tree, pts, k):
    """k nearest of every point with the point itself as column 0 (docs/torusnet.md)."""
    _, idx = tree.query(pts, k)
    idx = idx.astype(np.int64)
    own = np.arange(len(pts))
    first_ok = idx[:, 0] == own
    for i in np.nonzero(~first_ok)[0]:  # duplicates tie at distance 0: put i itself first
        row = [j for j in idx[i] if j != i]
        idx[i] = [i] + row[:k - 1]
    return idx


def make_cloud(rng, n_points=None, corruption=None):
    shape = shapes.random_shape(rng)
    if n_points is None:
        n_points = int(np.exp(rng.uniform(np.log(512), np.log(16384))))
    pts, nrm = shape.sample_surface(rng, n_points)
    if corruption is None:
        corruption = 0.0 if rng.uniform() < 0.35 else rng.uniform(0.2, 1.0)
    pts, nrm, info = shapes.corrupt(rng, pts, nrm, corruption)
    return shape, pts, nrm, info


def make_queries(rng, shape, n_queries):
    """Half near the surface (normal offsets of log-uniform scale), half uniform in [-1,1]^3;
    only certified-exact ones are kept."""
    n_near = n_queries // 2
    sp, sn = shape.sample_surface(rng, n_near)
    sigma = np.exp(rng.uniform(np.log(0.002), np.log(0.15), n_near))
    near = sp + sn * (rng.normal(size=n_near) * sigma)[:, None]
    far = rng.uniform(-1, 1, (n_queries - n_near, 3))
    x = np.concatenate([near, far])
    phi = shape.exact_sdf(x)
    ok = np.isfinite(phi)
    return x[ok], phi[ok]


def make_example(seed, stream, index, k, n_queries=2048, n_points=None, corruption=None):
    rng = example_rng(seed, stream, index)
    shape, pts, nrm, info = make_cloud(rng, n_points, corruption)
    tree = cKDTree(pts)
    knn = knn_self_first(tree, pts, k)
    d1, _ = tree.query(pts, 2)
    h = float(d1[:, 1].mean())
    x, phi = make_queries(rng, shape, n_queries)
    _, qnbr = tree.query(x, QUERY_NEIGHBORS)
    return dict(points=pts.astype(np.float32), normals=nrm.astype(np.float32), knn=knn,
                queries=x.astype(np.float32), phi=phi.astype(np.float32),
                qnbr=qnbr.astype(np.int64), r_eval=np.float32(R_EVAL_SPACINGS * h))


def collate(examples):
    """Concatenates clouds; indices become global."""
    out = {key: [] for key in ('points', 'normals', 'knn', 'queries', 'phi', 'qnbr', 'r_eval')}
    base = 0
    for e in examples:
        n = len(e['points'])
        out['points'].append(e['points'])
        out['normals'].append(e['normals'])
        out['knn'].append(e['knn'] + base)
        out['queries'].append(e['queries'])
        out['phi'].append(e['phi'])
        out['qnbr'].append(e['qnbr'] + base)
        out['r_eval'].append(np.full(len(e['queries']), e['r_eval'], np.float32))
        base += n
    return {key: np.concatenate(v) for key, v in out.items()}
