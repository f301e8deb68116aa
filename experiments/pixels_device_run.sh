#!/bin/bash
# The GPU run that made the committed pixel weights (pixels.json says which commit and device).
# It ran from a copy: .devrun/src (this src), .devrun/cache/furniture (the converted sh3d cache),
# .devrun/whl (moderngl, glcontext for Python 3.12), .devrun/gl (EGL debs), .devrun/tools/rate.py
# (experiments/pixels_train_rate.py), .devrun/VERSION (git describe). As run, on one H100:
#   ON_DEVICE=1 FAKE_SH3F=1 BENCH_BY=505 CPURATE_BY=540 bash .devrun/run.sh 3000 390 230 470
# Proven first on CPU: MAXSTEPS=20 WORKERS=2 FRAMES=4 VAL=3900-3900 DEVICE=cpu BATCH=2 ... 3000 2 60 400
# One GPU run: render perception houses, train on the GPU, time inference and CPU steps on 2 cores.
# Usage (repo root): bash .devrun/run.sh FIRST_TRAIN_HOUSE MAX_HOUSES RENDER_END_S TRAIN_END_S
T0=$(date +%s); el() { echo $(( $(date +%s) - T0 )); }
FIRST=${1:-3000}; MAXH=${2:-480}; RENDER_END=${3:-250}; TRAIN_END=${4:-480}; MAXSTEPS=${MAXSTEPS:-7000}
BATCH=${BATCH:-16}; FRAMES=${FRAMES:-24}; WORKERS=${WORKERS:-16}
R=$PWD; WORK=${WORK:-$(mktemp -d)}  # scratch space: the data, the wheels, the output
D=${DATA:-$WORK/data}; V=$WORK/valdata; OUT=${OUT:-$WORK/out}; mkdir -p $OUT $D $V
export PYTHONUNBUFFERED=1
if [ -n "$ON_DEVICE" ]; then for f in .devrun/gl/*.deb; do dpkg -x $f /; done; ldconfig; fi
if [ -n "$ON_DEVICE" ] && ! python3 -c "import moderngl" 2>/dev/null; then
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target $WORK/site .devrun/whl/*.whl || exit 2
  export PYTHONPATH=$WORK/site
fi
export PYTHONPATH=$R/.devrun/src:$R/.devrun:${PYTHONPATH}
export EFFICIENTEQA_CACHE=$R/.devrun/cache EFFICIENTEQA_CODE_VERSION=$(cat .devrun/VERSION)
if [ -n "$FAKE_SH3F" ]; then  # the cached conversion only checks the source's size and mtime
  mkdir -p $WORK/sh3f; truncate -s 24649303 $WORK/sh3f/BlendSwap-CC-0.sh3f
  touch -d @1608597687 $WORK/sh3f/BlendSwap-CC-0.sh3f; export EFFICIENTEQA_FURNITURE_DIR=$WORK/sh3f
fi
PY=${PY:-python3}
EEQA() { $PY -c "import sys; from efficienteqa.cli import main; sys.argv[0]='efficienteqa'; main()" "$@"; }
nvidia-smi -L 2>/dev/null; nproc
echo "[$(el)s] GL check"
glcheck() { $PY -c "
from efficienteqa.envs.synthetic.render_gl import create_context
ctx = create_context(); print(ctx.info['GL_RENDERER'], ctx.info['GL_VERSION'])"; }
if ! glcheck; then
  [ -n "$ON_DEVICE" ] || exit 3
  export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
  ls /usr/local/nvidia/share/glvnd/egl_vendor.d/ /usr/share/glvnd/egl_vendor.d/ 2>&1
  glcheck || { echo "GL FAILED"; ldconfig -p | grep -i "egl\|libGL"; exit 3; }
fi
echo "[$(el)s] validation houses (background) + training houses"
EEQA perception dataset --seeds ${VAL:-3900-3909} --out $V --frames-per-house $FRAMES --workers 2 > $OUT/render.log 2>&1 &
VPID=$!
h=$FIRST; last=0; chunk=$(( WORKERS * 5 ))
while [ $h -lt $(( FIRST + MAXH )) ]; do
  n=$chunk; [ $h -eq $FIRST ] && [ $WORKERS -gt 4 ] && n=$(( (WORKERS - 2) * 5 ))
  [ $(( h + n )) -gt $(( FIRST + MAXH )) ] && n=$(( FIRST + MAXH - h ))
  s=$(el); [ $(( s + last )) -gt $RENDER_END ] && break
  EEQA perception dataset --seeds $h-$(( h + n - 1 )) --out $D --frames-per-house $FRAMES --workers $WORKERS >> $OUT/render.log 2>&1 || { tail -5 $OUT/render.log; exit 4; }
  last=$(( $(el) - s )); h=$(( h + n )); echo "[$(el)s] rendered up to $(( h - 1 )) (chunk ${last}s)"
done
wait $VPID || { tail -5 $OUT/render.log; exit 5; }
cp $V/houses-*.npz $D/ && EEQA perception dataset --seeds ${VAL:-3900-3909} --out $D --frames-per-house $FRAMES --workers 2 >> $OUT/render.log 2>&1 || exit 6
cp $D/meta.json $OUT/meta.json; du -sh $D
echo "[$(el)s] rate"
RATE=$($PY .devrun/tools/rate.py ${DEVICE:-cuda} $BATCH 40 2 | tee -a $OUT/bench.txt | awk '{print $(NF-1)}'); RATE=${RATE:-20}
NOW=$(el); AVAIL=$(( TRAIN_END - NOW - 60 ))
STEPS=$($PY -c "print(max(20, min($MAXSTEPS, int(0.85 * $RATE * $AVAIL))))")
echo "[$(el)s] rate $RATE steps/s, avail ${AVAIL}s -> $STEPS steps"
cp .devrun/src/efficienteqa/perception/pixels/weights/pixels.pt $WORK/committed.pt; cp .devrun/src/efficienteqa/perception/pixels/weights/pixels.json $WORK/committed.json
MIN=$($PY -c "print(round(($TRAIN_END - $NOW - 20) / 60, 2))")
EEQA perception train --data $D --out src/efficienteqa/perception/pixels/weights/pixels.pt --steps $STEPS --seed 0 --batch $BATCH --minutes $MIN --threads 2 --device ${DEVICE:-cuda} > $OUT/train.log 2>&1
tail -3 $OUT/train.log
cp src/efficienteqa/perception/pixels/weights/pixels.pt src/efficienteqa/perception/pixels/weights/pixels.json $OUT/
echo "[$(el)s] benchmarks on 2 cores"
if [ $(el) -lt ${BENCH_BY:-520} ]; then
  for w in $WORK/committed.pt src/efficienteqa/perception/pixels/weights/pixels.pt; do
    echo "== $w" >> $OUT/bench.txt
    taskset -c 0,1 $PY -m benchmarks.pixels_bench --frames 10 --weights $w >> $OUT/bench.txt 2>&1
  done
fi
[ $(el) -lt ${CPURATE_BY:-545} ] && taskset -c 0,1 $PY .devrun/tools/rate.py cpu $BATCH 4 2 >> $OUT/bench.txt 2>&1
cat $OUT/bench.txt; echo "[$(el)s] done"
