#!/usr/bin/env bash
# Sets the machine up (tools/setup.sh) and runs the main job on the bundled scene.
# For now the engine core: device report and a full check of the demo scene.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
cargo build --release --bin relit
./target/release/relit info
./target/release/relit scene check scenes/demo_room
