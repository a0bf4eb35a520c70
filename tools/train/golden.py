"""Writes the golden files of the engine's network test (tests/golden/): a RelightNet with random
weights (every parameter random, including the fixup scalars and the zero-initialized second
convs) and a random input, with the PyTorch output computed in float64.

  python3 tools/train/golden.py tests/golden [CASE ...]

(CASE: some of the cases below, by name; default all). A case with base "ratio" also holds
"image": the composed [O_d, O_v] (the ratio base added to O_d), which the engine's output
pass must reproduce from the raw output and the input (`frame::output::reference_network`),
"image_shrink": the same with `shrink` τ = SHRINK (the file's metadata "shrink"), and
"image_gate": the same with `gate` G = GATE (metadata "gate"), no shrink, and "image_gain": the
same with the gate and `gain` (its diffuse correction a colour-keeping gain on the ratio image),
and "image_agree": the same with the gate, the gain and `agree` A = AGREE (metadata "agree"). Its
input has holes: each of the layers I_2..I_8 is black at a fifth of the pixels and I_1 at a
twentieth, so the disagreement's count of layers varies. It also holds "glossy", a random
linear image standing in for glossy mode's, and "image_glossy": the same network with base
"glossy" (that image as its base) and the gate, the gain and the agreement.

and, whenever the shipped weights change, the output of the trained network built into relit
(engine/weights/relit.safetensors) on a random input, with the weights' metadata copied so that
the test can tell a stale file:

  python3 tools/train/golden.py tests/golden --shipped engine/weights/relit.safetensors
"""
import sys
from pathlib import Path

import torch
from safetensors.torch import save_file

import model as M

CASES = {
    # Width not a multiple of 4 or 16 and != 66: exercises the input conv and channel padding.
    "net_w12": dict(cfg=dict(width=12), size=(24, 40), dtype=torch.float32),
    # The paper's width with fewer blocks (keeps the file at ~1 MB), weights stored as fp16.
    "net_w66": dict(cfg=dict(width=66, trunk_blocks=1, levels=3, level_blocks=1, tail_blocks=1),
                    size=(20, 28), dtype=torch.float16),
    # The network correcting the ratio image (model.py's base "ratio").
    "net_w12r": dict(cfg=dict(width=12, levels=3, base="ratio"), size=(16, 24),
                     dtype=torch.float32),
}


# The soft threshold of the "image_shrink" golden (the random corrections are ~1 in size).
SHRINK = 0.05
# The gate of "image_gate": against the random input's new-light share f (its E_rem may exceed
# E_src, so f spreads over 0.5–1e4), about a quarter of the corrections are scaled down.
GATE = 2.0
# The agreement of "image_agree": the random layers' disagreement is ~1/3 (blurred: 0.2–0.45), so
# most corrections are scaled down.
AGREE = 0.4


def with_holes(x, gen):
    """x with I_2..I_8 black at a fifth of the pixels each and I_1 at a twentieth."""
    n, _, h, w = x.shape
    for k in range(8):
        black = torch.rand((n, 1, h, w), generator=gen, dtype=x.dtype) < (0.05 if k == 0 else 0.2)
        x[:, 3 * k:3 * k + 3] = torch.where(black, torch.zeros_like(x[:, :3]), x[:, 3 * k:3 * k + 3])
    return x


def randomize(net, gen):
    with torch.no_grad():
        for name, p in net.named_parameters():
            if p.dim() == 4:
                fan_in = p.shape[1] * p.shape[2] * p.shape[3]
                p.copy_(torch.randn(p.shape, generator=gen) * (1.0 / fan_in) ** 0.5)
            elif name.endswith("scale"):
                p.copy_(0.5 + torch.rand(p.shape, generator=gen))
            else:
                p.copy_(torch.randn(p.shape, generator=gen) * 0.1)


def main(out, names=()):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for name, case in CASES.items():
        if names and name not in names:
            continue
        gen = torch.Generator().manual_seed(2021)
        net = M.RelightNet(**case["cfg"])
        randomize(net, gen)
        # What the file holds is what the engine sees: round the weights to the file's dtype.
        M.save(net, out / f"{name}.safetensors", dtype=case["dtype"])
        net = M.load(out / f"{name}.safetensors").double()
        h, w = case["size"]
        x = torch.rand((1, net.config["in_channels"], h, w), generator=gen, dtype=torch.float64)
        if net.config["base"] != "none":
            x = with_holes(x, gen)
            # Drawn last, so that the tensors above stay as files written before it hold them.
            glossy = torch.rand((1, 3, h, w), generator=gen, dtype=torch.float64) * 0.8
        with torch.no_grad():
            y, image = net.raw(x), net(x)
        io = {"input": x[0].float().contiguous(), "output": y[0].float().contiguous()}
        meta = None
        if net.config["base"] != "none":
            io["image"] = image[0].float().contiguous()
            net.config["shrink"] = SHRINK
            with torch.no_grad():
                io["image_shrink"] = net(x)[0].float().contiguous()
            net.config["shrink"] = 0.0
            net.config["gate"] = GATE
            with torch.no_grad():
                io["image_gate"] = net(x)[0].float().contiguous()
                w = M.gate_weight(x, GATE)
            net.config["gain"] = True
            with torch.no_grad():
                io["image_gain"] = net(x)[0].float().contiguous()
            net.config["agree"] = AGREE
            with torch.no_grad():
                io["image_agree"] = net(x)[0].float().contiguous()
                a = M.agreement_weight(x, AGREE)
            net.config["base"] = "glossy"
            with torch.no_grad():
                io["image_glossy"] = net(x, glossy)[0].float().contiguous()
            io["glossy"] = glossy[0].float().contiguous()
            net.config["base"] = "ratio"
            net.config["gate"], net.config["gain"], net.config["agree"] = 0.0, False, 0.0
            for what, v in (("gate", w), ("agreement", a)):
                print(f"{name}: {what} weights {float(v.min()):.3f}..{float(v.max()):.3f}, "
                      f"{float((v < 1).float().mean()) * 100:.0f}% below 1")
            meta = {"shrink": str(SHRINK), "gate": str(GATE), "agree": str(AGREE)}
        save_file(io, out / f"{name}.io.safetensors", metadata=meta)
        print(name, tuple(y.shape), float(y.abs().max()))


def shipped(out, weights):
    from safetensors import safe_open
    with safe_open(weights, framework="pt") as f:
        meta = f.metadata()
    net = M.load(weights).double()
    gen = torch.Generator().manual_seed(2021)
    x = torch.rand((1, net.config["in_channels"], 24, 32), generator=gen, dtype=torch.float64)
    with torch.no_grad():
        y = net.raw(x)
    save_file({"input": x[0].float().contiguous(), "output": y[0].float().contiguous()},
              Path(out) / "net_shipped.io.safetensors",
              metadata={"relit.net": meta["relit.net"], "relit.trained": meta["relit.trained"]})
    print("net_shipped", tuple(y.shape), float(y.abs().max()))


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[2] == "--shipped":
        shipped(sys.argv[1], sys.argv[3])
    else:
        main(sys.argv[1] if len(sys.argv) > 1 else "tests/golden", sys.argv[2:])
