#!/usr/bin/env bash
# Installs what a fresh Debian/Ubuntu machine lacks to build, test and run splatbench:
# Mesa's software Vulkan driver (lavapipe) and the Vulkan loader, so wgpu finds an adapter
# with no GPU; jq, which scripts/gpu-bench.sh (run by the tests) reads summaries with; Xvfb
# and xauth (xvfb-run), the X server without a screen that the viewer's end-to-end test
# (tests/view.rs) opens its window on; rustfmt and clippy (CI lints) where rustup can add
# them. Plot and HUD fonts are embedded in the binary (harness/assets), nothing to install.
# Idempotent: installs nothing when everything is present.
set -euo pipefail

need=()
for pkg in mesa-vulkan-drivers libvulkan1 jq xvfb xauth; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || need+=("$pkg")
done

if [ ${#need[@]} -gt 0 ]; then
  sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  echo "setup: installing ${need[*]}"
  $sudo apt-get update -qq
  # `env` after sudo (which resets the environment); DEBCONF_NOWARNINGS silences debconf's
  # "delaying package configuration, since apt-utils is not installed", which is no failure.
  $sudo env DEBIAN_FRONTEND=noninteractive DEBCONF_NOWARNINGS=yes \
    apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi

command -v cargo >/dev/null || { echo "setup: cargo not found: install Rust (https://rustup.rs)" >&2; exit 1; }

# rustfmt and clippy, which CI (.ci/run) runs before the tests: rustup's default profile has
# them; a minimal one does not.
for tool in fmt clippy; do
  if ! cargo "$tool" --version >/dev/null 2>&1; then
    component=$([ "$tool" = fmt ] && echo rustfmt || echo clippy)
    command -v rustup >/dev/null || { echo "setup: cargo $tool not found and no rustup to add it: install the $component component" >&2; exit 1; }
    echo "setup: adding the $component component"
    rustup component add "$component"
  fi
done
echo "setup: ok (Vulkan loader + lavapipe, Xvfb present, $(cargo --version))"
