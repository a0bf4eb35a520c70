"""The moving-highlights figure (issues 22 and 49): one camera of the demo room looking at its
glossy floor, the original lights at 30 % and the lamp extra1 at its place in scene.json and at
the two places the main job's walk moves it to (paths/walk.json, t = 7.5 and 9.5). Rows: the
three places; columns: glossy mode, network mode, ratio mode and Mitsuba's truth. Prints, per
place, the highlight region's linear luminance in each (the region: the 5×5 pixels around the
brightest pixel of the truth's glossy part of the lamp on the floor, where the truth's normal
points up) and the image's row and column of that pixel.

  python3 tools/train/highlights.py --out DIR [--relit BIN] [--spp 256] [--jpg FIG.jpg]

The engine's frames come from `relit fly` over a three-second path whose lighting keyframes are
the three places (the camera still), as PNG at exposure 0.25 (linear values up to 4 kept;
decoded back to linear: ±0.5 % from the 8 bits); the truth from tools/groundtruth/render.py
with `--move-light` on a copy of scene.json whose one test view is this camera (its photos and
meshes linked, nothing of scenes/demo_room written but its bake cache, which `relit bake` made).
"""
import argparse
import json
import os
import shutil
import subprocess
import sys

import numpy as np

import heldout as H

SCENE = os.path.join(H.ROOT, "scenes", "demo_room")
CAMERA = {"position": [1.2, 1.7, -1.75], "look_at": [-0.3, 0.2, 0.4], "fov_deg": 80.0}
RES = (256, 192)
LAMP = "extra1"
MOVES = [[0.0, 0.0, 0.0], [1.16, 0.08, 0.09], [2.39, 0.17, 1.32]]
DIM = 0.7
EXPOSURE = 0.25
MODES = ["glossy", "network", "ratio"]


def lum(img):
    return img @ np.array([0.2126, 0.7152, 0.0722], np.float32)


def path_doc():
    key = lambda t: {"time": t, **CAMERA}
    light = lambda t, m: {"time": t, "dim": DIM, "intensities": {LAMP: 1.0},
                          "moves": {LAMP: m}}
    return {"interpolation": "linear", "keyframes": [key(0), key(2)],
            "lighting": [light(float(i), m) for i, m in enumerate(MOVES)]}


def engine_frames(relit, out, mode):
    """The three frames of `mode`, linear."""
    d = os.path.join(out, mode)
    os.makedirs(d, exist_ok=True)
    p = os.path.join(out, "path.json")
    H.write_json(p, path_doc())
    H.run([relit, "fly", SCENE, "--path", p, "--out", d, "--res", f"{RES[0]}x{RES[1]}",
           "--fps", "1", "--mode", mode, "--exposure", str(EXPOSURE)], f"relit fly --mode {mode}")
    from PIL import Image
    frames = []
    for i in range(len(MOVES)):
        srgb = np.asarray(Image.open(os.path.join(d, f"frame{i:05d}.png")).convert("RGB"),
                          np.float32) / 255.0
        lin = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
        frames.append(lin / EXPOSURE)
    return frames


def truth_scene(out):
    """A copy of the demo room's scene.json whose one test view is the figure's camera."""
    d = os.path.join(out, "truth_scene")
    os.makedirs(d, exist_ok=True)
    for name in os.listdir(SCENE):
        if name not in ("scene.json", "gt", ".relit") and not os.path.exists(os.path.join(d, name)):
            os.symlink(os.path.join(SCENE, name), os.path.join(d, name))
    with open(os.path.join(SCENE, "scene.json")) as f:
        doc = json.load(f)
    w, h = RES
    fx = w * 0.5 / np.tan(np.radians(CAMERA["fov_deg"]) * 0.5)
    cam = {"width": w, "height": h, "fx": float(fx), "fy": float(fx), "cx": w / 2, "cy": h / 2,
           "position": CAMERA["position"], "look_at": CAMERA["look_at"]}
    syn = doc["synthetic"]
    syn["test_views"] = [{"name": "fig", "camera": cam}]
    syn["conditions"] = [c for c in syn["conditions"] if c["name"] in ("original", LAMP)]
    syn["ground_truth"] = "gt"
    H.write_json(os.path.join(d, "scene.json"), doc)
    return d


