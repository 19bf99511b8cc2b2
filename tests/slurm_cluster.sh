#!/usr/bin/env bash
# A single-node SLURM cluster for the SLURM profile's test (tests/test_slurm.py):
#   tests/slurm_cluster.sh start DIR   installs Debian's slurm-wlm and munge if missing,
#                                      writes DIR/slurm.conf and starts munged, slurmctld, slurmd
#   tests/slurm_cluster.sh stop DIR    stops the daemons started in DIR
# Clients find the cluster through /etc/slurm/slurm.conf, a link to DIR/slurm.conf made
# here (srun inside a job looks there), so a machine with a SLURM configuration of its
# own is refused rather than changed. Needs root (apt-get, munged). Job status comes from squeue: no accounting
# database, and MinJobAge keeps finished jobs visible to it for 10 minutes.
set -euo pipefail

action=${1:?usage: slurm_cluster.sh start|stop DIR}
dir=$(realpath -m "${2:?usage: slurm_cluster.sh start|stop DIR}")

fail() { echo "slurm_cluster.sh: $*" >&2; exit 1; }

stop() {
    if [[ -L /etc/slurm/slurm.conf && $(readlink /etc/slurm/slurm.conf) == "$dir/slurm.conf" ]]; then
        rm -f /etc/slurm/slurm.conf
    fi
    # the pids first: a daemon removes its pid file while it shuts down
    pids=()
    for name in slurmd slurmctld munged; do
        [[ -f "$dir/$name.pid" ]] && pids+=("$(cat "$dir/$name.pid")")
    done
    for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
    # wait for them to go, so that a next start finds the ports free
    for _ in $(seq 100); do
        alive=0
        for pid in "${pids[@]}"; do kill -0 "$pid" 2>/dev/null && alive=1; done
        [[ $alive == 0 ]] && break
        sleep 0.2
    done
    for pid in "${pids[@]}"; do kill -9 "$pid" 2>/dev/null || true; done
    rm -f "$dir"/*.pid
}

start() {
    [[ $(id -u) == 0 ]] || fail "needs root (apt-get and munged); run the tests as root as CI does"
    if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
        (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge >/dev/null) \
            || fail "could not install slurm-wlm and munge with apt-get"
    fi
    mkdir -p "$dir/state" "$dir/spool" "$dir/munge"
    chown munge:munge "$dir/munge"
    [[ -s /etc/munge/munge.key ]] || mungekey --create --keyfile /etc/munge/munge.key
    chown munge:munge /etc/munge/munge.key && chmod 400 /etc/munge/munge.key
    host=$(hostname -s)
    mem=$(awk '/MemTotal/ {print int($2 / 1024 * 0.8)}' /proc/meminfo)
    cat >"$dir/slurm.conf" <<EOF
ClusterName=freqbrdf
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$dir/munge/munge.socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
SlurmctldPort=6817
SlurmdPort=6818
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
ReturnToService=2
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
MinJobAge=600
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
NodeName=$host CPUs=$(nproc) RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
    if [[ -e /etc/slurm/slurm.conf && ! -L /etc/slurm/slurm.conf ]]; then
        fail "/etc/slurm/slurm.conf exists: this machine has a SLURM configuration of its own; not touching it"
    fi
    mkdir -p /etc/slurm
    ln -sfn "$dir/slurm.conf" /etc/slurm/slurm.conf
    /usr/sbin/munged --force --socket="$dir/munge/munge.socket" --pid-file="$dir/munged.pid" \
        --log-file="$dir/munged.log" --seed-file="$dir/munge/seed" || fail "munged did not start ($dir/munged.log)"
    /usr/sbin/slurmctld -f "$dir/slurm.conf" || fail "slurmctld did not start ($dir/slurmctld.log)"
    /usr/sbin/slurmd -f "$dir/slurm.conf" || fail "slurmd did not start ($dir/slurmd.log)"
    for _ in $(seq 100); do
        if [[ $(sinfo -h -N -o %t 2>/dev/null) == idle ]]; then
            echo "slurm_cluster.sh: node $host idle (configuration $dir/slurm.conf)"
            return 0
        fi
        sleep 0.2
    done
    stop
    fail "node $host did not become idle within 20 s (logs in $dir)"
}

case $action in
    start) start ;;
    stop) stop ;;
    *) fail "unknown action $action (start or stop)" ;;
esac
