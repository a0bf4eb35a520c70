#!/usr/bin/env bash
# Sets the machine up (tools/setup.sh) and runs the whole test suite on the Vulkan device
# (lavapipe here), with the Khronos validation layer on: any validation error fails a test.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
# Build products live outside the clone and outlast it (CI tests a fresh clone each time): the
# dependencies (glslang's C++ above all) then compile once per machine, not once per run.
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/relit/target}"
cargo test --workspace "$@"
# The ground-truth renderer's own tests (they drive the scenegen binary).
cargo build -p relit-scenegen --bin scenegen
(cd tools/groundtruth && SCENEGEN="$CARGO_TARGET_DIR/debug/scenegen" python3 -m unittest -v test_groundtruth)
# The trainer's tests (a tiny relit dataset, resume bit for bit, the engine loads its weights).
RELIT="$CARGO_TARGET_DIR/debug/relit" "${RELIT_TRAIN_VENV:-$HOME/.cache/relit/train-venv}/bin/python" \
  -m unittest -v tools/train/test_train.py
# The capture tool's geometry and its dense step on a synthetic capture (scenegen photos
# rendered by Mitsuba, compared with the room's true mesh).
RELIT="$CARGO_TARGET_DIR/debug/relit" SCENEGEN="$CARGO_TARGET_DIR/debug/scenegen" \
  "${RELIT_TRAIN_VENV:-$HOME/.cache/relit/train-venv}/bin/python" -m unittest -v tools/capture/test_capture.py
# The cooperative-matrix kernels on lavapipe >= 26 (Mesa's emulation), in a Debian 13 root
# built once with debootstrap (~540 MB in ~/.cache/relit; tools/lavapipe26.sh).
bash tools/lavapipe26.sh
# Bounded fuzzing of every file format (2 min; tools/fuzz.sh).
bash tools/fuzz.sh 15
