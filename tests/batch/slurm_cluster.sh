#!/usr/bin/env bash
# A single-node Slurm cluster on the loopback for the length of one command: munged, slurmctld and
# slurmd started from a configuration in a temporary folder (their own key, sockets, ports, state
# and logs; nothing under /etc is read or written), COMMAND run with SLURM_CONF pointing at it,
# then every daemon stopped, also when COMMAND or the start fails. On a failure the daemons' logs
# are printed.
#
# usage: tests/batch/slurm_cluster.sh COMMAND [ARGS...]
#
# Needs Debian's slurm-wlm and munge (`apt-get install slurm-wlm munge`) and root: slurmd starts
# each job's steps as the submitting user. The cluster's user (SlurmUser, SlurmdUser) is the
# user running this script. COMMAND is stopped after BLOCKWALK_SLURM_TIMEOUT seconds (default
# 600; exit 124). BLOCKWALK_SLURM_KEEP=1 keeps the temporary folder.
#
# Configuration: ClusterName=blockwalk-test, SlurmctldHost=localhost, one node `localhost` with the
# CPUs and memory `slurmd -C` finds, one partition `batch`, proctrack/linuxproc, task/none,
# select/cons_tres (several array tasks share the node), no accounting.
set -euo pipefail

[ $# -ge 1 ] || { sed -n '2,/^set /p' "$0" | sed '$d; s/^# \{0,1\}//' >&2; exit 2; }
for tool in munged slurmctld slurmd sbatch scontrol sinfo squeue scancel; do
  command -v "$tool" >/dev/null || { echo "slurm_cluster: $tool not found (apt-get install slurm-wlm munge)" >&2; exit 3; }
done

T=$(mktemp -d "${TMPDIR:-/tmp}/blockwalk-slurm.XXXXXX")
# Others may pass through (munged wants its socket reachable), not list or write.
chmod 711 "$T"
mkdir -p "$T/munge" "$T/state" "$T/spool" "$T/log"
USER_NAME=$(id -un)
MUNGED_PID="" CTLD_PID="" SLURMD_PID="" CMD_PID=""

logs() {
  for f in "$T"/log/*.log; do
    [ -s "$f" ] || continue
    echo "----- $(basename "$f") (last 60 lines) -----" >&2
    tail -n 60 "$f" >&2
  done
}

# Stops one daemon started here: TERM, then KILL after 10 s.
stop() {
  local pid=$1
  [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null || return 0
  kill -TERM "$pid" 2>/dev/null || true
  for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || return 0; sleep 0.1; done
  kill -KILL "$pid" 2>/dev/null || true
}

cleanup() {
  local rc=$?
  trap - EXIT INT TERM
  trap '' PIPE   # a closed reader of the logs must not stop the cleanup
  set +e
  [ -n "$CMD_PID" ] && stop "$CMD_PID"
  if [ -n "$CTLD_PID" ] && kill -0 "$CTLD_PID" 2>/dev/null; then
    # This cluster's jobs only (SLURM_CONF names it): their steps end before slurmd does.
    scancel --user="$USER_NAME" >/dev/null 2>&1
    for _ in $(seq 50); do [ -z "$(squeue -h 2>/dev/null)" ] && break; sleep 0.2; done
  fi
  stop "$SLURMD_PID"; stop "$CTLD_PID"; stop "$MUNGED_PID"
  if [ $rc -ne 0 ]; then
    echo "slurm_cluster: failed (exit $rc); the daemons' logs, from $T/log:" >&2
    logs
  fi
  if [ "${BLOCKWALK_SLURM_KEEP:-}" = 1 ]; then echo "slurm_cluster: kept $T" >&2; else rm -rf "$T"; fi
  exit $rc
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

fail() { echo "slurm_cluster: $*" >&2; exit 1; }

# A free TCP port on the loopback (nothing answers a connection to it).
free_port() {
  local p
  for p in $(shuf -i 20000-60000 -n 50); do
    if ! (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null; then echo "$p"; return; fi
  done
  fail "no free port found on 127.0.0.1"
}

# munged with its own key and socket.
head -c 1024 /dev/urandom > "$T/munge/munge.key"
chmod 400 "$T/munge/munge.key"
munged --foreground --force --key-file="$T/munge/munge.key" --socket="$T/munge/munge.socket" \
  --pid-file="$T/munge/munged.pid" --seed-file="$T/munge/munged.seed" --log-file="$T/log/munged.log" \
  > "$T/log/munged.out.log" 2>&1 &
MUNGED_PID=$!
for _ in $(seq 100); do [ -S "$T/munge/munge.socket" ] && break; kill -0 $MUNGED_PID 2>/dev/null || break; sleep 0.1; done
[ -S "$T/munge/munge.socket" ] || fail "munged did not start"

CTLD_PORT=$(free_port)
SLURMD_PORT=$(free_port)
[ "$CTLD_PORT" != "$SLURMD_PORT" ] || SLURMD_PORT=$(free_port)
# The node as slurmd finds it (CPUs, sockets, cores, threads, memory), named localhost.
NODE=$(slurmd -C | head -n 1 | sed 's/^NodeName=[^ ]* //')
cat > "$T/slurm.conf" <<CONF
ClusterName=blockwalk-test
SlurmctldHost=localhost
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
SlurmUser=$USER_NAME
SlurmdUser=$USER_NAME
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$T/munge/munge.socket
StateSaveLocation=$T/state
SlurmdSpoolDir=$T/spool
SlurmctldPidFile=$T/slurmctld.pid
SlurmdPidFile=$T/slurmd.pid
SlurmctldLogFile=$T/log/slurmctld.log
SlurmdLogFile=$T/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
PlugStackConfig=$T/plugstack.conf
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
# Start the next array task as soon as one ends (a test cluster: no need to batch the work).
SchedulerParameters=batch_sched_delay=0,sched_min_interval=0
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
MpiDefault=none
MailProg=/bin/true
ReturnToService=2
MinJobAge=600
NodeName=localhost NodeAddr=127.0.0.1 $NODE State=UNKNOWN
PartitionName=batch Nodes=localhost Default=YES MaxTime=INFINITE State=UP
CONF
: > "$T/plugstack.conf"
export SLURM_CONF="$T/slurm.conf"

slurmctld -D -i -f "$SLURM_CONF" > "$T/log/slurmctld.out.log" 2>&1 &
CTLD_PID=$!
for _ in $(seq 150); do scontrol ping >/dev/null 2>&1 && break; kill -0 $CTLD_PID 2>/dev/null || break; sleep 0.2; done
scontrol ping >/dev/null 2>&1 || fail "slurmctld did not answer on port $CTLD_PORT"

slurmd -D -N localhost -f "$SLURM_CONF" > "$T/log/slurmd.out.log" 2>&1 &
SLURMD_PID=$!
# The node is ready when the controller sees it idle (60 s at most).
state=""
for _ in $(seq 300); do
  state=$(sinfo -h -n localhost -o %T 2>/dev/null || true)
  [ "$state" = idle ] && break
  kill -0 $SLURMD_PID 2>/dev/null || fail "slurmd exited"
  sleep 0.2
done
[ "$state" = idle ] || fail "node localhost is '${state:-unknown}', not idle, after 60 s: $(scontrol show node localhost 2>&1 | grep -E 'State|Reason' | tr -s ' ' | tr '\n' ' ')"
echo "slurm_cluster: munged, slurmctld (port $CTLD_PORT) and slurmd (port $SLURMD_PORT) up, node localhost idle ($NODE); SLURM_CONF=$SLURM_CONF" >&2

# In the background, so that a signal to this script reaches the trap at once.
timeout "${BLOCKWALK_SLURM_TIMEOUT:-600}" "$@" &
CMD_PID=$!
rc=0
wait $CMD_PID || rc=$?
CMD_PID=""
[ $rc -ne 124 ] || echo "slurm_cluster: $* ran past ${BLOCKWALK_SLURM_TIMEOUT:-600} s" >&2
exit $rc
