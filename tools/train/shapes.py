"""Procedural training shapes with exact signed distance (docs/torusnet.md, "Training data").

A shape is a union of 1-5 primitives (sphere, box, capped cylinder, torus, capsule) with random
sizes, orientations and positions, scaled into [-0.9, 0.9]^3. Primitive SDFs are exact; a union's
min() is exact outside but only a bound inside, so interior queries are *certified*: the nearest
primitive boundary point must lie on the union's boundary (outside every other primitive), else
the query is dropped. Surface samples are area-uniform on each primitive and kept only where they
lie on the union's boundary, so the union is sampled area-uniformly too.

Everything is deterministic from a numpy Generator.
"""
import numpy as np

TWO_PI = 2.0 * np.pi


def random_rotation(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


class Primitive:
    """A primitive in its local frame, placed by rotation R (local->world) and center c."""

    def __init__(self, R, c):
        self.R = R
        self.c = c

    def to_local(self, x):
        return (x - self.c) @ self.R

    def sdf(self, x):
        return self.local_sdf(self.to_local(x))

    def sample(self, rng, n):
        """n area-uniform surface samples (points, outward normals), world frame."""
        p, nrm = self.local_sample(rng, n)
        return p @ self.R.T + self.c, nrm @ self.R.T


class Sphere(Primitive):
    def __init__(self, R, c, r):
        super().__init__(R, c)
        self.r = r

    def area(self):
        return 4 * np.pi * self.r ** 2

    def local_sdf(self, y):
        return np.linalg.norm(y, axis=-1) - self.r

    def local_sample(self, rng, n):
        d = _unit(rng.normal(size=(n, 3)))
        return d * self.r, d


class Box(Primitive):
    def __init__(self, R, c, b):
        super().__init__(R, c)
        self.b = np.asarray(b, float)

    def area(self):
        bx, by, bz = self.b
        return 8 * (bx * by + by * bz + bx * bz)

    def local_sdf(self, y):
        q = np.abs(y) - self.b
        outside = np.linalg.norm(np.maximum(q, 0), axis=-1)
        inside = np.minimum(q.max(axis=-1), 0)
        return outside + inside

    def local_sample(self, rng, n):
        bx, by, bz = self.b
        face_area = np.array([by * bz, by * bz, bx * bz, bx * bz, bx * by, bx * by])
        face = rng.choice(6, size=n, p=face_area / face_area.sum())
        axis = face // 2
        sign = np.where(face % 2 == 0, 1.0, -1.0)
        p = (rng.uniform(-1, 1, size=(n, 3))) * self.b
        p[np.arange(n), axis] = sign * self.b[axis]
        nrm = np.zeros((n, 3))
        nrm[np.arange(n), axis] = sign
        return p, nrm


class Cylinder(Primitive):
    """Capped cylinder of radius r along local z, half height h."""

    def __init__(self, R, c, r, h):
        super().__init__(R, c)
        self.r, self.h = r, h

    def area(self):
        return 2 * np.pi * self.r * 2 * self.h + 2 * np.pi * self.r ** 2

    def local_sdf(self, y):
        d = np.stack([np.linalg.norm(y[:, :2], axis=-1) - self.r, np.abs(y[:, 2]) - self.h], -1)
        return np.minimum(d.max(axis=-1), 0) + np.linalg.norm(np.maximum(d, 0), axis=-1)

    def local_sample(self, rng, n):
        side = 2 * np.pi * self.r * 2 * self.h
        cap = np.pi * self.r ** 2
        kind = rng.choice(3, size=n, p=np.array([side, cap, cap]) / (side + 2 * cap))
        ang = rng.uniform(0, TWO_PI, n)
        rad = np.where(kind == 0, self.r, self.r * np.sqrt(rng.uniform(0, 1, n)))
        z = np.where(kind == 0, rng.uniform(-self.h, self.h, n), np.where(kind == 1, self.h, -self.h))
        p = np.stack([rad * np.cos(ang), rad * np.sin(ang), z], -1)
        nrm = np.where((kind == 0)[:, None], np.stack([np.cos(ang), np.sin(ang), np.zeros(n)], -1),
                       np.stack([np.zeros(n), np.zeros(n), np.where(kind == 1, 1.0, -1.0)], -1))
        return p, nrm


class Torus(Primitive):
    """Torus around local z with major radius Rm and minor radius r (r < Rm)."""

    def __init__(self, R, c, Rm, r):
        super().__init__(R, c)
        self.Rm, self.r = Rm, r

    def area(self):
        return 4 * np.pi ** 2 * self.Rm * self.r

    def local_sdf(self, y):
        q = np.stack([np.linalg.norm(y[:, :2], axis=-1) - self.Rm, y[:, 2]], -1)
        return np.linalg.norm(q, axis=-1) - self.r

    def local_sample(self, rng, n):
        # Area element ∝ (Rm + r cos v): rejection on v.
        vs = []
        while sum(len(v) for v in vs) < n:
            v = rng.uniform(0, TWO_PI, 2 * n)
            keep = rng.uniform(0, self.Rm + self.r, 2 * n) < self.Rm + self.r * np.cos(v)
            vs.append(v[keep])
        v = np.concatenate(vs)[:n]
        u = rng.uniform(0, TWO_PI, n)
        nrm = np.stack([np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)], -1)
        ring = np.stack([np.cos(u), np.sin(u), np.zeros(n)], -1) * self.Rm
        return ring + self.r * nrm, nrm


