#!/usr/bin/env python3
"""A folder of photos → a Relit scene (COLMAP model, undistorted photos, proxy mesh).

Runs on CPUs only: structure from motion with pycolmap (SIFT, exhaustive matching, incremental
mapping), undistortion to pinhole cameras, a dense step (dense.py: plane-sweep stereo per photo,
kept where neighbours agree, fused, with the room's large planes filled where stereo finds
nothing, then holes on one plane, then the room's box behind the rest), then a proxy surface by
screened Poisson (PyMeshLab) over the dense points, trimmed to where points are and decimated.
COLMAP's own dense stereo needs CUDA; this one runs on two cores.

    python tools/capture/capture.py PHOTOS OUT [--size 512] [--scale M] [--no-dense]
        [--holes planes|complete|backdrop] [--max-triangles N]

PHOTOS holds JPEG or PNG files (or an images/ folder of them). OUT gets images/, sparse/0/
(binary COLMAP, PINHOLE cameras) and mesh.ply, in metres with +Y up (the mean of the cameras' up
vectors). Without --scale, the median distance from a camera to the points it sees is set to
ROOM_DEPTH_M; give --scale (metres per SfM unit) when a real distance is known. --no-dense makes
the surface over the sparse points alone (the tool before the dense step). Work files go to
OUT.work/ and are reused when a stage's output is already there (the dense step's depth maps one
photo at a time). The terminal shows one progress line per stage; what COLMAP prints goes to
OUT.work/colmap.log, PyMeshLab's to OUT.work/meshlab.log. Then:
    relit scene check OUT; relit scene find-lights OUT; relit bake OUT
"""
import argparse
import contextlib
import json
import math
import os
import shutil
import sys
import threading
import time
from pathlib import Path

import numpy as np

PHOTO_SUFFIXES = {".jpg", ".jpeg", ".png"}
# What the tool runs on (measured with pycolmap 4.2.1, pymeshlab 2025.7).
REQUIREMENTS = ["pycolmap", "pymeshlab", "numpy", "pillow", "opencv-python-headless", "scipy"]
# Without a known distance: a camera in a room sees its points ~2 m away on average.
ROOM_DEPTH_M = 2.0
# Points kept for the surface: seen by at least this many photos, reprojecting within this.
MIN_TRACK = 3
MAX_REPROJ_PX = 2.0
# The dense surface is trimmed this many fusion voxels from the nearest dense point.
DENSE_REACH = 6.0
# The dense proxy's triangle budget: beyond it the bake slows and the view is no better
# (docs/captures.md gives the measurement).
MAX_TRIANGLES = 500_000


class CaptureError(Exception):
    pass


# The stages as the progress lines number them.
STAGES = ["photos", "features", "matching", "mapping", "world", "undistort", "dense", "mesh"]


class Progress:
    """One line per stage, `capture [3/7] mapping: …`. On a terminal the running stage's line
    shows its elapsed seconds, rewritten in place; elsewhere (a log file, CI) a line when a stage
    starts, every `every` seconds while it runs, and when it ends. Writes to a copy of the
    standard output taken when it is made, so it still reaches the terminal while
    `quiet` sends the process's own output to a log."""

    def __init__(self, stream=None, total=len(STAGES), every=30.0):
        self.own = stream is None
        if stream is None:
            try:
                stream = os.fdopen(os.dup(sys.stdout.fileno()), "w", buffering=1)
            except (AttributeError, OSError, ValueError):
                stream, self.own = sys.stdout, False
        self.out, self.total, self.every = stream, total, every
        self.tty = bool(getattr(stream, "isatty", lambda: False)())
        self.n, self.stage, self.what, self.t0 = 0, None, "", 0.0
        self._stop, self._ticker, self._lock = threading.Event(), None, threading.Lock()

    def _line(self, text, end):
        with self._lock:
            if self.tty:
                self.out.write("\r" + text + "\x1b[K" + end)
            else:
                self.out.write(text + end)
            self.out.flush()

    def _head(self):
        return f"capture [{self.n}/{self.total}] {self.stage}"

    def start(self, stage, what):
        self.n += 1
        self.stage, self.what, self.t0 = stage, what, time.time()
        self._line(f"{self._head()}: {what}", "" if self.tty else "\n")
        self._stop.clear()
        self._ticker = threading.Thread(target=self._tick, daemon=True)
        self._ticker.start()

    def _tick(self):
        step = 1.0 if self.tty else self.every
        while not self._stop.wait(step):
            took = time.time() - self.t0
            self._line(f"{self._head()}: {self.what} {took:.0f} s", "" if self.tty else "\n")

    def note(self, what):
        """What the running stage is doing now (shown with the next elapsed-time line)."""
        self.what = what

    def done(self, msg):
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join()
            self._ticker = None
        self._line(f"{self._head()}: {msg} ({time.time() - self.t0:.0f} s)", "\n")

    def close(self):
        """Ends a stage left running (an error stopped it) on its own line."""
        if self._ticker is not None:
            self._stop.set()
            self._ticker.join()
            self._ticker = None
            self._line(f"{self._head()}: stopped after {time.time() - self.t0:.0f} s", "\n")
        if self.own:
            self.out.close()
            self.own = False

    def skip(self, stage, msg):
        """A stage whose output is already in OUT.work/: one line."""
        self.n += 1
        self.stage, self.t0 = stage, time.time()
        self._line(f"{self._head()}: {msg}", "\n")


