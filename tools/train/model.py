"""The network of §5.1 (Philip et al. 2021) as a PyTorch module: the reference the engine's
compute kernels are tested against (tests/golden/net_*) and the model the trainer learns.

Structure (W = width):
  input (66 ch)  -> [in_conv 3x3 -> W, only when W != 66]
  trunk          : 4 fixup blocks
  pyramid        : p0 = trunk out; p_k = down_k(p_{k-1}), 4x4 conv stride 2 pad 1 (+bias), k=1..4
  levels         : each p_k through its own 4-block fixup ResNet
  sum            : level 0 + bilinear upsampling (align_corners=False) of levels 1..4 to full size
  tail           : 2 fixup blocks
  out_conv       : 3x3 conv W -> 6 (+bias): diffuse RGB, view-dependent RGB, tonemapped space
  base           : with base "ratio", the out_conv's diffuse channels are a correction added to
                   tm(R), R the ratio-relit composite of eq. 5 formed from the input channels
                   (ratio_base; the engine's output pass forms the same); out_conv starts at
                   zero, so an untrained network renders the ratio image and training adds to it.
                   base "glossy": the same correction added to tm(G), G glossy mode's image
                   (the engine's frame/glossy.comp: eq. 5 on the photos' diffuse part plus the
                   view-dependent layer fitted from the photos and their mirror images), which
                   the input tensor cannot form: forward takes it (`relit dump` writes it as
                   glossy_image; samples.py mixes it from the parts). Every key below applies
                   to both bases alike.
                   base "none": the network's output is the image (the paper's formulation).
  shrink         : τ ≥ 0 (base "ratio" or "glossy"): on covered pixels (I_1 not black) each correction
                   channel c becomes sign(c)·max(|c| − τ, 0), so corrections smaller than τ
                   (tonemapped) leave the ratio image as it is; 0 (default) keeps them all.
  gate           : G ≥ 0 (base "ratio" or "glossy"): on covered pixels each correction is scaled by
                   min(1, f / G), f the new light's share of the pixel's light, max over RGB of
                   E_add / (E_src − E_rem + E_add) (the denominator floored as ratio_base floors
                   E_src). Light is linear and α_dim scales every original light alike, so where
                   no lamp reaches (f = 0) the truth is (1 − α_dim) × the photos' lighting and
                   ratio's image, (1 − α_dim) × I_1, is exactly as right as the photos'
                   composite: the image is ratio's there, whatever the weights, and the network
                   corrects only what the new light brings. 0 (default): no gate.
  gain           : false or true (base "ratio" or "glossy"): true turns the diffuse correction, on covered
                   pixels, into a gain on the ratio image that keeps its colour: with B the
                   ratio base and D = B + O_d, the log of the RGB mean's ratio,
                   g = log(mean untm(D) + GAIN_EPS) − log(mean untm(B) + GAIN_EPS), scaled by
                   the gate, multiplies untm(B): the diffuse image is tm(untm(B)·exp(w·g)). A
                   network can then brighten or darken what ratio shows, not tint it (a
                   trained network's corrections carried one warm cast into every room,
                   whatever colour the lamp; session 19). false (default): additive corrections.
  agree          : A ≥ 0 (base "ratio" or "glossy"): on covered pixels each correction is also scaled by
                   min(1, D / A), D the input views' disagreement (`disagreement`): where the
                   reprojected views I_2..I_8 match I_1 the proxy puts every view's pixel on the
                   same surface point and the surface looks the same from each, which is where
                   eq. 5's ratio image is right; the corrections act where the views disagree
                   (a wrong proxy, view-dependent shading). A network trained on rooms with
                   inexact proxies corrected the edges of a room whose proxy was exact (session
                   22); this leaves such a room to ratio. 0 (default): no agreement scaling.

Choices where the paper is silent (documented in the README): no activation after the
downsampling convs, the input conv is linear, the output conv is linear with a bias.

Weights travel as safetensors; the configuration sits in the file's metadata under "relit.net"
as JSON (see save()). Parameter names are the state_dict names of this module.
"""
import json
import math

import torch
import torch.nn as nn
import torch.nn.functional as F
from constants import CH_E_ADD, CH_E_REM, CH_E_SRC, CH_I, E_FLOOR as _E_FLOOR, GAIN_EPS, IN_CHANNELS, MU

