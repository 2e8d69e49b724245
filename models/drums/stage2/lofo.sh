#!/bin/bash
# Leave-one-family-out screen of a training recipe (issue 10): five fold models, each trained
# on four of the five training families (timgm, csound, sonicpi, synth, remix) and never on
# the fifth, at 12 epochs; oof.py then scores each family with the fold that never saw
# it. usage: models/drums/stage2/lofo.sh NAME [extra train.py args]
#   -> $LOFO_DIR/NAME_<family>.bin (LOFO_DIR default /tmp/lofo; data LOFO_DATA, /work/data/drums)
#   LOFO_FOLDS: the families to hold out in turn (default all five)
#   LOFO_HELD: the groups every fold also leaves out (default fluid,musescore; empty: none)
cd "$(dirname "$0")/../../.."
D=${LOFO_DIR:-/tmp/lofo}; mkdir -p "$D"
N=$1; shift
H=${LOFO_HELD-fluid,musescore}
C="--data ${LOFO_DATA:-/work/data/drums} --conds iso,sep --neg-keep 0.5 --shift 0 --warp 1.5 --stretch 1.5 --families timgm,csound,sonicpi,synth,remix --future 4 --epochs 12"
for F in ${LOFO_FOLDS:-sonicpi timgm csound synth remix}; do
  [ -f $D/${N}_$F.bin ] && continue
  echo "$(date +%T) $N $F"; corpus/.venv/bin/python models/drums/train.py $C "$@" --held-out $F${H:+,$H} --out $D/${N}_$F.bin > $D/${N}_$F.log 2>&1
done
echo "$(date +%T) $N done"
