#!/usr/bin/env bash
# Flash and RAM of the firmware binaries (BENCHMARKS.md, "Firmware size"),
# from llvm-size's sections: flash = .vector_table + .text + .rodata + .data,
# static RAM = .data + .bss. Every sensor of yosemitech::SENSORS is measured,
# by name, as the generated code lists them.
set -euo pipefail
cd "$(dirname "$0")"
out=target/thumbv7em-none-eabihf/release
size() {
    llvm-size -A "$1" | awk '/^\.vector_table|^\.text|^\.rodata|^\.data|^\.bss/ {s[$1]=$2}
        END {printf "%d %d %d %d\n", s[".vector_table"]+s[".text"]+s[".rodata"]+s[".data"], s[".data"]+s[".bss"], s[".text"], s[".rodata"]}'
}
cargo build --release --quiet --bins
read -r base_flash base_ram _ _ < <(size $out/size_baseline)
echo "| binary | flash (bytes) | over the board alone | static RAM (bytes) |"
echo "|---|---|---|---|"
for bin in size_baseline size_driver read_probes rmodbus_probes; do
    read -r flash ram _ _ < <(size $out/$bin)
    echo "| \`$bin\` | $flash | $((flash - base_flash)) | $ram |"
done
for sensor in $(grep -oP '^\s+\K\w+(?=::MODULE,)' ../crates/yosemitech/generated/mod.rs); do
    SENSOR=$sensor cargo build --release --quiet --bin size_codecs
    read -r flash ram _ _ < <(size $out/size_codecs)
    echo "| \`size_codecs\` (SENSOR=$sensor) | $flash | $((flash - base_flash)) | $ram |"
done
# The same without the derived quantities: the command table's codecs alone.
for sensor in $(grep -oP '^\s+\K\w+(?=::MODULE,)' ../crates/yosemitech/generated/mod.rs); do
    COMMANDS_ONLY=1 SENSOR=$sensor cargo build --release --quiet --bin size_codecs
    read -r flash ram _ _ < <(size $out/size_codecs)
    echo "| \`size_codecs\` (SENSOR=$sensor COMMANDS_ONLY=1) | $flash | $((flash - base_flash)) | $ram |"
done
