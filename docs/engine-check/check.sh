#!/bin/sh
# Loads the `--engine godot` lightmaps of a sample level (the ZIP EXR and
# the padded PNG) with Godot 3's Image class, headless, and compares every
# texel with what the `image` crate reads from the same files. Needs the
# Debian package godot3-server (Godot 3.2; `godot3` works too, under
# xvfb-run). Run from the repository's top folder:
#   sh docs/engine-check/check.sh [LEVEL.png] [OUTPUT FOLDER]
set -eu
level=${1:-levels/cornell.png}
out=${2:-/tmp/flatbake-engine-check}
name=$(basename "$level" .png)
godot=$(command -v godot3-server || command -v godot3)
cargo build --release --quiet --bin flatbake --example engine_check
mkdir -p "$out"
./target/release/flatbake bake "$level" -o "$out" --engine godot --force --quiet
exr="$out/$name.lightmap.exr"
png="$out/$name.lightmap.png"
# Godot writes a logs/ folder where it runs: run it in the output folder.
script=$(realpath docs/engine-check/dump.gd)
exr=$(realpath "$exr")
png=$(realpath "$png")
(cd "$out" && "$godot" --no-window -s "$script" -- exr "$exr" png "$png") \
    > "$out/godot.log" 2>&1 || true
grep -E '^(exr|png) ' "$out/godot.log" > "$out/godot.txt" || true
./target/release/examples/engine_check exr "$exr" png "$png" > "$out/flatbake.txt"
echo "Godot $("$godot" --version 2>/dev/null | tail -1) on $exr and $png:"
grep -E '^(exr|png) (error|format)' "$out/godot.txt" || true
# Texel by texel: the largest difference per file, absolute and relative
# to the texel's largest channel, and how many texels differ at all.
awk '
    NR == FNR { if ($2 != "format" && $2 != "error") want[$1 " " $2 " " $3] = $0; next }
    $2 == "format" || $2 == "error" { next }
    {
        key = $1 " " $2 " " $3; split(want[key], w, " ")
        if (!(key in want)) { missing[$1]++; next }
        n[$1]++; top = 0
        for (k = 4; k <= 6; k++) if (w[k] + 0 > top) top = w[k] + 0
        for (k = 4; k <= 7; k++) {
            d = $k - w[k]; if (d < 0) d = -d
            if (d > abs[$1]) abs[$1] = d
            if (k < 7 && top > 0 && d / top > rel[$1]) rel[$1] = d / top
            if (d > 0) differ[$1 " " key] = 1
        }
    }
    END {
        for (k in differ) { split(k, p, " "); count[p[1]]++ }
        for (f in n) printf "%s: %d texels compared, %d differ, largest difference %.3g (%.3g of the texel'"'"'s brightest channel)%s\n", f, n[f], count[f] + 0, abs[f], rel[f], (f in missing) ? ", " missing[f] " missing" : ""
    }' "$out/flatbake.txt" "$out/godot.txt"
