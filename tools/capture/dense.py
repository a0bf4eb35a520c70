"""The dense step of `capture.py`: a depth map per photo by plane-sweep stereo, kept where its
neighbours agree, fused into oriented points, with the large planes that stereo cannot see
(textureless walls, floors, ceilings, table tops) filled from planes fitted to those points,
then holes on one plane, then the room's box behind what is left.

Runs on CPUs with OpenCV and NumPy (and SciPy's k-d tree). Why not the engine's compute shaders:
the sweep is a few hundred image warps and box filters per photo, which OpenCV runs vectorised on
both cores (seconds a photo at 512 px, measured in docs/captures.md), while lavapipe would compile
and run the same as 8-lane fp32 code on the same two cores; a GPU would be faster, but the machine
this step exists for has none.

1. **Neighbours** (`neighbours`): for each photo, the photos that see its centre point at a
   triangulation angle near STEREO_ANGLE, facing the same way.
2. **Plane sweep** (`sweep`): fronto-parallel planes uniform in inverse depth over the range of
   the sparse points the photo sees; each neighbour warped onto each plane (a homography), its
   normalized cross-correlation (NCC) with the photo over NCC_WINDOW² pixels; a plane's score is
   the mean of the best NCC_BEST neighbours (an occluded neighbour does not veto). The best plane,
   refined by a parabola; kept where its score reaches NCC_MIN and the photo has texture there.
3. **Consistency** (`consistent`): a depth is kept when it agrees with at least MIN_AGREE
   neighbours' depth maps (reprojection within AGREE_PX, depth within AGREE_DEPTH).
4. **Fusion** (`fuse`): the kept points averaged in voxels of VOXEL_PX pixels' footprint at the
   median depth, normals by principal axes of each voxel's neighbours, turned towards the photos
   that saw it.
5. **Planes** (`fit_planes`, `fill`): planes found by RANSAC among the fused points, each
   bounded by the room's box when it bounds the room (walls, floor, ceiling), else by the hull of
   its largest connected patch of points (a table top); a photo's pixel with no kept depth whose
   ray meets such a plane first becomes a point of that plane, unless a neighbour sees a surface
   behind it.
6. **Completion** (`complete`): a hole left whose edge lies on one plane (inverse depth affine
   in the pixel coordinates) takes it, with the same free-space check.
7. **Backdrop** (`backdrop`): what is still without depth, on the room's box where the ray
   leaves it (the far content a capture does not resolve).

Each photo's depth map is cached in WORK/dense/depth/NAME.npz, so a stopped run resumes.
"""
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# Constants of the dense step (docs/captures.md gives the reasons for each).
NEIGHBOURS = 4  # photos compared with each photo
NCC_BEST = 2  # a plane's score: the mean of this many best neighbours
STEREO_ANGLE = 15.0  # degrees: the triangulation angle neighbours are chosen around
PLANES_PER_PX = 1.0  # depth hypotheses per pixel of disparity over the depth range
PLANES_MIN, PLANES_MAX = 32, 192
NCC_WINDOW = 7  # pixels
NCC_MIN = 0.5  # a depth is kept when its score reaches this
TEXTURE_MIN = 0.01  # grey-level standard deviation in the window (0–1) below which NCC is noise
MIN_AGREE = 2  # neighbours whose depth maps must agree
AGREE_PX = 1.0
AGREE_DEPTH = 0.02  # relative
ISOLATED_VOXELS, ISOLATED_MIN = 3.0, 8  # a point needs this many others this near
VOXEL_PX = 2.0  # fusion voxel: this many pixels' footprint at the median depth
PLANE_MIN_SHARE = 0.02  # a plane holds at least this share of the fused points
PLANE_MAX = 12
PLANE_ITERS = 400
PLANE_NORMAL_COS = 0.8  # a plane's point has its own normal within ~37° of the plane's
VERTICAL_CONE_DEG = 30.0  # the room's up is sought this near the cameras' mean up
PLANE_AXIS_DEG = 10.0  # a plane's normal is within this of +Y or of the horizontal
PLANE_BOUND = 0.97  # share of the points on the photos' side of a plane that bounds the room
PATCH_CELL = 4.0  # voxels: the cells a plane that bounds nothing is joined over
BOX_MARGIN = 0.05  # the room's box: the fused points' bounds widened by this share
BOX_PERCENTILE = 1.0  # the bounds leave out this percentage of outlying points on each side
FREE_MARGIN = 0.05  # a filled point this much nearer than what a neighbour sees is dropped
COMPLETE_CELL = 4  # pixels: the grid the holes' inverse depth is fitted on
PLANAR_TOL = 0.01  # a hole's edge fits a plane within this RMS share of its inverse depth
HOLES = ("planes", "complete", "backdrop")  # what fills the pixels stereo keeps no depth for


OUTSIDE = -1e4  # a warped sample outside the neighbour's photo (grey levels are 0–1)


class DenseError(Exception):
    pass


