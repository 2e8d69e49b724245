#!/usr/bin/env bash
# Whole-song timing of the ONNX separators against issue 5's targets: `tactus render` of a
# 3.5-minute song with --separator htdemucs (full-size model, random weights: same speed as
# trained ones) and with --separator spleeter, end to end (decode, separation, every
# feature chain, pattern file).
#
# Prints per separator: wall time, the paper's 180.45 s divided by it, peak RSS
# (/usr/bin/time -f "%e %M"), the network time per segment (count, mean, min, max) and the
# share of time outside the network (STFT, iSTFT, overlap-add, masks) from `--verbose`, and
# the load average before and after (the machine may be shared: wall time is only
# meaningful when the load is low; memory and the outside share barely depend on it).
# One htdemucs run takes about 100 s on 2 idle cores.
#
# Usage: benches/htdemucs.sh [SEPARATOR...]      (default: htdemucs spleeter)
# Environment:
#   SONG=PATH        the song (default target/bench-song-210s.wav, else benches/make_song.sh's MP3)
#   THREADS=N        --threads for ONNX Runtime (default 2, the issue's "2 cores")
#   CPUS=LIST        pin the whole process to these CPUs with taskset (e.g. 0,1)
#   HTDEMUCS_MODEL   default models/htdemucs-random.onnx (models/export_htdemucs.py --random-weights)
#   SPLEETER_MODEL   default models/spleeter-2stems.onnx (models/setup_models.sh)
#   NO_BUILD=1       skip `cargo build --release --features onnx`
# Targets (htdemucs): wall <= 90 s on 2 cores, outside the network <= 5 % of the network's
# time, peak memory <= 2.5 GB.
set -euo pipefail
cd "$(dirname "$0")/.."

PAPER_S=180.45
threads=${THREADS:-2}
export ORT_DYLIB_PATH=${ORT_DYLIB_PATH:-$PWD/vendor/onnxruntime/capi/libonnxruntime.so.1.31.1}
[ -f "$ORT_DYLIB_PATH" ] || { echo "no ONNX Runtime at $ORT_DYLIB_PATH: run models/setup_onnxruntime.sh" >&2; exit 1; }
[ -x /usr/bin/time ] || { echo "needs /usr/bin/time (Debian package: time)" >&2; exit 1; }

song=${SONG:-}
if [ -z "$song" ]; then
    if [ -f target/bench-song-210s.wav ]; then
        song=target/bench-song-210s.wav
    else
        song=target/song210.mp3
        [ -f "$song" ] || benches/make_song.sh "$song" >/dev/null
    fi
fi
[ -f "$song" ] || { echo "no song at $song" >&2; exit 1; }

if [ -z "${NO_BUILD:-}" ]; then
    cargo build --release --features onnx --bin tactus >&2
fi
bin=target/release/tactus
pin=()
[ -n "${CPUS:-}" ] && pin=(taskset -c "$CPUS")

seps=("$@")
[ ${#seps[@]} -gt 0 ] || seps=(htdemucs spleeter)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

echo "song: $song; --threads $threads; $(nproc) CPUs${CPUS:+, pinned to $CPUS}; $(date -u +%FT%TZ)"
echo
echo "| separator | wall | paper 180.45 s / wall | peak RSS | segments | network per segment (mean / min / max) | outside the network | load avg before / after |"
echo "|---|---|---|---|---|---|---|---|"

for sep in "${seps[@]}"; do
    case $sep in
        htdemucs) model=${HTDEMUCS_MODEL:-models/htdemucs-random.onnx} ;;
        spleeter) model=${SPLEETER_MODEL:-models/spleeter-2stems.onnx} ;;
        *) echo "unknown separator $sep (htdemucs, spleeter)" >&2; exit 2 ;;
    esac
    [ -f "$model" ] || { echo "no model at $model (see models/README.md)" >&2; exit 1; }
    load_before=$(cut -d' ' -f1 /proc/loadavg)
    "${pin[@]}" /usr/bin/time -f "%e %M" -o "$tmp/time" "$bin" render "$song" \
        --separator "$sep" --model "$model" --threads "$threads" --verbose \
        -o "$tmp/pattern.json" 2>"$tmp/log" || { cat "$tmp/log" >&2; exit 1; }
    load_after=$(cut -d' ' -f1 /proc/loadavg)
    read -r wall rss_kb <"$tmp/time"
    seg=$(grep -m1 'network segments:' "$tmp/log" || true)
    out=$(grep -m1 'outside the network' "$tmp/log" || true)
    n=$(sed -E 's/.*segments: ([0-9]+),.*/\1/' <<<"$seg")
    per=$(sed -E 's/.*mean ([0-9.]+) s, min ([0-9.]+) s, max ([0-9.]+) s.*/\1 \/ \2 \/ \3 s/' <<<"$seg")
    share=$(sed -E 's/.*= ([0-9.]+) %.*/\1/' <<<"$out")
    out_s=$(sed -E 's/.*\): ([0-9.]+) s = .*/\1/' <<<"$out")
    awk -v sep="$sep" -v wall="$wall" -v kb="$rss_kb" -v n="$n" -v per="$per" \
        -v share="$share" -v out_s="$out_s" -v lb="$load_before" -v la="$load_after" -v paper="$PAPER_S" \
        'BEGIN { printf "| %s | %.1f s | %.2f× | %.2f GB | %s | %s | %s s = %s %% | %s / %s |\n",
                 sep, wall, paper / wall, kb * 1024 / 1e9, n, per, out_s, share, lb, la }'
    if [ "$sep" = htdemucs ]; then
        awk -v wall="$wall" -v kb="$rss_kb" -v share="$share" 'BEGIN {
            printf "  targets: wall %.1f s %s 90 s; outside %.1f %% %s 5 %%; peak %.2f GB %s 2.5 GB\n",
                wall, (wall <= 90 ? "<=" : "> MISSED"), share, (share <= 5 ? "<=" : "> MISSED"),
                kb * 1024 / 1e9, (kb * 1024 / 1e9 <= 2.5 ? "<=" : "> MISSED") }' >&2
    fi
done

