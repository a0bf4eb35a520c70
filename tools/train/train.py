"""Trains RelightNet (model.py) on a `relit dataset` and exports weights the engine loads
(`relit render --weights RUN/weights.safetensors`).

  python3 tools/train/train.py --data DATASET --out RUN [--width 32] [--steps N] [--resume]
  torchrun --nproc_per_node N tools/train/train.py --device cuda ...   (data-parallel)

DATASET holds train/ and val/ samples written by `relit dump --parts`: lighting kept linear, so
every step draws its own lighting (§6: the original lighting, dimmed or off, and random added
lights at random intensities) and assembles the input and targets exactly as the engine does
(samples.py). Losses (§5.3), in tonemapped space (μ = 64): L1(O_d, O*_d) + λ_vdep·L1(O_v, O*_v)
+ L1(O, O*), O*_v = tm(O*) − tm(O*_d), λ_vdep = 10; RMSProp, learning rate 1e-4 (§5.4).
Each further term of §5.3 has a switch, its weight (0 turns it off; defaults are the paper's):
--vgg 0.1, the perceptual twin of each L1 term (perceptual.py: VGG16 in place of VGG19);
--multiview 1, O_diffuse consistent with the nearest camera of the same scene reprojected with
the true depth (multiview.py; both views whole, not cropped); --adv 0.05, a relativistic
discriminator on [O_d, O_v] (adversarial.py), trained alongside with RMSProp at the same rate.

RUN gets checkpoint.pt (model, optimizer, step, every RNG state; written atomically every
--checkpoint-minutes and at the end), log.jsonl (training loss per step, validation loss every
--val-every steps), curves.png and weights.safetensors. --resume continues a run bit for bit:
the same steps, the same losses, the same weights as an uninterrupted run.
"""
import argparse
import glob
import json
import os
import random
import signal
import sys
import time

import numpy as np

os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")  # deterministic cuBLAS (--device cuda)
import torch  # noqa: E402
import torch.nn.functional as F

import adversarial as A  # noqa: E402
import model as M  # noqa: E402
import multiview as MV  # noqa: E402
import perceptual as P  # noqa: E402
import samples as S  # noqa: E402

tonemap = M.tm
# 50 dB: below it a crop's error is noise in the truth, not something worth a large gradient.
MARGIN_MSE_FLOOR = 1e-5


def load_split(folder):
    paths = sorted(glob.glob(os.path.join(folder, "*.safetensors")))
    out = [S.Sample(p) for p in paths]
    out = [s for s in out if s.has_targets()]
    return out


def random_lighting(sample, rng):
    """α_dim (0 keeps the original light, 1 removes it) and added-light intensities: one draw
    in six the original lighting (what the photos show, what users see first), else the
    original kept, dimmed or off with lamps on at random, at least one."""
    n = len(sample.lights)
    if n == 0 or rng.random() < 1.0 / 6.0:
        return 0.0, [0.0] * n   # α_dim 0: the original light untouched
    alpha = rng.choice([0.0, rng.random(), 1.0])
    intens = [rng.uniform(0.25, 2.0) if rng.random() < 0.5 else 0.0 for _ in sample.lights]
    if not any(intens):
        intens[rng.randrange(n)] = rng.uniform(0.25, 2.0)
    return alpha, intens


def batch(sample, alpha, intens, crop, rng, device="cpu", glossy=False):
    """(input, tm(diffuse), tm(total), lights) as 1×C×h×w tensors, a random crop (or the whole
    view). lights: 1×4×h×w, where a declared original light shows (channel 0: 1) and tm of what
    the frame draws there (1–3), as draw_lights reads it; None for samples without light_glow.
    With `glossy` the input carries glossy mode's image (linear) as three more channels: the
    base of a network with base "glossy" (model.py takes it from there)."""
    x = sample.input(alpha, intens)
    if glossy:
        g = sample.glossy(alpha, intens)
        if g is None:
            raise ValueError(f"{sample.path}: no view-dependent layer (written before relit dump "
                             "--parts stored it): rebuild the dataset for --base glossy")
        x = np.concatenate([x, g])
    d, t = sample.targets(alpha, intens)
    drawn = sample.drawn_lights(alpha, intens)
    h, w = x.shape[-2:]
    ch, cw = (h, w) if crop is None else (min(crop, h), min(crop, w))
    y0, x0 = rng.randrange(h - ch + 1), rng.randrange(w - cw + 1)
    s = (slice(None), slice(y0, y0 + ch), slice(x0, x0 + cw))
    to = lambda a: torch.from_numpy(np.ascontiguousarray(a[s], dtype=np.float32))[None].to(device)
    lights = None if drawn is None else torch.cat([to(drawn[0]), tonemap(to(drawn[1]))], 1)
    return to(x), tonemap(to(d)), tonemap(to(t)), lights


