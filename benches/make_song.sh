#!/usr/bin/env bash
# Builds the 3.5-minute stereo test song used for the whole-song timings in README.md:
# the bundled demo (two corpus chorales with drums) looped to 210 s and encoded as MP3.
# Needs ffmpeg (Debian package). Usage: benches/make_song.sh [OUT.mp3]
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/song210.mp3}
ffmpeg -loglevel error -y -stream_loop 13 -i examples/demo.ogg -t 210 -c:a libmp3lame -b:a 192k "$out"
echo "$out"