@contextlib.contextmanager
def quiet(log: Path):
    """Sends everything the process writes to its standard output and error (COLMAP's glog
    lines and progress, PyMeshLab's messages, a child's output) to `log`, appended, and
    restores both afterwards. Works on the file descriptors, where the C++ libraries write."""
    log.parent.mkdir(parents=True, exist_ok=True)
    for s in (sys.stdout, sys.stderr):
        s.flush()
    saved = [os.dup(1), os.dup(2)]
    with open(log, "ab") as fh:
        fh.write(f"--- {time.strftime('%Y-%m-%d %H:%M:%S')}\n".encode())
        fh.flush()
        try:
            os.dup2(fh.fileno(), 1)
            os.dup2(fh.fileno(), 2)
            yield
        finally:
            for s in (sys.stdout, sys.stderr):
                s.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)


def photos_in(folder: Path):
    if not folder.is_dir():
        raise CaptureError(f"{folder}: not a directory of photos")
    src = folder / "images" if (folder / "images").is_dir() else folder
    files = sorted(p for p in src.iterdir() if p.suffix.lower() in PHOTO_SUFFIXES and p.is_file())
    if len(files) < 3:
        raise CaptureError(f"{src}: {len(files)} JPEG/PNG photos; structure from motion needs at least 3")
    return files


def resized_copies(files, dst: Path, long_side: int):
    """The photos at `long_side` pixels on their longer side (EXIF kept: COLMAP reads the focal
    length from it), as the input of SfM."""
    from PIL import Image, ImageOps  # noqa: F401 (ImageOps: transpose by EXIF orientation)

    dst.mkdir(parents=True, exist_ok=True)
    for f in files:
        out = dst / (f.stem + ".jpg")
        if out.exists():
            continue
        try:
            im = Image.open(f)
            im.load()
        except Exception as e:
            raise CaptureError(f"{f}: not a readable image ({e})")
        exif = im.info.get("exif", b"")
        s = long_side / max(im.size)
        if s < 1:
            im = im.resize((round(im.size[0] * s), round(im.size[1] * s)), Image.LANCZOS)
        tmp = out.with_suffix(".tmp.jpg")
        im.convert("RGB").save(tmp, quality=95, exif=exif)
        os.replace(tmp, out)


def sfm(images: Path, work: Path, prog: Progress):
    """SIFT, exhaustive matching and incremental mapping; the largest model. COLMAP's own
    output goes to work/colmap.log."""
    import pycolmap

    db, sparse, log = work / "database.db", work / "sparse", work / "colmap.log"
    if (sparse / "0" / "images.bin").exists():
        rec = pycolmap.Reconstruction(str(sparse / "0"))
        for stage in ("features", "matching"):
            prog.skip(stage, f"cached in {work}")
        prog.skip("mapping", f"cached: {rec.num_reg_images()} photos registered")
        return rec
    for p in [db, sparse]:
        shutil.rmtree(p, ignore_errors=True) if p.is_dir() else p.unlink(missing_ok=True)
    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = "OPENCV"
    prog.start("features", f"SIFT (COLMAP's log: {log})")
    with quiet(log):
        pycolmap.extract_features(db, images, camera_mode=pycolmap.CameraMode.SINGLE, reader_options=reader)
    prog.done("SIFT features extracted")
    prog.start("matching", "exhaustive")
    with quiet(log):
        pycolmap.match_exhaustive(db)
    prog.done("photos matched")
    prog.start("mapping", "incremental")
    with quiet(log):
        maps = pycolmap.incremental_mapping(db, images, sparse)
    if not maps:
        raise CaptureError(f"{images}: structure from motion registered no photos (too little overlap or texture; "
                           f"COLMAP's log: {log})")
    best = max(maps.values(), key=lambda r: r.num_reg_images())
    # Keep the largest model as sparse/0 whatever number COLMAP gave it.
    final = work / "sparse-best"
    shutil.rmtree(final, ignore_errors=True)
    final.mkdir()
    best.write(final)
    shutil.rmtree(sparse)
    (sparse).mkdir()
    os.replace(final, sparse / "0")
    prog.done(f"{best.num_reg_images()} photos registered, {best.num_points3D()} points")
    return best


