#!/usr/bin/env python3
"""Ground truth for Relit's synthetic scenes, rendered with Mitsuba 3 (the paper rendered its
targets with Mitsuba, §6).

For every camera (capture views and test views) and lighting condition of a scene written by
`scenegen`, it writes half-float EXRs under the scene's ground-truth directory:

  gt/<condition>/<view>.total.exr    O*: total radiance (path tracing)
  gt/<condition>/<view>.diffuse.exr  O*_diffuse = emission + rho_d(x)/pi * E(x) at the first hit,
                                     E being the full irradiance there (eq. 3's a(x)E(x))
  gt/<condition>/<view>.glossy.exr   O* - O*_diffuse (eq. 7's residual)
  gt/original/<view>.mirror.exr      radiance from the mirror direction at the first hit (§4.2)
  gt/aov/<view>.{albedo,normal,depth}.exr   diffuse albedo, world shading normal, camera-z depth

and the input photographs images/<view>.exr = the total radiance under the original lighting.

Usage: render.py SCENE_DIR [--spp N] [--only inputs|aov|all|photos] [--views a,b]
                 [--conditions a,b] [--denoise] [--denoise-photos] [--move-light NAME=DX,DY,DZ ...]

--move-light NAME=DX,DY,DZ (repeatable; metres) renders as if the light NAME stood that far
from where scene.json puts it (its quad's corner or its disk's centre moved; scene.json is not
written). Everything the run renders sees it moved, input photographs included: for the truth
of a lamp moved after the capture, render the test views alone (--views).

--denoise runs Intel Open Image Denoise (pyoidn) on the targets (total and diffuse, guided by the
albedo and normal AOVs; glossy stays their difference). Measured on a validation scene (4 test
views at 128x96, a lamp's condition, against 1024 spp, in the trainer's tonemapped space): 64 spp
+ OIDN gives the glossy part 37.5 dB on glossy pixels for 6.8 s, 256 spp alone 38.2 dB for 22.9 s,
64 spp alone 33.4 dB.

--denoise-photos denoises the input photographs the same way (their own albedo and normal AOVs):
a camera integrates every light path, so its photos have none of the path tracer's fireflies,
which caustics off near-mirrors and glossy floors scatter over a 64 spp image by the hundred
and which the ratio composite and the network carry into every relit frame. `--only photos`
denoises the photographs of a room rendered without it, in place (once: gt/.photos-denoised
records it); its bake must then be redone (the bake cache is keyed by the photos).
"""

import argparse
import json
import math
import os
import sys
import time


def _find_llvm():
    # Dr.Jit's LLVM backend crashes with Debian's LLVM 15 and works with libllvm19.
    for p in (os.environ.get("DRJIT_LIBLLVM_PATH", ""),
              "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1",
              "/usr/lib/llvm-19/lib/libLLVM.so.1",
              "/usr/lib/aarch64-linux-gnu/libLLVM.so.19.1"):
        if p and os.path.exists(p):
            return p
    return None


_llvm = _find_llvm()
if _llvm:
    os.environ["DRJIT_LIBLLVM_PATH"] = _llvm

import numpy as np  # noqa: E402
import mitsuba as mi  # noqa: E402
import drjit as dr  # noqa: E402

VARIANT = "llvm_ad_rgb" if _llvm else "scalar_rgb"
mi.set_variant(VARIANT)

MAX_DEPTH = 8
# Mitsuba starts camera rays on the near plane, so depth AOVs measure from there: add it back.
NEAR_CLIP = 0.01


class SceneError(Exception):
    """A scene description the renderer cannot use; the message names the file and field."""


# ---------------------------------------------------------------- the diffuse-split integrator