@dataclass
class View:
    """One undistorted photo: K (3×3, pixel centres at +0.5), world-to-camera R, t, grey 0–1."""

    name: str
    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    grey: np.ndarray

    @property
    def centre(self):
        return -self.R.T @ self.t

    @property
    def axis(self):
        return self.R[2]

    def project(self, X):
        """World points (N×3) → pixel coordinates (N×2, OpenCV's: centres at integers), depth."""
        c = X @ self.R.T + self.t
        z = c[:, 2]
        uv = (c[:, :2] / np.where(np.abs(z) < 1e-12, 1e-12, z)[:, None]) @ self.K[:2, :2].T + self.K[:2, 2]
        return uv - 0.5, z

    def sample(self, X, depth):
        """World points X projected into this photo: the nearest pixel (ui, vi), the points'
        depth z here, and this photo's `depth` map at that pixel (0 outside the photo)."""
        uv, z = self.project(X)
        h, w = depth.shape
        ui, vi = np.round(uv[:, 0]).astype(int), np.round(uv[:, 1]).astype(int)
        inside = (z > 0) & (ui >= 0) & (ui < w) & (vi >= 0) & (vi < h)
        d = np.zeros(len(X), np.float32)
        d[inside] = depth[vi[inside], ui[inside]]
        return ui, vi, z, d

    def rays(self):
        """World directions through every pixel centre (H×W×3, not normalized: z = 1 in camera)."""
        h, w = self.grey.shape
        u, v = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
        x = (u - self.K[0, 2]) / self.K[0, 0]
        y = (v - self.K[1, 2]) / self.K[1, 1]
        cam = np.stack([x, y, np.ones_like(x)], -1)
        return cam @ self.R  # R^T applied to each row

    def points(self, depth):
        return self.centre + self.rays() * depth[..., None]


def depth_range(view, points):
    """Near and far depth of the sparse points this photo sees, widened by a quarter."""
    uv, z = view.project(points)
    h, w = view.grey.shape
    inside = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
    if inside.sum() < 10:
        return None
    lo, hi = np.percentile(z[inside], [1, 99])
    return 0.75 * lo, 1.25 * hi


def _sees(view, points):
    uv, z = view.project(points)
    h, w = view.grey.shape
    return (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)


def neighbours(views, points, k=NEIGHBOURS):
    """For each photo, the k others that score highest on the share of its sparse points they
    also see times how near the median triangulation angle over those points is to STEREO_ANGLE
    (a Gaussian in the log of the ratio, so 7.5° and 30° score alike)."""
    seen = [_sees(v, points) for v in views]
    out = []
    for i, a in enumerate(views):
        mine = np.nonzero(seen[i])[0]
        scored = []
        for j, b in enumerate(views):
            if j == i or len(mine) < 10:
                continue
            both = mine[seen[j][mine]]
            share = len(both) / len(mine)
            if share < 0.2 or len(both) < 10:
                continue
            ra, rb = a.centre - points[both], b.centre - points[both]
            cos = (ra * rb).sum(1) / (np.linalg.norm(ra, axis=1) * np.linalg.norm(rb, axis=1))
            ang = float(np.degrees(np.arccos(np.clip(np.median(cos), -1, 1))))
            if ang < 1.0:
                continue
            scored.append((-share * math.exp(-(math.log(ang / STEREO_ANGLE) ** 2)), j))
        out.append([j for _, j in sorted(scored)[:k]])
    return out


def _cv_K(K):
    """K for OpenCV pixel indices (centres at integers)."""
    K = K.copy()
    K[0, 2] -= 0.5
    K[1, 2] -= 0.5
    return K


def _box(img, win):
    import cv2

    return cv2.boxFilter(img, -1, (win, win), borderType=cv2.BORDER_REFLECT)


def plane_count(ref, nbrs, near, far):
    """Enough planes that neighbouring ones differ by ~1/PLANES_PER_PX pixels of disparity in the
    widest-baseline neighbour, within PLANES_MIN..PLANES_MAX."""
    base = max(float(np.linalg.norm(nb.centre - ref.centre)) for nb in nbrs)
    span = ref.K[0, 0] * base * (1.0 / near - 1.0 / far)
    return int(np.clip(round(PLANES_PER_PX * span), PLANES_MIN, PLANES_MAX))


