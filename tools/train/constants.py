"""The constants Python shares with the engine and its shaders, read from their one source,
engine/constants.table (build.rs writes the same rows into Rust and GLSL)."""
import os

TABLE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "engine", "constants.table")


def read(path=TABLE):
    """{name: value} of the table's rows (float or int by the row's type)."""
    out = {}
    with open(path) as f:
        for n, line in enumerate(f, 1):
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            parts = line.split()
            if len(parts) < 3 or parts[1] not in ("float", "uint"):
                raise ValueError(f"{path}:{n}: expected `NAME float|uint VALUE MEANING`")
            out[parts[0]] = float(parts[2]) if parts[1] == "float" else int(parts[2])
    return out


_C = read()
MU = _C["MU"]
E_FLOOR = _C["E_FLOOR"]
GAIN_EPS = _C["GAIN_EPS"]
# The network input's channels: each group's first channel (frame/features.glsl's order).
IN_CHANNELS = _C["IN_CHANNELS"]
CH_I, CH_M_SRC, CH_M_TGT = _C["CH_I"], _C["CH_M_SRC"], _C["CH_M_TGT"]
CH_E_SRC, CH_E_ADD, CH_E_REM = _C["CH_E_SRC"], _C["CH_E_ADD"], _C["CH_E_REM"]
CH_MIRROR_DIST = _C["CH_MIRROR_DIST"]
