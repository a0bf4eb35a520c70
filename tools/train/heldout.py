"""Evaluation rooms that look like what users run (issue 22): scenegen rooms from seeds no
training or validation dataset uses, and rooms written by hand, at 256×192 with their input
views, each with one added lamp of a saturated or strongly tinted colour, Mitsuba's truth for
the test views under the original lighting and the lamp alone, and the bake users run.

  python3 tools/train/heldout.py build OUT [--set heldout|validation|glossy|tiny] [--spp 64]
                                     [--rooms A,B] [--relit BIN] [--scenegen BIN]

Sets (fixed here, so that every report speaks of the same rooms):
- heldout: only reports, never chooses. Six scenegen rooms (seeds 700000–700005, 32 views,
  4 test views), whose original lights are seen by 3, 1 or 0 of the light-aimed views, with a
  red, green, blue, warm, cold or magenta lamp; tests/scenes/hand_room (16 views, cold lamp)
  and tests/scenes/hand_room2 (near-mirror, glossy cabinet, strong wall colours; green lamp).
  It must keep at least three rooms with a glossy floor or a near-mirror (what glossy mode is
  judged on); it has all eight: scenegen's floors are plastic, GGX α 0.05–0.3 by seed (700000–
  700005: 0.10, 0.21, 0.06, 0.23, 0.17, 0.20), hand_room's floor is plastic α 0.1 and
  hand_room2 has a conductor mirror α 0.03.
- validation: what checkpoints and designs are chosen on: scenegen seeds 800000–800002;
  800002 has scenegen's varied finishes (coloured walls, a near-mirror, a lacquered cabinet),
  so that a choice meets what hand_room2 tests (added 2026-12-03: on hand_room2 the s7-clean
  network was 2–3 dB below ratio while it beat ratio on both classic validation rooms);
  800003 and 800004 have scenegen's sparse finishes (untextured, few objects, matte floors:
  the hand rooms' kind; added 2026-12-03 when 800002 turned out not to reproduce hand_room2's
  failure), 800004 with the true surfaces as its proxy as the hand rooms have. On 800004 the
  s7-clean network is 1.6–2.0 dB below ratio, as on hand_room2. tests/scenes/hand_room3 (added
  2026-12-03, session 14): a third room written by hand — a glossy dark floor, a rougher
  near-mirror, lacquered and glossy black furniture, four wall colours, a ceiling strip light —
  because no scenegen validation room showed the held-out hand rooms' losses under shrink.
- glossy: a quick report for the glossy render mode (added 2026-12-06), three rooms each with a
  glossy floor or a near-mirror in its test views: scenegen seeds 700010 and 700011 (used
  nowhere else) with varied finishes, which keep the classic glossy floor and add a conductor
  mirror and a lacquered cabinet — 700010: floor α 0.12, mirror 0.035, cabinet 0.05; 700011:
  floor α 0.20, table top 0.05 (the brightest highlights of its test views), mirror 0.031,
  cabinet 0.10 (their mirrors, on the north wall, are outside the test views) — and hand_room2
  as in heldout (matte floor, mirror α 0.03 in two of its four test views, cabinet 0.05).
  Pixels in the glossy mask (evaluate.py), per test view: 1–13 % in the scenegen rooms,
  0–7 % in hand_room2.
- tiny: one small room (the evaluation's own test).

Per room OUT/<room>/ holds a scene (scene.json, meshes, images/ denoised as a camera's photos
have no fireflies, gt/{original,lamp}/ for the test views, denoised) with the presets eval_original (α_dim 0), eval_dimmed (the original at
30 % + the lamp) and eval_alone (the lamp alone), and its preview bake. A finished room has
`.heldout-done`; an unfinished one is rebuilt from scratch (renders) or resumed (the bake). A
room built before its photographs were denoised (2026-12-02) has them denoised in place and
is baked again.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
DONE = ".heldout-done"

# Lamp tints (linear RGB; luminance is renormalized so the lamp keeps its power).
TINTS = {"red": [1.0, 0.12, 0.08], "green": [0.15, 1.0, 0.2], "blue": [0.12, 0.3, 1.0],
         "warm": [1.0, 0.62, 0.28], "cold": [0.55, 0.78, 1.0], "magenta": [1.0, 0.2, 0.85]}
LIGHTINGS = {"eval_original": (0.0, 0.0), "eval_dimmed": (0.7, 1.0), "eval_alone": (1.0, 1.0)}

# (room name, source, options): source "scenegen:SEED" or a directory written by hand.
SETS = {
    "heldout": [
        ("sg700000", "scenegen:700000", dict(light_views=3, tint="red")),
        ("hand_room", "tests/scenes/hand_room", dict(tint="cold")),
        ("hand_room2", "tests/scenes/hand_room2", dict(tint="green")),
        ("sg700001", "scenegen:700001", dict(light_views=1, tint="green")),
        ("sg700002", "scenegen:700002", dict(light_views=0, tint="blue")),
        ("sg700003", "scenegen:700003", dict(light_views=3, tint="warm")),
        ("sg700004", "scenegen:700004", dict(light_views=1, tint="cold")),
        ("sg700005", "scenegen:700005", dict(light_views=0, tint="magenta")),
    ],
    "validation": [
        ("sg800000", "scenegen:800000", dict(light_views=2, tint="green")),
        ("sg800001", "scenegen:800001", dict(light_views=0, tint="warm")),
        ("sg800002", "scenegen:800002", dict(light_views=1, tint="blue", finishes="varied")),
        ("sg800003", "scenegen:800003", dict(light_views=2, tint="red", finishes="sparse")),
        ("sg800004", "scenegen:800004", dict(light_views=3, tint="cold", finishes="sparse",
                                             proxy_error=0)),
        ("hand_room3", "tests/scenes/hand_room3", dict(tint="magenta")),
    ],
    "glossy": [
        ("sg700010", "scenegen:700010", dict(light_views=2, tint="warm", finishes="varied")),
        ("sg700011", "scenegen:700011", dict(light_views=1, tint="blue", finishes="varied")),
        ("hand_room2", "tests/scenes/hand_room2", dict(tint="green")),
    ],
    "tiny": [
        ("sg700100", "scenegen:700100", dict(light_views=1, tint="red", views=6, res=(48, 36),
                                             test_views=1)),
    ],
}
RES = (256, 192)
VIEWS = 32
TEST_VIEWS = 4


def lum(c):
    return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]


def run(args, what):
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{what} failed ({' '.join(map(str, args))}):\n{r.stdout}{r.stderr}")
    return r.stdout


def write_json(path, doc):
    with open(path + ".tmp", "w") as f:
        json.dump(doc, f, indent=1)
    os.replace(path + ".tmp", path)


def scale_camera(cam, res):
    s = res[0] / cam["width"]
    if abs(res[1] / cam["height"] - s) > 1e-6:
        raise ValueError(f"camera {cam['width']}x{cam['height']} cannot be scaled to {res}")
    for k in ("fx", "fy", "cx", "cy"):
        cam[k] = cam[k] * s
    cam["width"], cam["height"] = res


def prepare_scene(doc, tint, res):
    """One added lamp, recoloured at the same luminance, the cameras at `res`, the presets."""
    added = [l for l in doc["lights"] if not l.get("original")]
    lamp = added[0]
    doc["lights"] = [l for l in doc["lights"] if l.get("original")] + [lamp]
    t = TINTS[tint]
    y = lum(lamp["radiance"])
    lamp["radiance"] = [y * c / lum(t) for c in t]
    syn = doc["synthetic"]
    syn["conditions"] = [c for c in syn["conditions"] if c["name"] == "original"]
    syn["conditions"].append({"name": "lamp", "lights": [lamp["name"]]})
    for v in doc["views"]:
        scale_camera(v["camera"], res)
    for v in syn["test_views"]:
        scale_camera(v["camera"], res)
    doc["presets"] = [{"name": n, "dim": d, "intensities": {lamp["name"]: i}}
                      for n, (d, i) in LIGHTINGS.items()]
    return doc


def generate(room_dir, source, o, bins):
    if source.startswith("scenegen:"):
        seed = source.split(":")[1]
        w, h = o.get("res", RES)
        run([bins["scenegen"], "room", room_dir, "--seed", seed, "--views", str(o.get("views", VIEWS)),
             "--res", f"{w}x{h}", "--extra-lights", "1", "--test-views",
             str(o.get("test_views", TEST_VIEWS)), "--light-views", str(o["light_views"]),
             "--finishes", o.get("finishes", "classic"),
             "--proxy-error", str(o.get("proxy_error", 1))], "scenegen")
    else:
        shutil.copytree(os.path.join(ROOT, source), room_dir)
    path = os.path.join(room_dir, "scene.json")
    with open(path) as f:
        doc = json.load(f)
    write_json(path, prepare_scene(doc, o["tint"], o.get("res", RES)))
    # What the room is, beside the scene (scene.json admits only its own fields).
    write_json(os.path.join(room_dir, "heldout.json"), {"source": source, **o})


def photos_denoised(room):
    # render.py's PHOTOS_DENOISED marker (render.py imports Mitsuba, which this env lacks).
    return os.path.exists(os.path.join(room, "gt", ".photos-denoised"))


def build_room(out, name, source, o, a, bins, log):
    room = os.path.join(out, name)
    if os.path.exists(os.path.join(room, DONE)) and photos_denoised(room):
        return False
    t0 = time.time()
    render_py = os.path.join(ROOT, "tools", "groundtruth", "render.py")
    marker = os.path.join(room, ".rendered")
    if os.path.exists(marker) and not photos_denoised(room):
        run(["python3", render_py, room, "--only", "photos"], f"{name}: denoise photographs")
    if not os.path.exists(marker):
        if os.path.exists(room):
            shutil.rmtree(room)
        generate(room, source, o, bins)
        with open(os.path.join(room, "scene.json")) as f:
            tests = [v["name"] for v in json.load(f)["synthetic"]["test_views"]]
        # Mitsuba lives in the system Python (tools/setup.sh), not the trainer's environment.
        render = ["python3", render_py, room, "--spp", str(a.spp)]
        run(render + ["--only", "inputs", "--denoise-photos"], f"{name}: input photographs")
        run(render + ["--views", ",".join(tests), "--denoise"], f"{name}: test-view truth")
        open(marker, "w").close()
    run([bins["relit"], "bake", room, "--quality", "preview"], f"{name}: bake")
    with open(os.path.join(room, DONE), "w") as f:
        f.write(source + "\n")
    log(f"heldout: {name} built in {time.time() - t0:.0f} s")
    return True


def rooms(out, which):
    """(name, directory) of the finished rooms of a set, in the set's order."""
    return [(n, os.path.join(out, n)) for n, _, _ in SETS[which]
            if os.path.exists(os.path.join(out, n, DONE))]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    b = sub.add_parser("build")
    b.add_argument("out")
    b.add_argument("--set", choices=sorted(SETS), default="heldout")
    b.add_argument("--spp", type=int, default=64)
    b.add_argument("--rooms", help="comma-separated room names of the set, in this order "
                                   "(default: every room of the set)")
    b.add_argument("--relit", default=os.path.join(ROOT, "target", "release", "relit"))
    b.add_argument("--scenegen", default=os.path.join(ROOT, "target", "release", "scenegen"))
    a = ap.parse_args()
    bins = {"relit": a.relit, "scenegen": a.scenegen}
    for k, p in bins.items():
        if not os.path.exists(p):
            sys.exit(f"error: {p}: no {k} binary (cargo build --release -p "
                     f"{'relit' if k == 'relit' else 'relit-scenegen'})")
    os.makedirs(a.out, exist_ok=True)
    t0 = time.time()
    todo = SETS[a.set]
    if a.rooms:
        by_name = {r[0]: r for r in todo}
        unknown = [n for n in a.rooms.split(",") if n not in by_name]
        if unknown:
            sys.exit(f"error: --rooms: {', '.join(unknown)} not in set {a.set} "
                     f"({', '.join(by_name)})")
        todo = [by_name[n] for n in a.rooms.split(",")]
    try:
        for k, (name, source, o) in enumerate(todo):
            build_room(a.out, name, source, o, a, bins, lambda m: print(m, flush=True))
            print(f"heldout: {k + 1}/{len(todo)} rooms ({time.time() - t0:.0f} s)", flush=True)
    except (OSError, ValueError, RuntimeError, KeyError) as e:
        sys.exit(f"error: {e}")


if __name__ == "__main__":
    main()
