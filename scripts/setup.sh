#!/usr/bin/env bash
# Installs what arbor needs on Debian 12: Vulkan loader and lavapipe (software
# Vulkan), the Khronos validation layer, shaderc/glslang/SPIRV-Tools static libraries
# (linked into build.rs, see docs/build-notes.md), the assimp test models used by the tests,
# and Slurm with munge (the render-farm test starts a single-node cluster).
set -euo pipefail
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
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
if ! command -v cargo >/dev/null; then
  echo "setup: cargo not found; install a Rust toolchain (rustup, Rust 1.86 or newer)" >&2
  exit 1
fi
echo "setup: ok" >&2
