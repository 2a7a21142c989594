#!/usr/bin/env bash
# The project's one test command: makes sure a Vulkan driver is present (the GPU tests run on
# Mesa's software rasterizer, lavapipe, where there is no GPU), then runs the whole suite.
# Arguments go to `cargo test`, e.g. `scripts/test.sh --test stats`.
set -euo pipefail
cd "$(dirname "$0")/.."

# Vulkan needs the loader (libvulkan.so.1) and a driver manifest (ICD). Lavapipe's manifest is
# lvp_icd*.json; checked without vulkaninfo, which is not installed by default.
have_vulkan() {
    compgen -G '/usr/share/vulkan/icd.d/lvp_icd*.json' >/dev/null &&
        [[ $(PATH="$PATH:/sbin:/usr/sbin" ldconfig -p 2>/dev/null) == *'libvulkan.so.1 '* ]]
}
if ! have_vulkan; then
    packages=(mesa-vulkan-drivers libvulkan1)
    if [[ $(id -u) -eq 0 ]]; then
        as_root=()
    elif command -v sudo >/dev/null; then
        as_root=(sudo)
    else
        echo "error: no software Vulkan driver found; install as root: apt-get install ${packages[*]}" >&2
        exit 1
    fi
    echo "installing the Vulkan loader and Mesa's software driver: ${packages[*]}" >&2
    "${as_root[@]}" apt-get update
    "${as_root[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends "${packages[@]}"
fi

# Mesa warns when XDG_RUNTIME_DIR is unset (common in CI); give it a private directory.
XDG_RUNTIME_DIR=$(mktemp -d)
chmod 0700 "$XDG_RUNTIME_DIR"
export XDG_RUNTIME_DIR
trap 'rm -rf "$XDG_RUNTIME_DIR"' EXIT

# The dev/test profile is optimized (see Cargo.toml); --locked keeps CI on Cargo.lock.
cargo test --locked "$@"
