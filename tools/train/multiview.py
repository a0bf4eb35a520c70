"""The multi-view consistency term of §5.3 (eq. 11): the L1 difference between O_diffuse of a
view and O_diffuse of a nearby view reprojected onto it with the true geometry, which the
renderer knows (each sample's `depth_true`, camera-z, and its camera). Pixels the other view
does not see (outside its image, or its true depth disagrees by more than 2%) are left out.
Cameras follow the engine's convention (README, Conventions): q = R·(p − position),
pixel = (fx·qx/qz + cx, fy·qy/qz + cy), pixel centres at +½.
"""
import json

import numpy as np
import torch
import torch.nn.functional as F


def camera(sample):
    """(R, position, fx, fy, cx, cy) of a sample, numpy float64."""
    c = json.loads(sample.meta["relit.camera_params"])
    return (np.array(c["rotation"], dtype=np.float64), np.array(c["position"], dtype=np.float64),
            c["fx"], c["fy"], c["cx"], c["cy"])


def neighbours(samples, min_overlap=0.2):
    """For each sample, the sample of the same scene that sees most of its pixels (None when
    none sees min_overlap of them, or there is no true depth)."""
    scene = [s.path.rsplit("/", 1)[-1].split(".")[0] for s in samples]
    out = []
    for i, s in enumerate(samples):
        best, most = None, min_overlap
        for j, o in enumerate(samples):
            if j == i or scene[j] != scene[i] or "depth_true" not in o.t or "depth_true" not in s.t:
                continue
            seen = float(warp(s, o)[1].float().mean())
            if seen > most:
                best, most = j, seen
        out.append(best)
    return out


def warp(a, b):
    """(grid, valid): where each pixel of sample a lands in sample b, as grid_sample coordinates
    (1×H×W×2) and a visibility mask (H×W)."""
    ra, pa, fxa, fya, cxa, cya = camera(a)
    rb, pb, fxb, fyb, cxb, cyb = camera(b)
    za = a.t["depth_true"][0].astype(np.float64)
    zb = b.t["depth_true"][0]
    h, w = za.shape
    v, u = np.mgrid[0:h, 0:w] + 0.5
    q = np.stack([(u - cxa) / fxa * za, (v - cya) / fya * za, za], -1)
    world = q @ ra + pa                      # Rᵀ·q + position
    qb = (world - pb) @ rb.T
    z = qb[..., 2]
    ok = np.isfinite(za) & (za > 0) & (z > 1e-6)
    zs = np.where(ok, z, 1.0)
    ub, vb = fxb * qb[..., 0] / zs + cxb, fyb * qb[..., 1] / zs + cyb
    hb, wb = zb.shape
    ok &= (ub >= 0) & (vb >= 0) & (ub < wb) & (vb < hb)
    iu, iv = np.clip(ub.astype(int), 0, wb - 1), np.clip(vb.astype(int), 0, hb - 1)
    ok &= np.abs(zb[iv, iu] - z) < 0.02 * z
    grid = np.stack([ub / wb * 2 - 1, vb / hb * 2 - 1], -1)[None].astype(np.float32)
    return torch.from_numpy(grid), torch.from_numpy(ok)


def loss(od_a, od_b, grid, valid):
    """Mean |O_d(a) − O_d(b) reprojected| over the pixels b sees (0 when there are none)."""
    if not bool(valid.any()):
        return od_a.sum() * 0.0
    g = grid.to(od_b.device)
    warped = F.grid_sample(od_b, g, mode="bilinear", padding_mode="border", align_corners=False)
    m = valid.to(od_a.device)[None, None].expand_as(od_a)
    return (od_a - warped).abs()[m].mean()
