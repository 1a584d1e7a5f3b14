/*
 * tools/loom/shard_lock.h - who is writing into an export directory: fcntl
 * locks on DIR/.loom-export.lock, so that two runs of one shard (a
 * requeued Slurm task overlapping the original, a retry) never write the
 * same files at once, and a run may remove the temporary files of its
 * shard knowing that their writer is gone.
 *
 * The lock file's bytes stand for roles (fcntl locks are byte ranges):
 *
 *     byte N (1 <= N < 2^32)    split N: a read lock held by every run of
 *                               an N-way split (unsharded: N = 1) and by
 *                               its merge
 *     byte 2^33 + I             shard I: a write lock held by the run of
 *                               shard I (of the split held)
 *     byte 2^34                 merge: a write lock held by --merge
 *
 * A run takes its split's byte, then checks that no other split's byte is
 * held (runs of another split write the same tiles under other shard
 * numbers; two runs that start together both see each other and both
 * refuse, so neither writes), then takes its shard's byte or refuses.
 * The locks are the kernel's (or the NFS lock manager's): they end with
 * the process however it ends, kill -9 and node failures included, and
 * the lock file itself is never removed (removing it would let two runs
 * lock two different files).
 *
 * While a run holds its shard, no other process writes that shard's tiles
 * or its manifest, so every temporary file of them in DIR is a dead
 * writer's: export_remove_stale removes exactly those.  (When io/core
 * gives every atomic writer a lock on its own temporary, the sweep will
 * ask that lock instead; the shard lock stays, to keep runs apart.)
 */
#ifndef LOOM_SHARD_LOCK_H
#define LOOM_SHARD_LOCK_H

#include <stddef.h>
#include <stdint.h>

typedef struct shard_lock {
	int fd;                    /* the lock file, -1 when not held */
} shard_lock;

#define SHARD_LOCK_NAME ".loom-export.lock"

/* Take shard i of an n-way split (n = 1: unsharded) of the export in dir.
   0 when held; -1 with a message naming the other run (its process id,
   when on this host) when another run holds the shard or another split
   runs, or when the lock file cannot be made. */
int shard_lock_shard(shard_lock *l, const char *dir, uint32_t i, uint32_t n, char *msg,
                     size_t msz);
/* For --merge of an n-way split: the split, no shard of it running, and the
   merge byte.  0, or -1 with a message. */
int shard_lock_merge(shard_lock *l, const char *dir, uint32_t n, char *msg, size_t msz);
/* Release (closes the file; the locks end with it).  NULL-safe. */
void shard_lock_release(shard_lock *l);

/* The shards of an n-way split that are running now (their lock is held
   by a process), as flags running[0 .. n); 0, or -1 (no lock file: none
   is running, running is all 0). */
int shard_lock_running(const char *dir, uint32_t n, uint8_t *running);

#endif
