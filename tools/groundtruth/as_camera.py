"""A synthetic scene as a camera would have captured it (issue 25): its EXR photos saved as 8-bit
sRGB JPEGs at one auto exposure (the median pixel luminance over all views mapped to 0.18, so
that lights clip), its original lights left undeclared — what `relit scene find-lights` is for.

  python3 tools/groundtruth/as_camera.py SRC DST [--key 0.18] [--quality 95] [--keep-lights]

DST gets a copy of SRC (meshes, textures, ground truth) with images/*.jpg in place of the EXRs.
Added lights' radiance is multiplied by the exposure scale (lights are declared in the photos'
units); the ground truth stays in SRC's units, the scale goes to DST/camera.json, and
`evaluate.py` scales the truth by it.
"""
import argparse
import json
import os
import shutil
import sys

import numpy as np

import mitsuba as mi

mi.set_variant("scalar_rgb")


def srgb(x):
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("src")
    ap.add_argument("dst")
    ap.add_argument("--key", type=float, default=0.18, help="linear value of the median luminance")
    ap.add_argument("--quality", type=int, default=95)
    ap.add_argument("--keep-lights", action="store_true", help="keep the original lights declared")
    a = ap.parse_args()
    if os.path.exists(a.dst):
        sys.exit(f"{a.dst}: exists; remove it first")
    with open(os.path.join(a.src, "scene.json")) as f:
        doc = json.load(f)
    images = [np.array(mi.Bitmap(os.path.join(a.src, v["image"])), dtype=np.float32)[..., :3]
              for v in doc["views"]]
    lum = np.concatenate([(im @ np.array([0.2126, 0.7152, 0.0722], np.float32)).ravel() for im in images])
    scale = a.key / max(float(np.median(lum)), 1e-8)
    tmp = a.dst + ".tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    shutil.copytree(a.src, tmp, ignore=shutil.ignore_patterns(".relit"))
    clipped = 0
    for v, im in zip(doc["views"], images):
        code = np.round(srgb(im * scale) * 255.0).astype(np.uint8)
        clipped += int((code >= 250).any(axis=-1).sum())
        rel = os.path.splitext(v["image"])[0] + ".jpg"
        mi.Bitmap(code).write(os.path.join(tmp, rel), quality=a.quality)
        os.remove(os.path.join(tmp, v["image"]))
        v["image"] = rel
    # Added lights are declared in the photos' units (README: light radiance in a real capture).
    for l in doc.get("lights", []):
        if not l.get("original"):
            l["radiance"] = [r * scale for r in l["radiance"]]
    if not a.keep_lights:
        gone = {l["name"] for l in doc.get("lights", []) if l.get("original")}
        doc["lights"] = [l for l in doc.get("lights", []) if not l.get("original")]
        for c in doc.get("synthetic", {}).get("conditions", []):
            c["lights"] = [n for n in c["lights"] if n not in gone]
    with open(os.path.join(tmp, "scene.json"), "w") as f:
        json.dump(doc, f, indent=1)
    with open(os.path.join(tmp, "camera.json"), "w") as f:
        json.dump({"exposure_scale": scale, "key": a.key, "quality": a.quality}, f, indent=1)
    os.replace(tmp, a.dst)
    print(f"{a.dst}: {len(images)} JPEGs at exposure x{scale:.4g}, {clipped} clipped pixels")


if __name__ == "__main__":
    main()
