#!/usr/bin/env bash
# Stops the Slurm that up.sh started in the folder $1: cancels its jobs, then ends only the
# daemons whose pid files are in that folder (SIGTERM, then SIGKILL after a grace period).
set -uo pipefail
dir=$(realpath -m "${1:?usage: down.sh FOLDER}")
export SLURM_CONF="$dir/slurm.conf"
[ -f "$SLURM_CONF" ] && scancel --full --user=root >/dev/null 2>&1
pids=()
for pid_file in "$dir/slurmd.pid" "$dir/slurmctld.pid" "$dir/munge/munged.pid"; do
    [ -f "$pid_file" ] && pids+=("$(cat "$pid_file")")
done
for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null; done
for _ in $(seq 50); do
    alive=0
    for pid in "${pids[@]}"; do kill -0 "$pid" 2>/dev/null && alive=1; done
    [ $alive = 0 ] && exit 0
    sleep 0.1
done
for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null; done
exit 0
