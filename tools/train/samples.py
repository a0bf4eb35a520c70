"""Training samples with linear lighting (§6): reads what `relit dump --parts` writes and
assembles the network input and targets of any lighting, exactly as the engine forms them.

A sample keeps every lighting-dependent quantity as linear parts (the original lighting, each
added light alone at intensity 1), so the trainer can draw random intensities and α_dim
("original off", "dimmed", several lamps at once) without re-rendering. numpy only.

  python3 tools/train/samples.py --check PARTS.safetensors DUMP.safetensors
      assembles PARTS under DUMP's lighting (its relit.lighting metadata) and fails unless the
      input equals DUMP's within 1e-4 (and the targets, when both have them), and what the frame
      draws on the declared original lights equals DUMP's ratio_image there, and glossy mode's
      image (the base of a network with base "glossy") equals DUMP's glossy_image.
"""
import argparse
import json
import struct
import sys

import numpy as np

from constants import CH_E_ADD, CH_E_REM, CH_E_SRC, CH_M_TGT, CH_MIRROR_DIST, E_FLOOR, MU
DTYPES = {"F32": np.float32, "F16": np.float16, "I64": np.int64, "I32": np.int32}


def read_safetensors(path):
    """(tensors by name, metadata) of a safetensors file."""
    with open(path, "rb") as f:
        data = f.read()
    if len(data) < 8:
        raise ValueError(f"{path}: not a safetensors file (shorter than its 8-byte header size)")
    (n,) = struct.unpack("<Q", data[:8])
    if 8 + n > len(data):
        raise ValueError(f"{path}: header size {n} runs past the end of the file")
    header = json.loads(data[8:8 + n])
    meta = header.pop("__metadata__", {})
    body = memoryview(data)[8 + n:]
    out = {}
    for name, t in header.items():
        a, b = t["data_offsets"]
        arr = np.frombuffer(body[a:b], dtype=DTYPES[t["dtype"]])
        out[name] = arr.reshape(t["shape"])
    return out, meta


def tonemap(x):
    return np.log1p(MU * np.maximum(x, 0.0)) / np.log1p(MU)


class Sample:
    """One camera of one scene: the parts written by `relit dump --parts`."""

    def __init__(self, path):
        self.t, self.meta = read_safetensors(path)
        if "relit.parts" not in self.meta:
            raise ValueError(f"{path}: no relit.parts metadata (write it with relit dump --parts)")
        self.lights = json.loads(self.meta["relit.lights"])
        self.path = path

    def has_targets(self):
        return "target_diffuse.original" in self.t

    def mirror(self, alpha, intensities):
        """M_tgt (linear, 3×H×W) and the mirror-distance channel under a lighting."""
        t = self.t
        m = (1.0 - alpha) * t["m_orig"]
        for name, i in zip(self.lights, intensities):
            m = m + i * t[f"m_add.{name}"]
        dist = t["static"][CH_MIRROR_DIST].copy()
        # A mirror ray that meets a lit lamp sees the lamp, the nearest one, and nothing else.
        best = np.full(dist.shape, np.inf, dtype=np.float32)
        for name, i in zip(self.lights, intensities):
            if i <= 0.0:
                continue
            d = t[f"dist.{name}"][0]
            hit = (d != t["static"][CH_MIRROR_DIST]) & (d < best)
            best = np.where(hit, d, best)
            m = np.where(hit[None], i * t[f"m_add.{name}"], m)
            dist = np.where(hit, d, dist)
        return m, dist

    def input(self, alpha, intensities):
        """The network input (IN_CHANNELS, tonemapped) under a lighting."""
        t = self.t
        x = t["static"].copy()
        m, dist = self.mirror(alpha, intensities)
        e_add = sum(i * t[f"e_add.{n}"] for n, i in zip(self.lights, intensities))
        e_add = e_add + np.zeros_like(t["e_src"])
        x[CH_M_TGT : CH_M_TGT + 3] = tonemap(m)
        x[CH_E_SRC : CH_E_SRC + 3] = tonemap(t["e_src"] / np.pi)
        x[CH_E_ADD : CH_E_ADD + 3] = tonemap(e_add / np.pi)
        x[CH_E_REM : CH_E_REM + 3] = tonemap(alpha * t["e_src"] / np.pi)
        x[CH_MIRROR_DIST] = dist
        # Pixels without a surface stay zero in every channel.
        surface = np.any(t["static"] != 0.0, axis=0)
        return np.where(surface[None], x, 0.0).astype(np.float32)

    def glossy(self, alpha, intensities):
        """Glossy mode's image (linear 3×H×W) under a lighting before any light is drawn:
        the view-dependent layer's D relit by eq. 5 plus its S (frame/glossy.comp), which is
        linear in the lighting but where the target mirror is the regressor (lobe 0): there
        S = s·M_tgt, M_tgt as `mirror` assembles it. None for samples written before
        `relit dump --parts` wrote the layer."""
        t = self.t
        if "glossy_d" not in t:
            return None
        e_src = t["e_src"]
        e_add = sum(i * t[f"e_add.{n}"] for n, i in zip(self.lights, intensities))
        diffuse = t["glossy_d"] / np.maximum(e_src, E_FLOOR) * (e_add + e_src - alpha * e_src)
        s = (1.0 - alpha) * t["s_orig"]
        for name, i in zip(self.lights, intensities):
            s = s + i * t[f"s_add.{name}"]
        m, _ = self.mirror(alpha, intensities)
        s = np.where(t["glossy_lobe"] == 1.0, t["glossy_s"] * m, s)
        return (diffuse + s).astype(np.float32)

    def drawn_lights(self, alpha, intensities):
        """(where, value): the pixels that show a declared original light (1×H×W bool) and what
        the frame draws there in every mode under a lighting (linear 3×H×W; emitters.glsl):
        (1 − α) · light_glow + light_albedo · E_add / π. None for samples written before
        `relit dump --parts` wrote light_glow."""
        t = self.t
        if "light_glow" not in t:
            return None
        glow = t["light_glow"]
        e_add = sum(i * t[f"e_add.{n}"] for n, i in zip(self.lights, intensities))
        value = (1.0 - alpha) * glow + t["light_albedo"] * (e_add + np.zeros_like(glow)) / np.pi
        return np.any(glow != 0.0, axis=0, keepdims=True), value

    def targets(self, alpha, intensities):
        """(diffuse, total) linear targets under a lighting."""
        t = self.t
        d = (1.0 - alpha) * t["target_diffuse.original"]
        tot = (1.0 - alpha) * t["target_total.original"]
        for name, i in zip(self.lights, intensities):
            d = d + i * t[f"target_diffuse.{name}"]
            tot = tot + i * t[f"target_total.{name}"]
        return d, tot


