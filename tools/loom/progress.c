/*
 * tools/loom/progress.c - progress bar / plain progress lines on stderr
 * (see progress.h).
 */
#include "progress.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

double cli_now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static void fmt_count(char *buf, size_t n, double v)
{
	if (v >= 1e12)
		snprintf(buf, n, "%.2fT", v / 1e12);
	else if (v >= 1e9)
		snprintf(buf, n, "%.2fG", v / 1e9);
	else if (v >= 1e6)
		snprintf(buf, n, "%.2fM", v / 1e6);
	else if (v >= 1e4)
		snprintf(buf, n, "%.1fk", v / 1e3);
	else
		snprintf(buf, n, "%.0f", v);
}

static void fmt_eta(char *buf, size_t n, double s)
{
	if (!(s >= 0) || s > 360000.0) {
		snprintf(buf, n, "--:--");
		return;
	}
	unsigned long t = (unsigned long)(s + 0.5);
	if (t >= 3600)
		snprintf(buf, n, "%lu:%02lu:%02lu", t / 3600, t / 60 % 60, t % 60);
	else
		snprintf(buf, n, "%lu:%02lu", t / 60, t % 60);
}

void cli_progress_begin(cli_progress *p, const char *label, const char *unit,
                        uint64_t total, int quiet)
{
	memset(p, 0, sizeof *p);
	p->label = label;
	p->unit = unit;
	p->total = total;
	p->t0 = p->last = cli_now();
	p->mode = quiet ? PROGRESS_OFF
	          : isatty(2) ? PROGRESS_BAR : PROGRESS_LINES;
	const char *env = getenv("LOOM_PROGRESS");
	if (!quiet && env) {
		if (!strcmp(env, "off"))
			p->mode = PROGRESS_OFF;
		else if (!strcmp(env, "lines"))
			p->mode = PROGRESS_LINES;
		else if (!strcmp(env, "bar"))
			p->mode = PROGRESS_BAR;
	}
}

static void report(cli_progress *p, double now, int final)
{
	double el = now - p->t0;
	double rate = el > 0 ? (double)p->done / el : 0.0;
	char d[32], t[32], r[32], eta[32];
	fmt_count(d, sizeof d, (double)p->done);
	fmt_count(t, sizeof t, (double)p->total);
	fmt_count(r, sizeof r, rate);
	if (final)
		fmt_eta(eta, sizeof eta, el);
	else
		fmt_eta(eta, sizeof eta, rate > 0 && p->total >= p->done
		        ? (double)(p->total - p->done) / rate : -1.0);
	const char *eta_word = final ? "in" : "ETA";
	if (p->mode == PROGRESS_BAR) {
		char bar[33];
		int w = 30, fill = 0;
		if (p->total)
			fill = (int)((double)w * (double)p->done / (double)p->total);
		if (fill > w)
			fill = w;
		for (int i = 0; i < w; i++)
			bar[i] = i < fill ? '=' : (i == fill ? '>' : ' ');
		bar[w] = 0;
		if (p->total)
			fprintf(stderr, "\r%s [%s] %s/%s %s  %s/s  %s %s\033[K",
			        p->label, bar, d, t, p->unit, r, eta_word, eta);
		else
			fprintf(stderr, "\r%s %s %s  %s/s\033[K", p->label, d,
			        p->unit, r);
		p->drawn = 1;
		if (final) {
			fputc('\n', stderr);
			p->drawn = 0;
		}
	} else if (p->total) {
		fprintf(stderr, "%s: %s/%s %s (%.0f%%), %s/s, %s %s\n", p->label, d,
		        t, p->unit, 100.0 * (double)p->done / (double)p->total, r,
		        eta_word, eta);
	} else {
		fprintf(stderr, "%s: %s %s, %s/s\n", p->label, d, p->unit, r);
	}
	fflush(stderr);
}

void cli_progress_update(cli_progress *p, uint64_t done)
{
	p->done = done;
	if (p->mode == PROGRESS_OFF)
		return;
	double now = cli_now();
	if (p->mode == PROGRESS_BAR) {
		if (now - p->last < 0.1)
			return;
	} else {
		uint64_t step = p->total / 10;
		int due_work = p->total && done - p->last_done >= (step ? step : 1);
		if (!due_work && now - p->last < 10.0)
			return;
		p->last_done = done;
	}
	p->last = now;
	report(p, now, 0);
}

void cli_progress_end(cli_progress *p)
{
	if (p->mode == PROGRESS_OFF)
		return;
	report(p, cli_now(), 1);
}