class DiffuseFirstBounce(mi.SamplingIntegrator):
    """Radiance with only the first bounce restricted to the diffuse lobe:

        O_diffuse = Le(x) + rho_d(x)/pi * E(x),   E = E_direct + E_indirect,

    E_direct by emitter sampling (with visibility), E_indirect from one cosine-sampled ray whose
    radiance is a full path tracer's minus the emission it sees at its first hit (that light is
    already in E_direct). Cosine sampling gives E_indirect = pi * E[L], so its term is rho_d * L.
    """

    def __init__(self, props):
        super().__init__(props)
        depth = props.get("max_depth", MAX_DEPTH)
        self.path = mi.load_dict({"type": "path", "max_depth": max(depth - 1, 1)})

    def sample(self, scene, sampler, ray, medium=None, active=True):
        si = scene.ray_intersect(ray, active)
        valid = mi.Bool(active) & si.is_valid()
        em = si.emitter(scene, valid)
        emitted = dr.select(valid & (em != None), em.eval(si, valid), 0.0)  # noqa: E711
        albedo = si.bsdf(ray).eval_diffuse_reflectance(si, valid)
        n = si.sh_frame.n
        n = dr.select(dr.dot(n, -ray.d) < 0, -n, n)
        # Direct irradiance: weight = Le / pdf (solid angle), zero when occluded.
        ds, weight = scene.sample_emitter_direction(si, sampler.next_2d(valid), True, valid)
        e_direct = weight * dr.maximum(dr.dot(ds.d, n), 0.0)
        # Indirect: one cosine-sampled ray, emission at its first hit removed.
        d = mi.Frame3f(n).to_world(mi.warp.square_to_cosine_hemisphere(sampler.next_2d(valid)))
        ray2 = mi.RayDifferential3f(si.spawn_ray(d))
        si2 = scene.ray_intersect(ray2, valid)
        em2 = si2.emitter(scene, valid)
        le2 = dr.select(valid & si2.is_valid() & (em2 != None), em2.eval(si2, valid), 0.0)  # noqa: E711
        L, _, _ = self.path.sample(scene, sampler, ray2, medium, valid)
        out = emitted + albedo * (e_direct / dr.pi + (L - le2))
        return dr.select(valid, out, 0.0), valid, []

    def aov_names(self):
        return []

    def to_string(self):
        return "DiffuseFirstBounce[]"


mi.register_integrator("diffuse_first_bounce", lambda props: DiffuseFirstBounce(props))


class MirrorFirstBounce(mi.SamplingIntegrator):
    """The true mirror image (§4.2): radiance arriving at the first hit from the direction
    that mirrors the camera ray about the shading normal, path traced. The reference for the
    bake's source mirror images M_src."""

    def __init__(self, props):
        super().__init__(props)
        self.path = mi.load_dict({"type": "path", "max_depth": props.get("max_depth", MAX_DEPTH)})

    def sample(self, scene, sampler, ray, medium=None, active=True):
        si = scene.ray_intersect(ray, active)
        valid = mi.Bool(active) & si.is_valid()
        n = si.sh_frame.n
        n = dr.select(dr.dot(n, -ray.d) < 0, -n, n)
        r = ray.d - 2.0 * dr.dot(ray.d, n) * n
        L, _, _ = self.path.sample(scene, sampler, mi.RayDifferential3f(si.spawn_ray(r)), medium, valid)
        return dr.select(valid, L, 0.0), valid, []

    def aov_names(self):
        return []

    def to_string(self):
        return "MirrorFirstBounce[]"


mi.register_integrator("mirror_first_bounce", lambda props: MirrorFirstBounce(props))


# ---------------------------------------------------------------- scene description → Mitsuba

def _mat4(cols):
    """4x4 from three column vectors and a translation (numpy)."""
    m = np.eye(4)
    for i, c in enumerate(cols):
        m[:3, i] = c
    return mi.ScalarTransform4f(m.tolist())


def camera_rotation(cam):
    """World-to-camera R from a scene.json camera (rotation rows or look_at)."""
    pos = np.array(cam["position"], dtype=float)
    if cam.get("rotation") is not None:
        return np.array(cam["rotation"], dtype=float)
    fwd = np.array(cam["look_at"], dtype=float) - pos
    fwd /= np.linalg.norm(fwd)
    up = np.array(cam.get("up") or [0.0, 1.0, 0.0])
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    return np.stack([right, down, fwd])


