#!/usr/bin/env python3
"""Trains TorusNet end to end (thesis eq. 5.5): predict every point's coefficients, build tori,
blend them (eq. 5.6, the accelerated rule of src/blend), and minimize
mean |φ − φ_true| + mean |1 − ‖∇φ‖| at queries with exact signed distance.

  python3 tools/train/train.py --out run/ --steps 4000            # trains, checkpoints to run/
  python3 tools/train/train.py --out run/ --steps 4000 --resume   # continues from run/ckpt.pt

Batch b is made of examples (seed, 0, b·clouds + i), so a run is reproducible from its command
and a resumed run sees the data it would have seen. Writes run/log.csv, run/ckpt.pt,
run/torusnet.safetensors (the last weights) and run/loss.png.
"""
import argparse
import csv
import math
import os
import sys
import time

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import dataset  # noqa: E402
import torusnet  # noqa: E402

VAL_STREAM = 1  # validation examples during training (never the evaluation set's stream)


class Batches(torch.utils.data.Dataset):
    def __init__(self, seed, clouds, k, queries, stream=0):
        self.seed, self.clouds, self.k, self.queries, self.stream = seed, clouds, k, queries, stream

    def __len__(self):
        return 1 << 30

    def __getitem__(self, b):
        ex = [dataset.make_example(self.seed, self.stream, b * self.clouds + i, self.k, self.queries)
              for i in range(self.clouds)]
        return dataset.collate(ex)


def to_device(batch, device):
    return {k: torch.from_numpy(np.asarray(v)).to(device, non_blocking=True) for k, v in batch.items()}


def loss_terms(model, b, eikonal=True):
    pts, nrm, knn = b['points'], b['normals'], b['knn']
    tokens, m, frame = torusnet.features(pts[knn], nrm[knn])
    coeffs = model(tokens, m)
    tori = torusnet.Tori(pts, frame, coeffs, eps=1e-12)
    x = b['queries']
    if eikonal:
        x = x.clone().requires_grad_(True)
    phi = torusnet.blend(tori, pts, x, b['qnbr'], b['r_eval'], eps=1e-12)
    dist = (phi - b['phi']).abs()
    if not eikonal:
        return dist, None
    (g,) = torch.autograd.grad(phi.sum(), x, create_graph=True)
    eik = (1 - g.norm(dim=-1)).abs()
    return dist, eik


def lr_at(step, total, peak, warmup):
    if step < warmup:
        return peak * (step + 1) / warmup
    t = (step - warmup) / max(1, total - warmup)
    return peak * (0.05 + 0.95 * 0.5 * (1 + math.cos(math.pi * min(1.0, t))))


def validate(model, val_batches, device):
    model.eval()
    tot = near = 0.0
    count = 0
    for vb in val_batches:
        b = to_device(vb, device)
        with torch.enable_grad():
            dist, eik = loss_terms(model, b)
        tot += float(dist.sum() + eik.sum())
        near += float(dist.sum())
        count += len(dist)
    model.train()
    return tot / count, near / count


