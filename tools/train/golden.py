#!/usr/bin/env python3
"""Writes the conformance file that ties the C++ inference to PyTorch (docs/torusnet.md):
fixed neighborhoods from procedural clouds (clean, corrupted, and a few degenerate ones), the
features, the scale m and the coefficients PyTorch computes for them in float64.

  python3 tools/train/golden.py --model models/torusnet.safetensors \
      --out tests/data/torusnet_golden.safetensors
  python3 tools/train/golden.py --random-model /tmp/random.safetensors   # a test model
"""
import argparse
import os
import sys

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import dataset  # noqa: E402
import torusnet  # noqa: E402

GOLDEN_STREAM = 3


def neighborhoods(k, count, seed=7):
    """`count` neighborhoods [count, k, 3] of points and normals, token 0 the center."""
    pts_all, nrm_all = [], []
    rng = np.random.default_rng(seed)
    per = count // 4
    for c, corruption in enumerate([0.0, 0.0, 1.0, 0.6]):
        e = dataset.make_example(seed, GOLDEN_STREAM, c, k, n_queries=16,
                                 n_points=int(rng.integers(600, 4000)), corruption=corruption)
        pick = rng.choice(len(e['points']), per, replace=False)
        pts_all.append(e['points'][e['knn'][pick]])
        nrm_all.append(e['normals'][e['knn'][pick]])
    pts = np.concatenate(pts_all).astype(np.float64)
    nrm = np.concatenate(nrm_all).astype(np.float64)
    # Degenerate cases the implementations must agree on: a duplicate of the center, a flat
    # neighborhood with every normal equal, a far-scaled copy, and a neighbor with a
    # non-unit normal (normals are normalized by every implementation).
    pts[0, 1] = pts[0, 0]
    pts[1, :, 2] = pts[1, 0, 2]
    nrm[1] = [0.0, 0.0, 1.0]
    pts[2] = pts[2] * 1000.0
    nrm[3, 5] *= 3.0
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    nrm[3, 5] *= 3.0  # keep it non-unit on purpose
    return pts.astype(np.float32), nrm.astype(np.float32)


def random_model(k):
    torch.manual_seed(11)
    m = torusnet.TorusNet(k=k)
    with torch.no_grad():
        for p in m.parameters():
            p.add_(torch.randn_like(p) * 0.2)
    return m


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--model', help='weights to run (default: write and use a random test model)')
    ap.add_argument('--random-model', help='write a random test model here')
    ap.add_argument('--out', default='tests/data/torusnet_golden.safetensors')
    ap.add_argument('--count', type=int, default=64)
    args = ap.parse_args()

    if args.model:
        model, _ = torusnet.load_model(args.model)
    else:
        model = random_model(32)
        path = args.random_model or '/tmp/torusnet_random.safetensors'
        torusnet.save_model(path, model, 'random test model (tools/train/golden.py)')
        print(f'wrote random test model {path}')
    model = model.double().eval()
    k = model.config['k']
    pts, nrm = neighborhoods(k, args.count)
    with torch.no_grad():
        P = torch.from_numpy(pts).double()
        N = torch.from_numpy(nrm).double()
        tokens, m, _ = torusnet.features(P, N)
        coeffs = model(tokens, m)
    torusnet.save_safetensors(args.out, {
        'neighbors': pts, 'neighbor_normals': nrm,
        'features': tokens.numpy().astype(np.float32), 'scale': m.numpy().astype(np.float32),
        'coeffs': coeffs.numpy().astype(np.float32),
    }, {'format': 'gsd-torusnet-golden', 'model': os.path.basename(args.model or 'random'), 'k': str(k)})
    print(f'wrote {args.out}: {len(pts)} neighborhoods, k={k}')


if __name__ == '__main__':
    main()
