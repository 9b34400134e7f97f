#!/usr/bin/env bash
# Cold builds (target removed, registry cached, CARGO_INCREMENTAL=0) of the
# same read written with yosemitech and with tokio-modbus, one after the
# other, in debug and release; with a second checkout of the repository as
# its argument (`git worktree add ../before <commit>`), its yosemitech too.
# Prints each build's seconds and its ratio to the tokio-modbus build.
set -euo pipefail
cd "$(dirname "$0")"
before=${1:-}
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
cp -r tokio-modbus-read yosemitech-read "$scratch"/
sed -i "s#path = \"../../crates/yosemitech\"#path = \"$PWD/../crates/yosemitech\"#" "$scratch/yosemitech-read/Cargo.toml"
crates=(tokio-modbus-read yosemitech-read)
if [ -n "$before" ]; then
    cp -r yosemitech-read "$scratch/yosemitech-read-before"
    sed -i "s#path = \"../../crates/yosemitech\"#path = \"$(cd "$before" && pwd)/crates/yosemitech\"#; s/^name = \"yosemitech-read\"/name = \"yosemitech-read-before\"/" \
        "$scratch/yosemitech-read-before/Cargo.toml"
    crates=(tokio-modbus-read yosemitech-read-before yosemitech-read)
fi
# Fetch and resolve first, so that only compiling is timed.
for crate in "${crates[@]}"; do (cd "$scratch/$crate" && cargo fetch -q); done
for profile in debug release; do
    flag=()
    [ "$profile" = release ] && flag=(--release)
    yardstick=
    for crate in "${crates[@]}"; do
        rm -rf "$scratch/$crate/target"
        start=$(date +%s%N)
        (cd "$scratch/$crate" && CARGO_INCREMENTAL=0 cargo build -q "${flag[@]}")
        ms=$((($(date +%s%N) - start) / 1000000))
        yardstick=${yardstick:-$ms}
        printf '%-24s %-7s %6.1f s  %.2fx\n' "$crate" "$profile" "$(echo "$ms / 1000" | bc -l)" "$(echo "$ms / $yardstick" | bc -l)"
    done
done
