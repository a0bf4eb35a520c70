"""Per-light control of the original lights (issue 51), measured against Mitsuba: on rooms built
by heldout.py whose capture lighting has two or more original lights, each original light dimmed
on its own scores about as well as all of them dimmed together.

  python3 tools/train/perlight.py --set DIR --out OUT [--rooms a,b] [--factor 0.3] [--relit BIN]
                                  [--spp 64]

Per room, the truth of each original light alone is rendered once for the test views
(tools/groundtruth/render.py: a condition per original light, added to the room's scene.json,
denoised as the heldout truth is). Lightings, each with the room's lamp at intensity 1:
- all_F: α_dim = 1 − F (every original light at factor F; heldout's eval_dimmed for F = 0.3);
- NAME_F: original light NAME at factor F, the others as captured (a preset "originals" entry);
- all_off and NAME_off: the same at factor 0;
- uniform_F, uniform_off: what α_dim alone can do for one light at F: every original light at
  the mean factor (F + n − 1)/n, scored against each NAME_F truth (mode "MODE:uniform").
Truth by linearity: Σ_l c_l·T(l alone) + T(lamp) (all_F: (1 − α)·T(original) + T(lamp), as
evaluate.py). Each lighting is rendered by `relit render --batch` in ratio mode and in network
mode (the shipped network) and scored by log-PSNR on covered pixels (evaluate.py's tonemap).
The goal: NAME_F within 1 dB of all_F in each room and mode. Writes OUT/perlight.json and
OUT/perlight.md (a row per room and lighting) and OUT/<room>.png (rows: views; columns: truth
and ratio for all_off and each NAME_off).
"""
import argparse
import json
import os
import subprocess
import sys

import numpy as np

import evaluate as E
import heldout as H

MODES = ["ratio", "network"]


def originals(doc):
    return [l["name"] for l in doc["lights"] if l.get("original")]


def lamp_of(doc):
    return next(c["lights"][0] for c in doc["synthetic"]["conditions"] if c["name"] == "lamp")


def prepare(room, factor, spp):
    """Adds the per-light conditions and presets to the room's scene.json and renders the
    missing truth; returns (original light names, lightings {name: {light: factor}})."""
    path = os.path.join(room, "scene.json")
    with open(path) as f:
        doc = json.load(f)
    names, lamp = originals(doc), lamp_of(doc)
    conds = doc["synthetic"]["conditions"]
    for n in names:
        if not any(c["name"] == n for c in conds):
            conds.append({"name": n, "lights": [n]})
    lightings = {}
    for tag, f in ((f"{factor:g}", factor), ("off", 0.0)):
        lightings[f"all_{tag}"] = {n: f for n in names}
        for n in names:
            lightings[f"{n}_{tag}"] = {n: f}
        mean = (f + len(names) - 1) / max(len(names), 1)
        lightings[f"uniform_{tag}"] = {n: mean for n in names}
    presets = [p for p in doc.get("presets", []) if not p["name"].startswith("perlight_")]
    for lt, fs in lightings.items():
        p = {"name": f"perlight_{lt}", "intensities": {lamp: 1.0}}
        if lt.startswith(("all_", "uniform_")):
            p["dim"] = 1.0 - next(iter(fs.values()))
        else:
            p["originals"] = fs
        presets.append(p)
    doc["presets"] = presets
    with open(path + ".tmp", "w") as f:
        json.dump(doc, f, indent=1)
    os.replace(path + ".tmp", path)
    views = E.room_views(room)
    missing = [n for n in names
               if not all(os.path.exists(os.path.join(room, "gt", n, f"{v}.total.exr")) for v in views)]
    if missing:
        render_py = os.path.join(H.ROOT, "tools", "groundtruth", "render.py")
        subprocess.run(["python3", render_py, room, "--spp", str(spp), "--views", ",".join(views),
                        "--conditions", ",".join(missing), "--denoise"], check=True)
    return names, lightings


def truth(room, view, names, lt, fs):
    rd = lambda c: E.read_exr(os.path.join(room, "gt", c, f"{view}.total.exr"))
    t = rd("lamp")
    if lt.startswith("all_"):
        t = t + next(iter(fs.values())) * rd("original")
    else:
        for n in names:
            t = t + fs.get(n, 1.0) * rd(n)
    cam = os.path.join(room, "camera.json")
    if os.path.exists(cam):
        with open(cam) as f:
            t = t * json.load(f)["exposure_scale"]
    return t


def render(relit, room, views, lightings, out):
    jobs, paths = [], {}
    for m in MODES:
        for v in views:
            for lt in lightings:
                p = os.path.join(out, f"{v}.{lt}.{m}.exr")
                jobs.append({"camera": v, "lighting": f"perlight_{lt}", "out": p, "mode": m})
                paths[(m, v, lt)] = p
    jf = os.path.join(out, "jobs.json")
    with open(jf, "w") as f:
        json.dump(jobs, f)
    r = subprocess.run([relit, "render", room, "--batch", jf], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"relit render {room} --batch {jf}:\n{r.stderr}")
    return {k: E.read_exr(p) for k, p in paths.items()}