def plot(log_path, png_path):
    try:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
    except ImportError:
        return
    rows = list(csv.DictReader(open(log_path)))
    if not rows:
        return
    step = [int(r['step']) for r in rows]
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(step, [float(r['train_loss']) for r in rows], label='train loss (eq. 5.5)', lw=1)
    vs = [(int(r['step']), float(r['val_loss'])) for r in rows if r['val_loss']]
    if vs:
        ax.plot(*zip(*vs), 'o-', label='validation loss', ms=3)
        vd = [(int(r['step']), float(r['val_dist'])) for r in rows if r['val_dist']]
        ax.plot(*zip(*vd), 's-', label='validation mean |φ − φ_true|', ms=3)
    ax.set_yscale('log')
    ax.set_xlabel('step')
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(png_path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--out', required=True)
    ap.add_argument('--steps', type=int, default=4000)
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--clouds', type=int, default=8, help='clouds per batch')
    ap.add_argument('--queries', type=int, default=2048, help='queries per cloud')
    ap.add_argument('--k', type=int, default=32)
    ap.add_argument('--width', type=int, default=64)
    ap.add_argument('--blocks', type=int, default=2)
    ap.add_argument('--heads', type=int, default=4)
    ap.add_argument('--mlp', type=int, default=128)
    ap.add_argument('--lr', type=float, default=1e-3)
    ap.add_argument('--warmup', type=int, default=200)
    ap.add_argument('--workers', type=int, default=max(1, (os.cpu_count() or 2) - 1))
    ap.add_argument('--val-every', type=int, default=250)
    ap.add_argument('--val-clouds', type=int, default=16)
    ap.add_argument('--ckpt-every', type=float, default=60.0, help='seconds between checkpoints')
    ap.add_argument('--max-minutes', type=float, default=0, help='stop (with a checkpoint) after this')
    ap.add_argument('--resume', action='store_true')
    ap.add_argument('--device', default='cuda' if torch.cuda.is_available() else 'cpu')
    args = ap.parse_args()

    os.makedirs(args.out, exist_ok=True)
    torch.manual_seed(args.seed)
    device = torch.device(args.device)
    if device.type == 'cuda':
        torch.backends.cuda.matmul.allow_tf32 = True
    model = torusnet.TorusNet(args.k, args.width, args.blocks, args.heads, args.mlp).to(device)
    opt = torch.optim.AdamW(model.parameters(), lr=args.lr, weight_decay=1e-4)
    ckpt_path = os.path.join(args.out, 'ckpt.pt')
    log_path = os.path.join(args.out, 'log.csv')
    start, elapsed0 = 0, 0.0
    if args.resume and os.path.exists(ckpt_path):
        ck = torch.load(ckpt_path, map_location=device)
        model.load_state_dict(ck['model'])
        opt.load_state_dict(ck['opt'])
        start, elapsed0 = ck['step'], ck['elapsed']
        print(f'resumed at step {start} ({elapsed0 / 60:.1f} min so far)', flush=True)
    elif os.path.exists(log_path):
        os.remove(log_path)
    params = sum(p.numel() for p in model.parameters())
    print(f'TorusNet k={args.k} width={args.width} blocks={args.blocks} heads={args.heads} mlp={args.mlp}: '
          f'{params} parameters; device {device}', flush=True)

    val = Batches(args.seed, 4, args.k, args.queries, stream=VAL_STREAM)
    val_batches = [val[i] for i in range(max(1, args.val_clouds // 4))]
    loader = torch.utils.data.DataLoader(
        Batches(args.seed, args.clouds, args.k, args.queries),
        sampler=range(start, args.steps), batch_size=None, num_workers=args.workers,
        prefetch_factor=4 if args.workers else None, persistent_workers=False, pin_memory=device.type == 'cuda')

    new_log = not os.path.exists(log_path)
    logf = open(log_path, 'a', newline='')
    log = csv.writer(logf)
    if new_log:
        log.writerow(['step', 'minutes', 'lr', 'train_loss', 'val_loss', 'val_dist'])
    t0 = time.time()
    last_ckpt = t0
    running, seen = 0.0, 0

    def save(step):
        torch.save({'model': model.state_dict(), 'opt': opt.state_dict(), 'step': step,
                    'elapsed': elapsed0 + time.time() - t0, 'args': vars(args)}, ckpt_path + '.tmp')
        os.replace(ckpt_path + '.tmp', ckpt_path)
        torusnet.save_model(os.path.join(args.out, 'torusnet.safetensors'), model.cpu(),
                            f'TorusNet trained by tools/train/train.py, seed {args.seed}, step {step}')
        model.to(device)

    step = start
    for step, batch in zip(range(start, args.steps), loader):
        lr = lr_at(step, args.steps, args.lr, args.warmup)
        for g in opt.param_groups:
            g['lr'] = lr
        b = to_device(batch, device)
        dist, eik = loss_terms(model, b)
        loss = dist.mean() + eik.mean()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        opt.step()
        running += loss.item()
        seen += 1
        done = step + 1
        minutes = (elapsed0 + time.time() - t0) / 60
        if done % 25 == 0 or done == args.steps:
            vl = vd = ''
            if done % args.val_every == 0 or done == args.steps:
                vl, vd = validate(model, val_batches, device)
                vl, vd = f'{vl:.6f}', f'{vd:.6f}'
            log.writerow([done, f'{minutes:.3f}', f'{lr:.3e}', f'{running / seen:.6f}', vl, vd])
            logf.flush()
            print(f'step {done}/{args.steps}  {minutes:6.2f} min  loss {running / seen:.5f}'
                  + (f'  val {vl} (dist {vd})' if vl else ''), flush=True)
            running, seen = 0.0, 0
        if time.time() - last_ckpt > args.ckpt_every:
            save(done)
            last_ckpt = time.time()
        if args.max_minutes and minutes > args.max_minutes:
            print(f'stopping at the time limit ({args.max_minutes} min)', flush=True)
            break
    save(step + 1 if step >= start else start)
    logf.close()
    plot(log_path, os.path.join(args.out, 'loss.png'))


if __name__ == '__main__':
    main()