def sensor_dict(cam, where, spp, aov=False):
    w, h = cam["width"], cam["height"]
    if abs(cam["fx"] - cam["fy"]) > 1e-4 * cam["fx"]:
        raise SceneError(f"{where}: fx != fy; Mitsuba's perspective camera needs square pixels")
    if abs(cam["cx"] - w / 2) > 1e-3 or abs(cam["cy"] - h / 2) > 1e-3:
        raise SceneError(f"{where}: principal point must be the image centre for this renderer")
    R = camera_rotation(cam)
    # Mitsuba's camera frame is (left, up, forward); Relit's is (right, down, forward).
    axes = R.T @ np.diag([-1.0, -1.0, 1.0])
    to_world = _mat4([axes[:, 0], axes[:, 1], axes[:, 2]])
    to_world = mi.ScalarTransform4f.translate(cam["position"]) @ to_world
    fov = math.degrees(2 * math.atan(w / (2 * cam["fx"])))
    sampler = ({"type": "stratified", "sample_count": 1, "jitter": False} if aov
               else {"type": "independent", "sample_count": spp})
    return {
        "type": "perspective", "fov": fov, "fov_axis": "x", "to_world": to_world,
        "near_clip": NEAR_CLIP, "far_clip": 1000.0,
        "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"},
                 "pixel_format": "rgb"},
        "sampler": sampler,
    }


def texture(dirname, m):
    rgb = {"type": "rgb", "value": m["albedo"]}
    if m.get("albedo_texture"):
        s = float(m.get("texture_scale", 1.0))
        return {"type": "bitmap", "filename": os.path.join(dirname, m["albedo_texture"]),
                "to_uv": mi.ScalarTransform4f.scale([s, s, 1.0])}
    return rgb


def bsdf_dict(dirname, name, m, where):
    kind = m.get("kind")
    r = max(float(m.get("roughness", 0.0)), 0.01)
    if kind == "diffuse":
        inner = {"type": "diffuse", "reflectance": texture(dirname, m)}
    elif kind == "plastic":
        inner = {"type": "roughplastic", "distribution": "ggx", "alpha": r, "int_ior": 1.5,
                 "diffuse_reflectance": texture(dirname, m)}
    elif kind == "conductor":
        inner = {"type": "roughconductor", "distribution": "ggx", "alpha": r,
                 "specular_reflectance": {"type": "rgb", "value": m.get("specular", [0.9] * 3)}}
    else:
        raise SceneError(f"{where}: material {name}: kind {kind!r}; expected diffuse, plastic or conductor")
    return {"type": "twosided", "bsdf": inner}


def light_shape(light, radiance):
    black = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}
    if light["shape"] == "quad":
        c = np.array(light["corner"], float)
        u = np.array(light["edge_u"], float)
        v = np.array(light["edge_v"], float)
        n = np.cross(u, v)
        n /= np.linalg.norm(n)
        to_world = mi.ScalarTransform4f.translate((c + 0.5 * (u + v)).tolist()) @ _mat4([0.5 * u, 0.5 * v, n])
        d = {"type": "rectangle", "to_world": to_world, "bsdf": black}
    elif light["shape"] == "disk":
        n = np.array(light["normal"], float)
        n /= np.linalg.norm(n)
        t1 = np.cross(n, [0.0, 1.0, 0.0]) if abs(n[1]) < 0.9 else np.cross(n, [1.0, 0.0, 0.0])
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(n, t1)  # t1 x t2 = n
        r = float(light["radius"])
        to_world = mi.ScalarTransform4f.translate(light["center"]) @ _mat4([r * t1, r * t2, n])
        d = {"type": "disk", "to_world": to_world, "bsdf": black}
    else:
        raise SceneError(f"light {light.get('name')}: shape {light.get('shape')!r}")
    if radiance is not None:
        d["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": radiance}}
    return d


def load_description(scene_dir):
    path = os.path.join(scene_dir, "scene.json")
    try:
        with open(path) as f:
            doc = json.load(f)
    except (OSError, json.JSONDecodeError) as e:
        raise SceneError(f"{path}: {e}")
    if "synthetic" not in doc:
        raise SceneError(f"{path}: no \"synthetic\" block: only scenegen scenes have ground truth")
    return path, doc


