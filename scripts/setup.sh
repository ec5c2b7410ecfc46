#!/usr/bin/env bash
# Installs what arbor needs on Debian 12: Vulkan loader and lavapipe (software
# Vulkan), the Khronos validation layer, shaderc/glslang/SPIRV-Tools static libraries
# (linked into build.rs, see docs/build-notes.md), the assimp test models used by the tests,
# and Slurm with munge (the render-farm test starts a single-node cluster).
#
# --mesa-backports: also install Mesa's Vulkan drivers (lavapipe among them) from
# bookworm-backports (Mesa 25), whose lavapipe traces 15-35% faster than Debian 12's
# Mesa 22.3 (docs/lavapipe.md). It upgrades the system's Mesa (Vulkan and GL drivers)
# and libdrm, so it is opt-in; CI uses Debian 12's own.
set -euo pipefail
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
BACKPORTS=0
for arg in "$@"; do
  case "$arg" in
    --mesa-backports) BACKPORTS=1 ;;
    -h|--help) sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "setup: unknown option '$arg' (known: --mesa-backports, --help)" >&2; exit 2 ;;
  esac
done
PACKAGES=(
  mesa-vulkan-drivers vulkan-tools vulkan-validationlayers libvulkan-dev
  libshaderc-dev glslang-dev spirv-tools
  assimp-testmodels g++ pkg-config fonts-dejavu-core
  slurm-wlm munge
)
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}" >&2
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi
if [ "$BACKPORTS" = 1 ]; then
  codename=$(. /etc/os-release && echo "${VERSION_CODENAME:-}")
  if [ "$codename" != bookworm ]; then
    echo "setup: --mesa-backports is for Debian 12 (bookworm); this is '${codename:-unknown}'" >&2
    exit 1
  fi
  if ! grep -rqs "bookworm-backports" /etc/apt/sources.list /etc/apt/sources.list.d/; then
    echo "setup: adding bookworm-backports to /etc/apt/sources.list.d/bookworm-backports.list" >&2
    echo "deb http://deb.debian.org/debian bookworm-backports main" |
      $SUDO tee /etc/apt/sources.list.d/bookworm-backports.list >/dev/null
  fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq -t bookworm-backports mesa-vulkan-drivers >/dev/null
  echo "setup: mesa-vulkan-drivers $(dpkg-query -W -f='${Version}' mesa-vulkan-drivers) installed" >&2
fi
if ! command -v cargo >/dev/null; then
  echo "setup: cargo not found; install a Rust toolchain (rustup, Rust 1.86 or newer)" >&2
  exit 1
fi
echo "setup: ok" >&2
