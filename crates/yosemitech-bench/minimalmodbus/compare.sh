#!/usr/bin/env bash
# `yosemitech poll` against minimalmodbus, both reading one float from the same
# independent emulator (line_emulator.py: a slave written apart from this
# workspace, which keeps the wire's timing on a pty), in alternation, so both
# see the same machine load. Prints each tool's share of the wire limit
# (BENCHMARKS.md, "Against minimalmodbus").
#
# usage: compare.sh BAUD SECONDS ROUNDS [YOSEMITECH_BINARY...]
#   the binaries default to target/release/yosemitech (build it first:
#   cargo build --release -p yosemitech-cli); more than one compares builds.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
baud=$1; secs=$2; rounds=$3; shift 3
bins=("$@"); [ ${#bins[@]} -gt 0 ] || bins=("$here/../../../target/release/yosemitech")
python3 -c 'import minimalmodbus' 2>/dev/null || pip install --quiet minimalmodbus
path_file=$(mktemp)
python3 "$here/line_emulator.py" "$baud" > "$path_file" & emulator=$!
trap 'kill $emulator; rm -f "$path_file"' EXIT
while [ ! -s "$path_file" ]; do sleep 0.1; done
port=$(cat "$path_file")
# One read of 2 registers: 8 request and 9 reply characters, the slave's
# turnaround and the master's gap (t3.5 each; 1.75 ms above 19200 baud).
limit=$(python3 -c "c = 10 / $baud; t = 3.5 * c if $baud <= 19200 else 0.00175; print(1 / (17 * c + 2 * t))")
polls=$(python3 -c "print(int($limit * $secs))")
seconds() { /usr/bin/time -f %e "$@" 2>&1 >/dev/null | tail -1; }
rate() { # polls a second, the tool's start-up taken out by a short run
  local short long
  short=$(seconds "$1" poll ph_orp ph --port "$port" --baud "$baud" --interval 0 -n 20 -f csv)
  long=$(seconds "$1" poll ph_orp ph --port "$port" --baud "$baud" --interval 0 -n "$polls" -f csv)
  python3 -c "print(($polls - 20) / ($long - $short))"
}
share() { python3 -c "print(f'{100 * $1 / $limit:.1f} %')"; }
for round in $(seq "$rounds"); do
  line="$baud baud, round $round:"
  for bin in "${bins[@]}"; do line="$line  $(basename "$(dirname "$bin")")/$(basename "$bin") $(share "$(rate "$bin")")"; done
  line="$line  minimalmodbus $(share "$(python3 "$here/minimalmodbus_reads.py" "$port" "$baud" "$secs")")"
  echo "$line  (load $(cut -d' ' -f1 /proc/loadavg))"
done