def sweep(ref, nbrs, near, far, planes=None, win=NCC_WINDOW):
    """The plane sweep for one photo: depth (H×W, 0 where not kept) and its score."""
    import cv2

    h, w = ref.grey.shape
    r = ref.grey.astype(np.float32)
    mu_r = _box(r, win)
    var_r = np.maximum(_box(r * r, win) - mu_r * mu_r, 0)
    textured = var_r > TEXTURE_MIN**2
    planes = planes or plane_count(ref, nbrs, near, far)
    inv = np.linspace(1.0 / near, 1.0 / far, planes)
    Kr_inv = np.linalg.inv(_cv_K(ref.K))
    best_n = min(NCC_BEST, len(nbrs))
    scores = np.empty((planes, h, w), np.float16)
    for pi, q in enumerate(inv):
        per = np.empty((len(nbrs), h, w), np.float32)
        for ni, nb in enumerate(nbrs):
            R_rel = nb.R @ ref.R.T
            t_rel = nb.t - R_rel @ ref.t
            H = _cv_K(nb.K) @ (R_rel + np.outer(t_rel, [0.0, 0.0, q])) @ Kr_inv
            # Outside the neighbour's frame a sample is OUTSIDE, so any window touching it has a
            # negative mean (a box filter's running sums cannot carry NaN).
            warped = cv2.warpPerspective(nb.grey, H, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                         borderMode=cv2.BORDER_CONSTANT, borderValue=OUTSIDE)
            mu_w = _box(warped, win)
            var_w = _box(warped * warped, win) - mu_w * mu_w
            cov = _box(r * warped, win) - mu_r * mu_w
            ncc = cov / np.sqrt(np.maximum(var_r * var_w, 1e-12))
            ncc[~(var_w > TEXTURE_MIN**2 * 0.25) | (mu_w < 0)] = -1.0
            per[ni] = ncc
        if best_n < len(nbrs):
            per = -np.partition(-per, best_n - 1, axis=0)[:best_n]
        scores[pi] = per.mean(0)
    best = scores.argmax(0)
    s0 = np.take_along_axis(scores, best[None], 0)[0].astype(np.float32)
    lo = np.take_along_axis(scores, np.maximum(best - 1, 0)[None], 0)[0].astype(np.float32)
    hi = np.take_along_axis(scores, np.minimum(best + 1, planes - 1)[None], 0)[0].astype(np.float32)
    curv = lo - 2 * s0 + hi
    off = np.where(curv < -1e-6, np.clip(0.5 * (lo - hi) / np.where(curv < -1e-6, curv, -1), -0.5, 0.5), 0)
    q = np.interp(best + off, np.arange(planes), inv)
    depth = (1.0 / q).astype(np.float32)
    keep = textured & (s0 >= NCC_MIN) & (best > 0) & (best < planes - 1)
    depth[~keep] = 0
    return depth, s0


def consistent(views, depths, nbrs):
    """Each photo's depth map, kept where at least MIN_AGREE of its neighbours' maps agree."""
    out = []
    for i, v in enumerate(views):
        d = depths[i]
        ok = d > 0
        if not ok.any() or not nbrs[i]:
            out.append(np.zeros_like(d))
            continue
        X = v.points(d)[ok]
        agree = np.zeros(len(X), np.int32)
        for j in nbrs[i]:
            nb = views[j]
            ui, vi, _, dd = nb.sample(X, depths[j])
            has = dd > 0
            # the neighbour's point at that pixel, back into this photo
            Xn = nb.centre + nb.rays()[vi[has], ui[has]] * dd[has, None]
            uv2, z2 = v.project(Xn)
            ys, xs = np.nonzero(ok)
            own = np.stack([xs, ys], 1)[has]
            good = (np.linalg.norm(uv2 - own, axis=1) < AGREE_PX) & (np.abs(z2 - d[ok][has]) < AGREE_DEPTH * d[ok][has])
            agree[np.nonzero(has)[0][good]] += 1
        need = min(MIN_AGREE, len(nbrs[i]))
        kept = np.zeros_like(d)
        kept[ok] = np.where(agree >= need, d[ok], 0)
        out.append(kept)
    return out


def voxel_size(views, ranges):
    """VOXEL_PX pixels' footprint at the median of the photos' depth ranges."""
    mids = [math.sqrt(r[0] * r[1]) / 1.25 for r in ranges if r is not None]
    f = np.median([v.K[0, 0] for v in views])
    return VOXEL_PX * float(np.median(mids)) / float(f)


class Voxels:
    """Points averaged per voxel, with the summed unit directions towards their photos."""

    def __init__(self, size):
        self.size = size
        self.keys, self.sums, self.towards, self.counts = [], [], [], []

    def add(self, X, towards):
        if len(X):
            self.keys.append(np.floor(X / self.size).astype(np.int64))
            self.sums.append(X)
            self.towards.append(towards)
            self.counts.append(np.ones(len(X), np.int64))
        if sum(len(k) for k in self.keys) > 4_000_000:
            self._reduce()

    def _reduce(self):
        if not self.keys:
            return
        k = np.concatenate(self.keys)
        key = (k[:, 0] * 2_097_152 + k[:, 1]) * 2_097_152 + k[:, 2] if len(k) else k
        uniq, inv = np.unique(key, return_inverse=True)
        n = len(uniq)
        first = np.zeros(n, np.int64)
        first[inv[::-1]] = np.arange(len(inv))[::-1]
        red = lambda a: np.stack([np.bincount(inv, a[:, c], n) for c in range(a.shape[1])], 1)  # noqa: E731
        self.keys = [k[first]]
        self.sums = [red(np.concatenate(self.sums))]
        self.towards = [red(np.concatenate(self.towards))]
        self.counts = [np.bincount(inv, np.concatenate(self.counts), n).astype(np.int64)]

    def result(self):
        self._reduce()
        if not self.keys:
            return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, np.int64)
        c = self.counts[0]
        t = self.towards[0]
        return self.sums[0] / c[:, None], t / (np.linalg.norm(t, axis=1, keepdims=True) + 1e-12), c


