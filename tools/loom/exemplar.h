/*
 * tools/loom/exemplar.h - the parts of `loom exemplar`, one file per job:
 * cmd_exemplar.c (dispatch, generate), exemplar_scan.c (generate --scan),
 * exemplar_build.c (build), exemplar_info.c (info, verify, export, convert).
 */
#ifndef LOOM_EXEMPLAR_H
#define LOOM_EXEMPLAR_H

#include <stdint.h>
#include <string.h>

int exemplar_generate_scan(int argc, char **argv); /* exemplar_scan.c */
int exemplar_build(int argc, char **argv);         /* exemplar_build.c */
int exemplar_info(int argc, char **argv);          /* exemplar_info.c */
int exemplar_verify(int argc, char **argv);
int exemplar_export(int argc, char **argv);
int exemplar_convert(int argc, char **argv);

/* 1 if s ends in suf (case-sensitive). */
static inline int exemplar_ends_with(const char *s, const char *suf)
{
	size_t a = strlen(s), b = strlen(suf);
	return a >= b && strcmp(s + a - b, suf) == 0;
}

#endif
