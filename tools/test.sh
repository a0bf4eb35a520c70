#!/usr/bin/env bash
# Sets the machine up (tools/setup.sh) and runs the whole test suite on the Vulkan device
# (lavapipe here), with the Khronos validation layer on: any validation error fails a test.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
cargo test --workspace "$@"
# The ground-truth renderer's own tests (they drive the scenegen binary).
cargo build -p relit-scenegen --bin scenegen
(cd tools/groundtruth && python3 -m unittest -v test_groundtruth)
# The trainer's tests (a tiny relit dataset, resume bit for bit, the engine loads its weights).
RELIT="$PWD/target/debug/relit" "${RELIT_TRAIN_VENV:-$HOME/.cache/relit/train-venv}/bin/python" \
  -m unittest -v tools/train/test_train.py
# The cooperative-matrix kernels on lavapipe >= 26 (Mesa's emulation), in a Debian 13 root
# built once with debootstrap (~600 MB in ~/.cache/relit; tools/lavapipe26.sh).
bash tools/lavapipe26.sh
# Bounded fuzzing of every file format (2 min; tools/fuzz.sh).
bash tools/fuzz.sh 15