def fuse(views, depths, voxel):
    vox = Voxels(voxel)
    for v, d in zip(views, depths):
        ok = d > 0
        X = v.points(d)[ok]
        to = v.centre - X
        vox.add(X, to / (np.linalg.norm(to, axis=1, keepdims=True) + 1e-12))
    return vox.result()


def isolated_out(points, towards, voxel):
    """Drops points with fewer than ISOLATED_MIN others within ISOLATED_VOXELS voxels: stereo's
    stray matches, each of which would grow a blob of surface."""
    from scipy.spatial import cKDTree

    tree = cKDTree(points)
    n = np.array([len(x) for x in tree.query_ball_point(points, ISOLATED_VOXELS * voxel)])
    keep = n > ISOLATED_MIN
    return points[keep], towards[keep]


def normals(points, towards, k=16):
    """Principal-axis normals over each point's k nearest (a k-d tree), facing its photos."""
    from scipy.spatial import cKDTree

    k = min(k, len(points))
    _, idx = cKDTree(points).query(points, k)
    out = np.empty_like(points)
    for s in range(0, len(points), 65536):
        nb = points[idx[s : s + 65536]]
        nb = nb - nb.mean(1, keepdims=True)
        _, vecs = np.linalg.eigh(np.einsum("nki,nkj->nij", nb, nb))
        out[s : s + 65536] = vecs[:, :, 0]
    return out * np.sign((out * towards).sum(1, keepdims=True) + 1e-12)


@dataclass
class Plane:
    normal: np.ndarray  # towards the photos
    offset: float  # normal · x = offset
    count: int
    extent: object = None  # None: the room's box bounds it; else (origin, 2×3 axes, Delaunay)

    def holds(self, X):
        """Which of the points X (on the plane) lie within its extent."""
        if self.extent is None:
            return np.ones(len(X), bool)
        origin, axes, tri = self.extent
        return tri.find_simplex((X - origin) @ axes.T) >= 0


def fit_planes(points, nrm, centres, voxel, up=None, rng=None):
    """The planes that bound the fused points (a room's walls, floor and ceiling): found by
    level planes from a histogram of heights, upright ones by RANSAC over pairs of points (inliers
    within 2 voxels whose own normal agrees), largest first, kept when at least
    PLANE_BOUND of all points lie on the photos' side of it. A table top or a plane through
    clutter has points on both sides and is not kept (its points are still taken out)."""
    rng = rng or np.random.default_rng(0)
    up = vertical(points, nrm, 2.0 * voxel) if up is None else up
    left, lnrm = points, nrm
    need = max(int(PLANE_MIN_SHARE * len(points)), 200)
    tol = 2.0 * voxel
    found = []
    for _ in range(PLANE_MAX):
        if len(left) < need:
            break
        pick = np.arange(len(left)) if len(left) <= 100_000 else rng.choice(len(left), 100_000, replace=False)
        sample, snrm = left[pick], lnrm[pick]
        best = _best_level(sample, snrm, up, tol)
        for _ in range(PLANE_ITERS):
            # an upright plane through two points: its normal is horizontal
            a, b = sample[rng.choice(len(sample), 2, replace=False)]
            n = np.cross(b - a, up)
            if np.linalg.norm(n) < 1e-9:
                continue
            n /= np.linalg.norm(n)
            cnt = int(_inliers(sample, snrm, n, float(n @ a), tol).sum())
            if best is None or cnt > best[0]:
                best = (cnt, n, float(n @ a))
        if best is None:
            break
        inl = _inliers(left, lnrm, best[1], best[2], tol)
        if inl.sum() < need:
            break
        # refit by least squares, twice over the inliers of the refit (the candidate's direction
        # comes from `up` or two points, each a degree or two off)
        n = best[1]
        for _ in range(3):
            P = left[inl]
            c = P.mean(0)
            n = np.linalg.svd(P - c, full_matrices=False)[2][2]
            inl = _inliers(left, lnrm, n, float(n @ c), tol)
            if inl.sum() < need:
                break
        if inl.sum() < need or not _level_or_upright(n, up):
            left, lnrm = left[~inl], lnrm[~inl]
            continue
        P = left[inl]
        c = P.mean(0)
        if np.mean(centres @ n - n @ c) < 0:
            n = -n
        off = float(n @ c)
        if np.mean(points @ n - off > -2 * tol) >= PLANE_BOUND:
            found.append(Plane(n, off, int(inl.sum())))
        else:
            extent = _patch(P, n, voxel, need)
            if extent is not None:
                found.append(Plane(n, off, int(inl.sum()), extent))
        left, lnrm = left[~inl], lnrm[~inl]
    return found


