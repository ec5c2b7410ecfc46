#!/usr/bin/env bash
# Installs what arbor needs on Debian 12: Vulkan loader and lavapipe (software
# Vulkan), the Khronos validation layer, shaderc/glslang/SPIRV-Tools static libraries
# (linked into build.rs, see docs/build-notes.md), the assimp test models used by the tests,
# Slurm with munge (the render-farm test starts a single-node cluster), and Python's
# venv and pip (the Python module's tests, docs/python.md).
#
# --mesa-backports: also install Mesa's Vulkan drivers (lavapipe among them) from
# bookworm-backports (Mesa 25), whose lavapipe traces 15-35% faster than Debian 12's
# Mesa 22.3 (docs/lavapipe.md). It upgrades the system's Mesa (Vulkan and GL drivers)
# and libdrm, so it is opt-in; CI uses Debian 12's own.
#
# --mesa-aside DIR: unpack Mesa 25's lavapipe (and the libdrm it needs) from
# bookworm-backports into DIR without installing it, and write DIR/lvp_icd.json.
# Use it with VK_DRIVER_FILES=DIR/lvp_icd.json
# LD_LIBRARY_PATH=DIR/usr/lib/x86_64-linux-gnu: it has VK_KHR_ray_query
# (`--accel rayquery`) while the system keeps Debian 12's Mesa. CI tests both.
set -euo pipefail
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
BACKPORTS=0
ASIDE=""
while [ $# -gt 0 ]; do
  case "$1" in
    --mesa-backports) BACKPORTS=1 ;;
    --mesa-aside)
      [ $# -ge 2 ] && [ -n "$2" ] || { echo "setup: --mesa-aside needs a directory" >&2; exit 2; }
      ASIDE="$2"; shift ;;
    -h|--help) sed -n '2,17p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "setup: unknown option '$1' (known: --mesa-backports, --mesa-aside DIR, --help)" >&2; exit 2 ;;
  esac
  shift
done
PACKAGES=(
  mesa-vulkan-drivers vulkan-tools vulkan-validationlayers libvulkan-dev
  libshaderc-dev glslang-dev spirv-tools
  assimp-testmodels g++ pkg-config
  slurm-wlm munge
  python3-venv python3-pip binutils
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
backports_source() {
  codename=$(. /etc/os-release && echo "${VERSION_CODENAME:-}")
  if [ "$codename" != bookworm ]; then
    echo "setup: $1 is for Debian 12 (bookworm); this is '${codename:-unknown}'" >&2
    exit 1
  fi
  if ! grep -rqs "bookworm-backports" /etc/apt/sources.list /etc/apt/sources.list.d/; then
    echo "setup: adding bookworm-backports to /etc/apt/sources.list.d/bookworm-backports.list" >&2
    echo "deb http://deb.debian.org/debian bookworm-backports main" |
      $SUDO tee /etc/apt/sources.list.d/bookworm-backports.list >/dev/null
  fi
  $SUDO apt-get update -qq
}
if [ -n "$ASIDE" ]; then
  backports_source --mesa-aside
  mkdir -p "$ASIDE"
  ASIDE=$(cd "$ASIDE" && pwd)
  debs=$(mktemp -d)
  # apt's sandbox user must be able to write the download directory.
  chmod 777 "$debs"
  (cd "$debs" && apt-get download -qq -t bookworm-backports mesa-vulkan-drivers libdrm2 libdrm-amdgpu1)
  for d in "$debs"/*.deb; do dpkg-deb -x "$d" "$ASIDE"; done
  ver=$(dpkg-deb -f "$debs"/mesa-vulkan-drivers_*.deb Version)
  rm -rf "$debs"
  lib="$ASIDE/usr/lib/x86_64-linux-gnu/libvulkan_lvp.so"
  [ -f "$lib" ] || { echo "setup: $lib missing after unpacking" >&2; exit 1; }
  api=$(sed -n 's/.*"api_version": *"\([^"]*\)".*/\1/p' "$ASIDE/usr/share/vulkan/icd.d/lvp_icd.json")
  printf '{\n    "ICD": {\n        "api_version": "%s",\n        "library_path": "%s"\n    },\n    "file_format_version": "1.0.0"\n}\n' \
    "${api:-1.3.0}" "$lib" > "$ASIDE/lvp_icd.json"
  echo "setup: Mesa $ver lavapipe unpacked in $ASIDE; use VK_DRIVER_FILES=$ASIDE/lvp_icd.json LD_LIBRARY_PATH=$ASIDE/usr/lib/x86_64-linux-gnu" >&2
fi
if [ "$BACKPORTS" = 1 ]; then
  backports_source --mesa-backports
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq -t bookworm-backports mesa-vulkan-drivers >/dev/null
  echo "setup: mesa-vulkan-drivers $(dpkg-query -W -f='${Version}' mesa-vulkan-drivers) installed" >&2
fi
if ! command -v cargo >/dev/null; then
  echo "setup: cargo not found; install a Rust toolchain (rustup, Rust 1.86 or newer)" >&2
  exit 1
fi
echo "setup: ok" >&2