DEFAULT_CONFIG = dict(in_channels=IN_CHANNELS, width=66, trunk_blocks=4, levels=5, level_blocks=4,
                      tail_blocks=2, out_channels=6, base="none", shrink=0.0,
                      gate=0.0, gain=False, agree=0.0)
BASES = ("none", "ratio", "glossy")
# Bases whose diffuse output is a correction of an image (the keys below apply to them).
CORRECTING = ("ratio", "glossy")

# Input channels (the CH_* rows of engine/constants.table): I_1, E_src/π, E_add/π, E_rem/π.
I1, E_SRC, E_ADD, E_REM = (slice(c, c + 3) for c in (CH_I, CH_E_SRC, CH_E_ADD, CH_E_REM))
# Ratio mode's floor on E_src (output.glsl: E_FLOOR on E, here on E/π).
ES_FLOOR = _E_FLOOR / math.pi


def tm(x):
    """The tonemap of §5.2: log(1 + μx) / log(1 + μ)."""
    return torch.log1p(MU * x.clamp(min=0)) / math.log1p(MU)


def untm(y):
    return torch.expm1(y.clamp(min=0) * math.log1p(MU)) / MU


def full_config(cfg):
    """A configuration with every key: checkpoints and files written before a key existed
    (base, shrink, gate, gain, agree) hold its default."""
    return dict(DEFAULT_CONFIG, **cfg)


def parameters_of(cfg):
    """The keys of a configuration that decide the parameters (not the OUTPUT_KEYS, which act
    on the output): two networks with equal ones can load each other's weights."""
    return {k: v for k, v in full_config(cfg).items() if k not in OUTPUT_KEYS}


# The configuration keys that act on the output only.
OUTPUT_KEYS = ("shrink", "gate", "gain", "agree")


def soft_threshold(c, tau):
    """sign(c)·max(|c| − τ, 0): what `shrink` does to a correction."""
    return torch.sign(c) * (c.abs() - tau).clamp(min=0)


def covered(x):
    """N×1×H×W: the pixels an input view covers (I_1 not black); the rest are holes."""
    return (x[:, I1] != 0).any(1, keepdim=True)


def ratio_base(x):
    """tm of eq. 5's ratio image, I_1 / E_src · (E_add + E_src − E_rem), from the input tensor
    (N×66×H×W); zero where no view covers the pixel (I_1 = 0)."""
    es, ea, er = input_irradiance(x)
    return tm(untm(x[:, I1]) / es.clamp(min=ES_FLOOR) * (ea + es - er))


def input_irradiance(x):
    """E_src, E_add, E_rem (/π, untonemapped) from the input tensor, as ratio_base and the gate
    read them."""
    return (untm(x[:, c]) for c in (E_SRC, E_ADD, E_REM))


def new_light_share(x):
    """N×1×H×W: f = max over RGB of E_add / (E_src − E_rem + E_add) at each pixel, from the
    input tensor (the denominator floored at ES_FLOOR): 0 where no lamp reaches the pixel."""
    es, ea, er = input_irradiance(x)
    return (ea / (es - er + ea).clamp(min=ES_FLOOR)).amax(1, keepdim=True)


def log_gain(base, cd):
    """N×1×H×W: g of `gain`, the log ratio of the RGB means of untm(base + cd) and untm(base)."""
    a = untm(base + cd).mean(1, keepdim=True)
    b = untm(base).mean(1, keepdim=True)
    return torch.log(a + GAIN_EPS) - torch.log(b + GAIN_EPS)


# The 5-tap binomial filter (σ = 1 px) that smooths the disagreement, clamped at the image's edges
# (output.glsl and output.rs apply the same).
BINOMIAL5 = (1 / 16, 4 / 16, 6 / 16, 4 / 16, 1 / 16)


