#!/usr/bin/env bash
# Runs the network's cooperative-matrix tests on lavapipe >= 26 (Mesa's emulated
# VK_KHR_cooperative_matrix: 8x8x8 fp16 at 8 lanes), which Debian 12 does not package.
#
#   bash tools/lavapipe26.sh [TEST_BINARY ...]   # tests (default: the net and gpu tests)
#   bash tools/lavapipe26.sh --run CMD [ARG ...]  # any host-built command, e.g. relit bench net
#
# It builds a Debian 13 (trixie) root with debootstrap once, with Mesa from trixie-backports and
# the validation layers (~540 MB, kept in $RELIT_LP26_ROOT, default ~/.cache/relit/trixie-root),
# then runs host-built binaries inside it (chroot in a private mount namespace, the repository
# mounted at its own path). Tests run with RELIT_REQUIRE_COOP=1: they fail unless the
# cooperative-matrix kernels run. Needs root (or sudo) for debootstrap and chroot.
set -euo pipefail
cd "$(dirname "$0")/.."
repo="$(pwd)"
# Host-built binaries run inside the root at their own paths: the build directory is mounted
# there too when it is outside the repository (tools/test.sh keeps it in ~/.cache).
target="$(cargo metadata --no-deps --format-version 1 2>/dev/null \
  | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')"
root="${RELIT_LP26_ROOT:-$HOME/.cache/relit/trixie-root}"
mirror="${RELIT_DEBIAN_MIRROR:-http://deb.debian.org/debian}"
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi

build_root() {
  command -v debootstrap >/dev/null || $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq debootstrap
  local tmp="$root.partial"
  # A half-made root from a killed run is started over: debootstrap cannot resume it.
  $SUDO rm -rf "$tmp"
  mkdir -p "$(dirname "$root")"
  echo "lavapipe26: debootstrap trixie into $tmp"
  $SUDO debootstrap --variant=minbase trixie "$tmp" "$mirror" >"$tmp.log" 2>&1 \
    || { tail -20 "$tmp.log"; echo "lavapipe26: debootstrap failed (log: $tmp.log)" >&2; exit 1; }
  echo "deb $mirror trixie-backports main" | $SUDO tee "$tmp/etc/apt/sources.list.d/backports.list" >/dev/null
  in_root "$tmp" apt-get update -qq
  # Backports are never chosen by default: ask for Mesa from there explicitly.
  in_root "$tmp" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    -t trixie-backports mesa-vulkan-drivers libvulkan1 vulkan-validationlayers >>"$tmp.log" 2>&1 \
    || { tail -20 "$tmp.log"; echo "lavapipe26: apt-get in the root failed (log: $tmp.log)" >&2; exit 1; }
  in_root "$tmp" apt-get clean
  $SUDO touch "$tmp/.relit-ready"
  $SUDO rm -rf "$root"
  $SUDO mv -T "$tmp" "$root"
  rm -f "$tmp.log"
}

# Runs a command inside root $1, with /proc, /dev and the repository mounted; the mounts live in
# a private namespace, so they vanish with it even if the command is killed.
in_root() {
  local r="$1"
  shift
  $SUDO unshare --mount --propagation private -- sh -c '
    r="$1"; repo="$2"; target="$3"; shift 3
    mount -t proc proc "$r/proc"
    mount --rbind /dev "$r/dev"
    mkdir -p "$r$repo" "$r/tmp"
    mount --bind "$repo" "$r$repo"
    case "$target" in
      "$repo"/*|"") ;;
      *) mkdir -p "$r$target" && mount --bind "$target" "$r$target" ;;
    esac
    cp /etc/resolv.conf "$r/etc/resolv.conf" 2>/dev/null || true
    exec chroot "$r" "$@"
  ' sh "$r" "$repo" "${target:-}" "$@"
}

mesa_version() {
  in_root "$root" dpkg-query -W -f='${Version}' mesa-vulkan-drivers
}

[ -f "$root/.relit-ready" ] || build_root
echo "lavapipe26: root $root, Mesa $(mesa_version)"

if [ "${1:-}" = "--run" ]; then
  shift
  in_root "$root" env -C "$repo" "$@"
  exit
fi

# Default: the network's kernel tests (gpu: GEMM and backend choice; net: every conv kernel
# against the CPU reference, the network against the PyTorch golden), with the cooperative-
# matrix kernels required, validation on; then what `relit info` reports there.
if [ $# -eq 0 ]; then
  mapfile -t bins < <(cargo test --test net --test gpu --no-run --message-format=json 2>/dev/null \
    | python3 -c 'import json,sys
for l in sys.stdin:
    m = json.loads(l)
    if m.get("executable") and m.get("profile", {}).get("test"): print(m["executable"])')
  [ "${#bins[@]}" = 2 ] || { echo "lavapipe26: could not build the net and gpu tests" >&2; exit 1; }
  set -- "${bins[@]}"
  cargo build -q --bin relit
  paths="$(in_root "$root" env -C "$repo" "$target/debug/relit" info | grep "network path")"
  echo "$paths"
  case "$paths" in
    *"F16 storage: cooperative matrix"*) ;;
    *) echo "lavapipe26: relit info does not report the cooperative-matrix path" >&2; exit 1 ;;
  esac
fi
for bin in "$@"; do
  echo "lavapipe26: $(basename "$bin")"
  in_root "$root" env -C "$repo" RELIT_REQUIRE_COOP=1 "$bin" --test-threads 1
done
