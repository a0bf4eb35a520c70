"""Trains RelightNet (model.py) on tensors written by `relit dump` and exports safetensors the
engine loads (`relit render --weights FILE`).

  python3 tools/train/train.py --data DUMPS_DIR --out weights.safetensors [--width 66]
         [--steps N] [--crop 128] [--lr 1e-4]

Each dump holds `input` (66×H×W, the engine's exact features) and, for synthetic scenes,
`target_diffuse` and `target_total` (linear radiance). The losses are the L1 terms of §5.3 in
tonemapped space (μ = 64): L1(O_d, O*_d) + λ_vdep·L1(O_v, O*_v) + L1(O, O*), with O*_v =
tm(O*) − tm(O*_d) and λ_vdep = 10; RMSProp with learning rate 1e-4 as in §5.4. Not here yet:
the VGG19 perceptual terms (no VGG19 weights are available offline), the multi-view and
adversarial terms.
"""
import argparse
import glob
import os
import random

import torch
import torch.nn.functional as F
from safetensors.torch import load_file

import model as M

MU = 64.0


def tonemap(x):
    return torch.log1p(MU * x.clamp(min=0)) / torch.log1p(torch.tensor(MU))


def load_dumps(folder):
    samples = []
    for path in sorted(glob.glob(os.path.join(folder, "*.safetensors"))):
        t = load_file(path)
        if "target_diffuse" not in t:
            print(f"skipping {path}: no ground-truth targets")
            continue
        samples.append((t["input"], tonemap(t["target_diffuse"]), tonemap(t["target_total"])))
    if not samples:
        raise SystemExit(f"{folder}: no dumps with targets (relit dump on a synthetic scene)")
    return samples


def crop(sample, size, rng):
    x, d, t = sample
    h, w = x.shape[-2:]
    ch, cw = min(size, h), min(size, w)
    y0, x0 = rng.randrange(h - ch + 1), rng.randrange(w - cw + 1)
    s = (slice(None), slice(y0, y0 + ch), slice(x0, x0 + cw))
    return x[s][None], d[s][None], t[s][None]


def losses(out, d, t, lambda_vdep=10.0):
    od, ov = out[:, :3], out[:, 3:6]
    return (F.l1_loss(od, d) + lambda_vdep * F.l1_loss(ov, t - d) + F.l1_loss(od + ov, t))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--width", type=int, default=66)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--crop", type=int, default=128)
    ap.add_argument("--lr", type=float, default=1e-4)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    torch.manual_seed(a.seed)
    rng = random.Random(a.seed)
    data = load_dumps(a.data)
    net = M.RelightNet(width=a.width)
    opt = torch.optim.RMSprop(net.parameters(), lr=a.lr)
    first = None
    for step in range(1, a.steps + 1):
        x, d, t = crop(rng.choice(data), a.crop, rng)
        loss = losses(net(x), d, t)
        opt.zero_grad()
        loss.backward()
        opt.step()
        first = first if first is not None else loss.item()
        if step % max(1, a.steps // 10) == 0 or step == 1:
            print(f"step {step}: loss {loss.item():.4f}")
    tmp = a.out + ".tmp"
    M.save(net, tmp)
    os.replace(tmp, a.out)
    print(f"{a.out}: width {a.width}, {len(data)} dumps, loss {first:.4f} -> {loss.item():.4f}")


if __name__ == "__main__":
    main()
