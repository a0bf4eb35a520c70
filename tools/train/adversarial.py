"""The adversarial term of §5.3 (eq. 12): a global relativistic discriminator (Jolicoeur-Martineau
2019, RSGAN) with Radford et al.'s (DCGAN) architecture on the concatenated outputs
[O_diffuse, O_vdep] (6 channels, tonemapped). Our choices where the paper is silent: no batch
normalization (the batch is one image), and the last layer averages a 3×3 convolution's map to
one logit, so any crop size works.
"""
import torch.nn as nn
import torch.nn.functional as F


class Discriminator(nn.Module):
    def __init__(self, channels=6, width=64, strided=4):
        super().__init__()
        layers, c = [], channels
        for k in range(strided):
            n = width * 2 ** k
            layers += [nn.Conv2d(c, n, 4, 2, 1), nn.LeakyReLU(0.2)]
            c = n
        layers.append(nn.Conv2d(c, 1, 3, 1, 1))
        self.net = nn.Sequential(*layers)

    def forward(self, x):
        return self.net(x).mean(dim=(1, 2, 3))


def generator_loss(d, fake, real):
    """The generator's relativistic loss: its output should look more real than the truth."""
    return F.softplus(-(d(fake) - d(real))).mean()


def discriminator_loss(d, fake, real):
    """The discriminator's: the truth should look more real than the (detached) output."""
    return F.softplus(-(d(real) - d(fake.detach()))).mean()