def disagreement(x):
    """N×1×H×W: D of `agree`. At each pixel, the mean over the layers k = 2..8 that cover it
    together with I_1 of the RGB mean of |I_k − I_1| (tonemapped input channels), 0 where none
    does; then BINOMIAL5 across rows and columns, edge pixels repeated."""
    n, _, h, w = x.shape
    layers = x[:, :24].reshape(n, 8, 3, h, w)
    seen = (layers != 0).any(2)
    both = (seen[:, 1:] & seen[:, :1]).to(x.dtype)
    d = (layers[:, 1:] - layers[:, :1]).abs().mean(2)
    per_pixel = (d * both).sum(1, keepdim=True) / both.sum(1, keepdim=True).clamp(min=1)
    k = torch.tensor(BINOMIAL5, dtype=x.dtype, device=x.device)
    rows = F.conv2d(F.pad(per_pixel, (2, 2, 0, 0), mode="replicate"), k.view(1, 1, 1, 5))
    return F.conv2d(F.pad(rows, (0, 0, 2, 2), mode="replicate"), k.view(1, 1, 5, 1))


def agreement_weight(x, a):
    """N×1×H×W: min(1, D / A) on covered pixels, 1 in the holes (`agree`)."""
    return torch.where(covered(x), (disagreement(x) / a).clamp(max=1.0), torch.ones_like(x[:, :1]))


def gate_weight(x, g):
    """N×1×H×W: min(1, f / G) on covered pixels, 1 in the holes (`gate`)."""
    return torch.where(covered(x), (new_light_share(x) / g).clamp(max=1.0), torch.ones_like(x[:, :1]))


class FixupBlock(nn.Module):
    """Fixup residual block (Zhang et al. 2019): scalar biases before each conv and before the
    first activation, a scalar multiplier and bias after the second conv, which starts at zero."""

    def __init__(self, width, total_blocks):
        super().__init__()
        self.bias1a = nn.Parameter(torch.zeros(1))
        self.conv1 = nn.Conv2d(width, width, 3, 1, 1, bias=False)
        self.bias1b = nn.Parameter(torch.zeros(1))
        self.bias2a = nn.Parameter(torch.zeros(1))
        self.conv2 = nn.Conv2d(width, width, 3, 1, 1, bias=False)
        self.scale = nn.Parameter(torch.ones(1))
        self.bias2b = nn.Parameter(torch.zeros(1))
        # Fixup initialization: He init scaled by L^(-1/(2m-2)) with m = 2 layers per branch.
        fan_in = width * 9
        nn.init.normal_(self.conv1.weight, 0.0, math.sqrt(2.0 / fan_in) * total_blocks ** -0.5)
        nn.init.zeros_(self.conv2.weight)

    def forward(self, x):
        h = F.relu(self.conv1(x + self.bias1a) + self.bias1b)
        h = self.conv2(h + self.bias2a) * self.scale + self.bias2b
        return F.relu(h + x)


def resnet(width, blocks, total):
    return nn.Sequential(*[FixupBlock(width, total) for _ in range(blocks)])


