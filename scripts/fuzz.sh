#!/usr/bin/env bash
# Coverage-guided fuzzing of tetvr's readers with libFuzzer, on the stable toolchain.
#
#   scripts/fuzz.sh [--seconds N] [TARGET...]   build, then fuzz each target N seconds (default 60)
#   scripts/fuzz.sh --list                      the targets
#
# libfuzzer-sys compiles libFuzzer (C++) and the targets are instrumented with LLVM's
# SanitizerCoverage through stable rustc flags (-Cpasses=sancov-module and -Cllvm-args), which
# is what `cargo fuzz` does on nightly without a sanitizer; no nightly toolchain is needed.
# Each target's corpus grows in fuzz/corpus/TARGET (not in git), starting from fuzz/seeds/TARGET.
# libFuzzer runs in fork mode so a finding does not end the run: every crash, timeout (over 1 s)
# and out-of-memory case (over 2 GB resident, or one allocation over 1 GB) is kept in
# fuzz/artifacts/TARGET/ (emptied at the start of each run of that target). The script fails if
# a target found anything, unless the target is listed in fuzz/known-open-targets (findings
# whose fix is pending).
#
# Exit status: 0 clean, 1 findings or a build failure, 2 no C++ compiler and none could be
# installed (the caller then relies on the corpus replay in `cargo test --test fuzz_replay`).
set -euo pipefail
cd "$(dirname "$0")/.."

seconds=60
targets=()
while [[ $# -gt 0 ]]; do
    case $1 in
        --seconds) seconds=$2; shift 2 ;;
        --list) sed -n 's/^name = "\(.*\)"$/\1/p' fuzz/Cargo.toml | grep -v tetvr-fuzz; exit 0 ;;
        *) targets+=("$1"); shift ;;
    esac
done
if [[ ${#targets[@]} -eq 0 ]]; then
    mapfile -t targets < <("$0" --list)
fi

# libFuzzer is C++: libfuzzer-sys builds it with the system compiler.
if ! command -v c++ >/dev/null; then
    if [[ $(id -u) -eq 0 ]] && command -v apt-get >/dev/null; then
        echo "installing a C++ compiler for libFuzzer: g++" >&2
        apt-get update >&2 && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends g++ >&2
    else
        echo "fuzz: no C++ compiler (c++) to build libFuzzer; install g++ to fuzz" >&2
        exit 2
    fi
fi

host=$(rustc -vV | sed -n 's/^host: //p')
# The flags cargo-fuzz passes for `--sanitizer none`; --target keeps them off build scripts.
export RUSTFLAGS="--cfg fuzzing -Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares"
(cd fuzz && cargo build --locked --release --target "$host" --bins)
bin=fuzz/target/$host/release

known_open=$(grep -v '^#' fuzz/known-open-targets 2>/dev/null || true)
failed=()
for t in "${targets[@]}"; do
    rm -rf "fuzz/artifacts/$t"
    mkdir -p "fuzz/corpus/$t" "fuzz/artifacts/$t" "fuzz/seeds/$t"
    log=fuzz/artifacts/$t.log
    "$bin/$t" -fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1 \
        -max_total_time="$seconds" -timeout=1 -rss_limit_mb=2048 -malloc_limit_mb=1024 \
        -artifact_prefix="fuzz/artifacts/$t/" "fuzz/corpus/$t" "fuzz/seeds/$t" >"$log" 2>&1 || true
    # Fork mode's last status line: "#N: cov: C ft: F corp: K exec/s: E oom/timeout/crash: ...".
    stats=$(grep -E '^#[0-9]+: cov:' "$log" | tail -1)
    findings=$(find "fuzz/artifacts/$t" -type f | wc -l)
    echo "fuzz $t: ${stats:-no status line, see $log}; findings kept: $findings"
    if [[ -z $stats ]] || { [[ $findings -gt 0 ]] && ! grep -qx "$t" <<<"$known_open"; }; then
        failed+=("$t")
    fi
done
if [[ ${#failed[@]} -gt 0 ]]; then
    echo "fuzz: findings or failures in: ${failed[*]} (inputs in fuzz/artifacts/TARGET/, logs in fuzz/artifacts/TARGET.log);" \
        "keep each as a regression file: README, 'Fuzzing'" >&2
    exit 1
fi