class Capsule(Primitive):
    """Segment from (0,0,-h) to (0,0,h) of radius r."""

    def __init__(self, R, c, r, h):
        super().__init__(R, c)
        self.r, self.h = r, h

    def area(self):
        return 2 * np.pi * self.r * 2 * self.h + 4 * np.pi * self.r ** 2

    def local_sdf(self, y):
        z = np.clip(y[:, 2], -self.h, self.h)
        d = y.copy()
        d[:, 2] -= z
        return np.linalg.norm(d, axis=-1) - self.r

    def local_sample(self, rng, n):
        side = 2 * np.pi * self.r * 2 * self.h
        ball = 4 * np.pi * self.r ** 2
        on_side = rng.uniform(0, side + ball, n) < side
        ang = rng.uniform(0, TWO_PI, n)
        d = _unit(rng.normal(size=(n, 3)))
        nrm = np.where(on_side[:, None], np.stack([np.cos(ang), np.sin(ang), np.zeros(n)], -1), d)
        p = nrm * self.r
        p[:, 2] += np.where(on_side, rng.uniform(-self.h, self.h, n), np.where(d[:, 2] >= 0, self.h, -self.h))
        return p, nrm


def random_primitive(rng, thin):
    """One primitive of size ~1 near the origin; `thin` makes plates, rods and thin tubes likely."""
    R = random_rotation(rng)
    c = rng.uniform(-0.45, 0.45, 3)
    kind = rng.integers(5)
    small = lambda: rng.uniform(0.02, 0.08) if thin else rng.uniform(0.15, 0.5)
    big = lambda: rng.uniform(0.25, 0.7)
    if kind == 0:
        return Sphere(R, c, small() if thin else rng.uniform(0.2, 0.6))
    if kind == 1:
        b = np.array([big(), big(), small()]) if thin else rng.uniform(0.15, 0.6, 3)
        return Box(R, c, b)
    if kind == 2:
        return Cylinder(R, c, small(), big())
    if kind == 3:
        Rm = rng.uniform(0.25, 0.6)
        r = rng.uniform(0.03, 0.08) if thin else rng.uniform(0.08, 0.6 * Rm)
        return Torus(R, c, Rm, r)
    return Capsule(R, c, small(), big())


