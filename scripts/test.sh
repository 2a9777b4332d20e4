#!/usr/bin/env bash
# The whole test suite. Installs lavapipe (Mesa's CPU Vulkan driver), the
# Khronos validation layer, POV-Ray 3.7 and a font for the charts first when they are missing and
# this user can (root with apt-get), so the GPU tests and the POV-Ray
# comparisons (tests/povray.rs) run on any machine; then runs every test
# with WHITTED_REQUIRE_GPU=1 and WHITTED_REQUIRE_POVRAY=1, which make those
# tests fail, not skip, when no Vulkan device or no povray can be had.
set -euo pipefail
cd "$(dirname "$0")/.."
# A driver manifest in either place (ls of both fails when one folder is
# missing, which made every run reinstall the drivers).
have_icd() { ls /usr/share/vulkan/icd.d/*.json >/dev/null 2>&1 || ls /etc/vulkan/icd.d/*.json >/dev/null 2>&1; }
have_layer() { ls /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json >/dev/null 2>&1; }
need=()
if ! have_icd || ! have_layer; then
  need+=(mesa-vulkan-drivers libvulkan1 vulkan-validationlayers)
fi
command -v povray >/dev/null || need+=(povray)
# The charts' text (src/plot.rs) needs a TrueType font.
ls /usr/share/fonts/truetype/dejavu/DejaVuSans.ttf >/dev/null 2>&1 || need+=(fonts-dejavu-core)
if [ ${#need[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "test.sh: installing ${need[*]}" >&2
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null
  else
    echo "test.sh: missing ${need[*]}, and cannot install them (need root and apt-get)" >&2
  fi
fi
export WHITTED_REQUIRE_GPU=${WHITTED_REQUIRE_GPU:-1}
export WHITTED_REQUIRE_POVRAY=${WHITTED_REQUIRE_POVRAY:-1}
cargo test --all-targets "$@"
# The generators against the SPD's own files, where they are (the plain
# suite checks facts recorded from them everywhere).
spd_dir=${WHITTED_SPD_DIR:-../shared/scenes/spd}
if [ -d "$spd_dir" ]; then
  cargo test --test spd "$@" -- --ignored
fi