class RelightNet(nn.Module):
    def __init__(self, **cfg):
        super().__init__()
        c = dict(DEFAULT_CONFIG)
        c.update(cfg)
        if c["base"] not in BASES:
            raise ValueError(f"base {c['base']!r}: expected one of {BASES}")
        for key in ("shrink", "gate", "agree"):
            if not (c[key] >= 0 and math.isfinite(c[key])):
                raise ValueError(f"{key} {c[key]!r}: expected a finite value >= 0")
            if c[key] > 0 and c["base"] not in CORRECTING:
                raise ValueError(f"{key} applies to a network with base \"ratio\" or \"glossy\" only")
        if c["gain"] not in (False, True):
            raise ValueError(f"gain {c['gain']!r}: expected false or true")
        c["gain"] = bool(c["gain"])
        if c["gain"] and c["base"] not in CORRECTING:
            raise ValueError("gain applies to a network with base \"ratio\" or \"glossy\" only")
        self.config = c
        w = c["width"]
        total = c["trunk_blocks"] + c["levels"] * c["level_blocks"] + c["tail_blocks"]
        self.in_conv = nn.Conv2d(c["in_channels"], w, 3, 1, 1) if w != c["in_channels"] else None
        self.trunk = resnet(w, c["trunk_blocks"], total)
        self.down = nn.ModuleList([nn.Conv2d(w, w, 4, 2, 1) for _ in range(c["levels"] - 1)])
        self.levels = nn.ModuleList([resnet(w, c["level_blocks"], total) for _ in range(c["levels"])])
        self.tail = resnet(w, c["tail_blocks"], total)
        self.out_conv = nn.Conv2d(w, c["out_channels"], 3, 1, 1)
        if c["base"] in CORRECTING:
            nn.init.zeros_(self.out_conv.weight)
            nn.init.zeros_(self.out_conv.bias)

    def forward(self, x, glossy=None):
        """[O_d, O_v] in tonemapped space: the raw output, plus the base on O_d. `glossy`
        (N×3×H×W, linear): glossy mode's image, the base of a network with base "glossy"; or
        appended to x as three more channels (the trainer's batches, see train.batch)."""
        n = self.config["in_channels"]
        if glossy is None and x.shape[1] == n + 3:
            x, glossy = x[:, :n], x[:, n:]
        y = self.raw(x)
        if self.config["base"] == "glossy" and glossy is None:
            raise ValueError("a network with base \"glossy\" needs glossy mode's image")
        if self.config["base"] in CORRECTING:
            cd, cv = y[:, :3], y[:, 3:]
            tau = self.config["shrink"]
            if tau > 0:
                seen = covered(x)
                cd = torch.where(seen, soft_threshold(cd, tau), cd)
                cv = torch.where(seen, soft_threshold(cv, tau), cv)
            w = gate_weight(x, self.config["gate"]) if self.config["gate"] > 0 else 1.0
            if self.config["agree"] > 0:
                w = w * agreement_weight(x, self.config["agree"])
            base = ratio_base(x) if self.config["base"] == "ratio" else tm(glossy)
            diffuse = base + w * cd
            if self.config["gain"]:
                lit = tm(untm(base) * torch.exp(w * log_gain(base, cd)))
                diffuse = torch.where(covered(x), lit, diffuse)
            y = torch.cat([diffuse, cv * w], 1)
        return y

    def raw(self, x):
        """What the convolutions compute (the engine's network; the output pass adds the base)."""
        h = self.in_conv(x) if self.in_conv is not None else x
        h = self.trunk(h)
        size = h.shape[-2:]
        pyramid = [h]
        for d in self.down:
            pyramid.append(d(pyramid[-1]))
        acc = self.levels[0](pyramid[0])
        for k in range(1, len(pyramid)):
            lk = self.levels[k](pyramid[k])
            acc = acc + F.interpolate(lk, size=size, mode="bilinear", align_corners=False)
        return self.out_conv(self.tail(acc))

    def flops(self, h, w):
        """Multiply-adds x 2 of the convolutions at an h x w input."""
        counts = []

        def hook(mod, inp, out):
            counts.append(2 * out.numel() * mod.in_channels * mod.kernel_size[0] * mod.kernel_size[1])

        hs = [m.register_forward_hook(hook) for m in self.modules() if isinstance(m, nn.Conv2d)]
        with torch.no_grad():
            self(torch.zeros(1, self.config["in_channels"], h, w))
        for x in hs:
            x.remove()
        return sum(counts)


def save(model, path, dtype=torch.float32, trained=None):
    """`trained`: how the weights were made (a dict stored as JSON under "relit.trained")."""
    from safetensors.torch import save_file
    tensors = {k: v.detach().to("cpu", dtype).contiguous() for k, v in model.state_dict().items()}
    cfg = dict(model.config)
    if cfg["base"] == "none":
        del cfg["base"]  # as files written before the option, which every engine reads
    if cfg["shrink"] == 0:
        del cfg["shrink"]  # likewise
    if cfg["gate"] == 0:
        del cfg["gate"]  # likewise
    if not cfg["gain"]:
        del cfg["gain"]  # likewise
    if cfg["agree"] == 0:
        del cfg["agree"]  # likewise
    meta = {"relit.net": json.dumps(cfg, sort_keys=True)}
    if trained is not None:
        meta["relit.trained"] = json.dumps(trained, sort_keys=True)
    save_file(tensors, path, metadata=meta)


def load(path):
    from safetensors import safe_open
    with safe_open(path, framework="pt") as f:
        cfg = json.loads(f.metadata()["relit.net"])
        model = RelightNet(**cfg)
        model.load_state_dict({k: f.get_tensor(k).float() for k in f.keys()})
    return model
