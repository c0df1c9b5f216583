#!/usr/bin/env bash
# A city in tiles on Kubernetes: the plan Job, then the Indexed Job of the tiles (completions =
# the plan's tiles), then the merge Job, each waited for; on the volume of pvc.yaml, which must
# already hold the city under /data/city (see README.md).
#
# usage: examples/jobs/k8s/run.sh [--namespace NS] [--parallel P] [--timeout SECONDS]
#        examples/jobs/k8s/run.sh render-tiles TILES PARALLEL   (print tiles-job.yaml filled in)
#
# --parallel: tile pods at once (default 8); --timeout: seconds each Job may take (default 21600).
# Jobs of an earlier run (same names) are deleted first: a Job's spec cannot be changed.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)

die() { echo "run.sh: $*" >&2; exit 2; }

render_tiles() {
  [[ $1 =~ ^[1-9][0-9]*$ && $2 =~ ^[1-9][0-9]*$ ]] || die "TILES and PARALLEL must be positive integers, not '$1' '$2'"
  sed -e "s/\${TILES}/$1/g" -e "s/\${PARALLEL}/$2/g" "$HERE/tiles-job.yaml"
}

if [ "${1:-}" = render-tiles ]; then
  [ $# -eq 3 ] || die "usage: run.sh render-tiles TILES PARALLEL"
  render_tiles "$2" "$3"
  exit 0
fi

NS=() P=8 TIMEOUT=21600
while [ $# -gt 0 ]; do
  case $1 in
    --namespace) NS=(--namespace "$2"); shift 2 ;;
    --parallel) P=$2; shift 2 ;;
    --timeout) TIMEOUT=$2; shift 2 ;;
    *) die "unknown argument $1" ;;
  esac
done
K() { kubectl "${NS[@]}" "$@"; }

# Waits until job/$1 is Complete (returns 0) or Failed (prints its pods' states, returns 1).
wait_job() {
  local end=$((SECONDS + TIMEOUT)) c
  while [ $SECONDS -lt $end ]; do
    c=$(K get job "$1" -o jsonpath='{range .status.conditions[?(@.status=="True")]}{.type} {end}')
    case " $c " in
      *" Complete "*) return 0 ;;
      *" Failed "*)
        echo "run.sh: job $1 failed:" >&2
        K get pods -l "job-name=$1" -o wide >&2 || true
        return 1 ;;
    esac
    sleep 5
  done
  echo "run.sh: job $1 did not finish in $TIMEOUT s" >&2
  return 1
}

K delete job blockwalk-plan blockwalk-tiles blockwalk-merge --ignore-not-found >/dev/null
K apply -f "$HERE/pvc.yaml"
K apply -f "$HERE/plan-job.yaml"
wait_job blockwalk-plan
# The plan's pod that succeeded (an earlier try may have failed) printed one `jobs run` line per tile.
POD=$(K get pods -l job-name=blockwalk-plan --field-selector=status.phase=Succeeded -o name | head -n 1)
N=$(K logs "$POD" | grep -c ' jobs run ' || true)
[ "$N" -ge 1 ] || die "the plan printed no tiles: $(K logs "$POD" | tail -n 5)"
echo "plan: $N tiles; the tiles Job runs $P pods at once" >&2
render_tiles "$N" "$P" | K apply -f -
wait_job blockwalk-tiles
K apply -f "$HERE/merge-job.yaml"
wait_job blockwalk-merge
K logs job/blockwalk-merge