def draw_lights(img, lights):
    """A tonemapped image (N×3, or the network's N×6 output) with the declared original lights
    drawn as the engine's output pass draws them over every mode: their value as the diffuse
    image, no view-dependent part. The network's output there never reaches the screen, so it
    gets no gradient there."""
    if lights is None:
        return img
    on = lights[:, :1] > 0
    od = torch.where(on, lights[:, 1:4], img[:, :3])
    if img.shape[1] == 3:
        return od
    return torch.cat([od, torch.where(on, torch.zeros_like(img[:, 3:6]), img[:, 3:6])], 1)


def drawn_targets(d, t, lights):
    """The loss's targets (tm diffuse, tm total) with the drawn lights' value on their pixels:
    the frame draws them whatever the network outputs, so nothing is asked of it there. (The
    truth's split of an emitter's radiance into diffuse and view-dependent parts would otherwise
    weigh 10× in the view-dependent term on pixels no output of the network reaches.)"""
    if lights is None:
        return d, t
    on = lights[:, :1] > 0
    return torch.where(on, lights[:, 1:4], d), torch.where(on, lights[:, 1:4], t)


def ratio_image(x, lights=None):
    """The image the network corrects as the trainer sees it, tonemapped, with the declared
    original lights drawn: eq. 5's ratio image (ratio mode), or glossy mode's image where the
    batch carries it (three channels past the input's: base "glossy")."""
    n = M.IN_CHANNELS
    base = M.tm(x[:, n : n + 3]) if x.shape[1] == n + 3 else M.ratio_base(x)
    return draw_lights(base, lights)


def losses(out, d, t, lambda_vdep=10.0, vgg=None, lambda_vgg=0.0):
    """§5.3's eq. 8–10: L1 (and, with vgg, perceptual) terms on diffuse, view-dependent, sum."""
    od, ov = out[:, :3], out[:, 3:6]
    loss = F.l1_loss(od, d) + lambda_vdep * F.l1_loss(ov, t - d) + F.l1_loss(od + ov, t)
    if vgg is not None and lambda_vgg > 0:
        loss = loss + lambda_vgg * (vgg(od, d) + vgg(ov, t - d) + vgg(od + ov, t))
    return loss


def correction_l1(out, x, lights=None):
    """Mean |correction| on covered pixels of a base-"ratio" network: what it adds to the ratio
    image (diffuse) and its view-dependent output. As a penalty it keeps a correction only where
    the data terms pay for it, so that surfaces the ratio image already renders stay as they are."""
    covered = M.covered(x)
    c = torch.cat([out[:, :3] - ratio_image(x, lights), out[:, 3:6]], 1)
    return (c.abs() * covered).sum() / (covered.sum() * c.shape[1]).clamp(min=1)


def margin_loss(out, t, x, lights=None, floor=MARGIN_MSE_FLOOR):
    """dB by which the network's image falls below the ratio image on the covered pixels of this
    crop: 10·log10(MSE(ours) / MSE(ratio)), the evaluation's per-view margin with its sign turned.
    Its gradient is that of the squared error divided by the crop's own error, so a crop the ratio
    image already renders at 45 dB weighs as much as one at 25 dB: small corrections on clean
    views, which the L1 terms barely see, cost here what they cost in the evaluation. 0 when no
    pixel is covered; `floor` keeps a perfect crop's weight finite."""
    ours = covered_mse(out[:, :3] + out[:, 3:6], t, x)
    if ours is None:
        return out.sum() * 0.0
    return 10.0 * torch.log10((ours + floor) / (covered_mse(ratio_image(x, lights), t, x) + floor))


def covered_mse(img, t, x):
    """Mean squared error of a tonemapped image (negatives clamped) on the pixels an input view
    covers (I_1 not black), as evaluate.py scores them; None when no pixel is covered."""
    covered = M.covered(x).expand_as(t)
    if not covered.any():
        return None
    return ((img.clamp(min=0) - t) ** 2)[covered].mean()