def parse_move(spec):
    """NAME=DX,DY,DZ (an argparse type) → (NAME, offset in metres)."""
    name, _, d = spec.partition("=")
    try:
        off = [float(x) for x in d.split(",")]
    except ValueError:
        off = []
    if not name or len(off) != 3 or not all(map(math.isfinite, off)):
        raise argparse.ArgumentTypeError(f"{spec!r}: expected NAME=DX,DY,DZ (metres)")
    return name, off


def move_lights(doc, moves, where):
    """Moves each light named in `moves` ((name, offset) pairs) by its offset, in `doc`."""
    lights = {l["name"]: l for l in doc.get("lights", [])}
    for name, off in moves or []:
        if name not in lights:
            raise SceneError(f"{where}: --move-light {name}: no such light "
                             f"(lights: {', '.join(lights) or 'none'})")
        l = lights[name]
        # A quad stands at its corner, a disk at its centre (light_shape; the scene format
        # has no other shapes).
        key = "corner" if l.get("shape") == "quad" else "center"
        if key not in l:
            raise SceneError(f"{where}: --move-light {name}: shape {l.get('shape')!r} has no {key}")
        l[key] = [float(p) + o for p, o in zip(l[key], off)]


def mitsuba_scene(scene_dir, doc, where, lit, cameras, spp, aov=False, intensities=None):
    """`lit`: names of the lights that emit (radiance × intensity); the others are black."""
    syn = doc["synthetic"]
    d = {"type": "scene"}
    for name, m in syn["materials"].items():
        d["mat_" + name] = bsdf_dict(scene_dir, name, m, where)
    for o in syn["objects"]:
        mesh = os.path.join(scene_dir, o["mesh"])
        if not os.path.exists(mesh):
            raise SceneError(f"{where}: object {o['name']}: mesh {mesh} does not exist")
        if o["material"] not in syn["materials"]:
            raise SceneError(f"{where}: object {o['name']}: unknown material {o['material']!r}")
        d["obj_" + o["name"]] = {"type": "ply", "filename": mesh, "face_normals": True,
                                 "bsdf": {"type": "ref", "id": "mat_" + o["material"]}}
    # Only the lit lights exist: a light that is off is not in the capture (the added lights are
    # virtual, §4.1.3). The one light's shape can shadow another's light, which makes sums of
    # conditions differ from a joint render by that (small) occlusion only.
    for l in doc.get("lights", []):
        if l["name"] in lit:
            k = (intensities or {}).get(l["name"], 1.0)
            d["light_" + l["name"]] = light_shape(l, [k * c for c in l["radiance"]])
    for i, (name, cam) in enumerate(cameras):
        d[f"sensor_{i:04d}"] = sensor_dict(cam, f"{where}: view {name}", spp, aov)
    # Mitsuba's optimization pass (merging objects) leaves the shapes, and so the emitters a
    # light sample picks from, in an order that changes from process to process: two renders
    # of a room with two lights differed everywhere (up to 0.6 at 4 spp). Without it, and on
    # one thread, the order is the dictionary's and a render is reproducible byte for byte.
    return mi.load_dict(d, parallel=False, optimize=False)


# ---------------------------------------------------------------- output

def write_exr(path, arr):
    arr = np.asarray(arr, dtype=np.float32)
    if arr.shape[2] == 1:
        arr = np.repeat(arr, 3, axis=2)  # one-channel maps stored as grey RGB: every reader opens them
    bmp = mi.Bitmap(arr, mi.Bitmap.PixelFormat.RGB)
    bmp = bmp.convert(bmp.pixel_format(), mi.Struct.Type.Float16, srgb_gamma=False)
    tmp = path + f".{os.getpid()}.tmp.exr"
    bmp.write(tmp)
    os.replace(tmp, path)


def read_exr(path):
    return np.array(mi.Bitmap(path), dtype=np.float32)


def views_of(doc, scene_path):
    """(name, camera dict) of capture views, then test views."""
    out = [(v["name"], v["camera"]) for v in doc["views"]]
    out += [(v["name"], v["camera"]) for v in doc["synthetic"]["test_views"]]
    names = [n for n, _ in out]
    if len(set(names)) != len(names):
        raise SceneError(f"{scene_path}: view names must be unique across views and test_views")
    return out