def _patch(P, n, voxel, need):
    """The extent of a plane that does not bound the room (a table top, a cabinet's side): the
    convex hull of its largest connected patch of points, cells of PATCH_CELL voxels joined
    when they touch. Scattered points at one height across a room make small patches, and a
    patch of fewer than need/2 points is no plane."""
    import cv2
    from scipy.spatial import ConvexHull, Delaunay

    a = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 0.0, 1.0])
    axes = np.stack([a / np.linalg.norm(a), np.cross(n, a / np.linalg.norm(a))])
    origin = P.mean(0)
    uv = (P - origin) @ axes.T
    cell = PATCH_CELL * voxel
    ij = np.floor((uv - uv.min(0)) / cell).astype(int)
    if ij.max() > 4096:
        return None
    grid = np.zeros(ij.max(0) + 1, np.uint8)
    grid[ij[:, 0], ij[:, 1]] = 1
    _, labels = cv2.connectedComponents(grid, connectivity=8)
    lab = labels[ij[:, 0], ij[:, 1]]
    biggest = np.bincount(lab).argmax()
    mine = uv[lab == biggest]
    if len(mine) < need / 2:
        return None
    try:
        hull = mine[ConvexHull(mine).vertices]
        return origin, axes, Delaunay(hull)
    except Exception:  # a patch on a line has no hull
        return None


def vertical(points, nrm, tol, guess=(0.0, 1.0, 0.0), rng=None):
    """The room's up direction: the normal of the plane holding the most points among those
    whose own normal is within VERTICAL_CONE_DEG of `guess` (the cameras' mean up, which is off
    by the cameras' mean tilt: 22° for TUM's desk sequence). A floor or a table top is that
    plane; its least-squares normal is up. Wider, a wall photographed from below or above wins
    (instant-ngp's fox: 40°)."""
    rng = rng or np.random.default_rng(1)
    guess = np.asarray(guess, float)
    sel = np.abs(nrm @ guess) > math.cos(math.radians(VERTICAL_CONE_DEG))
    P, N = points[sel], nrm[sel]
    if len(P) < 50:
        return guess
    if len(P) > 100_000:
        pick = rng.choice(len(P), 100_000, replace=False)
        P, N = P[pick], N[pick]
    found = []
    for _ in range(3):
        if len(P) < 50:
            break
        best = None
        for _ in range(PLANE_ITERS):
            a, b, c = P[rng.choice(len(P), 3, replace=False)]
            n = np.cross(b - a, c - a)
            if np.linalg.norm(n) < 1e-12 or abs(n @ guess) < math.cos(math.radians(VERTICAL_CONE_DEG)) * np.linalg.norm(n):
                continue
            n /= np.linalg.norm(n)
            inl = _inliers(P, N, n, float(n @ a), tol)
            if best is None or inl.sum() > best.sum():
                best = inl
        if best is None or best.sum() < 10:
            break
        Q = P[best]
        n = np.linalg.svd(Q - Q.mean(0), full_matrices=False)[2][2]
        found.append((int(best.sum()), n * np.sign(n @ guess)))
        P, N = P[~best], N[~best]
    if not found:
        return guess
    # The largest plane's neighbours in direction (a floor, a ceiling, table tops) vote with it,
    # weighted by their points: one plane's least-squares normal is noisy by a degree or two.
    first = found[0][1]
    m = sum(cnt * n for cnt, n in found if n @ first > math.cos(math.radians(PLANE_AXIS_DEG)))
    return m / np.linalg.norm(m)


def _best_level(points, nrm, up, tol):
    """The level plane (normal `up`) holding the most points: the fullest window of 2·tol in a
    histogram of the heights of the points whose own normal is near vertical."""
    y = points[np.abs(nrm @ up) > PLANE_NORMAL_COS] @ up
    if len(y) == 0:
        return None
    edges = np.arange(y.min() - tol, y.max() + 2 * tol, tol / 2)
    hist, _ = np.histogram(y, edges)
    window = np.convolve(hist, np.ones(4, int), "same")
    k = int(window.argmax())
    height = float(np.median(y[np.abs(y - edges[k]) < tol])) if window[k] else float(edges[k])
    return int(_inliers(points, nrm, up, height, tol).sum()), up, height


def _level_or_upright(n, up):
    """A room's planes are level (floor, ceiling, table tops) or upright (walls); a plane tilted
    between is clutter or a fit across a corner."""
    c = abs(float(n @ up))
    return c > math.cos(math.radians(PLANE_AXIS_DEG)) or c < math.sin(math.radians(PLANE_AXIS_DEG))


def _inliers(points, nrm, n, off, tol):
    """Points within `tol` of the plane whose own normal is near the plane's: a plane through
    points of several surfaces (a corner's two walls) gets none of them."""
    return (np.abs(points @ n - off) < tol) & (np.abs(nrm @ n) > PLANE_NORMAL_COS)