def covered_psnr(img, t, x):
    """log-PSNR of a tonemapped image on the pixels an input view covers (I_1 not black), as
    evaluate.py scores them; None when no pixel is covered."""
    mse = covered_mse(img, t, x)
    return None if mse is None else 10 * np.log10(1.0 / max(mse.item(), 1e-12))


def validate(net, val, seed, device, vgg, lambda_vgg):
    """Mean loss over the validation samples, each under three fixed lightings, and the mean
    covered-pixel log-PSNR of the network's image and of the ratio image (the floor)."""
    if not val:
        return None
    rng = random.Random(seed)
    total, n, ours, ratio = 0.0, 0, [], []
    with torch.no_grad():
        for s in val:
            for _ in range(3):
                x, d, t, lights = batch(s, *random_lighting(s, rng), None, rng, device,
                                        glossy=net.config["base"] == "glossy")
                out = draw_lights(net(x), lights)
                total += losses(out, *drawn_targets(d, t, lights), vgg=vgg, lambda_vgg=lambda_vgg).item()
                n += 1
                p = covered_psnr(out[:, :3] + out[:, 3:6], t, x)
                r = covered_psnr(ratio_image(x, lights), t, x)
                if p is not None:
                    ours.append(p)
                    ratio.append(r)
    return {"val": total / n, "val_psnr": float(np.mean(ours)) if ours else None,
            "ratio_psnr": float(np.mean(ratio)) if ratio else None}


def learning_rate(a, step):
    """--lr, ramped up linearly over the first --warmup steps: a fresh RMSProp's first steps are
    ~10× the rate (its running mean of g² starts at zero), enough to jolt a pretrained network."""
    return a.lr * min(1.0, (step + 1) / a.warmup) if a.warmup > 0 else a.lr


def save_atomic(obj, path):
    tmp = path + ".tmp"
    torch.save(obj, tmp)
    os.replace(tmp, path)


def rng_states(rng):
    return {"python": rng.getstate(), "torch": torch.get_rng_state()}