def denoiser(gt):
    """Denoises a target with Intel Open Image Denoise (pyoidn), guided by the view's albedo and
    normal AOVs (rendered first, at 1 spp, so not clean): HDR, linear, float32."""
    import pyoidn

    def run(name, img):
        alb = np.clip(read_exr(os.path.join(gt, "aov", f"{name}.albedo.exr")), 0.0, 1.0)
        nrm = np.clip(read_exr(os.path.join(gt, "aov", f"{name}.normal.exr")), -1.0, 1.0)
        img = np.ascontiguousarray(np.maximum(img[:, :, :3], 0.0), dtype=np.float32)
        return pyoidn.denoise(img, alb, nrm, hdr=True)
    return run


PHOTOS_DENOISED = ".photos-denoised"


def render_aovs(s_dir, doc, scene_path, gt, cams):
    """gt/aov/<view>.{albedo,normal,depth}.exr of `cams` at 1 spp."""
    os.makedirs(os.path.join(gt, "aov"), exist_ok=True)
    s = mitsuba_scene(s_dir, doc, scene_path, set(), cams, 1, aov=True)
    integ = mi.load_dict({"type": "aov", "aovs": "a:albedo,n:sh_normal,d:depth"})
    for i, (name, cam) in enumerate(cams):
        img = np.array(mi.render(s, integrator=integ, sensor=i, spp=1))
        w, h = cam["width"], cam["height"]
        # Mitsuba's depth is the distance along the unit ray; Relit stores camera z.
        xs = (np.arange(w) + 0.5 - cam["cx"]) / cam["fx"]
        ys = (np.arange(h) + 0.5 - cam["cy"]) / cam["fy"]
        norm = np.sqrt(xs[None, :] ** 2 + ys[:, None] ** 2 + 1.0)
        write_exr(os.path.join(gt, "aov", f"{name}.albedo.exr"), img[:, :, 0:3])
        write_exr(os.path.join(gt, "aov", f"{name}.normal.exr"), img[:, :, 3:6])
        z = np.where(img[:, :, 6] > 0, img[:, :, 6] / norm + NEAR_CLIP, 0.0)
        write_exr(os.path.join(gt, "aov", f"{name}.depth.exr"), z[:, :, None])


def denoise_photos_in_place(scene_dir, log=print):
    """`--only photos`: denoises the input photographs of a room rendered without
    --denoise-photos (their AOVs rendered first where missing); a no-op the second time."""
    scene_path, doc = load_description(scene_dir)
    gt = os.path.join(scene_dir, doc["synthetic"]["ground_truth"])
    if os.path.exists(os.path.join(gt, PHOTOS_DENOISED)):
        log(f"{scene_dir}: photographs already denoised")
        return
    inputs = {v["name"]: os.path.join(scene_dir, v["image"]) for v in doc["views"]}
    cams = [c for c in views_of(doc, scene_path) if c[0] in inputs]
    missing = [c for c in cams if not os.path.exists(os.path.join(gt, "aov", f"{c[0]}.normal.exr"))]
    if missing:
        render_aovs(scene_dir, doc, scene_path, gt, missing)
    dn = denoiser(gt)
    for name, _ in cams:
        write_exr(inputs[name], dn(name, read_exr(inputs[name])))
    open(os.path.join(gt, PHOTOS_DENOISED), "w").close()
    log(f"{scene_dir}: {len(cams)} photographs denoised")


