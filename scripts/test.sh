#!/usr/bin/env bash
# The project's one test command: makes sure a Vulkan driver is present (the GPU tests run on
# Mesa's software rasterizer, lavapipe, where there is no GPU) and Xvfb for the viewer's window
# test, then runs the whole suite.
# Arguments go to `cargo test`, e.g. `scripts/test.sh --test stats`.
set -euo pipefail
cd "$(dirname "$0")/.."

# Vulkan needs the loader (libvulkan.so.1) and a driver manifest (ICD). Lavapipe's manifest is
# lvp_icd*.json; checked without vulkaninfo, which is not installed by default.
have_vulkan() {
    compgen -G '/usr/share/vulkan/icd.d/lvp_icd*.json' >/dev/null &&
        [[ $(PATH="$PATH:/sbin:/usr/sbin" ldconfig -p 2>/dev/null) == *'libvulkan.so.1 '* ]]
}
# The viewer's window test (tests/viewer.rs) runs under Xvfb and drives the window with
# xdotool; winit loads the X11 client libraries at run time.
have_x_test_tools() {
    command -v xvfb-run >/dev/null && command -v xdotool >/dev/null
}
packages=()
have_vulkan || packages+=(mesa-vulkan-drivers libvulkan1)
have_x_test_tools ||
    packages+=(xvfb xauth xdotool libxkbcommon-x11-0 libx11-xcb1 libxcursor1 libxrandr2 libxi6)
if [[ ${#packages[@]} -gt 0 ]]; then
    if [[ $(id -u) -eq 0 ]]; then
        as_root=()
    elif command -v sudo >/dev/null; then
        as_root=(sudo)
    elif ! have_vulkan; then
        echo "error: no software Vulkan driver found; install as root: apt-get install ${packages[*]}" >&2
        exit 1
    else
        echo "note: the viewer's window test will skip; install as root: apt-get install ${packages[*]}" >&2
        packages=()
    fi
fi
if [[ ${#packages[@]} -gt 0 ]]; then
    echo "installing what the tests need: ${packages[*]}" >&2
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

# The whole suite (no arguments) ends with a bounded coverage-guided fuzzing run of every
# reader: TETVR_FUZZ_SECONDS per target (11 targets, plus about 3 minutes to build them the
# first time); 0 skips it. Without a C++ compiler for libFuzzer (exit 2) the fuzz corpus
# replay above (tests/fuzz_replay.rs) is what remains.
fuzz_seconds=${TETVR_FUZZ_SECONDS:-15}
if [[ $# -eq 0 && $fuzz_seconds -gt 0 ]]; then
    status=0
    scripts/fuzz.sh --seconds "$fuzz_seconds" || status=$?
    if [[ $status -eq 2 ]]; then
        echo "fuzzing skipped: no libFuzzer toolchain; the corpus was replayed by cargo test" >&2
    elif [[ $status -ne 0 ]]; then
        exit "$status"
    fi
fi
