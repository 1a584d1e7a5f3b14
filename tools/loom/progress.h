/*
 * tools/loom/progress.h - progress reports of long commands on stderr.
 *
 * Three modes, chosen at begin: a bar redrawn in place when stderr is a
 * terminal ("label [=====>    ] 40/100 tiles  3.2/s  ETA 0:19"), plain
 * lines when it is not (at most one per 10% of the work or per 10 s, so
 * logs of batch jobs stay short), nothing with --quiet.  Rates and ETA
 * come from the monotonic clock.  Not thread-safe: call update from one
 * thread (or under the caller's lock).
 */
#ifndef LOOM_PROGRESS_H
#define LOOM_PROGRESS_H

#include <stdint.h>

enum { PROGRESS_OFF = 0, PROGRESS_BAR = 1, PROGRESS_LINES = 2 };

typedef struct cli_progress {
	const char *label;  /* "loom export" */
	const char *unit;   /* "tiles", "voxels" */
	uint64_t total;     /* 0: unknown (no bar, no ETA) */
	uint64_t done;
	double t0;          /* seconds at begin */
	double last;        /* seconds at the last report */
	uint64_t last_done; /* done at the last plain line */
	int mode;           /* PROGRESS_* */
	int drawn;          /* a bar is on the terminal line */
} cli_progress;

/* Start a report; quiet selects PROGRESS_OFF.  $LOOM_PROGRESS=lines|bar|off
   overrides the choice (tests use it). */
void cli_progress_begin(cli_progress *p, const char *label, const char *unit,
                        uint64_t total, int quiet);
/* Set the amount done (absolute); reports when due. */
void cli_progress_update(cli_progress *p, uint64_t done);
/* Final report (100% line or the finished bar and a newline). */
void cli_progress_end(cli_progress *p);
/* Seconds on the monotonic clock. */
double cli_now(void);

#endif