def fill(view, depth, planes, box):
    """Depth for the pixels with none: where the pixel's ray first meets one of the bounding
    planes inside `box` (the fused points' bounds, widened). Returns the filled depth map (0
    where no plane is met) and the planes' normals there."""
    rays = view.rays()[depth <= 0]
    o = view.centre
    best = np.full(len(rays), np.inf)
    nrm = np.zeros((len(rays), 3), np.float32)
    for p in planes:
        den = rays @ p.normal
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (p.offset - o @ p.normal) / den
        X = o + rays * np.where(np.isfinite(t), t, 0)[:, None]
        ok = (den < -1e-6) & (t > 0) & (t < best) & ((X >= box[0]) & (X <= box[1])).all(1)
        ok[ok] = p.holds(X[ok])
        best[ok] = t[ok]
        nrm[ok] = p.normal
    out = np.zeros(depth.shape, np.float32)
    out[depth <= 0] = np.where(np.isfinite(best), best, 0)
    full = np.zeros(depth.shape + (3,), np.float32)
    full[depth <= 0] = nrm
    return out, full


def free_space(views, i, nbrs, fd, kept):
    """Drops the filled depths of photo i that would stand in front of a surface one of its
    neighbours sees (by more than FREE_MARGIN): the plane is not there."""
    v = views[i]
    ok = fd > 0
    X = v.points(fd)[ok]
    bad = np.zeros(len(X), bool)
    for j in nbrs[i]:
        _, _, z, seen = views[j].sample(X, kept[j])
        bad |= (seen > 0) & (z < seen * (1 - FREE_MARGIN))
    out = fd.copy()
    out[ok] = np.where(bad, 0, fd[ok])
    return out


