#!/usr/bin/env python3
"""Contact sheet of a synthetic scene (PNG): the input views, the proxy mesh against the true
mesh (camera-z depth of each from the same view and their difference), and the diffuse/glossy
split of two views under the original lighting.

Usage: contact_sheet.py SCENE_DIR --out sheet.png [--columns 8]
Needs the scene rendered (render.py); renders the two depth maps itself.
"""

import argparse
import os

import numpy as np

import render  # sets up Mitsuba (variant, LLVM path)

mi = render.mi


def display(img, exposure):
    """Linear → sRGB 8-bit with an exposure scale."""
    x = np.clip(img * exposure, 0.0, 1.0)
    x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (x * 255 + 0.5).astype(np.uint8)


def auto_exposure(imgs):
    lum = np.concatenate([np.asarray(i).reshape(-1, 3).mean(axis=1) for i in imgs])
    p = np.percentile(lum, 95)
    return 0.85 / max(p, 1e-6)


def colormap(x, lo, hi):
    """Blue-white-red for signed values, grey ramp when lo == 0."""
    t = np.clip((x - lo) / max(hi - lo, 1e-9), 0, 1)
    if lo < 0:
        r = np.clip(2 * t, 0, 1)
        b = np.clip(2 - 2 * t, 0, 1)
        g = 1 - np.abs(2 * t - 1)
        return (np.stack([r, g, b], -1) * 255).astype(np.uint8)
    return (np.stack([t, t, t], -1) * 255).astype(np.uint8)


def depth_of(scene_dir, mesh, cam):
    d = {"type": "scene",
         "m": {"type": "ply", "filename": mesh, "face_normals": True},
         "s": render.sensor_dict(cam, "contact sheet", 1, aov=True)}
    s = mi.load_dict(d)
    img = np.array(mi.render(s, integrator=mi.load_dict({"type": "aov", "aovs": "d:depth"}), spp=1))[:, :, 0]
    w, h = cam["width"], cam["height"]
    xs = (np.arange(w) + 0.5 - cam["cx"]) / cam["fx"]
    ys = (np.arange(h) + 0.5 - cam["cy"]) / cam["fy"]
    return np.where(img > 0, img / np.sqrt(xs[None, :] ** 2 + ys[:, None] ** 2 + 1.0) + render.NEAR_CLIP, 0.0)


def grid(tiles, cols, pad=4):
    h, w = tiles[0].shape[:2]
    rows = (len(tiles) + cols - 1) // cols
    out = np.full((rows * (h + pad) + pad, cols * (w + pad) + pad, 3), 24, np.uint8)
    for i, t in enumerate(tiles):
        r, c = divmod(i, cols)
        out[pad + r * (h + pad):pad + r * (h + pad) + h, pad + c * (w + pad):pad + c * (w + pad) + w] = t
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("--out", required=True)
    ap.add_argument("--columns", type=int, default=8)
    a = ap.parse_args()
    path, doc = render.load_description(a.scene)
    views = doc["views"]
    imgs = [render.read_exr(os.path.join(a.scene, v["image"])) for v in views]
    exp = auto_exposure(imgs)
    sections = [grid([display(i, exp) for i in imgs], a.columns)]

    # Proxy vs true depth for the first view: true, proxy, difference (±5 cm, holes black).
    cam = views[0]["camera"]
    dt = depth_of(a.scene, os.path.join(a.scene, doc["true_mesh"]), cam)
    dp = depth_of(a.scene, os.path.join(a.scene, doc["mesh"]), cam)
    far = np.percentile(dt, 99)
    diff = colormap(dp - dt, -0.05, 0.05)
    diff[dp <= 0] = 0
    sections.append(grid([colormap(dt, 0, far), colormap(dp, 0, far), diff], 3))

    # Diffuse / glossy split of two views (glossy brightened 4x for display).
    gt = os.path.join(a.scene, doc["synthetic"]["ground_truth"], "original")
    tiles = []
    for v in views[:2]:
        base = os.path.join(gt, v["name"])
        if not os.path.exists(base + ".total.exr"):
            continue
        t, d, g = (render.read_exr(f"{base}.{k}.exr") for k in ("total", "diffuse", "glossy"))
        tiles += [display(t, exp), display(d, exp), display(np.maximum(g, 0), 4 * exp)]
    if tiles:
        sections.append(grid(tiles, 3))

    width = max(s.shape[1] for s in sections)
    sheet = np.concatenate([np.pad(s, ((0, 0), (0, width - s.shape[1]), (0, 0)), constant_values=24) for s in sections])
    tmp = a.out + ".tmp.png"
    mi.Bitmap(sheet).write(tmp)
    os.replace(tmp, a.out)
    print(f"wrote {a.out}: {len(views)} views; rows: views | true depth, proxy depth, "
          f"proxy - true (±5 cm) | total, diffuse, glossy×4 of two views")


if __name__ == "__main__":
    main()