def val(x):
    """A pycolmap attribute that some versions make a method and others a property."""
    return x() if callable(x) else x


def posed(rec):
    return [img for img in rec.images.values() if val(img.has_pose)]


def to_world(rec, scale):
    """Metres and +Y up: a similarity taking the cameras' mean up vector to +Y and the median
    camera-to-point depth to ROOM_DEPTH_M unless `scale` (metres per SfM unit) is given."""
    import pycolmap

    ups, depths = [], []
    for img in posed(rec):
        w2c = val(img.cam_from_world).matrix()
        r = w2c[:, :3]
        ups.append(-r[1])  # COLMAP camera y points down; its world up is −row 1 of R
        pts = [rec.points3D[p.point3D_id].xyz for p in img.points2D if p.has_point3D()]
        if pts:
            z = (np.asarray(pts) @ r.T + w2c[:, 3])[:, 2]
            depths.append(np.median(z))
    up = np.mean(ups, axis=0)
    up /= np.linalg.norm(up)
    if scale is None:
        scale = ROOM_DEPTH_M / float(np.median(depths))
    rot = rotation_to_y(up)
    centre = np.median([img.projection_center() for img in posed(rec)], axis=0)
    t = -scale * rot @ centre
    sim = pycolmap.Sim3d(scale, pycolmap.Rotation3d(rot), t)
    rec.transform(sim)
    return scale


def rotation_to_y(up):
    """The rotation taking the unit vector `up` to +Y (Rodrigues about up × Y)."""
    y = np.array([0.0, 1.0, 0.0])
    v, c = np.cross(up, y), float(up @ y)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1 + c) if c > -0.999 else np.diag([1.0, -1.0, -1.0])


def level(und: Path, res):
    """Turns the undistorted model and the dense points so that the room's up (the floor's or a
    table's normal, found by the dense step) is +Y: the cameras' mean up, used until now, is
    off by their mean tilt. Returns the angle turned (degrees)."""
    import pycolmap

    angle = math.degrees(math.acos(float(np.clip(res.up[1], -1, 1))))
    if angle < 0.5:
        return angle
    rot = rotation_to_y(res.up)
    rec = pycolmap.Reconstruction(str(und / "sparse"))
    rec.transform(pycolmap.Sim3d(1.0, pycolmap.Rotation3d(rot), np.zeros(3)))
    rec.write(und / "sparse")
    res.points, res.normals, res.up = res.points @ rot.T, res.normals @ rot.T, rot @ res.up
    return angle


def undistort(rec_dir: Path, images: Path, out: Path, long_side: int, log: Path):
    """Pinhole photos at `long_side` px; COLMAP's own output goes to `log`."""
    import pycolmap

    opts = pycolmap.UndistortCameraOptions()
    opts.max_image_size = long_side
    tmp = out.parent / (out.name + ".undist")
    shutil.rmtree(tmp, ignore_errors=True)
    with quiet(log):
        pycolmap.undistort_images(tmp, rec_dir, images, undistort_options=opts)
    return tmp


def carry_exif(originals: Path, photos: Path):
    """Puts each original's EXIF (exposure time, f-number, ISO: what relit puts the photos on one
    radiance scale with) back into its undistorted photo, which the undistorter writes without
    it. A photo is saved again only when its original has EXIF."""
    from PIL import Image

    for p in sorted(photos.iterdir()):
        src = originals / p.name
        if not src.exists():
            continue
        exif = Image.open(src).info.get("exif", b"")
        if not exif:
            continue
        im = Image.open(p)
        im.load()
        tmp = p.with_suffix(".tmp" + p.suffix)
        im.save(tmp, quality=95, exif=exif)
        os.replace(tmp, p)


