#!/usr/bin/env bash
# The main job on the bundled scene: sets the machine up (tools/setup.sh), reports the device,
# checks and bakes scenes/demo_room (preview quality: 79 s on 2 AVX-512 cores on 2026-12-06,
# docs/benchmarks.md; a second run finds everything cached), renders one novel view and
# records a walk through the room (paths/walk.json:
# the TV and the window's reflection on the floor, the table, the bed, the shelf; the lamp by the
# TV switches on, the original light dims to 30%, the lamp moves mid-room and on towards the bed,
# and the original light returns) to out/demo_room_fly.mp4 in relit's default mode (the one that
# scores best on rooms never trained on: the shipped network, which corrects glossy mode's image
# where the lamp's light reaches and the photos disagree, and fills the holes no photo sees;
# docs/evaluation.md), and with the ratio rule alone (its holes black) to
# out/demo_room_fly_ratio.mp4 for comparison, and in glossy mode to out/demo_room_fly_glossy.mp4.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
cargo build --release --bin relit
R=./target/release/relit
S=scenes/demo_room
$R info
$R scene check $S
$R bake $S --quality preview
mkdir -p out
$R render $S --camera test003 --lighting extra0_on_dimmed --out out/demo_room_test003.png
$R fly $S --path $S/paths/walk.json --out out/demo_room_fly.mp4 --res 256x192 --fps 12
# The same path with the ratio rule alone (no network: the holes stay black).
$R fly $S --path $S/paths/walk.json --out out/demo_room_fly_ratio.mp4 --res 256x192 --fps 12 --mode ratio
# And in glossy mode (§3's L = a·E + S), the network's base, without the network: the lamp's
# floor highlight moves with it in both.
$R fly $S --path $S/paths/walk.json --out out/demo_room_fly_glossy.mp4 --res 256x192 --fps 12 --mode glossy
echo "main job done: out/demo_room_fly.mp4, out/demo_room_fly_ratio.mp4, out/demo_room_fly_glossy.mp4, out/demo_room_test003.png"