def plot(run):
    """curves.png from log.jsonl (skipped without matplotlib)."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    with open(os.path.join(run, "log.jsonl")) as f:
        rows = [json.loads(line) for line in f]
    tr = [(r["step"], r["loss"]) for r in rows if "loss" in r]
    va = [(r["step"], r["val"]) for r in rows if "val" in r]
    fig, ax = plt.subplots(figsize=(6, 4))
    if tr:
        steps, vals = zip(*tr)
        k = max(1, len(vals) // 100)
        smooth = np.convolve(vals, np.ones(k) / k, mode="valid")
        ax.plot(steps[k - 1:], smooth, label=f"training (mean of {k})")
    if va:
        ax.plot(*zip(*va), "o-", label="validation")
    for r in rows:
        if "data" in r and r["step"] > 0:
            ax.axvline(r["step"], color="gray", linestyle="--", linewidth=0.8)
            what = ("from " + os.path.basename(os.path.dirname(r["init_from"])) if "init_from" in r
                    else "data: " + os.path.basename(r["data"]))
            ax.annotate(what, (r["step"], 0.98),
                        xycoords=("data", "axes fraction"), fontsize=7, va="top")
    ax.set_xlabel("step")
    ax.set_ylabel("loss (§5.3 L1 terms)")
    ax.set_yscale("log")
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(run, "curves.png.tmp.png"), dpi=100)
    os.replace(os.path.join(run, "curves.png.tmp.png"), os.path.join(run, "curves.png"))
    plt.close(fig)


def trim_log(run, step):
    """Drops log lines past the checkpoint's step (written after it by an interrupted run)."""
    path = os.path.join(run, "log.jsonl")
    if not os.path.exists(path):
        return
    keep = []
    with open(path) as f:
        lines = f.readlines()
    for line in lines:
        try:
            if json.loads(line)["step"] <= step:
                keep.append(line)
        except (ValueError, KeyError):
            break  # a line torn by the interruption: nothing after it was checkpointed
    with open(path + ".tmp", "w") as f:
        f.writelines(keep)
    os.replace(path + ".tmp", path)


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, help="a relit dataset directory (train/, val/)")
    # --out, not --run: torchrun would take --run for an abbreviation of its --run-path.
    ap.add_argument("--out", required=True, help="run directory: checkpoints, log, weights")
    ap.add_argument("--width", type=int, default=32)
    ap.add_argument("--trunk-blocks", type=int, default=M.DEFAULT_CONFIG["trunk_blocks"])
    ap.add_argument("--level-blocks", type=int, default=M.DEFAULT_CONFIG["level_blocks"])
    ap.add_argument("--tail-blocks", type=int, default=M.DEFAULT_CONFIG["tail_blocks"])
    ap.add_argument("--steps", type=int, default=1000, help="train until this step")
    ap.add_argument("--crop", type=int, default=128)
    ap.add_argument("--lr", type=float, default=1e-4)
    ap.add_argument("--warmup", type=int, default=0, metavar="N",
                    help="ramp the learning rate up linearly over steps 1..N (fine-tuning)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--val-every", type=int, default=200)
    ap.add_argument("--checkpoint-minutes", type=float, default=5.0)
    ap.add_argument("--save-every", type=int, default=0, metavar="N",
                    help="also keep the weights every N steps (weights-STEP.safetensors, for "
                         "export.py --average and evaluations)")
    ap.add_argument("--threads", type=int, default=0, help="torch CPU threads (0: torch's default)")
    ap.add_argument("--resume", action="store_true", help="continue RUN from its checkpoint")
    ap.add_argument("--init-from", metavar="CHECKPOINT",
                    help="start a new run from another run's checkpoint.pt: its network, optimizer "
                         "state and step, with this run's terms (ablations from a common point)")
    ap.add_argument("--base", choices=M.BASES, default="ratio",
                    help="ratio: the network corrects the ratio-relit composite (starts as it); "
                         "glossy: it corrects glossy mode's image (the view-dependent layer; "
                         "needs a dataset whose parts carry it); "
                         "none: the network's output is the image (the paper's formulation)")
    ap.add_argument("--init-weights", metavar="WEIGHTS",
                    help="start a new run's network from a weights file (e.g. the shipped one); "
                         "when its base differs from --base, the output conv keeps its "
                         "initialization (zero for --base ratio)")
    ap.add_argument("--device", default="cpu",
                    help="torch device: cpu or cuda (under torchrun, each process takes its own GPU)")
    ap.add_argument("--correction-l1", type=float, default=0.0, metavar="λ",
                    help="base ratio: λ · mean |correction| on covered pixels (0: off)")
    ap.add_argument("--margin", type=float, default=0.0, metavar="λ",
                    help="base ratio: λ · dB by which the image falls below the ratio image on "
                         "the crop's covered pixels (the evaluation's per-view margin; 0: off)")
    ap.add_argument("--floor", type=float, default=0.0, metavar="λ",
                    help="base ratio: λ · the dB by which the image falls below the ratio image, "
                         "only where it does (the --margin term's hinge: a crop above ratio "
                         "earns nothing, so corrections are pushed off crops they worsen)")
    ap.add_argument("--gate", type=float, default=0.0, metavar="G",
                    help="base ratio: scale corrections by min(1, new light's share / G) on "
                         "covered pixels, so that where no lamp reaches the image is ratio's (0: off)")
    ap.add_argument("--gain", action="store_true",
                    help="base ratio: the diffuse correction as a gain on the ratio image that "
                         "keeps its colour on covered pixels (model.py's gain)")
    ap.add_argument("--agree", type=float, default=0.0, metavar="A",
                    help="base ratio: scale corrections by min(1, input views' disagreement / A) "
                         "on covered pixels, so that where the views agree the image is ratio's "
                         "(model.py's agree; 0: off)")
    ap.add_argument("--vgg", type=float, default=0.1, help="λ_vgg of the perceptual terms (0: off)")
    ap.add_argument("--multiview", type=float, default=1.0,
                    help="weight of the multi-view consistency term (0: off)")
    ap.add_argument("--adv", type=float, default=0.05, help="λ_adv of the adversarial term (0: off)")
    ap.add_argument("--vgg-weights", default=os.path.expanduser("~/.cache/relit/vgg16.safetensors"),
                    help="VGG16 features converted by perceptual.py (tools/setup.sh makes them)")
    return ap.parse_args()


def save_weights(net, path, run=None, step=None):
    """The network's weights for the engine, written atomically (a temp file, then rename)."""
    trained = {"run": os.path.basename(os.path.abspath(run)), "step": step} if run else None
    tmp = path + ".tmp"
    M.save(net, tmp, trained=trained)
    os.replace(tmp, path)