def complete(depth, cell=COMPLETE_CELL, tol=PLANAR_TOL):
    """Depth for the holes that lie within one plane: each hole's edge (the known pixels around
    it) is fitted by an affine function of the pixel coordinates in inverse depth, which a plane
    is exactly; where the fit's RMS error is within `tol` of the inverse depth, the hole takes it.
    A hole whose edge spans a depth edge (between a chair's back and the wall behind) fits no
    plane and is left alone: interpolating across it would stand a membrane in front of what
    other photos see. Worked on a grid of `cell` pixels (a cell known when most of its pixels
    are) and interpolated back. Returns depth (0 where known or left alone)."""
    import cv2

    h, w = depth.shape
    hc, wc = -(-h // cell), -(-w // cell)
    pad = np.zeros((hc * cell, wc * cell), np.float64)
    has = np.zeros_like(pad)
    pad[:h, :w] = np.where(depth > 0, 1.0 / np.maximum(depth, 1e-12), 0)
    has[:h, :w] = depth > 0
    blocks = lambda a: a.reshape(hc, cell, wc, cell).sum((1, 3))  # noqa: E731
    n = blocks(has)
    hole = n < cell * cell / 2
    inv = np.where(hole, 0, blocks(pad) / np.maximum(n, 1))
    if not hole.any() or hole.all():
        return np.zeros_like(depth)
    nlab, lab = cv2.connectedComponents(hole.astype(np.uint8), connectivity=4)
    # each (hole cell, known neighbour) pair: the neighbour is on that hole's edge
    lab_e, pos_e, val_e = [], [], []
    for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
        y, x = np.nonzero(hole)
        vy, vx = y + dy, x + dx
        ok = (vy >= 0) & (vy < hc) & (vx >= 0) & (vx < wc)
        y, x, vy, vx = y[ok], x[ok], vy[ok], vx[ok]
        edge = ~hole[vy, vx]
        lab_e.append(lab[y[edge], x[edge]])
        pos_e.append(np.c_[vx[edge], vy[edge]])
        val_e.append(inv[vy[edge], vx[edge]])
    lab_e, pos_e, val_e = np.concatenate(lab_e), np.concatenate(pos_e).astype(np.float64), np.concatenate(val_e)
    cnt = np.bincount(lab_e, minlength=nlab)
    mid = np.stack([np.bincount(lab_e, pos_e[:, k], nlab) for k in (0, 1)], 1) / np.maximum(cnt, 1)[:, None]
    A = np.c_[pos_e - mid[lab_e], np.ones(len(pos_e))]
    # per hole: the least-squares plane through its edge (normal equations summed by label); an
    # edge along a line (a hole at the image's border) leaves the slope across it at zero
    AtA = np.zeros((nlab, 3, 3))
    Atb = np.zeros((nlab, 3))
    np.add.at(AtA, lab_e, A[:, :, None] * A[:, None, :])
    np.add.at(Atb, lab_e, A * val_e[:, None])
    coef = np.linalg.solve(AtA + 1e-6 * np.diag([1.0, 1.0, 0.0]) + 1e-12 * np.eye(3), Atb[..., None])[..., 0]
    rel = ((A * coef[lab_e]).sum(1) - val_e) / val_e
    sq = np.bincount(lab_e, rel * rel, nlab)
    planar = (cnt >= 3) & (np.sqrt(sq / np.maximum(cnt, 1)) <= tol)
    planar[0] = False  # label 0: the known cells
    yy, xx = np.mgrid[0:hc, 0:wc]
    c, m = coef[lab], mid[lab]
    fit = c[..., 0] * (xx - m[..., 0]) + c[..., 1] * (yy - m[..., 1]) + c[..., 2]
    take = hole & planar[lab] & (fit > 0)
    inv[take] = fit[take]
    inv[hole & ~take] = np.nan  # bilinear interpolation carries NaN: no depth beside them
    full = cv2.resize(inv.astype(np.float32), (wc * cell, hc * cell), interpolation=cv2.INTER_LINEAR)[:h, :w]
    ok = (depth <= 0) & np.isfinite(full) & (full > 0)
    return np.where(ok, 1.0 / np.where(ok, full, 1), 0).astype(np.float32)


def surface_normals(view, depth):
    """Normals of the surface a depth map describes (finite differences of its points), facing
    the photo; zero where a neighbouring pixel has no depth."""
    P = view.points(depth)
    du, dv = np.gradient(P, axis=1), np.gradient(P, axis=0)
    n = np.cross(du, dv)
    n /= np.linalg.norm(n, axis=-1, keepdims=True) + 1e-12
    n *= np.sign(((view.centre - P) * n).sum(-1, keepdims=True) + 1e-12)
    valid = depth > 0
    for ax in (0, 1):
        for s in (1, -1):
            valid &= np.roll(depth > 0, s, axis=ax)
    return np.where(valid[..., None], n, 0).astype(np.float32)


def backdrop(view, depth, box):
    """Depth for the pixels with none where the ray leaves the room's box: the photos' far
    content (a room seen through a door, an office behind the object) laid on the box's faces,
    as image-based renderers' far proxies do. Returns depth (0 where known) and the faces'
    inward normals."""
    rays = view.rays()[depth <= 0]
    o = view.centre
    with np.errstate(divide="ignore", invalid="ignore"):
        ts = np.where(rays > 0, (box[1] - o) / rays, np.where(rays < 0, (box[0] - o) / rays, np.inf))
    axis = ts.argmin(1)
    t = ts[np.arange(len(ts)), axis]
    inside = ((o >= box[0]) & (o <= box[1])).all()
    ok = np.isfinite(t) & (t > 0) & inside
    nrm = np.zeros((len(rays), 3), np.float32)
    nrm[np.arange(len(rays)), axis] = -np.sign(rays[np.arange(len(rays)), axis])
    out = np.zeros(depth.shape, np.float32)
    out[depth <= 0] = np.where(ok, t, 0)
    full = np.zeros(depth.shape + (3,), np.float32)
    full[depth <= 0] = np.where(ok[:, None], nrm, 0)
    return out, full


def fill_holes(views, nbrs, kept, found, box, stages, voxel):
    """The points each of `stages` (a prefix of HOLES) gives the pixels with no kept depth, by
    stage (Voxels). A filled point is dropped where a neighbour sees a surface behind it: stereo's
    for the planes, stereo's and the planes' for the later stages."""
    vox = {k: Voxels(voxel) for k in stages}
    seen = []  # stereo's and the planes' depth: one map a photo (no normals kept: 300 photos)
    for i, (v, d) in enumerate(zip(views, kept)):
        fd, fn = fill(v, d, found, box)
        fd = free_space(views, i, nbrs, fd, kept)
        vox["planes"].add(v.points(fd)[fd > 0], fn[fd > 0])
        seen.append(np.where(d > 0, d, fd))
    # the backdrop's box holds the cameras too: photos taken from outside the points' bounds
    # (a desk seen from across the room) still see the room's far side on it
    cams = np.array([v.centre for v in views])
    pad = BOX_MARGIN / (1 + 2 * BOX_MARGIN) * (box[1] - box[0])
    far = (np.minimum(box[0], cams.min(0) - pad), np.maximum(box[1], cams.max(0) + pad))
    for i, v in enumerate(views):
        now = seen[i]
        if "complete" in stages:
            cd = free_space(views, i, nbrs, complete(now), seen)
            cn = surface_normals(v, np.where(cd > 0, cd, now))
            towards = v.centre - v.points(cd)
            towards /= np.linalg.norm(towards, axis=-1, keepdims=True) + 1e-12
            cn = np.where((cn == 0).all(-1, keepdims=True), towards, cn)  # no normal at a hole's rim
            vox["complete"].add(v.points(cd)[cd > 0], cn[cd > 0])
            now = np.where(cd > 0, cd, now)
        if "backdrop" in stages:
            bd, bn = backdrop(v, now, far)
            bd = free_space(views, i, nbrs, bd, seen)
            vox["backdrop"].add(v.points(bd)[bd > 0], bn[bd > 0])
    return vox


@dataclass
class Result:
    points: np.ndarray
    normals: np.ndarray
    voxel: float
    stereo_points: int
    filled_points: dict  # fused points from each hole-filling stage (HOLES), by name
    planes: int
    kept_share: float  # pixels with a consistent depth, over all photos
    filled_share: dict  # pixels given a depth by each stage, over all photos
    up: np.ndarray  # the room's up direction (`vertical`)


def sweep_key():
    """Names the depth maps' cache after what makes them: another setting, another folder."""
    import hashlib

    what = (NEIGHBOURS, NCC_BEST, STEREO_ANGLE, PLANES_PER_PX, PLANES_MIN, PLANES_MAX, NCC_WINDOW, NCC_MIN,
            TEXTURE_MIN)
    return "sweep-" + hashlib.sha1(repr(what).encode()).hexdigest()[:10]


_JOB = {}


def _sweep_one(i):
    """One photo's plane sweep, in a worker process (OpenCV on one thread there)."""
    import cv2

    cv2.setNumThreads(1)
    views, ranges, nbrs = _JOB["views"], _JOB["ranges"], _JOB["nbrs"]
    if ranges[i] is None or not nbrs[i]:
        return i, np.zeros(views[i].grey.shape, np.float32)
    return i, sweep(views[i], [views[j] for j in nbrs[i]], *ranges[i])[0]


def depth_maps(views, ranges, nbrs, cache, log, workers=None):
    """Every photo's depth map: from the cache where there, else swept by `workers` processes
    (default: one per core) and written to the cache as each finishes (temporary file, rename)."""
    import multiprocessing

    depths = [None] * len(views)
    todo = []
    for i, v in enumerate(views):
        f = cache / f"{v.name}.npz" if cache else None
        if f is not None and f.exists():
            depths[i] = np.load(f)["depth"]
        else:
            todo.append(i)
    workers = max(1, min(workers or os.cpu_count() or 1, len(todo)))
    job = dict(views=views, ranges=ranges, nbrs=nbrs)
    t0 = time.time()
    # Spawned, not forked: a fork copies OpenCV's thread pool mid-state and the child can hang.
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(workers, _job, (job,)) if workers > 1 else _Serial(job) as pool:
        for n, (i, d) in enumerate(pool.imap_unordered(_sweep_one, todo)):
            if cache is not None:
                cache.mkdir(parents=True, exist_ok=True)
                f = cache / f"{views[i].name}.npz"
                tmp = f.with_suffix(".tmp.npz")
                np.savez_compressed(tmp, depth=d)
                os.replace(tmp, f)
            depths[i] = d
            log(f"depth maps {len(views) - len(todo) + n + 1}/{len(views)} ({time.time() - t0:.0f} s)")
    _JOB.clear()
    return depths


def _job(job):
    _JOB.update(job)


class _Serial:
    """A pool of one: the sweep in this process."""

    def __init__(self, job):
        _job(job)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def imap_unordered(self, fn, items):
        return map(fn, items)


def run(views, sparse_points, cache: Path = None, log=lambda s: None, holes="backdrop"):
    """The whole dense step over `views` (a list of View) with the sparse points giving each
    photo's depth range. Depth maps are cached under `cache` (one .npz a photo) when given.
    `holes` (one of HOLES) names the last of the stages that fill what stereo keeps no depth for:
    the room's planes, then the holes on one plane (`complete`), then the room's box
    (`backdrop`)."""
    cache = cache / sweep_key() if cache else None
    ranges = [depth_range(v, sparse_points) for v in views]
    if all(r is None for r in ranges):
        raise DenseError("no photo sees 10 sparse points; the dense step needs depth ranges")
    nbrs = neighbours(views, sparse_points)
    depths = depth_maps(views, ranges, nbrs, cache, log)
    kept = consistent(views, depths, nbrs)
    voxel = voxel_size(views, ranges)
    pts, towards, _ = fuse(views, kept, voxel)
    if len(pts) < 100:
        raise DenseError(f"stereo kept {len(pts)} points; the photos agree nowhere (too little overlap or texture)")
    pts, towards = isolated_out(pts, towards, voxel)
    nrm = normals(pts, towards)
    up = vertical(pts, nrm, 2.0 * voxel)
    found = fit_planes(pts, nrm, np.array([v.centre for v in views]), voxel, up)
    lo, hi = np.percentile(pts, BOX_PERCENTILE, axis=0), np.percentile(pts, 100 - BOX_PERCENTILE, axis=0)
    box = (lo - BOX_MARGIN * (hi - lo), hi + BOX_MARGIN * (hi - lo))
    vox = fill_holes(views, nbrs, kept, found, box, HOLES[: HOLES.index(holes) + 1], voxel)
    parts = {k: vb.result()[:2] for k, vb in vox.items()}
    total = sum(d.size for d in kept)
    share = {k: int(sum(c.sum() for c in vb.counts)) for k, vb in vox.items()}  # pixels, before voxels
    all_pts = np.concatenate([pts] + [p for p, _ in parts.values()])
    all_nrm = np.concatenate([nrm] + [n for _, n in parts.values()])
    return Result(all_pts, all_nrm, voxel, len(pts), {k: len(p) for k, (p, _) in parts.items()}, len(found),
                  sum(int((d > 0).sum()) for d in kept) / total, {k: n / total for k, n in share.items()}, up)
