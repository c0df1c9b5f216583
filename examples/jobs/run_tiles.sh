#!/bin/bash
# A city in tiles on one machine: plan, every tile with `xargs -P`, merge, each step under
# /usr/bin/time -v (peak memory per job). The figures in docs/jobs.md come from this script.
#
# usage: examples/jobs/run_tiles.sh CITY_DIR OUT_DIR MAX_BUILDINGS [PARALLEL] [-- run options, e.g. --blockmaps 64]
set -euo pipefail
B=${BLOCKWALK:-target/release/blockwalk}
CITY=$1; OUT=$2; MAXB=$3; P=${4:-2}; shift $(( $# >= 4 ? 4 : 3 ))
[ "${1:-}" = "--" ] && shift
LOG=$OUT.log
rm -rf "$OUT" "$LOG"; mkdir -p "$LOG"
t0=$(date +%s.%N)
/usr/bin/time -v "$B" jobs plan "$CITY" -o "$OUT" --max-buildings "$MAXB" > "$LOG/commands.txt" 2> "$LOG/plan.time"
t1=$(date +%s.%N)
N=$(wc -l < "$LOG/commands.txt")
seq 0 $((N - 1)) | xargs -P "$P" -I{} sh -c \
  "/usr/bin/time -v '$B' jobs run '$OUT/plan.json' --tile {} $* > '$LOG/tile{}.out' 2> '$LOG/tile{}.time'"
t2=$(date +%s.%N)
/usr/bin/time -v "$B" jobs merge "$OUT" | tee "$LOG/merge.out"
t3=$(date +%s.%N)
echo "tiles $N; plan $(echo "$t1 - $t0" | bc) s, tiles $(echo "$t2 - $t1" | bc) s, merge $(echo "$t3 - $t2" | bc) s, total $(echo "$t3 - $t0" | bc) s"
echo "peak RSS per tile job, KiB (min, max):"
grep -h "Maximum resident" "$LOG"/tile*.time | awk '{print $6}' | sort -n | sed -n '1p;$p'