def check(parts_path, dump_path, tol=1e-4):
    s = Sample(parts_path)
    dump, meta = read_safetensors(dump_path)
    lit = json.loads(meta["relit.lighting"])
    by_name = dict(lit["intensities"])
    intens = [by_name.get(n, 0.0) for n in s.lights]
    x = s.input(lit["alpha_dim"], intens)
    diff = np.abs(x - dump["input"])
    worst = np.unravel_index(np.argmax(diff), diff.shape)
    print(f"input: max |assembled - dump| = {diff.max():.3g} at channel {worst[0]}, "
          f"pixel ({worst[2]}, {worst[1]})")
    ok = diff.max() <= tol
    drawn = s.drawn_lights(lit["alpha_dim"], intens)
    if drawn is not None and "ratio_image" in dump:
        on, value = drawn
        n = int(on.sum())
        e = np.abs(np.where(on, value - dump["ratio_image"], 0.0)).max() if n else 0.0
        e /= max(np.abs(dump["ratio_image"]).max(), 1e-6)
        print(f"drawn original lights: {n} pixels, max relative difference {e:.3g}")
        ok &= e <= tol
    g = s.glossy(lit["alpha_dim"], intens)
    if g is not None and "glossy_image" in dump:
        e = np.abs(g - dump["glossy_image"]).max() / max(np.abs(dump["glossy_image"]).max(), 1e-6)
        print(f"glossy_image: max relative difference {e:.3g}")
        ok &= e <= tol
    if s.has_targets() and "target_diffuse" in dump:
        d, tot = s.targets(lit["alpha_dim"], intens)
        for name, a in (("target_diffuse", d), ("target_total", tot)):
            e = np.abs(a - dump[name]).max() / max(np.abs(dump[name]).max(), 1e-6)
            print(f"{name}: max relative difference {e:.3g}")
            ok &= e <= tol
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", nargs=2, metavar=("PARTS", "DUMP"), required=True)
    ap.add_argument("--tol", type=float, default=1e-4)
    a = ap.parse_args()
    try:
        ok = check(*a.check, tol=a.tol)
    except (OSError, ValueError, KeyError) as e:
        sys.exit(f"error: {e}")
    if not ok:
        sys.exit("assembled sample differs from relit dump")


if __name__ == "__main__":
    main()