def good_points(rec):
    """Points seen by MIN_TRACK photos within MAX_REPROJ_PX, with the mean direction towards the
    cameras that saw them (which way the surface faces)."""
    xyz, towards = [], []
    centres = {img.image_id: img.projection_center() for img in posed(rec)}
    for p in rec.points3D.values():
        ids = [e.image_id for e in p.track.elements]
        if len(ids) < MIN_TRACK or p.error > MAX_REPROJ_PX:
            continue
        d = np.mean([centres[i] - p.xyz for i in ids], axis=0)
        xyz.append(p.xyz)
        towards.append(d / (np.linalg.norm(d) + 1e-12))
    if len(xyz) < 100:
        raise CaptureError(f"structure from motion kept {len(xyz)} well-seen points; a surface needs at least 100")
    return np.asarray(xyz), np.asarray(towards)


def knn(points, k, chunk=2048):
    """Indices of each point's k nearest points (itself first) and the distances."""
    idx, dist = [], []
    sq = (points**2).sum(1)
    for s in range(0, len(points), chunk):
        q = points[s : s + chunk]
        d2 = sq[None, :] - 2 * q @ points.T + (q**2).sum(1)[:, None]
        part = np.argpartition(d2, k, axis=1)[:, :k]
        order = np.take_along_axis(d2, part, 1).argsort(1)
        part = np.take_along_axis(part, order, 1)
        idx.append(part)
        dist.append(np.sqrt(np.maximum(np.take_along_axis(d2, part, 1), 0)))
    return np.concatenate(idx), np.concatenate(dist)


def normals(points, towards, k=16):
    """Normals by principal axes of each point's neighbourhood, turned to face its cameras (the
    dense step's, over a k-d tree)."""
    import dense

    return dense.normals(points, towards, k)


def poisson_depth(points, reach):
    """The coarsest octree depth (8 to 12) whose cells are at most a quarter of `reach`: Poisson's
    grid spans every point, and a capture of one object with far background points (60 m of
    extent against a 0.09 m reach on AliceVision's buddha) otherwise leaves the surface's
    vertices too far apart for the trim to keep any of it (341 triangles at depth 8, 42 054 at 12)."""
    extent = 1.1 * float((points.max(0) - points.min(0)).max())  # the solver's default scale
    need = math.ceil(math.log2(max(extent / (reach / 4), 1.0)))
    return min(max(need, 8), 12)


def surface(points, nrm, depth, out: Path, log: Path):
    """Screened Poisson over the oriented points (depth None: `poisson_depth`), trimmed where no
    point is near; PyMeshLab's own output goes to `log`. Returns what the progress line says."""
    import pymeshlab

    _, spacing = knn(points, 2)
    reach = 8.0 * float(np.median(spacing[:, 1]))
    if depth is None:
        depth = poisson_depth(points, reach)
    with quiet(log):
        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=points, v_normals_matrix=nrm))
        ms.generate_surface_reconstruction_screened_poisson(depth=depth, preclean=True)
    m = ms.current_mesh()
    v, f = m.vertex_matrix(), m.face_matrix()
    near = np.zeros(len(v), bool)
    for s in range(0, len(v), 4096):
        q = v[s : s + 4096]
        d2 = (q**2).sum(1)[:, None] - 2 * q @ points.T + (points**2).sum(1)[None, :]
        near[s : s + 4096] = d2.min(1) <= reach * reach
    keep = near[f].all(1)
    if keep.sum() < 100:
        raise CaptureError(f"the Poisson surface (depth {depth}) keeps {keep.sum()} faces near the points; "
                           f"try another --poisson-depth (a deeper grid follows the points more closely)")
    write_ply(out, v, f[keep])
    return f"{keep.sum()} triangles within {reach:.3f} m of a point (Poisson depth {depth})"


def dense_views(und: Path):
    """The undistorted photos as the dense step's views (pinhole cameras, grey 0–1)."""
    import pycolmap
    from PIL import Image

    import dense

    rec = pycolmap.Reconstruction(str(und / "sparse"))
    views = []
    for img in sorted(posed(rec), key=lambda i: i.name):
        cam = rec.cameras[img.camera_id]
        fx, fy, cx, cy = cam.params[:4]
        K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
        w2c = val(img.cam_from_world).matrix()
        grey = np.asarray(Image.open(und / "images" / img.name).convert("L"), np.float32) / 255.0
        views.append(dense.View(Path(img.name).stem, K, w2c[:, :3].copy(), w2c[:, 3].copy(), grey))
    return rec, views


