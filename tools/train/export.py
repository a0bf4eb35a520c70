"""Exports the weights of a run's latest checkpoint without stopping the run: the engine's
weights file (`relit render --weights W`) and the run's curves.png.

    python tools/train/export.py RUN [--out W] [--dtype f16|f32]

The file is written atomically (temporary file, rename). fp16 halves the size; the engine
computes in fp32 either way, and its fp16-storage path rounds the weights to fp16 anyway.
"""

import argparse
import os
import sys

import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import model as M  # noqa: E402
from train import plot  # noqa: E402


def export(run, out, dtype):
    ckpt = os.path.join(run, "checkpoint.pt")
    if not os.path.isfile(ckpt):
        sys.exit(f"{ckpt}: no checkpoint (expected a run directory written by train.py)")
    c = torch.load(ckpt, weights_only=False, map_location="cpu")
    net = M.RelightNet(**c["config"])
    net.load_state_dict(c["model"])
    tmp = out + ".tmp"
    M.save(net, tmp, dtype={"f16": torch.float16, "f32": torch.float32}[dtype])
    os.replace(tmp, out)
    plot(run)
    return c["step"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", help="a run directory (checkpoint.pt, log.jsonl)")
    ap.add_argument("--out", help="weights file (default: RUN/weights.safetensors)")
    ap.add_argument("--dtype", choices=["f16", "f32"], default="f32")
    a = ap.parse_args()
    out = a.out or os.path.join(a.run, "weights.safetensors")
    step = export(a.run, out, a.dtype)
    print(f"{out}: step {step}, {os.path.getsize(out) / 1e6:.1f} MB ({a.dtype})")


if __name__ == "__main__":
    main()
