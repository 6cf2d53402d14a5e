#!/usr/bin/env bash
# Brings up a single-node Slurm cluster on this machine: writes a minimal
# /etc/slurm/slurm.conf for this host (its hostname, CPUs and memory as
# `slurmd -C` reports them), then starts munged, slurmctld and slurmd and
# waits until the node is idle. Needs root and Debian's `slurm-wlm` and
# `munge` (`apt-get install -y slurm-wlm munge`). Idempotent: a running
# daemon is left running.
set -euo pipefail

host=$(hostname -s)
# `slurmd -C` prints this node's line of slurm.conf (and an UpTime line).
node=$(slurmd -C | grep '^NodeName=')

mkdir -p /etc/slurm /var/spool/slurmctld /var/spool/slurmd /var/log/slurm /run/munge /run/slurm
chown slurm:slurm /var/spool/slurmctld /var/log/slurm /run/slurm
chown munge:munge /run/munge

cat > /etc/slurm/slurm.conf <<CONF
# A single-node cluster (scripts/slurm/setup.sh).
ClusterName=lagrangian
SlurmctldHost=$host
AuthType=auth/munge
SlurmUser=slurm
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
SlurmctldPidFile=/run/slurm/slurmctld.pid
SlurmdPidFile=/run/slurm/slurmd.pid
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
# No cgroups (a container may not delegate them): processes tracked by parent id.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
# One CPU per array task by default, so the tasks share the node's cores.
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MpiDefault=none
$node State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF

pgrep -x munged >/dev/null || runuser -u munge -- /usr/sbin/munged
pgrep -x slurmctld >/dev/null || /usr/sbin/slurmctld
pgrep -x slurmd >/dev/null || /usr/sbin/slurmd

for _ in $(seq 60); do
    state=$(sinfo --noheader --nodes="$host" --format=%T 2>/dev/null || true)
    if [ "$state" = idle ]; then
        echo "slurm: node $host idle ($node)"
        exit 0
    fi
    sleep 1
done
echo "slurm: node $host not idle after 60 s (state: ${state:-none}); see /var/log/slurm/" >&2
exit 1