def dense_points(und: Path, cache: Path, prog: Progress, holes="backdrop"):
    """The dense step (tools/capture/dense.py) over the undistorted photos: fused oriented points
    and what the progress line says."""
    import dense

    rec, views = dense_views(und)
    xyz, _ = good_points(rec)
    t0 = time.time()
    try:
        res = dense.run(views, xyz, cache=cache, log=lambda s: prog.note(s), holes=holes)
    except dense.DenseError as e:
        raise CaptureError(f"dense step: {e}")
    what = {"planes": f"{res.planes} planes", "complete": "holes on one plane", "backdrop": "the room's box"}
    filled = "".join(f"{res.filled_points[k]} from {what[k]} ({100 * res.filled_share[k]:.0f} % of pixels), "
                     for k in res.filled_points)
    msg = (f"{res.stereo_points} points from stereo ({100 * res.kept_share:.0f} % of pixels), {filled}"
           f"voxel {res.voxel * 1000:.1f} mm, {time.time() - t0:.0f} s")
    return res, msg


def dense_surface(res, depth, out: Path, log: Path, max_triangles=MAX_TRIANGLES):
    """Screened Poisson over the dense points, trimmed to DENSE_REACH voxels from a point,
    decimated to `max_triangles`."""
    import pymeshlab
    from scipy.spatial import cKDTree

    reach = DENSE_REACH * res.voxel
    if depth is None:
        depth = poisson_depth(res.points, reach)
    with quiet(log):
        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=res.points, v_normals_matrix=res.normals))
        ms.generate_surface_reconstruction_screened_poisson(depth=depth, preclean=True)
    m = ms.current_mesh()
    v, f = m.vertex_matrix(), m.face_matrix()
    near = cKDTree(res.points).query(v, distance_upper_bound=reach)[0] <= reach
    keep = near[f].all(1)
    if keep.sum() < 100:
        raise CaptureError(f"the Poisson surface (depth {depth}) keeps {keep.sum()} faces near the dense points")
    v, f = decimated(v, f[keep], max_triangles, log)
    write_ply(out, v, f)
    less = f", decimated to {len(f)}" if len(f) < keep.sum() else ""
    return f"{keep.sum()} triangles within {reach:.3f} m of a point (Poisson depth {depth}){less}"


def decimated(v, f, target, log: Path):
    """The mesh with at most `target` triangles (quadric edge collapse; planes, most of a filled
    room, lose nothing): the bake traces every photo's pixels against it, and its time grows with
    the triangles (docs/captures.md)."""
    import pymeshlab

    if target is None or len(f) <= target:
        return v, f
    with quiet(log):
        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=v, face_matrix=f))
        ms.meshing_decimation_quadric_edge_collapse(targetfacenum=int(target), preservenormal=True,
                                                    preservetopology=True, planarquadric=True)
    m = ms.current_mesh()
    return m.vertex_matrix(), m.face_matrix()


