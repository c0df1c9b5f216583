#!/usr/bin/env bash
# A city in tiles on a Slurm cluster: `blockwalk jobs plan`, then one array task per tile
# (`sbatch --array=0-(N-1)%P`, each task `blockwalk jobs run PLAN --tile $SLURM_ARRAY_TASK_ID`),
# then `blockwalk jobs merge` as a job that starts only when every task has succeeded
# (`--dependency=afterok:ARRAY_JOB`). Submit from a login node; the binary, CITY and OUT must be
# on a file system every compute node sees, under the same paths.
#
# usage: examples/jobs/slurm.sh [options] CITY OUT [-- jobs run options, e.g. --blockmaps 64]
#
#   CITY                 a generated city's folder, or a footprint .shp with --streets
#   OUT                  the plan's folder (plan.json, tiles/, index.json)
#   --streets FILE       street centre lines, when CITY is a footprint file
#   --max-buildings N    buildings per tile (default 50000)
#   --parallel P         array tasks running at once, the array's %P (default 16)
#   --partition NAME     partition of every job (default: the cluster's default partition)
#   --time LIMIT         time limit of every job, in sbatch's form (default $SBATCH_TIMELIMIT,
#                        else 1:00:00)
#   --mem SIZE           memory of every job (default $SBATCH_MEM_PER_NODE, else 2G; a
#                        100,000-building tile peaks near
#                        0.5 GiB, the plan of a million buildings near 0.25 GiB)
#   --account NAME       account to charge
#   --sbatch-arg ARG     one more sbatch option for every job (repeatable, e.g. --sbatch-arg=--qos=low)
#   --plan-job           run the plan as a Slurm job too (waits for it) instead of on this node
#   --logs DIR           the jobs' batch scripts (with their #SBATCH options) and logs
#                        (default OUT.slurm): plan.out/.err, tile_I.out/.err per task,
#                        merge.out/.err
#   --wait               wait for the merge and exit with its status; on a failure, list the
#                        tasks that failed
#   --poll SECONDS       how often the state of a job waited for is asked (default 5)
#
# The environment: BLOCKWALK (the binary; default `blockwalk` on PATH), and sbatch's own
# SBATCH_* variables (SBATCH_PARTITION, SBATCH_ACCOUNT, ...), which the options override.
#
# Prints the array's and the merge's job ids (without --wait) or the merge's summary (with it).
# A tile that failed can be run again alone, with the same options, then the merge:
#   sbatch --array=I OUT.slurm/tile.sbatch && sbatch OUT.slurm/merge.sbatch
# An array has at most MaxArraySize - 1 as its last index (`scontrol show config`, 1001 by
# default): choose --max-buildings so that the plan has fewer tiles.
set -euo pipefail

die() { echo "slurm.sh: $*" >&2; exit 2; }
usage() { sed -n '2,/^set /p' "$0" | sed '$d; s/^# \{0,1\}//' >&2; exit 2; }

STREETS="" MAXB=50000 P=16 PARTITION="" TIME=${SBATCH_TIMELIMIT:-1:00:00} MEM=${SBATCH_MEM_PER_NODE:-2G} ACCOUNT="" PLAN_JOB=0 LOGS="" WAIT=0 POLL=5
EXTRA=() POS=() RUN_OPTS=()
while [ $# -gt 0 ]; do
  case $1 in
    --streets) STREETS=$2; shift 2 ;;
    --max-buildings) MAXB=$2; shift 2 ;;
    --parallel) P=$2; shift 2 ;;
    --partition) PARTITION=$2; shift 2 ;;
    --time) TIME=$2; shift 2 ;;
    --mem) MEM=$2; shift 2 ;;
    --account) ACCOUNT=$2; shift 2 ;;
    --sbatch-arg) EXTRA+=("$2"); shift 2 ;;
    --sbatch-arg=*) EXTRA+=("${1#--sbatch-arg=}"); shift ;;
    --plan-job) PLAN_JOB=1; shift ;;
    --logs) LOGS=$2; shift 2 ;;
    --wait) WAIT=1; shift ;;
    --poll) POLL=$2; shift 2 ;;
    -h|--help) usage ;;
    --) shift; RUN_OPTS=("$@"); break ;;
    -*) die "unknown option $1 (see --help)" ;;
    *) POS+=("$1"); shift ;;
  esac
done
[ ${#POS[@]} -eq 2 ] || usage
[[ $P =~ ^[1-9][0-9]*$ ]] || die "--parallel must be a positive integer, not '$P'"
[[ $POLL =~ ^[0-9]+(\.[0-9]+)?$ ]] || die "--poll must be a number of seconds, not '$POLL'"
command -v sbatch >/dev/null || die "sbatch not found: run this on a Slurm login node"

B=$(command -v "${BLOCKWALK:-blockwalk}") || die "blockwalk not found (set BLOCKWALK to the binary)"
B=$(realpath "$B")
CITY=$(realpath "${POS[0]}")
mkdir -p "${POS[1]}"
OUT=$(realpath "${POS[1]}")
LOGS=$(realpath -m "${LOGS:-$OUT.slurm}")
mkdir -p "$LOGS"
PLAN_ARGS=(jobs plan "$CITY" -o "$OUT" --max-buildings "$MAXB")
[ -n "$STREETS" ] && PLAN_ARGS+=(--streets "$(realpath "$STREETS")")

# Options of every job.
COMMON=(--time="$TIME" --mem="$MEM")
[ -n "$PARTITION" ] && COMMON+=(--partition="$PARTITION")
[ -n "$ACCOUNT" ] && COMMON+=(--account="$ACCOUNT")
COMMON+=("${EXTRA[@]}")

# A batch script FILE: the shebang, an #SBATCH line per option (the options before `--`; a value
# with spaces in double quotes), then one command line with every word quoted (`printf %q`),
# where a word @TILE@ becomes the array task's index and `>` FILE sends the output to FILE.
script() {
  local file=$1 w; shift
  {
    echo '#!/bin/bash'
    while [ "$1" != -- ]; do
      case $1 in
        *=*\ *) echo "#SBATCH ${1%%=*}=\"${1#*=}\"" ;;
        *) echo "#SBATCH $1" ;;
      esac
      shift
    done
    shift
    while [ $# -gt 0 ]; do
      case $1 in
        @TILE@) printf '"$SLURM_ARRAY_TASK_ID" ' ;;
        '>') printf '> %q' "$2"; shift ;;
        *) printf '%q ' "$1" ;;
      esac
      shift
    done
    echo
  } > "$file"
}

