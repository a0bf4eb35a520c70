#!/usr/bin/env bash
# Regenerates scenes/demo_room: a scenegen room (seed 2, 32 views at 256x192), its input views
# rendered by Mitsuba 3 under the original lighting and denoised as a camera's photos are clean
# (render.py --denoise-photos; their AOVs are dropped again, but v000's and v001's), ground
# truth (total/diffuse/glossy + AOVs) for two views, and the contact sheet. Takes a few minutes
# on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
SPP="${SPP:-128}"
OUT=scenes/demo_room
cargo build --release -p relit-scenegen
rm -rf "$OUT"
./target/release/scenegen room "$OUT" --seed 2 --views 32 --res 256x192 --test-views 8 --extra-lights 6
python3 tools/groundtruth/render.py "$OUT" --only inputs --spp "$SPP" --denoise-photos
find "$OUT/gt/aov" -type f ! -name 'v000.*' ! -name 'v001.*' -delete
python3 tools/groundtruth/render.py "$OUT" --views v000,v001 --conditions original --spp "$SPP" --denoise-photos
python3 tools/groundtruth/contact_sheet.py "$OUT" --out "$OUT/contact_sheet.png"
du -sh "$OUT"