def render_all(scene_dir, spp=128, only="all", views=None, conditions=None, seed=0, log=print,
               denoise=False, denoise_photos=False, moves=None):
    """Renders the ground truth. With `denoise`, the targets (total and diffuse; glossy is their
    difference) are denoised with OIDN; with `denoise_photos`, the input photographs; the mirror
    images never are. `moves`: (light name, offset) pairs applied before rendering."""
    if only == "photos":
        t0 = time.time()
        denoise_photos_in_place(scene_dir, log)
        return time.time() - t0
    scene_path, doc = load_description(scene_dir)
    move_lights(doc, moves, scene_path)
    syn = doc["synthetic"]
    gt = os.path.join(scene_dir, syn["ground_truth"])
    cams = views_of(doc, scene_path)
    if views:
        cams = [c for c in cams if c[0] in views]
    inputs = {v["name"]: os.path.join(scene_dir, v["image"]) for v in doc["views"]}
    conds = syn["conditions"]
    if only == "inputs":
        conds = [c for c in conds if c["name"] == "original"]
        cams = [c for c in cams if c[0] in inputs]
    if conditions:
        conds = [c for c in conds if c["name"] in conditions]
    t0 = time.time()
    if only in ("all", "aov") or (only == "inputs" and denoise_photos):
        render_aovs(scene_dir, doc, scene_path, gt, cams)
    dn = denoiser(gt) if denoise and only == "all" else None
    photo_dn = (dn or denoiser(gt)) if denoise_photos else None
    photos = 0
    if only in ("all", "inputs"):
        diffuse = mi.load_dict({"type": "diffuse_first_bounce", "max_depth": MAX_DEPTH})
        mirror = mi.load_dict({"type": "mirror_first_bounce", "max_depth": MAX_DEPTH})
        path = mi.load_dict({"type": "path", "max_depth": MAX_DEPTH})
        for c in conds:
            out = os.path.join(gt, c["name"])
            os.makedirs(out, exist_ok=True)
            s = mitsuba_scene(scene_dir, doc, scene_path, set(c["lights"]), cams, spp)
            for i, (name, cam) in enumerate(cams):
                total = np.array(mi.render(s, integrator=path, sensor=i, spp=spp, seed=seed + 2 * i))
                if name in inputs and c["name"] == "original":
                    os.makedirs(os.path.dirname(inputs[name]), exist_ok=True)
                    write_exr(inputs[name], photo_dn(name, total) if photo_dn else total)
                    photos += 1
                if only == "inputs":
                    continue
                diff = np.array(mi.render(s, integrator=diffuse, sensor=i, spp=spp, seed=seed + 2 * i + 1))
                if dn is not None:
                    total, diff = dn(name, total), dn(name, diff)
                write_exr(os.path.join(out, f"{name}.total.exr"), total)
                write_exr(os.path.join(out, f"{name}.diffuse.exr"), diff)
                write_exr(os.path.join(out, f"{name}.glossy.exr"), total - diff)
                if c["name"] == "original":
                    m = np.array(mi.render(s, integrator=mirror, sensor=i, spp=spp, seed=seed + 7919 + i))
                    write_exr(os.path.join(out, f"{name}.mirror.exr"), m)
            log(f"  {c['name']}: {len(cams)} views ({time.time() - t0:.1f} s)")
    if photo_dn and photos == len(inputs):
        open(os.path.join(gt, PHOTOS_DENOISED), "w").close()
    return time.time() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--only", choices=["all", "inputs", "aov", "photos"], default="all")
    ap.add_argument("--views", help="comma-separated view names")
    ap.add_argument("--conditions", help="comma-separated condition names")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--denoise", action="store_true",
                    help="denoise the targets with Intel Open Image Denoise (pyoidn)")
    ap.add_argument("--denoise-photos", action="store_true",
                    help="denoise the input photographs too (a camera's photo has no fireflies)")
    ap.add_argument("--move-light", type=parse_move, action="append", default=[],
                    metavar="NAME=DX,DY,DZ", help="move a light by this offset (metres) first")
    a = ap.parse_args()
    try:
        t = render_all(a.scene, a.spp, a.only,
                       a.views.split(",") if a.views else None,
                       a.conditions.split(",") if a.conditions else None, a.seed,
                       denoise=a.denoise, denoise_photos=a.denoise_photos, moves=a.move_light)
    except SceneError as e:
        print(f"error: {e}", file=sys.stderr)
        sys.exit(1)
    print(f"rendered {a.scene} in {t:.1f} s ({VARIANT}, {a.spp} spp)")


if __name__ == "__main__":
    main()
