#!/usr/bin/env bash
# Sets the machine up (tools/setup.sh) and runs the main job on the bundled scene: device
# report, a full check of the demo scene, and its bake (preview quality, ~10 min on 2 cores;
# a second run finds everything cached). Rendering and flythroughs come with the frame passes.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
cargo build --release --bin relit
./target/release/relit info
./target/release/relit scene check scenes/demo_room
./target/release/relit bake scenes/demo_room --quality preview
