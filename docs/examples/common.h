/*
 * docs/examples/common.h - what the examples share: open a database,
 * weave a small design over it and open its virtual texture.
 *
 *   cc example.c $(pkg-config --cflags --libs loom) -pthread
 */
#ifndef LOOM_EXAMPLE_COMMON_H
#define LOOM_EXAMPLE_COMMON_H

#include <loom.h>
#include <stdio.h>
#include <stdlib.h>

typedef struct example {
	loom_db *db;
	loom_design *design;
	loom_fabric *fabric;
	loom_texture *tex;
} example;

/* The weave `pattern` (e.g. "twill:2/3") of rows x cols crossings over
   the database db_path, with a texture of budget_mib MiB for `threads`
   threads.  Exits with a message on failure. */
static void example_open(example *e, const char *db_path, const char *pattern,
                         uint32_t rows, uint32_t cols, size_t budget_mib, uint32_t threads)
{
	loom_diag diag = {0};
	loom_weave_params p;
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;

	if (loom_db_open(db_path, &e->db, &diag) != LOOM_OK ||
	    loom_weave_parse(pattern, &p, &diag) != LOOM_OK ||
	    loom_design_make(&p, rows, cols, &e->design, &diag) != LOOM_OK ||
	    loom_fabric_synthesize(e->design, e->db, db_path, NULL, &e->fabric, &diag) != LOOM_OK) {
		fprintf(stderr, "example: %s\n", diag.message);
		exit(1);
	}
	o.budget_bytes = budget_mib << 20;
	o.max_threads = threads;
	if (loom_texture_open(e->fabric, NULL, &o, &e->tex, &diag) != LOOM_OK) {
		fprintf(stderr, "example: texture: %s\n", diag.message);
		exit(1);
	}
}

static void example_close(example *e)
{
	loom_texture_close(e->tex);
	loom_fabric_free(e->fabric);
	loom_design_free(e->design);
	loom_db_close(e->db);
}

#endif
