#!/usr/bin/env bash
# Shows that the working tree renders every GPU mode bit for bit as revision REV did (default:
# the commit before the GPU restructuring, issue 14): runs `examples/fingerprint.rs` of both
# (each revision's own copy, so the example may follow API changes) and compares the hashes of
# the f32 pictures, scene by scene and mode by mode. Exits non-zero on any difference.
#   scripts/bit-identical.sh [REV]
set -euo pipefail
cd "$(dirname "$0")/.."
rev=${1:-4ba53e579ac1491808a117c510f96b099500e387}
out=target/bit-identical
mkdir -p "$out"
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}

base_tree=$out/base-tree
rm -rf "$base_tree"
git worktree prune
git worktree add --detach "$base_tree" "$rev" >/dev/null
trap 'git worktree remove --force "$base_tree" 2>/dev/null || true' EXIT
# Both trees build into this checkout's target directory (dependencies compile once). The two
# builds of tetvr share cargo's fingerprint (same package, same relative paths), so cargo tells
# them apart only by the source files' mtimes: the base tree is checked out fresh (newer than
# any artifact, so it rebuilds), and it is removed before the working tree's build, whose
# artifacts would otherwise look fresh against the base tree's files and run the base's binary.
CARGO_TARGET_DIR=$PWD/target cargo run --quiet --locked --example fingerprint \
    --manifest-path "$base_tree/Cargo.toml" >"$out/base.txt"
git worktree remove --force "$base_tree"
cargo run --quiet --locked --example fingerprint >"$out/head.txt"
# Each line must match the base, except that a refusal of the base on the 64 KiB-binding context
# may become a picture, if that picture is bit for bit the unchunked one (the mesh then spans
# several buffers, which must not change a bit).
python3 - "$out/base.txt" "$out/head.txt" "$rev" <<'PY'
import sys
base, head = ([l.rstrip("\n") for l in open(f)] for f in sys.argv[1:3])
key = lambda l: " ".join(l.split()[:3])
value = lambda l: l.split(None, 3)[3]
head_by_key = {key(l): value(l) for l in head}
base_keys = {key(l) for l in base}
unchunked = lambda k: head_by_key.get(k.replace("-chunked", "", 1))
# A constructor's refusal ("new") on the chunked context may become pictures of every view, each
# bit for bit the unchunked one.
lifted_new = {k.rsplit(" ", 1)[0] for l in base for k in [key(l)]
              if "-chunked" in k and k.endswith(" new") and value(l).startswith("error:")
              and k not in head_by_key}
def lifted_picture(k):
    return k.rsplit(" ", 1)[0] in lifted_new and head_by_key[k] == unchunked(k)
lifted = sum(1 for k in head_by_key if k not in base_keys and lifted_picture(k))
bad = [k for k in base_keys if k not in head_by_key and k.rsplit(" ", 1)[0] not in lifted_new] + [
    k for k in head_by_key if k not in base_keys and not lifted_picture(k)]
for l in base:
    k, v = key(l), value(l)
    h = head_by_key.get(k)
    if h is None or h == v:
        continue
    if v.startswith("error:") and "-chunked" in k and h == unchunked(k):
        lifted += 1
        continue
    bad.append(f"{k}: {v} -> {h}")
for b in bad:
    print("differs:", b, file=sys.stderr)
if bad:
    sys.exit(f"{len(bad)} of {len(base)} pictures differ from {sys.argv[3]}")
print(f"bit-identical: {len(base)} pictures match {sys.argv[3]}"
      + (f" ({lifted} refusals of the chunked context now render as unchunked)" if lifted else ""))
PY
