"""The capture tool's own parts (no pycolmap needed): neighbours, normals, the trimmed mesh
file relit reads, its progress lines and the log that takes COLMAP's output, and its errors. Run: RELIT=target/debug/relit python -m unittest tools/capture/test_capture.py
"""
import io
import os
import subprocess
import sys
import tempfile
import time
import unittest
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import capture as C  # noqa: E402


class CaptureGeometry(unittest.TestCase):
    def test_knn_matches_brute_force(self):
        rng = np.random.default_rng(1)
        p = rng.random((300, 3))
        idx, dist = C.knn(p, 5, chunk=64)
        d = np.linalg.norm(p[:, None] - p[None], axis=-1)
        want = np.argsort(d, 1, kind="stable")[:, :5]
        np.testing.assert_array_equal(np.sort(idx, 1), np.sort(want, 1))
        self.assertTrue((idx[:, 0] == np.arange(300)).all(), "each point is its own nearest")
        np.testing.assert_allclose(dist, np.take_along_axis(d, idx, 1), atol=1e-6)

    def test_normals_face_the_cameras(self):
        rng = np.random.default_rng(2)
        p = np.c_[rng.random((500, 2)), 0.001 * rng.standard_normal(500)]
        down = np.tile([0.0, 0.0, -1.0], (500, 1))
        n = C.normals(p, down)
        self.assertGreater(float((n @ [0, 0, -1]).min()), 0.99)

    def test_poisson_depth_follows_the_points_spacing(self):
        room = np.array([[0.0, 0.0, 0.0], [4.0, 2.5, 3.0]])
        self.assertEqual(C.poisson_depth(room, 0.09), 8, "a room's points: the usual depth")
        # one object with far background points (AliceVision's buddha: 60 m against 0.09 m)
        far = np.array([[0.0, 0.0, 0.0], [49.4, 24.6, 60.2]])
        self.assertEqual(C.poisson_depth(far, 0.09), 12)
        cell = 1.1 * 30.0 / 2 ** C.poisson_depth(np.array([[0.0] * 3, [30.0] * 3]), 0.09)
        self.assertLessEqual(cell, 0.09 / 4, "cells within a quarter of the trim's reach")

    def test_written_mesh_is_read_by_relit(self):
        relit = os.environ.get("RELIT")
        if not relit:
            self.skipTest("RELIT (the relit binary) not set")
        v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [5, 5, 5]], float)
        f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "tet.ply"
            C.write_ply(path, v, f)
            self.assertFalse((Path(d) / "tet.tmp.ply").exists())
            out = subprocess.run([relit, "bench", "rays", "--mesh", str(path), "--rays", "256",
                                  "--repeats", "1"], capture_output=True, text=True)
            self.assertEqual(out.returncode, 0, out.stderr)
            # The unused vertex (5, 5, 5) is dropped: 4 vertices, 4 triangles.
            head = path.read_bytes().split(b"end_header\n")[0].decode()
            self.assertIn("element vertex 4", head)
            self.assertIn("element face 4", head)

    def test_exposure_tags_reach_the_undistorted_photos(self):
        from PIL import Image
        with tempfile.TemporaryDirectory() as d:
            orig, und = Path(d) / "orig", Path(d) / "und"
            orig.mkdir(), und.mkdir()
            exif = Image.Exif()
            exif[0x8769] = {0x829A: 0.01, 0x829D: 2.8, 0x8827: 200}  # Exif IFD: t, N, ISO
            Image.new("RGB", (8, 6), (90, 90, 90)).save(orig / "a.jpg", exif=exif)
            Image.new("RGB", (8, 6), (90, 90, 90)).save(orig / "b.jpg")
            for n in ("a.jpg", "b.jpg"):
                Image.new("RGB", (4, 3), (80, 80, 80)).save(und / n)
            C.carry_exif(orig, und)
            ifd = Image.open(und / "a.jpg").getexif().get_ifd(0x8769)
            self.assertAlmostEqual(float(ifd[0x829A]), 0.01)
            self.assertEqual(int(ifd[0x8827]), 200)
            self.assertEqual(Image.open(und / "a.jpg").size, (4, 3), "the undistorted pixels stay")
            self.assertFalse(Image.open(und / "b.jpg").info.get("exif"), "no EXIF made up")

    def test_colmaps_output_goes_to_the_log_and_the_stages_to_progress_lines(self):
        with tempfile.TemporaryDirectory() as d:
            log = Path(d) / "out.work" / "colmap.log"
            shown = io.StringIO()
            prog = C.Progress(shown, total=2, every=0.05)
            prog.start("features", "SIFT")
            before = [os.fstat(fd) for fd in (1, 2)]
            with C.quiet(log):
                # What the C++ library does: writes to the file descriptors, also from children.
                os.write(1, b"glog on stdout\n")
                os.write(2, b"glog on stderr\n")
                subprocess.run(["sh", "-c", "echo from a child; echo child error >&2"], check=True)
                time.sleep(0.2)
            after = [os.fstat(fd) for fd in (1, 2)]
            prog.done("11 photos")
            prog.skip("mapping", "cached")
            prog.close()
            for b, a in zip(before, after):
                self.assertEqual((b.st_dev, b.st_ino), (a.st_dev, a.st_ino), "stdout and stderr restored")
            text = log.read_text()
            for s in ["glog on stdout", "glog on stderr", "from a child", "child error"]:
                self.assertIn(s, text)
            lines = shown.getvalue().splitlines()
            self.assertEqual(lines[0], "capture [1/2] features: SIFT")
            self.assertRegex(lines[-2], r"^capture \[1/2\] features: 11 photos \(\d+ s\)$")
            self.assertEqual(lines[-1], "capture [2/2] mapping: cached")
            self.assertTrue(any("features: SIFT " in l and l.endswith(" s") for l in lines[1:-2]),
                            "a line while the stage runs")
            self.assertFalse(any("glog" in l or "child" in l for l in lines))
            # A second stage appends to the same log.
            with C.quiet(log):
                os.write(2, b"second stage\n")
            self.assertIn("glog on stdout", log.read_text())
            self.assertIn("second stage", log.read_text())

    def test_a_stage_stopped_by_an_error_ends_its_line(self):
        shown = io.StringIO()
        prog = C.Progress(shown, total=7)
        prog.start("mesh", "Poisson")
        prog.close()
        self.assertRegex(shown.getvalue().splitlines()[-1], r"^capture \[1/7\] mesh: stopped after \d+ s$")

    def test_too_few_photos_is_an_error_naming_the_folder(self):
        with tempfile.TemporaryDirectory() as d:
            (Path(d) / "a.jpg").write_bytes(b"")
            with self.assertRaises(C.CaptureError) as e:
                C.photos_in(Path(d))
            self.assertIn(d, str(e.exception))
            self.assertIn("at least 3", str(e.exception))
            self.assertEqual(C.main([d, str(Path(d) / "out")]), 1)


if __name__ == "__main__":
    unittest.main()
