"""TorusNet in PyTorch: features, network, tori, blend, and the weights file (docs/torusnet.md).

Mirrors the C++ code: `features` ↔ src/pat/torus_net.cpp, `torus_from_jet`/`torus_sdf_local` ↔
src/pat/torus_math.hpp, `blend` ↔ src/blend/blend_cpu.cpp (accelerated rule). Runs on Debian's
torch 1.13 (CPU) and on recent CUDA builds alike.
"""
import json
import math
import struct

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

INPUTS = 7
OUTPUTS = 6


# ---- features ---------------------------------------------------------------------------------

def tangent_of(n):
    """Mirrors gsd::tangent_of: cross n with the axis least aligned with it."""
    ax = n.abs()
    a = torch.zeros_like(n)
    use_x = ax[:, 0] < 0.57735
    use_y = (~use_x) & (ax[:, 1] < 0.57735)
    use_z = ~(use_x | use_y)
    a[use_x, 0] = 1
    a[use_y, 1] = 1
    a[use_z, 2] = 1
    s = torch.cross(n, a, dim=-1)
    return s / s.norm(dim=-1, keepdim=True)


def features(nb_points, nb_normals):
    """Tokens of neighborhoods. nb_points/nb_normals: [P, k, 3], token 0 = the center.
    Returns tokens [P, k, 7], scale m [P], frame (s, t, n) each [P, 3]."""
    p = nb_points[:, :1, :]
    n = nb_normals[:, 0, :]
    n = n / n.norm(dim=-1, keepdim=True)
    s = tangent_of(n)
    t = torch.cross(n, s, dim=-1)
    d = nb_points - p
    k = nb_points.shape[1]
    dist = d[:, 1:, :].norm(dim=-1)
    srt, _ = dist.sort(dim=-1)
    m = srt[:, (k - 2) // 2]
    dmax = srt[:, -1]
    m = torch.maximum(m, 1e-3 * dmax)
    m = torch.where(dmax > 0, m, torch.ones_like(m))
    frame = torch.stack([s, t, n], dim=1)  # [P, 3, 3] rows s, t, n
    loc = torch.einsum('pkc,pac->pka', d, frame) / m[:, None, None]
    nn_ = nb_normals / nb_normals.norm(dim=-1, keepdim=True).clamp_min(1e-30)
    nloc = torch.einsum('pkc,pac->pka', nn_, frame)
    flag = torch.zeros_like(loc[..., :1])
    flag[:, 0] = 1
    return torch.cat([loc, nloc, flag], dim=-1), m, (s, t, n)


# ---- network ----------------------------------------------------------------------------------

class Block(nn.Module):
    def __init__(self, width, heads, mlp):
        super().__init__()
        self.heads = heads
        self.norm1 = nn.LayerNorm(width, eps=1e-5)
        self.qkv = nn.Linear(width, 3 * width)
        self.proj = nn.Linear(width, width)
        self.norm2 = nn.LayerNorm(width, eps=1e-5)
        self.fc1 = nn.Linear(width, mlp)
        self.fc2 = nn.Linear(mlp, width)

    def forward(self, x):
        P, k, W = x.shape
        H = self.heads
        q, kk, v = self.qkv(self.norm1(x)).split(W, dim=-1)
        q = q.view(P, k, H, W // H).transpose(1, 2)
        kk = kk.view(P, k, H, W // H).transpose(1, 2)
        v = v.view(P, k, H, W // H).transpose(1, 2)
        if hasattr(F, 'scaled_dot_product_attention'):  # torch ≥ 2: fused, far less memory
            o = F.scaled_dot_product_attention(q, kk, v)
        else:
            o = torch.softmax(q @ kk.transpose(-1, -2) / math.sqrt(W // H), dim=-1) @ v
        o = o.transpose(1, 2).reshape(P, k, W)
        x = x + self.proj(o)
        return x + self.fc2(F.gelu(self.fc1(self.norm2(x)), approximate='tanh'))


class TorusNet(nn.Module):
    def __init__(self, k=32, width=64, blocks=2, heads=4, mlp=128):
        super().__init__()
        self.config = dict(k=k, width=width, blocks=blocks, heads=heads, mlp=mlp)
        self.embed = nn.Linear(INPUTS, width)
        self.embed_norm = nn.LayerNorm(width, eps=1e-5)
        self.blocks = nn.ModuleList([Block(width, heads, mlp) for _ in range(blocks)])
        self.final_norm = nn.LayerNorm(width, eps=1e-5)
        self.head = nn.Linear(width, OUTPUTS)
        nn.init.zeros_(self.head.weight)
        with torch.no_grad():
            # Start from a gently convex paraboloid (radius 4m): a sphere-like torus per point.
            self.head.bias.copy_(torch.tensor([0, 0, 0, 0, -0.125, -0.125]))

    def forward(self, tokens, m):
        x = self.embed_norm(self.embed(tokens))
        for b in self.blocks:
            x = b(x)
        r = self.head(self.final_norm(x[:, 0]))
        return torch.stack([r[:, 0] * m, r[:, 1], r[:, 2], r[:, 3] / m, r[:, 4] / m, r[:, 5] / m], -1)


# ---- tori (mirrors src/pat/torus_math.hpp) ----------------------------------------------------

def torus_from_jet(a, eps=0.0):
    """a: [P, 6] → (a00, n_loc [P,3], e1_loc [P,3], k1, k2) in the frame (s, t, n).
    eps > 0 regularizes square roots at umbilics for training gradients."""
    a10, a01, a11, a20, a02 = a[:, 1], a[:, 2], a[:, 3], a[:, 4], a[:, 5]
    A = torch.sqrt(1 + a10 * a10 + a01 * a01)
    I11 = 1 + a10 * a10
    I12 = a10 * a01
    B11, B12, B22 = 2 * a20 / A, a11 / A, 2 * a02 / A
    l11 = torch.sqrt(I11)
    la, lb, ld = 1 / l11, -I12 / (l11 * A), l11 / A
    C11 = la * la * B11
    C12 = la * (lb * B11 + ld * B12)
    C22 = lb * lb * B11 + 2 * lb * ld * B12 + ld * ld * B22
    mean, half = (C11 + C22) / 2, (C11 - C22) / 2
    gap = torch.sqrt(half * half + C12 * C12 + eps)
    pos = mean >= 0
    big = torch.where(pos, mean + gap, mean - gap)
    small = torch.where(pos, mean - gap, mean + gap)
    w0, w1 = C12, big - C11
    u0, u1 = big - C22, C12
    use_u = u0 * u0 + u1 * u1 > w0 * w0 + w1 * w1
    w0, w1 = torch.where(use_u, u0, w0), torch.where(use_u, u1, w1)
    tiny = w0 * w0 + w1 * w1 <= 1e-30
    w0 = torch.where(tiny, torch.ones_like(w0), w0)
    w1 = torch.where(tiny, torch.zeros_like(w1), w1)
    v0, v1 = la * w0 + lb * w1, ld * w1
    e = torch.stack([v0, v1, v0 * a10 + v1 * a01], -1)
    e1 = e / torch.sqrt((e * e).sum(-1, keepdim=True) + eps)
    n = torch.stack([-a10 / A, -a01 / A, 1 / A], -1)
    return a[:, 0], n, e1, big, small


def _safe_div(num, den, ok):
    return num / torch.where(ok, den, torch.ones_like(den))


def torus_sdf_local(k1, k2, y1, y2, y3, eps=0.0):
    """Signed distance of the curvature-form torus at local coordinates (e1, e2, n)."""
    yp2 = y2 * y2 + y3 * y3
    k1_nz = k1 != 0
    tau = torch.where(k1_nz, _safe_div(k2, k1, k1_nz), torch.zeros_like(k1)).clamp(-1, 1)
    u2, u3 = k2 * y2, k2 * y3 - 1
    sqrtS = torch.sqrt(u2 * u2 + u3 * u3 + eps)
    D = sqrtS + (1 - tau)
    okD = D > 1e-30
    E = torch.where(okD, _safe_div(k1 * k2 * yp2 - 2 * k1 * y3 + 2 - tau, D, okD), torch.zeros_like(D))
    Fv = _safe_div((tau * k2 * yp2 - 2 * tau * y3) / (sqrtS + 1) - k2 * yp2 + 2 * y3, D, okD)
    Fv = torch.where(okD, Fv, _safe_div(torch.ones_like(k1), k1, k1_nz))
    k1y1 = k1 * y1
    Q = torch.sqrt(E * E + k1y1 * k1y1 + eps)
    return (Fv * (1 + E) - k1 * y1 * y1) / (1 + Q)


class Tori:
    """World-frame tori of P points: q, e1, e2, n, k1, k2."""

    def __init__(self, points, frame, coeffs, eps=0.0):
        s, t, n = frame
        a00, nl, el, k1, k2 = torus_from_jet(coeffs, eps)
        B = torch.stack([s, t, n], dim=1)  # rows s, t, n
        self.q = points + a00[:, None] * n
        nw = torch.einsum('pa,pac->pc', nl, B)
        self.n = nw / nw.norm(dim=-1, keepdim=True)
        ew = torch.einsum('pa,pac->pc', el, B)
        self.e1 = ew / ew.norm(dim=-1, keepdim=True)
        self.e2 = torch.cross(self.n, self.e1, dim=-1)
        self.k1, self.k2 = k1, k2


def blend(tori, points, x, nbr, r_eval, C=64.0, fallback_k=32, eps=0.0):
    """Accelerated PAT blend (src/blend/blend_cpu.cpp) of queries x [Q,3] over their nearest
    cloud points nbr [Q, K≥fallback_k] (sorted by distance): ρ = max(r_eval, d_k), points
    within ρ, σ = ρ/2, λ = C/σ, taper (1 − (d/ρ)²)³ + 1e-9."""
    p = points[nbr]                       # [Q, K, 3]
    diff = x[:, None, :] - p
    d = torch.sqrt((diff * diff).sum(-1) + 1e-20)
    rho = torch.maximum(d[:, fallback_k - 1], r_eval)
    sigma = rho / 2
    lam = C / sigma
    v = d / rho[:, None]
    inside = v <= 1
    a = 1 - torch.clamp(v * v, max=1.0)
    logw = -lam[:, None] * (d - sigma[:, None])
    logw = torch.where(inside, logw, torch.full_like(logw, -1e4))
    # Weights relative to the largest exponent: the ratio is what the blend uses.
    e = torch.exp(logw - logw.max(dim=1, keepdim=True).values.detach())
    w = e * (a * a * a + 1e-9) * inside
    y = x[:, None, :] - tori.q[nbr]
    y1 = (y * tori.e1[nbr]).sum(-1)
    y2 = (y * tori.e2[nbr]).sum(-1)
    y3 = (y * tori.n[nbr]).sum(-1)
    g = torus_sdf_local(tori.k1[nbr], tori.k2[nbr], y1, y2, y3, eps)
    return (w * g).sum(-1) / w.sum(-1)


# ---- weights file (safetensors, written by hand: no extra dependency) -------------------------

def state_for_file(model):
    """Tensor name → float32 numpy array, with the names of docs/torusnet.md."""
    out = {}
    for name, t in model.state_dict().items():
        out[name] = t.detach().cpu().float().numpy()
    return out


def save_safetensors(path, tensors, metadata):
    header = {}
    offset = 0
    blobs = []
    for name in sorted(tensors):
        arr = np.ascontiguousarray(tensors[name], dtype='<f4')
        header[name] = {'dtype': 'F32', 'shape': list(arr.shape),
                        'data_offsets': [offset, offset + arr.nbytes]}
        offset += arr.nbytes
        blobs.append(arr.tobytes())
    header['__metadata__'] = {k: str(v) for k, v in metadata.items()}
    text = json.dumps(header, separators=(',', ':')).encode()
    text += b' ' * ((8 - len(text) % 8) % 8)  # keep the data 8-byte aligned
    with open(path, 'wb') as f:
        f.write(struct.pack('<Q', len(text)))
        f.write(text)
        for b in blobs:
            f.write(b)


def load_safetensors(path):
    with open(path, 'rb') as f:
        raw = f.read()
    (hlen,) = struct.unpack('<Q', raw[:8])
    header = json.loads(raw[8:8 + hlen])
    meta = header.pop('__metadata__', {})
    data = raw[8 + hlen:]
    dtypes = {'F32': '<f4', 'F64': '<f8', 'I32': '<i4', 'I64': '<i8'}
    tensors = {}
    for name, h in header.items():
        b, e = h['data_offsets']
        tensors[name] = np.frombuffer(data[b:e], dtype=dtypes[h['dtype']]).reshape(h['shape']).copy()
    return tensors, meta


def save_model(path, model, description=''):
    meta = {'format': 'gsd-torusnet', 'version': '1', 'description': description}
    meta.update({k: str(v) for k, v in model.config.items()})
    save_safetensors(path, state_for_file(model), meta)


def load_model(path):
    tensors, meta = load_safetensors(path)
    cfg = {k: int(meta[k]) for k in ('k', 'width', 'blocks', 'heads', 'mlp')}
    model = TorusNet(**cfg)
    model.load_state_dict({k: torch.from_numpy(v) for k, v in tensors.items()})
    return model, meta
