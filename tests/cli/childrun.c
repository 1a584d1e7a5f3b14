/*
 * tests/cli/childrun.c - run one command as a child and report how it
 * ended and its peak resident memory, for the hostile-input table
 * (tests/cli/test_hostile.sh).
 *
 *   childrun SECONDS CMD [ARGS...]   run CMD; kill it after SECONDS (a hang
 *                                    guard, not a timing assertion)
 *   childrun SECONDS --exr FILE      the child calls loom_exr_read(FILE)
 *                                    (no loom command reads EXR files)
 *
 * The child's stdout and stderr are its own.  On its own stdout childrun
 * prints one line: "exit N maxrss_kib K" (N is 128+signal when killed, and
 * "timeout" replaces the exit when the guard fired).  childrun exits 0.
 */
#include "loom.h"

#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

static int read_exr(const char *path)
{
	loom_diag diag;
	loom_exr_image *img = NULL;

	memset(&diag, 0, sizeof diag);
	if (loom_exr_read(path, &img, &diag) != LOOM_OK) {
		fprintf(stderr, "childrun: %s\n", diag.message);
		return 1;
	}
	loom_exr_image_free(img);
	return 0;
}

int main(int argc, char **argv)
{
	struct rusage ru;
	int status, timed_out = 0, code;
	unsigned secs;
	pid_t pid;

	if (argc < 3) {
		fprintf(stderr, "usage: childrun SECONDS CMD [ARGS...]\n");
		return 2;
	}
	secs = (unsigned)atoi(argv[1]);
	pid = fork();
	if (pid < 0) {
		perror("childrun: fork");
		return 2;
	}
	if (pid == 0) {
		if (strcmp(argv[2], "--exr") == 0 && argc == 4)
			_exit(read_exr(argv[3]));
		execvp(argv[2], argv + 2);
		perror("childrun: exec");
		_exit(127);
	}
	for (unsigned waited = 0;; waited++) {
		pid_t r = wait4(pid, &status, WNOHANG, &ru);
		if (r == pid)
			break;
		if (r < 0) {
			perror("childrun: wait4");
			return 2;
		}
		if (waited >= secs * 100 && !timed_out) {
			kill(pid, SIGKILL);
			timed_out = 1;
		}
		usleep(10000);
	}
	code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
	if (timed_out)
		printf("timeout maxrss_kib %ld\n", ru.ru_maxrss);
	else
		printf("exit %d maxrss_kib %ld\n", code, ru.ru_maxrss);
	return 0;
}