def write_ply(path: Path, v, f):
    """Binary little-endian PLY, written to a temporary file and renamed."""
    used = np.unique(f)
    remap = np.full(len(v), -1, np.int64)
    remap[used] = np.arange(len(used))
    v, f = v[used].astype("<f4"), remap[f].astype("<i4")
    head = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(v)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    faces = np.zeros(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    faces["n"], faces["i"] = 3, f
    tmp = path.with_suffix(".tmp.ply")
    with open(tmp, "wb") as fh:
        fh.write(head.encode())
        fh.write(v.tobytes())
        fh.write(faces.tobytes())
    os.replace(tmp, path)


def main(argv=None):
    import dense

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("photos", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--size", type=int, default=512, help="longer side of the scene's photos (px)")
    ap.add_argument("--sfm-size", type=int, default=1024, help="longer side the SfM sees (px)")
    ap.add_argument("--scale", type=float, help="metres per SfM unit (default: median depth 2 m)")
    ap.add_argument("--poisson-depth", type=int,
                    help="octree depth of the surface (default: the coarsest of 8-12 fine enough for the points' spacing)")
    ap.add_argument("--no-dense", dest="dense", action="store_false",
                    help="the surface over the sparse points only (no dense step)")
    ap.add_argument("--max-triangles", type=int, default=MAX_TRIANGLES,
                    help=f"the dense surface's triangle budget (default {MAX_TRIANGLES}; decimated beyond it)")
    ap.add_argument("--holes", choices=dense.HOLES, default="backdrop",
                    help="what fills the pixels stereo keeps no depth for: the room's planes; then also the "
                         "holes whose edge lies on one plane; then also the room's box (default)")
    a = ap.parse_args(argv)
    if a.max_triangles < 1000:
        ap.error(f"--max-triangles {a.max_triangles}: expected at least 1000 (a surface needs triangles)")
    try:
        run(a)
    except CaptureError as e:
        print(f"capture: error: {e}", file=sys.stderr)
        return 1
    return 0


def run(a):
    if a.out.exists() and any(a.out.iterdir()):
        raise CaptureError(f"{a.out}: exists and is not empty; give a new folder")
    files = photos_in(a.photos)
    try:
        import pycolmap
        import pymeshlab  # noqa: F401
        from PIL import Image  # noqa: F401
        if a.dense:
            import cv2  # noqa: F401
            import scipy  # noqa: F401
    except ImportError as e:
        raise CaptureError(f"{e.name} is not installed: pip install {' '.join(REQUIREMENTS)}")
    work = a.out.parent / (a.out.name + ".work")
    t0 = time.time()
    prog = Progress()
    try:
        prog.start("photos", f"{len(files)} photos to {a.sfm_size} px")
        resized_copies(files, work / "images", a.sfm_size)
        prog.done(f"{len(files)} photos at {a.sfm_size} px")
        rec = sfm(work / "images", work, prog)
        if rec.num_reg_images() < 3:
            raise CaptureError(f"{a.photos}: only {rec.num_reg_images()} photos registered")
        prog.start("world", "metres, +Y up")
        scale = to_world(rec, a.scale)
        world = work / "world"
        shutil.rmtree(world, ignore_errors=True)
        world.mkdir()
        rec.write(world)
        prog.done(f"{scale:.4g} m per SfM unit, +Y up")
        prog.start("undistort", f"pinhole photos at {a.size} px")
        und = undistort(world, work / "images", a.out, a.size, work / "colmap.log")
        carry_exif(work / "images", und / "images")
        prog.done(f"pinhole photos at {a.size} px")
        res, turned = None, 0.0
        if a.dense:
            prog.start("dense", f"plane-sweep stereo, depth maps cached in {work / 'dense'}")
            res, msg = dense_points(und, work / "dense" / f"{a.size}px", prog, a.holes)
            turned = level(und, res)
            prog.done(msg + f"; +Y turned {turned:.1f}° to the room's up")
        else:
            prog.skip("dense", "skipped (--no-dense)")
        stage = a.out.parent / (a.out.name + ".tmp")
        shutil.rmtree(stage, ignore_errors=True)
        (stage / "sparse").mkdir(parents=True)
        if res is None:
            prog.start("mesh", "screened Poisson over the sparse points")
            pts, towards = good_points(pycolmap.Reconstruction(str(und / "sparse")))
            msg = surface(pts, normals(pts, towards), a.poisson_depth, stage / "mesh.ply", work / "meshlab.log")
        else:
            prog.start("mesh", "screened Poisson over the dense points")
            msg = dense_surface(res, a.poisson_depth, stage / "mesh.ply", work / "meshlab.log", a.max_triangles)
        os.replace(und / "images", stage / "images")
        os.replace(und / "sparse", stage / "sparse" / "0")
        prog.done(msg)
        (stage / "capture.json").write_text(
            json.dumps(
                {
                    "photos": str(a.photos),
                    "registered": rec.num_reg_images(),
                    "of": len(files),
                    "metres_per_sfm_unit": scale,
                    "scale_given": a.scale is not None,
                    "size": a.size,
                    "dense": a.dense,
                    "holes": a.holes if a.dense else None,
                    "up_turned_deg": round(turned, 2),
                },
                indent=1,
            )
        )
        shutil.rmtree(und, ignore_errors=True)
        if a.out.exists():
            a.out.rmdir()
        os.replace(stage, a.out)
        print(f"capture: {a.out} in {time.time() - t0:.0f} s (logs in {work}); next `relit scene check {a.out}`",
              flush=True)
    finally:
        prog.close()


if __name__ == "__main__":
    sys.exit(main())
