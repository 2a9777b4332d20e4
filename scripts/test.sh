#!/usr/bin/env bash
# The whole test suite. Installs lavapipe (Mesa's CPU Vulkan driver) and the
# Khronos validation layer first when they are missing and this user can
# (root with apt-get), so the GPU tests run on any machine; then runs every
# test with WHITTED_REQUIRE_GPU=1, which makes GPU tests fail, not skip,
# when no Vulkan device can be had.
set -euo pipefail
cd "$(dirname "$0")/.."
have_icd() { ls /usr/share/vulkan/icd.d/*.json /etc/vulkan/icd.d/*.json >/dev/null 2>&1; }
have_layer() { ls /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json >/dev/null 2>&1; }
if ! have_icd || ! have_layer; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "test.sh: installing lavapipe and the Vulkan validation layer" >&2
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq mesa-vulkan-drivers libvulkan1 vulkan-validationlayers >/dev/null
  else
    echo "test.sh: no Vulkan driver or validation layer, and cannot install them (need root and apt-get)" >&2
  fi
fi
export WHITTED_REQUIRE_GPU=${WHITTED_REQUIRE_GPU:-1}
cargo test --all-targets "$@"
