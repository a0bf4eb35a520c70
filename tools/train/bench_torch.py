"""Times the network of model.py with PyTorch on the CPU, for comparison with
`relit bench net` (same width, resolution and FLOP count):

  python3 tools/train/bench_torch.py --width 66 --res 256x192 --threads 2
"""
import argparse
import json
import time

import torch

import model as M


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--width", type=int, default=66)
    ap.add_argument("--res", default="256x192")
    ap.add_argument("--threads", type=int, default=torch.get_num_threads())
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json")
    a = ap.parse_args()
    w, h = (int(v) for v in a.res.split("x"))
    torch.set_num_threads(a.threads)
    net = M.RelightNet(width=a.width).eval()
    flops = net.flops(h, w)
    x = torch.rand(1, net.config["in_channels"], h, w)
    times = []
    with torch.no_grad():
        net(x)  # warm-up
        for _ in range(a.repeats):
            t = time.perf_counter()
            net(x)
            times.append(time.perf_counter() - t)
    t = sorted(times)[len(times) // 2]
    print(f"pytorch {torch.__version__}, {a.threads} threads: width {a.width}, {w}x{h}, "
          f"{flops / 1e9:.2f} GFLOP, {t * 1e3:.1f} ms, {flops / t / 1e9:.2f} GFLOP/s")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(dict(width=a.width, res=[w, h], threads=a.threads, ms=t * 1e3,
                           gflop=flops / 1e9, gflops=flops / t / 1e9), f, indent=2)


if __name__ == "__main__":
    main()
