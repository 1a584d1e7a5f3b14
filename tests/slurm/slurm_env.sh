# tests/slurm/slurm_env.sh - a private single-node Slurm for tests: munged,
# slurmctld and slurmd on localhost, state and logs under one directory.
# Source it, then `slurm_start DIR` (0 when the node is idle and takes
# jobs, else 1 with the reason in $slurm_why) and `slurm_stop` (kills the
# three daemons by the PIDs it recorded, removes DIR).  Facts it relies
# on: ../../DEPENDENCIES.md of the shared notes ("Slurm 22.05 on one
# node"): root, no systemd, no cgroups, proctrack/linuxproc, task/none.

slurm_pids=""
slurm_dir=""
slurm_why=""

# A free TCP port on the loopback interface.
slurm_free_port() {
	python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

slurm_start() { # DIR
	slurm_dir=$1
	if [ "$(id -u)" != 0 ]; then
		slurm_why="not root: slurmd needs root to start jobs as their user (CI runs as root)"
		return 1
	fi
	for c in munged mungekey slurmctld slurmd sbatch squeue scancel scontrol sinfo; do
		if ! command -v $c >/dev/null 2>&1; then
			slurm_why="$c is missing (tools/deps.sh slurm installs slurmctld, slurmd, slurm-client, munge)"
			return 1
		fi
	done
	mkdir -p "$slurm_dir/munge" "$slurm_dir/state" "$slurm_dir/spool" "$slurm_dir/log" || return 1
	chmod 0700 "$slurm_dir/munge"
	if ! mungekey -c -k "$slurm_dir/munge/munge.key" >/dev/null 2>&1; then
		slurm_why="mungekey cannot make a key"
		return 1
	fi
	# -F: stay in the foreground so that $! is the daemon; -f: accept the
	# private (0700) socket directory
	munged -F -f --socket="$slurm_dir/munge/munge.socket" --key-file="$slurm_dir/munge/munge.key" \
		--pid-file="$slurm_dir/munge/munged.pid" --log-file="$slurm_dir/log/munged.log" \
		--seed-file="$slurm_dir/munge/munged.seed" >"$slurm_dir/log/munged.out" 2>&1 &
	slurm_pids="$!"
	cpus=$(nproc)
	mem=$(awk '/^MemTotal:/ { printf "%d", $2 / 1024 * 0.8 }' /proc/meminfo)
	p1=$(slurm_free_port)
	p2=$(slurm_free_port)
	while [ "$p2" = "$p1" ]; do p2=$(slurm_free_port); done
	cat >"$slurm_dir/slurm.conf" <<CONF
ClusterName=loomtest
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort=$p1
SlurmdPort=$p2
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$slurm_dir/munge/munge.socket
StateSaveLocation=$slurm_dir/state
SlurmdSpoolDir=$slurm_dir/spool
SlurmctldPidFile=$slurm_dir/slurmctld.pid
SlurmdPidFile=$slurm_dir/slurmd.pid
SlurmctldLogFile=$slurm_dir/log/slurmctld.log
SlurmdLogFile=$slurm_dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU_Memory
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
MinJobAge=600
NodeName=localhost NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=loom Nodes=localhost Default=YES MaxTime=INFINITE State=UP
CONF
	export SLURM_CONF="$slurm_dir/slurm.conf"
	i=0
	while ! [ -S "$slurm_dir/munge/munge.socket" ]; do
		i=$((i + 1))
		if [ $i -gt 100 ] || ! kill -0 $slurm_pids 2>/dev/null; then
			slurm_why="munged did not start: $(tail -3 "$slurm_dir/log/munged.log" "$slurm_dir/log/munged.out" 2>/dev/null)"
			return 1
		fi
		sleep 0.1
	done
	slurmctld -D -i -f "$SLURM_CONF" >"$slurm_dir/log/slurmctld.out" 2>&1 &
	slurm_pids="$slurm_pids $!"
	slurmd -D -N localhost -f "$SLURM_CONF" >"$slurm_dir/log/slurmd.out" 2>&1 &
	slurm_pids="$slurm_pids $!"
	# the node idle within a few seconds
	i=0
	while :; do
		st=$(sinfo -h -N -o '%T' 2>/dev/null | head -1)
		case $st in
		idle*) break ;;
		esac
		i=$((i + 1))
		for p in $slurm_pids; do
			if ! kill -0 "$p" 2>/dev/null; then
				slurm_why="a Slurm daemon (pid $p) died: $(tail -5 "$slurm_dir/log/slurmctld.log" "$slurm_dir/log/slurmd.log" 2>/dev/null)"
				return 1
			fi
		done
		if [ $i -gt 300 ]; then
			slurm_why="the node is not idle after 30 s (state '$st'): $(tail -5 "$slurm_dir/log/slurmctld.log" "$slurm_dir/log/slurmd.log" 2>/dev/null)"
			return 1
		fi
		sleep 0.1
	done
	return 0
}

slurm_stop() {
	for p in $slurm_pids; do
		kill "$p" 2>/dev/null
	done
	for p in $slurm_pids; do
		i=0
		while kill -0 "$p" 2>/dev/null && [ $i -lt 50 ]; do sleep 0.1; i=$((i + 1)); done
		kill -KILL "$p" 2>/dev/null
	done
	slurm_pids=""
	[ -n "$slurm_dir" ] && rm -rf "$slurm_dir"
	slurm_dir=""
}
