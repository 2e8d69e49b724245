#!/usr/bin/env bash
# Reproduces RESULTS.md: tactus criterion medians, then the Python peers, same machine, one go.
set -euo pipefail
cd "$(dirname "$0")/../.."
P=benches/peers
[ -x $P/.venv/bin/python ] || { python3 -m venv $P/.venv && $P/.venv/bin/pip install -r $P/requirements.txt; }
uptime
cargo bench -p tactus-dsp --bench pitch -- --warm-up-time 1 --measurement-time 3 song
cargo bench -p tactus-dsp --bench onsets -- --warm-up-time 1 --measurement-time 3 song_180s
uptime
for f in song_180s/yin song_180s/pyin onsets_song_180s/frame2048_hop512; do
  python3 -c "import json; m=json.load(open('target/criterion/$f/new/estimates.json'))['median']; print('$f median', round(m['point_estimate']/1e6, 2), 'ms')"
done
$P/.venv/bin/python $P/peers.py
uptime