def truth_frames(out, spp):
    """(total, lamp's glossy part) per place, linear: the original at 1 − DIM plus the lamp."""
    d = truth_scene(out)
    render = os.path.join(H.ROOT, "tools", "groundtruth", "render.py")
    # Mitsuba lives in the system Python (tools/setup.sh), not in the trainer's environment.
    base = ["python3", render, d, "--spp", str(spp), "--views", "fig", "--denoise",
            "--only", "all"]
    gt = os.path.join(d, "gt")
    if not os.path.exists(os.path.join(gt, "original", "fig.total.exr")):
        H.run(base + ["--conditions", "original"], "render.py original")
    orig = _read_exr(os.path.join(gt, "original", "fig.total.exr"))
    frames = []
    for i, m in enumerate(MOVES):
        keep = os.path.join(out, f"truth_lamp{i}")
        if not os.path.exists(os.path.join(keep, "fig.total.exr")):
            H.run(base + ["--conditions", LAMP, "--move-light", f"{LAMP}={m[0]},{m[1]},{m[2]}"],
                  f"render.py {LAMP} moved {m}")
            shutil.copytree(os.path.join(gt, LAMP), keep, dirs_exist_ok=True)
        lamp = _read_exr(os.path.join(keep, "fig.total.exr"))
        glossy = _read_exr(os.path.join(keep, "fig.glossy.exr"))
        frames.append(((1 - DIM) * orig + lamp, glossy))
    return frames


def _read_exr(path):
    import OpenEXR
    with OpenEXR.File(path) as f:
        ch = f.channels()
        if "RGB" in ch:
            return np.asarray(ch["RGB"].pixels, np.float32)[..., :3]
        return np.stack([np.asarray(ch[c].pixels, np.float32) for c in "RGB"], -1)


def region(glossy, floor):
    """The 5×5 window around the brightest pixel of the (3×3-box-smoothed) glossy part on the
    floor (`floor`: the truth's shading normal points up; the lamp itself is no highlight)."""
    g = lum(np.maximum(glossy, 0)) * floor
    s = sum(np.roll(np.roll(g, dy, 0), dx, 1) for dy in (-1, 0, 1) for dx in (-1, 0, 1))
    s[:2], s[-2:], s[:, :2], s[:, -2:] = 0, 0, 0, 0
    y, x = np.unravel_index(np.argmax(s), s.shape)
    return (slice(y - 2, y + 3), slice(x - 2, x + 3)), (int(y), int(x))


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True)
    ap.add_argument("--relit", default=os.path.join(H.ROOT, "target", "release", "relit"))
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--jpg", help="write the figure here (rows: places; columns: modes, truth)")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    engine = {m: engine_frames(a.relit, a.out, m) for m in MODES}
    truth = truth_frames(a.out, a.spp)
    normal = _read_exr(os.path.join(a.out, "truth_scene", "gt", "aov", "fig.normal.exr"))
    floor = normal[..., 1] > 0.9
    rows, report = [], {}
    print(f"place | highlight pixel (row, col) | {' | '.join(MODES)} | truth")
    for i, (t, g) in enumerate(truth):
        win, at = region(g, floor)
        vals = {m: float(lum(engine[m][i][win]).mean()) for m in MODES}
        vals["truth"] = float(lum(t[win]).mean())
        report[f"place{i}"] = {"pixel": at, "move": MOVES[i], **vals}
        print(f"{i} {MOVES[i]} | {at} | " + " | ".join(f"{vals[m]:.3f}" for m in MODES)
              + f" | {vals['truth']:.3f}")
        rows.append(np.concatenate([engine[m][i] for m in MODES] + [t], 1))
    H.write_json(os.path.join(a.out, "highlights.json"), report)
    if a.jpg:
        from PIL import Image
        img = np.concatenate(rows, 0)
        srgb = np.where(img <= 0.0031308, img * 12.92, 1.055 * np.maximum(img, 0) ** (1 / 2.4) - 0.055)
        Image.fromarray((np.clip(srgb, 0, 1) * 255 + 0.5).astype(np.uint8)).save(a.jpg, quality=90)


if __name__ == "__main__":
    main()