def evaluate_room(a, name, room):
    names, lightings = prepare(room, a.factor, a.spp)
    if len(names) < 2:
        print(f"{name}: {len(names)} original light(s): skipped", file=sys.stderr)
        return []
    views = E.room_views(room)
    out = os.path.join(a.out, "renders", name)
    os.makedirs(out, exist_ok=True)
    imgs = render(a.relit, room, views, lightings, out)
    rows, sheet = [], []
    for v in views:
        covered = imgs[("ratio", v, f"all_{a.factor:g}")].max(-1) > 0
        line = []
        for lt, fs in lightings.items():
            if lt.startswith("uniform_"):
                continue
            t = E.tm(truth(room, v, names, lt, fs))
            tag = lt.rsplit("_", 1)[1]
            for m in MODES:
                img = E.tm(imgs[(m, v, lt)])
                rows.append({"room": name, "view": v, "lighting": lt, "mode": m,
                             "psnr": E.psnr(img, t, covered)})
                if not lt.startswith("all_"):
                    img = E.tm(imgs[(m, v, f"uniform_{tag}")])
                    rows.append({"room": name, "view": v, "lighting": lt, "mode": f"{m}:uniform",
                                 "psnr": E.psnr(img, t, covered)})
            if lt.endswith("_off"):
                line += [t, E.tm(imgs[("ratio", v, lt)])]
        sheet.append(np.concatenate(line, 1))
    E.save_png(os.path.join(a.out, f"{name}.png"), np.concatenate(sheet, 0))
    return rows


def summarize(rows, factor):
    """Per room, lighting and mode: mean log-PSNR over the views, and its gap to all_* (the
    same factor on every original light)."""
    per = {}
    for r in rows:
        per.setdefault((r["room"], r["lighting"], r["mode"]), []).append(r["psnr"])
    mean = {k: float(np.mean(v)) for k, v in per.items()}
    out = []
    for (room, lt, m), p in sorted(mean.items()):
        tag = lt.rsplit("_", 1)[1]
        gap = p - mean[(room, f"all_{tag}", m.split(":")[0])]
        out.append({"room": room, "lighting": lt, "mode": m, "psnr": p, "gap_to_all": gap})
    return out


def table(summary):
    """A row per room and one-light lighting: log-PSNR (covered) per mode, per-light control and
    α_dim alone (uniform), and the same room with every original light at that factor."""
    at = {(s["room"], s["lighting"], s["mode"]): s["psnr"] for s in summary}
    lines = ["| room | lighting | ratio | ratio, α_dim alone | network | network, α_dim alone | "
             "all at that factor: ratio / network | gap to it: ratio / network |",
             "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for room, lt in sorted({(s["room"], s["lighting"]) for s in summary}):
        if lt.startswith("all_"):
            continue
        alike = f"all_{lt.rsplit('_', 1)[1]}"
        v = [at[(room, lt, m)] for m in ("ratio", "ratio:uniform", "network", "network:uniform")]
        a = [at[(room, alike, m)] for m in MODES]
        lines.append(f"| {room} | {lt} | {v[0]:.2f} | {v[1]:.2f} | {v[2]:.2f} | {v[3]:.2f} | "
                     f"{a[0]:.2f} / {a[1]:.2f} | {v[0] - a[0]:+.2f} / {v[2] - a[1]:+.2f} |")
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--set", required=True, help="a directory built by heldout.py")
    ap.add_argument("--out", required=True)
    ap.add_argument("--rooms", help="comma-separated room names (default: every room with two or more original lights)")
    ap.add_argument("--factor", type=float, default=0.3)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--relit", default=os.path.join(H.ROOT, "target", "release", "relit"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    rooms = sorted(d for d in os.listdir(a.set) if os.path.exists(os.path.join(a.set, d, "scene.json")))
    if a.rooms:
        rooms = a.rooms.split(",")
    rows = []
    for name in rooms:
        rows += evaluate_room(a, name, os.path.join(a.set, name))
    summary = summarize(rows, a.factor)
    with open(os.path.join(a.out, "perlight.json"), "w") as f:
        json.dump({"images": rows, "summary": summary}, f, indent=1)
    lines = table(summary)
    with open(os.path.join(a.out, "perlight.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))
    worst = min((s["gap_to_all"] for s in summary if ":" not in s["mode"]), default=None)
    print(f"worst gap to all dimmed alike: {worst:+.2f} dB (goal: > -1 dB)" if worst is not None else "no room")


if __name__ == "__main__":
    main()
