"""Ground-truth renderer tests (run by tools/test.sh after cargo has built `scenegen`):
linearity of light transport, the diffuse/glossy split, and a Lambertian plane under a
rectangular light against Lambert's closed-form irradiance.
"""

import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import numpy as np

import render

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "train"))
import samples  # noqa: E402  (tools/train: the trainer's tonemap)

mi = render.mi
ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def scenegen():
    for p in (os.environ.get("SCENEGEN", ""), os.path.join(ROOT, "target/debug/scenegen"),
              os.path.join(ROOT, "target/release/scenegen")):
        if p and os.path.exists(p):
            return p
    raise RuntimeError("scenegen not built: run cargo build --workspace first")


def make_scene(tmp, seed=7, extra=2):
    d = os.path.join(tmp, f"scene{seed}")
    subprocess.run([scenegen(), "room", d, "--seed", str(seed), "--views", "2", "--res", "32x24",
                    "--test-views", "1", "--extra-lights", str(extra)], check=True, capture_output=True)
    return d


class GroundTruth(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="relit-gt-")
        cls.scene = make_scene(cls.tmp)
        _, cls.doc = render.load_description(cls.scene)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def render_lit(self, lit, integrator="path", spp=512, seed=0):
        cams = render.views_of(self.doc, "test")[:1]
        s = render.mitsuba_scene(self.scene, self.doc, "test", set(lit), cams, spp)
        integ = mi.load_dict({"type": integrator, "max_depth": render.MAX_DEPTH})
        return np.array(mi.render(s, integrator=integ, sensor=0, spp=spp, seed=seed))

    def test_two_lights_are_the_sum_of_each(self):
        a = self.render_lit(["extra0"], seed=1)
        b = self.render_lit(["extra1"], seed=2)
        ab = self.render_lit(["extra0", "extra1"], seed=3)
        # Independent Monte Carlo estimates: the image means agree within 3%, and the
        # per-pixel difference has no bias (mean within 3% of the mean).
        self.assertGreater(ab.mean(), 0)
        self.assertLess(abs((a + b).mean() - ab.mean()) / ab.mean(), 0.03)
        self.assertLess(abs(np.median((a + b - ab) / ab.mean())), 0.03)

    def test_split_sums_to_total_and_diffuse_scene_has_no_glossy(self):
        render.render_all(self.scene, spp=32, conditions=["original"], log=lambda *_: None)
        gt = os.path.join(self.scene, "gt", "original")
        for v in ("v000", "test000"):
            t, d, g = (render.read_exr(os.path.join(gt, f"{v}.{k}.exr")) for k in ("total", "diffuse", "glossy"))
            # Written in half precision: 2^-10 relative.
            np.testing.assert_allclose(d + g, t, rtol=2e-3, atol=2e-3)
        self.assertTrue(os.path.exists(os.path.join(self.scene, "images", "v000.exr")))
        # All materials Lambertian: the diffuse integrator must reproduce the path tracer
        # (image means within 3% at 512 spp).
        doc = json.loads(json.dumps(self.doc))
        for m in doc["synthetic"]["materials"].values():
            m["kind"], m["roughness"] = "diffuse", 0.0
            if not any(m["albedo"]):
                m["albedo"] = [0.5, 0.5, 0.5]
        saved, self.doc = self.doc, doc
        try:
            lit = doc["synthetic"]["conditions"][0]["lights"]
            t = self.render_lit(lit, "path", seed=4)
            d = self.render_lit(lit, "diffuse_first_bounce", seed=5)
        finally:
            self.doc = saved
        self.assertLess(abs(d.mean() - t.mean()) / t.mean(), 0.03)

    def test_denoised_targets_are_closer_to_many_samples(self):
        d = make_scene(self.tmp, seed=8)
        quiet = dict(views=["test000"], conditions=["original"], log=lambda *_: None)
        out = os.path.join(d, "gt", "original")

        def targets():
            return [render.read_exr(os.path.join(out, f"test000.{k}.exr")) for k in ("total", "diffuse", "glossy")]
        render.render_all(d, spp=1024, seed=11, **quiet)
        ref = targets()
        render.render_all(d, spp=4, **quiet)
        raw = targets()
        render.render_all(d, spp=4, denoise=True, **quiet)
        dn = targets()
        # The trainer's tonemapped space.
        tm = samples.tonemap
        err = lambda a, b: float(np.sqrt(np.mean((tm(a) - tm(b)) ** 2)))
        for k, name in enumerate(("total", "diffuse")):
            self.assertLess(err(dn[k], ref[k]), 0.8 * err(raw[k], ref[k]), name)
        # glossy stays the difference of the denoised total and diffuse (half precision).
        np.testing.assert_allclose(dn[1] + dn[2], dn[0], rtol=2e-3, atol=2e-3)

    def test_denoised_photos_are_closer_to_many_samples_and_denoised_once(self):
        d = make_scene(self.tmp, seed=9)
        _, doc = render.load_description(d)
        photos = [os.path.join(d, v["image"]) for v in doc["views"]]
        quiet = dict(only="inputs", log=lambda *_: None)
        read = lambda: [render.read_exr(p) for p in photos]
        render.render_all(d, spp=1024, seed=11, **quiet)
        ref = read()
        render.render_all(d, spp=4, **quiet)
        raw = read()
        render.render_all(d, only="photos", log=lambda *_: None)
        dn = read()
        tm = samples.tonemap
        err = lambda a, b: float(np.sqrt(np.mean((tm(a) - tm(b)) ** 2)))
        for r, a, b in zip(ref, raw, dn):
            self.assertLess(err(b, r), 0.8 * err(a, r))
        # Once: a second call leaves the photographs as they are.
        render.render_all(d, only="photos", log=lambda *_: None)
        for a, b in zip(dn, read()):
            np.testing.assert_array_equal(a, b)
        # Rendering with --denoise-photos denoises as they are written.
        os.remove(os.path.join(d, "gt", render.PHOTOS_DENOISED))
        render.render_all(d, spp=4, denoise_photos=True, **quiet)
        self.assertTrue(os.path.exists(os.path.join(d, "gt", render.PHOTOS_DENOISED)))
        for r, a, b in zip(ref, raw, read()):
            self.assertLess(err(b, r), 0.8 * err(a, r))

    def test_lambertian_plane_matches_closed_form(self):
        rho, L = 0.5, 10.0
        # A 1 m x 0.6 m light 1 m above a large plane, facing down.
        corner = np.array([-0.5, 1.0, -0.3])
        eu, ev = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 0.6])
        light = {"name": "l", "shape": "quad", "corner": corner.tolist(), "edge_u": eu.tolist(),
                 "edge_v": ev.tolist(), "radiance": [L] * 3}
        self.assertLess(np.cross(eu, ev)[1], 0)
        cam = {"width": 16, "height": 16, "fx": 40.0, "fy": 40.0, "cx": 8.0, "cy": 8.0,
               "position": [0.2, 0.5, 0.1], "look_at": [0.2, 0.0, 0.1], "up": [0.0, 0.0, 1.0]}
        plane = {"type": "rectangle", "to_world": mi.ScalarTransform4f.rotate([1, 0, 0], -90).scale([5, 5, 1]),
                 "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [rho] * 3}}}
        s = mi.load_dict({"type": "scene", "plane": plane, "light": render.light_shape(light, [L] * 3),
                          "sensor": render.sensor_dict(cam, "test", 4096)})
        out = {}
        for integ in ("path", "diffuse_first_bounce"):
            # 4096 spp: per-pixel noise ~0.5%; fixed seeds make the run deterministic.
            out[integ] = np.array(mi.render(s, integrator=mi.load_dict({"type": integ, "max_depth": 4}), spp=4096))
        verts = [corner, corner + eu, corner + eu + ev, corner + ev]
        R = render.camera_rotation(cam)
        c = np.array(cam["position"])
        for y in range(4, 12):
            for x in range(4, 12):
                dcam = np.array([(x + 0.5 - 8) / 40.0, (y + 0.5 - 8) / 40.0, 1.0])
                dw = R.T @ dcam
                p = c + dw * (-c[1] / dw[1])  # the plane y = 0
                # Lambert: E = L/2 * sum_i theta_i * (n . unit(a_i x b_i)), n = +Y.
                e = 0.0
                for i in range(4):
                    a = verts[i] - p
                    b = verts[(i + 1) % 4] - p
                    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
                    cr = np.cross(a, b)
                    e += math.acos(np.clip(a @ b, -1, 1)) * cr[1] / np.linalg.norm(cr)
                expect = rho / math.pi * abs(e) * L / 2
                for integ, img in out.items():
                    got = img[y, x].mean()
                    self.assertLess(abs(got - expect) / expect, 0.01,
                                    f"{integ} pixel ({x}, {y}): {got} vs {expect}")

    def test_a_scene_loads_its_shapes_in_one_order(self):
        # Mitsuba's scene optimization ordered the shapes (and the emitters a light sample picks
        # from) differently at every load: 8 loads gave 8 orders.
        cams = render.views_of(self.doc, "test")[:1]
        lit = {l["name"] for l in self.doc["lights"]}
        orders = {tuple(sh.id() for sh in render.mitsuba_scene(
            self.scene, self.doc, "test", lit, cams, 1).shapes()) for _ in range(8)}
        self.assertEqual(len(orders), 1, orders)
        lights = [i for i in next(iter(orders)) if i.startswith("light_")]
        self.assertEqual(lights, ["light_" + l["name"] for l in self.doc["lights"]])

    def test_two_runs_render_the_same_bytes(self):
        # Two processes, a room whose original lighting has two lights: the emitters' order once
        # followed Mitsuba's scene optimization, and the renders differed in every pixel.
        a = make_scene(self.tmp, seed=5, extra=1)
        b = shutil.copytree(a, os.path.join(self.tmp, "scene5b"))
        lights = json.load(open(os.path.join(a, "scene.json")))["synthetic"]["conditions"][0]
        self.assertGreaterEqual(len(lights["lights"]), 2)
        for d in (a, b):
            subprocess.run(["python3", os.path.join(ROOT, "tools/groundtruth/render.py"), d,
                            "--spp", "2", "--conditions", "original"], check=True,
                           capture_output=True)
        files = sorted(os.listdir(os.path.join(a, "gt", "original")))
        self.assertGreaterEqual(len(files), 4)
        for f in files:
            with open(os.path.join(a, "gt", "original", f), "rb") as x, \
                    open(os.path.join(b, "gt", "original", f), "rb") as y:
                self.assertEqual(x.read(), y.read(), f"{f} differs between two renders")

    def test_bad_description_is_a_clear_error(self):
        d = make_scene(self.tmp, seed=9, extra=1)
        p = os.path.join(d, "scene.json")
        with open(p) as f:
            doc = json.load(f)
        doc["synthetic"]["materials"]["wall"]["kind"] = "velvet"
        with open(p, "w") as f:
            json.dump(doc, f)
        r = subprocess.run(["python3", os.path.join(ROOT, "tools/groundtruth/render.py"), d, "--spp", "1"],
                           capture_output=True, text=True)
        self.assertEqual(r.returncode, 1)
        self.assertIn("scene.json", r.stderr)
        self.assertIn("velvet", r.stderr)
        self.assertNotIn("Traceback", r.stderr)


class MoveLight(unittest.TestCase):
    """--move-light: its argument and the geometry it moves (nothing rendered)."""

    def doc(self):
        quad = {"name": "lamp", "shape": "quad", "corner": [1.0, 2.0, 3.0],
                "edge_u": [0.5, 0.0, 0.0], "edge_v": [0.0, 0.0, 0.5], "radiance": [1.0] * 3}
        disk = {"name": "spot", "shape": "disk", "center": [0.0, 2.5, 0.0],
                "normal": [0.0, -1.0, 0.0], "radius": 0.1, "radiance": [1.0] * 3}
        return {"lights": [quad, disk]}

    def test_parses_name_and_offset(self):
        self.assertEqual(render.parse_move("lamp=0.5,0,-1"), ("lamp", [0.5, 0.0, -1.0]))
        for bad in ("lamp", "lamp=1,2", "=1,2,3", "lamp=1,x,3", "lamp=1,2,nan"):
            with self.assertRaises(render.argparse.ArgumentTypeError, msg=bad):
                render.parse_move(bad)

    def test_moves_the_corner_or_centre_and_keeps_the_rest(self):
        doc = self.doc()
        render.move_lights(doc, [("lamp", [0.5, 0.0, -1.0]), ("spot", [0.0, -0.5, 0.0]),
                                 ("lamp", [0.0, 1.0, 0.0])], "test")
        quad, disk = doc["lights"]
        self.assertEqual(quad["corner"], [1.5, 3.0, 2.0])
        self.assertEqual(quad["edge_u"], [0.5, 0.0, 0.0])
        self.assertEqual(disk["center"], [0.0, 2.0, 0.0])
        self.assertEqual(disk["normal"], [0.0, -1.0, 0.0])

    def test_an_unknown_light_is_named(self):
        with self.assertRaisesRegex(render.SceneError, "ghost.*lamp, spot"):
            render.move_lights(self.doc(), [("ghost", [0.0, 0.0, 1.0])], "test")


if __name__ == "__main__":
    unittest.main()