# Waits until job $1 has ended; prints its last state (JobState=COMPLETED, ...), or nothing when
# the controller has already forgotten it (MinJobAge after its end).
wait_job() {
  local state
  while :; do
    state=$(scontrol -o show job "$1" 2>/dev/null | grep -o 'JobState=[A-Z_]*' | head -n 1 || true)
    case $state in
      JobState=PENDING|JobState=CONFIGURING|JobState=RUNNING|JobState=COMPLETING|JobState=SUSPENDED|\
      JobState=REQUEUED*|JobState=RESIZING|JobState=SIGNALING|JobState=STAGE_OUT) sleep "$POLL" ;;
      *) echo "$state"; return ;;
    esac
  done
}

# 1. The plan, which says how many tiles there are.
if [ $PLAN_JOB = 1 ]; then
  # Its standard output is the list of the tiles' commands.
  script "$LOGS/plan.sbatch" "${COMMON[@]}" --job-name=blockwalk-plan --output="$LOGS/plan.out" \
    --error="$LOGS/plan.err" -- "$B" "${PLAN_ARGS[@]}" '>' "$LOGS/commands.txt"
  echo "plan: a Slurm job (waiting for it)..." >&2
  PLAN=$(sbatch --parsable "$LOGS/plan.sbatch")
  STATE=$(wait_job "${PLAN%%;*}")
  [ "${STATE:-JobState=COMPLETED}" = JobState=COMPLETED ] \
    || die "plan job ${PLAN%%;*}: ${STATE#JobState=}: $(tail -n 5 "$LOGS/plan.err" 2>/dev/null)"
else
  "$B" "${PLAN_ARGS[@]}" > "$LOGS/commands.txt" 2> "$LOGS/plan.err" \
    || die "jobs plan failed: $(cat "$LOGS/plan.err")"
fi
N=$(grep -c -- ' jobs run ' "$LOGS/commands.txt" || true)
[ "$N" -ge 1 ] || die "the plan has no tiles ($LOGS/commands.txt)"
MAX_ARRAY=$(scontrol show config 2>/dev/null | awk '$1 == "MaxArraySize" {print $3}')
if [ -n "$MAX_ARRAY" ] && [ "$N" -gt "$MAX_ARRAY" ]; then
  die "$N tiles, but this cluster's arrays end at index $((MAX_ARRAY - 1)) (MaxArraySize): raise --max-buildings"
fi
echo "plan: $N tiles in $OUT/plan.json" >&2

# 2. The tiles: one array task each, at most P at once.
script "$LOGS/tile.sbatch" "${COMMON[@]}" --job-name=blockwalk-tiles --output="$LOGS/tile_%a.out" \
  --error="$LOGS/tile_%a.err" -- "$B" jobs run "$OUT/plan.json" --tile @TILE@ "${RUN_OPTS[@]}"
ARRAY=$(sbatch --parsable --array="0-$((N - 1))%$P" "$LOGS/tile.sbatch")
ARRAY=${ARRAY%%;*}
echo "tiles: array job $ARRAY, tasks 0-$((N - 1)), at most $P at once; logs $LOGS/tile_I.out, .err" >&2

# 3. The merge, once every task has succeeded (cancelled if one fails).
script "$LOGS/merge.sbatch" "${COMMON[@]}" --job-name=blockwalk-merge --output="$LOGS/merge.out" \
  --error="$LOGS/merge.err" -- "$B" jobs merge "$OUT"
MERGE=$(sbatch --parsable --dependency="afterok:$ARRAY" --kill-on-invalid-dep=yes "$LOGS/merge.sbatch")
MERGE=${MERGE%%;*}
if [ $WAIT = 0 ]; then
  echo "merge: job $MERGE after array $ARRAY; its summary will be in $LOGS/merge.out" >&2
  echo "$ARRAY $MERGE"
  exit 0
fi
echo "merge: job $MERGE after array $ARRAY (waiting for it, asking every $POLL s)..." >&2
# A merge whose dependency failed is cancelled before it runs.
STATE=$(wait_job "$MERGE")
if [ "${STATE:-JobState=COMPLETED}" = JobState=COMPLETED ] && [ -s "$LOGS/merge.out" ]; then
  cat "$LOGS/merge.out"
  exit 0
fi
echo "slurm.sh: merge job $MERGE did not complete (${STATE:-no merge.out}); the array's tasks that did not complete:" >&2
scontrol -o show job "$ARRAY" 2>/dev/null \
  | awk '{for (i = 1; i <= NF; i++) if ($i ~ /^(ArrayTaskId|JobState|ExitCode)=/) printf "%s ", $i; print ""}' \
  | grep -v 'JobState=COMPLETED' >&2 || true
for f in "$LOGS"/tile_*.err "$LOGS/merge.err"; do
  [ -s "$f" ] && { echo "--- $f" >&2; tail -n 5 "$f" >&2; }
done
exit 1
