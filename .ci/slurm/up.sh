#!/usr/bin/env bash
# Starts a single-node Slurm on loopback for tests: munged, slurmctld and slurmd, with every
# file (key, config, state, spool, logs, pid files) under the folder given as $1.
# Prints the path of the slurm.conf to export as SLURM_CONF. Needs root and the Debian packages
# slurmctld slurmd slurm-client munge. Stop it with down.sh and the same folder.
set -euo pipefail
dir=$(realpath -m "${1:?usage: up.sh FOLDER}")
mkdir -p "$dir"
chmod 755 "$dir"
# munged (which runs as the user munge) must be able to reach its files.
ancestor=$dir
while [ "$ancestor" != / ]; do
    ancestor=$(dirname "$ancestor")
    if ! setpriv --reuid=munge --regid=munge --init-groups test -x "$ancestor"; then
        echo "up.sh: $ancestor is not searchable by the user munge; use a folder under one that is (mode 755)" >&2
        exit 1
    fi
done
node=$(hostname -s)

# Slurm binds to what the host name resolves to; make that loopback.
if ! getent hosts "$node" | grep -q '^127\.'; then
    echo "127.0.0.1 $node" >> /etc/hosts
fi

# munge refuses key and socket folders writable by others, and sockets in folders others
# cannot search.
munge_dir="$dir/munge"
mkdir -p "$munge_dir"
chown munge:munge "$munge_dir"
chmod 755 "$munge_dir"
dd if=/dev/urandom of="$munge_dir/munge.key" bs=1024 count=1 status=none
chown munge:munge "$munge_dir/munge.key"
chmod 400 "$munge_dir/munge.key"
setpriv --reuid=munge --regid=munge --init-groups munged \
    --socket="$munge_dir/munge.socket" --key-file="$munge_dir/munge.key" \
    --pid-file="$munge_dir/munged.pid" --log-file="$munge_dir/munged.log" \
    --seed-file="$munge_dir/munged.seed"

mkdir -p "$dir/state" "$dir/spool" "$dir/log"
# A re-queued job may start again only when its old credential has expired: cred_expire
# (default 120 s) is that wait, kept short so that tests of re-queueing stay quick.
node_line=$(slurmd -C | head -1 | sed 's/ RealMemory=[0-9]*//')
cat > "$dir/slurm.conf" <<CONF
ClusterName=loopback
SlurmctldHost=$node(127.0.0.1)
AuthType=auth/munge
AuthInfo=socket=$munge_dir/munge.socket,cred_expire=5
CommunicationParameters=NoCtldInAddrAny,NoInAddrAny
SlurmUser=root
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerParameters=batch_sched_delay=0
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
JobAcctGatherType=jobacct_gather/none
MailProg=/bin/true
ReturnToService=2
$node_line NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=debug Nodes=$node Default=YES MaxTime=INFINITE State=UP
CONF

export SLURM_CONF="$dir/slurm.conf"
slurmctld -c -f "$SLURM_CONF"
for _ in $(seq 100); do scontrol ping 2>/dev/null | grep -q UP && break; sleep 0.1; done
slurmd -f "$SLURM_CONF" -N "$node"
for _ in $(seq 100); do [ "$(sinfo -h -n "$node" -o %t 2>/dev/null)" = idle ] && break; sleep 0.1; done
state=$(sinfo -h -n "$node" -o %t)
if [ "$state" != idle ]; then
    echo "slurmd did not become idle (state: $state); logs in $dir/log" >&2
    exit 1
fi
echo "$SLURM_CONF"