class Shape:
    """A union of primitives, scaled by `scale` and shifted by `shift` (world = local*s + t)."""

    def __init__(self, prims, scale=1.0, shift=np.zeros(3)):
        self.prims = prims
        self.scale = scale
        self.shift = shift

    def _local(self, x):
        return (x - self.shift) / self.scale

    def prim_sdfs(self, x):
        y = self._local(x)
        return np.stack([p.sdf(y) for p in self.prims], -1) * self.scale

    def sdf_bound(self, x):
        return self.prim_sdfs(x).min(axis=-1)

    def sample_surface(self, rng, n):
        """~n area-uniform samples of the union's boundary (points, normals)."""
        areas = np.array([p.area() for p in self.prims])
        pts, nrms = [], []
        want = n
        for _ in range(20):
            counts = rng.multinomial(int(want * 1.3) + 16, areas / areas.sum())
            for i, (prim, m) in enumerate(zip(self.prims, counts)):
                if m == 0:
                    continue
                p, nr = prim.sample(rng, m)
                others = [q.sdf(p) for j, q in enumerate(self.prims) if j != i]
                keep = np.all(np.stack(others, -1) >= 0, axis=-1) if others else np.ones(m, bool)
                pts.append(p[keep])
                nrms.append(nr[keep])
            got = sum(len(p) for p in pts)
            if got >= n:
                break
            want = n - got
        p = np.concatenate(pts)
        nr = np.concatenate(nrms)
        order = rng.permutation(len(p))[:n]
        return p[order] * self.scale + self.shift, nr[order]

    def exact_sdf(self, x, eps=1e-5):
        """Exact signed distance where certified; NaN where it can't be certified."""
        d = self.prim_sdfs(x)
        phi = d.min(axis=-1)
        out = phi.copy()
        inside = phi < 0
        if not inside.any():
            return out
        xi = x[inside]
        di = d[inside]
        j = np.abs(di).argmin(axis=-1)
        # Closest point on primitive j's boundary from a central-difference gradient.
        h = 1e-4 * self.scale
        g = np.zeros_like(xi)
        for a in range(3):
            e = np.zeros(3)
            e[a] = h
            g[:, a] = (self.prim_sdfs(xi + e)[np.arange(len(xi)), j] -
                       self.prim_sdfs(xi - e)[np.arange(len(xi)), j]) / (2 * h)
        dj = di[np.arange(len(xi)), j]
        cp = xi - dj[:, None] * g
        dcp = self.prim_sdfs(cp)
        on_j = np.abs(dcp[np.arange(len(xi)), j]) < 1e-3 * self.scale
        dcp[np.arange(len(xi)), j] = np.inf
        free = dcp.min(axis=-1) >= -eps * self.scale
        ok = on_j & free & (np.abs(np.linalg.norm(g, axis=-1) - 1) < 1e-2)
        vals = -np.abs(dj)
        vals[~ok] = np.nan
        out[inside] = vals
        return out


def random_shape(rng, max_prims=5):
    thin = rng.uniform() < 0.3
    count = rng.integers(1, max_prims + 1)
    prims = [random_primitive(rng, thin and i == 0) for i in range(count)]
    shape = Shape(prims)
    # Fit into [-0.9, 0.9]^3 using a dense sample's bounding box.
    p, _ = shape.sample_surface(rng, 4000)
    lo, hi = p.min(0), p.max(0)
    s = 1.8 / max((hi - lo).max(), 1e-6)
    return Shape(prims, scale=s, shift=-(lo + hi) / 2 * s)


def corrupt(rng, pts, nrm, level):
    """Thesis §7.2 corruptions plus holes. `level` in [0, 1] scales all of them."""
    n = len(pts)
    h = mean_spacing(pts)
    info = {}
    if level <= 0:
        return pts, nrm, info
    keep = np.ones(n, bool)
    for _ in range(rng.integers(0, 3)):  # holes
        c = pts[rng.integers(n)]
        r = rng.uniform(3, 10) * h * level
        keep &= np.linalg.norm(pts - c, axis=-1) > r
    if keep.sum() >= max(64, n // 2):
        pts, nrm = pts[keep], nrm[keep]
        n = len(pts)
    sigma_p = rng.uniform(0, 0.5) * h * level
    pts = pts + rng.normal(size=pts.shape) * sigma_p
    sigma_n = rng.uniform(0, 0.2) * level
    nrm = _unit(nrm + rng.normal(size=nrm.shape) * sigma_n)
    flip = rng.uniform(size=n) < rng.uniform(0, 0.03) * level
    nrm[flip] *= -1
    n_out = int(n * rng.uniform(0, 0.01) * level)
    if n_out:
        pts = np.concatenate([pts, rng.uniform(-1, 1, (n_out, 3))])
        nrm = np.concatenate([nrm, _unit(rng.normal(size=(n_out, 3)))])
    info.update(sigma_p=sigma_p, sigma_n=sigma_n, flipped=int(flip.sum()), outliers=n_out)
    return pts, nrm, info


def mean_spacing(pts):
    from scipy.spatial import cKDTree
    d, _ = cKDTree(pts).query(pts, 2)
    return float(d[:, 1].mean())
