"""Exports the weights of a run's latest checkpoint without stopping the run: the engine's
weights file (`relit render --weights W`) and the run's curves.png.

    python tools/train/export.py RUN|W [--out W] [--dtype f16|f32] [--average W1 ...] [--shrink T]
        [--gate G] [--gain] [--agree A] [--base ratio|glossy]

RUN is a run directory (its checkpoint is exported), W weights a run kept along the way
(`train.py --save-every`).

The file is written atomically (temporary file, rename). fp16 halves the size; the engine
computes in fp32 either way, and its fp16-storage path rounds the weights to fp16 anyway.

`--average` exports the mean of the checkpoint's weights and those of earlier exports of the
same network (stochastic weight averaging: a run that oscillates between checkpoints, as ours
does under the adversarial term, can be better at their mean than at either); their steps go
into the "relit.trained" metadata.

`--shrink T` sets the exported network's soft threshold on its corrections (model.py's
`shrink`, base "ratio" or "glossy"): a correction smaller than T in tonemapped space leaves the ratio
image as it is. Choose T on the validation rooms (evaluate.py), never on held-out ones.

`--gate G` sets the exported network's gate (model.py's `gate`, base "ratio" or "glossy"): on a
covered pixel each correction is scaled by min(1, f / G), f the new light's share of the pixel's
light, so that where no lamp reaches the image is ratio's exactly.

`--gain` makes the exported network's diffuse correction a gain on the ratio image that keeps
its colour (model.py's `gain`, base "ratio" or "glossy").

`--agree A` scales each correction on a covered pixel also by min(1, D / A), D the input views'
disagreement (model.py's `agree`, base "ratio" or "glossy"): where the reprojected views agree, the
image is ratio's. Choose A on the validation rooms.

`--base ratio|glossy` moves a correcting network's corrections onto another base: glossy puts
them on glossy mode's image (the view-dependent layer, model.py's base "glossy"), ratio on eq.
5's ratio image. A network trained on one base was not trained on the other: evaluate the
exported file before shipping it.
"""

import argparse
import json
import os
import sys

import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import model as M  # noqa: E402
from train import plot  # noqa: E402


def trained_step(path):
    return trained_meta(path).get("step")


def average_into(net, files):
    """Replaces net's parameters by their mean with the networks in `files` (same config)."""
    state = {k: v.clone().float() for k, v in net.state_dict().items()}
    for path in files:
        other = M.load(path)
        if other.config != net.config:
            sys.exit(f"{path}: network {other.config} differs from the run's {net.config}")
        for k, v in other.state_dict().items():
            state[k] += v.float()
    net.load_state_dict({k: v / (1 + len(files)) for k, v in state.items()})
    return [{"file": os.path.basename(p), "step": trained_step(p)} for p in files]


def trained_meta(path):
    from safetensors import safe_open
    with safe_open(path, framework="pt") as f:
        return json.loads((f.metadata() or {}).get("relit.trained", "{}"))


def load_base(run):
    """The network to export and how it was trained: a run's checkpoint, or weights that a run
    kept along the way (`train.py --save-every`)."""
    if os.path.isfile(run) and run.endswith(".safetensors"):
        trained = trained_meta(run)
        if "run" not in trained or "step" not in trained:
            sys.exit(f"{run}: no \"relit.trained\" run and step in its metadata "
                     "(expected weights kept by train.py --save-every)")
        return M.load(run), {"run": trained["run"], "step": trained["step"]}
    ckpt = os.path.join(run, "checkpoint.pt")
    if not os.path.isfile(ckpt):
        sys.exit(f"{ckpt}: no checkpoint (expected a run directory written by train.py)")
    c = torch.load(ckpt, weights_only=False, map_location="cpu")
    net = M.RelightNet(**c["config"])
    net.load_state_dict(c["model"])
    return net, {"run": os.path.basename(os.path.abspath(run)), "step": c["step"]}


def with_option(net, key, value):
    """net with config[key] = value, checked as the model checks it (exits on a bad value)."""
    cfg = dict(net.config, **{key: value})
    try:
        M.RelightNet(**cfg)
    except ValueError as e:
        sys.exit(f"--{key} {value}: {e}")
    net.config = cfg


def export(run, out, dtype, average=(), shrink=None, gate=None, gain=None, agree=None, base=None):
    net, trained = load_base(run)
    if average:
        trained["averaged_with"] = average_into(net, average)
    if base is not None:
        if net.config["base"] not in M.CORRECTING:
            sys.exit(f"--base {base}: the network's base is {net.config['base']!r}; only a "
                     "network that corrects a base image can take another")
        if base != net.config["base"]:
            trained["trained_base"] = net.config["base"]
        with_option(net, "base", base)
    for key, value in (("shrink", shrink), ("gate", gate), ("gain", gain), ("agree", agree)):
        if value is not None:
            with_option(net, key, value)
    tmp = out + ".tmp"
    M.save(net, tmp, dtype={"f16": torch.float16, "f32": torch.float32}[dtype], trained=trained)
    os.replace(tmp, out)
    if os.path.isdir(run):
        plot(run)
    return trained["step"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", help="a run directory (checkpoint.pt, log.jsonl), or weights kept by "
                                "train.py --save-every")
    ap.add_argument("--out", help="weights file (default: RUN/weights.safetensors)")
    ap.add_argument("--dtype", choices=["f16", "f32"], default="f32")
    ap.add_argument("--average", nargs="+", default=[], metavar="W",
                    help="weights files of the same network to average with the checkpoint's")
    ap.add_argument("--shrink", type=float, metavar="T",
                    help="soft threshold on the corrections (base ratio): below T, the base image")
    ap.add_argument("--gate", type=float, metavar="G",
                    help="scale corrections by min(1, new light's share / G) (base ratio or glossy)")
    ap.add_argument("--gain", action="store_const", const=True,
                    help="the diffuse correction as a colour-keeping gain on the ratio image")
    ap.add_argument("--agree", type=float, metavar="A",
                    help="scale corrections by min(1, input views' disagreement / A) (base ratio or glossy)")
    ap.add_argument("--base", choices=M.CORRECTING,
                    help="the image the corrections land on (a network trained on another "
                         "base keeps its weights; its metadata records the base it learned on)")
    a = ap.parse_args()
    if not a.out and not os.path.isdir(a.run):
        sys.exit("--out is needed when exporting a weights file")
    out = a.out or os.path.join(a.run, "weights.safetensors")
    step = export(a.run, out, a.dtype, a.average, a.shrink, a.gate, a.gain, a.agree, a.base)
    print(f"{out}: step {step}, {os.path.getsize(out) / 1e6:.1f} MB ({a.dtype})"
          + (f", averaged with {', '.join(a.average)}" if a.average else ""))


if __name__ == "__main__":
    main()