def init_from(a, net, opt, disc, opt_d, lead):
    """Loads another run's network and optimizer state (RMSProp's running averages, so the first
    steps are not oversized) and returns its step; this run's terms and seed apply from there.
    A discriminator and its optimizer are taken over when both runs have one, else start
    afresh."""
    if not os.path.exists(a.init_from):
        sys.exit(f"{a.init_from}: no checkpoint to start from (--init-from)")
    c = torch.load(a.init_from, weights_only=False, map_location=a.device)
    if M.parameters_of(c["config"]) != M.parameters_of(net.config):
        sys.exit(f"{a.init_from}: network {c['config']} differs from {net.config} "
                 "(--width, --*-blocks, --base)")
    net.load_state_dict(c["model"])
    opt.load_state_dict(c["optimizer"])
    if disc is not None and c.get("disc") is not None:
        disc.load_state_dict(c["disc"])
        opt_d.load_state_dict(c["disc_optimizer"])
    if lead:
        with open(os.path.join(a.out, "log.jsonl"), "a") as f:
            f.write(json.dumps({"step": c["step"], "init_from": os.path.abspath(a.init_from),
                                "from_terms": c["terms"], "data": os.path.abspath(a.data)}) + "\n")
    return c["step"]


def init_weights(a, net, lead):
    """Loads a weights file's network into `net` (same shape); with another base, every tensor
    but the output conv's, which keeps this run's initialization."""
    if a.resume or a.init_from:
        sys.exit("--init-weights starts a new run: not with --resume or --init-from")
    try:
        src = M.load(a.init_weights)
    except (OSError, KeyError, ValueError) as e:
        sys.exit(f"{a.init_weights}: not a weights file ({e})")
    shape = lambda c: {k: v for k, v in M.parameters_of(c).items() if k != "base"}
    if shape(src.config) != shape(net.config):
        sys.exit(f"{a.init_weights}: network {src.config} differs from {net.config} "
                 "(--width, --*-blocks)")
    state = src.state_dict()
    if src.config["base"] != net.config["base"]:
        state = {k: v for k, v in state.items() if not k.startswith("out_conv.")}
    net.load_state_dict(state, strict=False)
    if lead:
        with open(os.path.join(a.out, "log.jsonl"), "a") as f:
            f.write(json.dumps({"step": 0, "init_weights": os.path.abspath(a.init_weights),
                                "from_base": src.config["base"]}) + "\n")


class Dist:
    """Data-parallel training under torchrun (WORLD_SIZE > 1): every process draws its own
    samples and lightings, gradients are averaged before each optimizer step, process 0 logs,
    validates and checkpoints (with every process's RNG state, so --resume is exact)."""

    def __init__(self, a):
        self.world = int(os.environ.get("WORLD_SIZE", "1"))
        self.rank = int(os.environ.get("RANK", "0"))
        if self.world > 1:
            import torch.distributed as dist
            self.dist = dist
            dist.init_process_group("nccl" if a.device.startswith("cuda") else "gloo")
            if a.device.startswith("cuda"):
                a.device = f"cuda:{int(os.environ.get('LOCAL_RANK', '0'))}"

    def average_gradients(self, module):
        if self.world == 1:
            return
        for p in module.parameters():
            if p.grad is not None:
                self.dist.all_reduce(p.grad)
                p.grad /= self.world

    def gather(self, obj):
        """Every process's obj, in rank order, on every process."""
        if self.world == 1:
            return [obj]
        out = [None] * self.world
        self.dist.all_gather_object(out, obj)
        return out

    def barrier(self):
        if self.world > 1:
            self.dist.barrier()

    def close(self):
        """Every process waits for the others, then tears the process group down: a process
        that exits with gloo's threads still running aborts ("terminate called without an
        active exception"), which torchrun reports as a failed run."""
        if self.world > 1:
            self.dist.barrier()
            self.dist.destroy_process_group()


def step_loss(a, net, disc, vgg, train, nbr, warps, i, lighting, rng, row):
    """The generator's loss of one step (eq. 8–12 as switched on) and the discriminator's input."""
    s = train[i]
    both = a.multiview > 0 and nbr[i] is not None
    glossy = a.base == "glossy"
    x, d, t, lights = batch(s, *lighting, None if both else a.crop, rng, a.device, glossy)
    d, t = drawn_targets(d, t, lights)
    if both:
        # The neighbour goes through the network in the same batch (one forward, one backward).
        xb, _, _, lights_b = batch(train[nbr[i]], *lighting, None, rng, a.device, glossy)
        outs = net(torch.cat([x, xb]))
        out = draw_lights(outs[:1], lights)
        outs = torch.cat([out, draw_lights(outs[1:], lights_b)])
    else:
        out = draw_lights(net(x), lights)
    loss = losses(out, d, t, vgg=vgg, lambda_vgg=a.vgg)
    if a.correction_l1 > 0:
        c = correction_l1(out, x, lights)
        row["correction_l1"] = c.item()
        loss = loss + a.correction_l1 * c
    if a.margin > 0 or a.floor > 0:
        m = margin_loss(out, t, x, lights)
        row["margin"] = m.item()
        loss = loss + a.margin * m + a.floor * torch.relu(m)
    if both:
        if (i, nbr[i]) not in warps:
            warps[(i, nbr[i])] = MV.warp(s, train[nbr[i]])
        mv = MV.loss(out[:, :3], outs[1:, :3], *warps[(i, nbr[i])])
        row["multiview"] = mv.item()
        loss = loss + a.multiview * mv
    fake, real = out[:, :6], torch.cat([d, t - d], 1)
    if disc is not None:
        g = A.generator_loss(disc, fake, real)
        row["adv"] = g.item()
        loss = loss + a.adv * g
    return loss, fake, real


def main():
    a = parse_args()
    if a.resume and a.init_from:
        sys.exit("--resume continues this run, --init-from starts one: pass one of them")
    corrects = a.base in M.CORRECTING
    if a.correction_l1 and not corrects:
        sys.exit("--correction-l1 needs --base ratio or glossy (a correction is relative to the "
                 "base image)")
    if (a.margin or a.floor) and not corrects:
        sys.exit("--margin and --floor need --base ratio or glossy (they measure the image "
                 "against the base image)")
    if a.gate and not corrects:
        sys.exit("--gate needs --base ratio or glossy (it scales the corrections to the base)")
    if a.gain and not corrects:
        sys.exit("--gain needs --base ratio or glossy (it is a gain on the base image)")
    if a.agree and not corrects:
        sys.exit("--agree needs --base ratio or glossy (it scales the corrections to the base)")
    if a.threads:
        torch.set_num_threads(a.threads)
    torch.use_deterministic_algorithms(True)
    dd = Dist(a)
    lead = dd.rank == 0
    train = load_split(os.path.join(a.data, "train"))
    val = load_split(os.path.join(a.data, "val"))
    if not train:
        sys.exit(f"{a.data}/train: no samples with targets (build them with relit dataset)")
    vgg = None
    if a.vgg > 0:
        if not os.path.exists(a.vgg_weights):
            sys.exit(f"{a.vgg_weights}: no VGG16 weights (run tools/setup.sh, or --vgg 0)")
        vgg = P.vgg_loss_module(a.vgg_weights).to(a.device)
    os.makedirs(a.out, exist_ok=True)
    ckpt = os.path.join(a.out, "checkpoint.pt")
    # The same initial weights in every process; the data each draws differs.
    torch.manual_seed(a.seed)
    net = M.RelightNet(width=a.width, trunk_blocks=a.trunk_blocks, level_blocks=a.level_blocks,
                       tail_blocks=a.tail_blocks, base=a.base, gate=a.gate,
                       gain=a.gain, agree=a.agree).to(a.device)
    opt = torch.optim.RMSprop(net.parameters(), lr=a.lr)
    disc = A.Discriminator().to(a.device) if a.adv > 0 else None
    opt_d = torch.optim.RMSprop(disc.parameters(), lr=a.lr) if disc is not None else None
    rng = random.Random(a.seed * 1000 + dd.rank)
    torch.manual_seed(a.seed * 1000 + dd.rank)
    nbr = MV.neighbours(train) if a.multiview > 0 else [None] * len(train)
    warps = {}
    terms = {"vgg": a.vgg, "multiview": a.multiview, "adv": a.adv, "processes": dd.world}
    if a.correction_l1:
        terms["correction_l1"] = a.correction_l1   # absent before the term existed
    if a.margin:
        terms["margin"] = a.margin
    if a.floor:
        terms["floor"] = a.floor   # absent before the term existed
    step = 0
    if a.resume:
        if not os.path.exists(ckpt):
            sys.exit(f"{ckpt}: no checkpoint to resume")
        c = torch.load(ckpt, weights_only=False, map_location=a.device)
        if c["terms"] != terms:
            sys.exit(f"{ckpt}: trained with {c['terms']}, not {terms} "
                     "(--vgg, --multiview, --adv, torchrun processes)")
        if M.full_config(c["config"]) != net.config:
            sys.exit(f"{ckpt}: network {c['config']} differs from {net.config} "
                     "(--width, --*-blocks, --base, --gate, --gain, --agree)")
        net.load_state_dict(c["model"])
        opt.load_state_dict(c["optimizer"])
        if disc is not None:
            disc.load_state_dict(c["disc"])
            opt_d.load_state_dict(c["disc_optimizer"])
        step = c["step"]
        rng.setstate(c["rng"][dd.rank]["python"])
        torch.set_rng_state(c["rng"][dd.rank]["torch"].cpu())
        if lead:
            trim_log(a.out, step)
            if os.path.abspath(a.data) != c.get("data"):
                # Fine-tuning on other data: the log and curves.png mark where it began.
                with open(os.path.join(a.out, "log.jsonl"), "a") as f:
                    f.write(json.dumps({"step": step, "data": os.path.abspath(a.data)}) + "\n")
    elif os.path.exists(ckpt):
        sys.exit(f"{ckpt} exists: pass --resume to continue it, or choose another --out")
    else:
        if lead:
            open(os.path.join(a.out, "log.jsonl"), "w").close()
        if a.init_from:
            step = init_from(a, net, opt, disc, opt_d, lead)
        elif a.init_weights:
            init_weights(a, net, lead)
    dd.barrier()

    def checkpoint():
        states = dd.gather(rng_states(rng))
        if lead:
            save_atomic({"model": net.state_dict(), "optimizer": opt.state_dict(), "step": step,
                         "rng": states, "config": net.config, "terms": terms,
                         "data": os.path.abspath(a.data),
                         "disc": disc.state_dict() if disc is not None else None,
                         "disc_optimizer": opt_d.state_dict() if opt_d is not None else None}, ckpt)

    # SIGTERM or Ctrl-C: finish the step, checkpoint, and exit cleanly (a session's end, `kill`).
    stop = []
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda signum, _frame: stop.append(signum))
    log = open(os.path.join(a.out, "log.jsonl"), "a") if lead else None
    t0 = last_ckpt = time.time()
    start = step
    while step < a.steps:
        i = rng.randrange(len(train))
        row = {"step": step + 1}
        for o in (opt, opt_d) if opt_d is not None else (opt,):
            for g in o.param_groups:
                g["lr"] = learning_rate(a, step)
        loss, fake, real = step_loss(a, net, disc, vgg, train, nbr, warps, i,
                                     random_lighting(train[i], rng), rng, row)
        opt.zero_grad()
        loss.backward()
        dd.average_gradients(net)
        opt.step()
        if disc is not None:
            dl = A.discriminator_loss(disc, fake, real)
            opt_d.zero_grad()
            dl.backward()
            dd.average_gradients(disc)
            opt_d.step()
            row["disc"] = dl.item()
        step += 1
        row["loss"] = loss.item()
        if lead and (step % a.val_every == 0 or step == a.steps):
            v = validate(net, val, a.seed, a.device, vgg, a.vgg)
            if v is not None:
                row.update(v)
            rate = (time.time() - t0) / (step - start)
            print(f"step {step}/{a.steps}: loss {row['loss']:.4f}, validation {v}, "
                  f"{rate:.2f} s/step, ETA {(a.steps - step) * rate / 60:.0f} min", flush=True)
        if lead:
            log.write(json.dumps(row) + "\n")
        if lead and a.save_every and step % a.save_every == 0:
            save_weights(net, os.path.join(a.out, f"weights-{step:05d}.safetensors"), a.out, step)
        # Every process decides alike when to checkpoint or stop (the gathers are collective).
        if any(dd.gather(bool(stop))):
            if lead:
                print(f"step {step}: stopping on a signal; --resume continues from here",
                      flush=True)
            break
        due = dd.gather(time.time() - last_ckpt > 60 * a.checkpoint_minutes)[0]
        if due:
            if lead:
                log.flush()
            checkpoint()
            last_ckpt = time.time()
    checkpoint()
    if lead:
        log.close()
        save_weights(net, os.path.join(a.out, "weights.safetensors"))
        plot(a.out)
        print(f"{a.out}: step {step}, {len(train)} training and {len(val)} validation samples, "
              f"{dd.world} process(es)")
    dd.close()


if __name__ == "__main__":
    main()
