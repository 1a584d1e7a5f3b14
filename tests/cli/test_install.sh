# make install into a temporary prefix, then build and run a small C
# program against it with pkg-config, as a renderer author would.
SUITE=install
. "$LOOM_TOP/tests/cli/lib.sh"
P=$T/prefix
# -o all: install what `make test` built and tested, never rebuild it here
# (a source edited while the suite runs would otherwise mix builds)
if make -C "$LOOM_TOP" --no-print-directory -s -o all BUILD="$LOOM_BUILD" PREFIX="$P" install >"$T/install.log" 2>&1; then
	pass make_install
else
	fail make_install "$(tail -5 "$T/install.log")"
fi
for f in lib/libloom.a lib/libloom.so include/loom.h include/loom/common.h lib/pkgconfig/loom.pc bin/loom; do
	if [ -e "$P/$f" ]; then pass "installed_$(echo "$f" | tr '/.' '__')"; else fail "installed_$f" "missing $P/$f"; fi
done
cat >"$T/prog.c" <<'C'
#include <loom.h>
#include <stdio.h>
#include <string.h>
int main(void)
{
	loom_weave_params p;
	loom_design *d = NULL;
	loom_diag diag = {0};
	if (loom_weave_parse("twill:2/3", &p, &diag) != LOOM_OK) return 1;
	if (loom_design_make(&p, 0, 0, &d, &diag) != LOOM_OK) return 1;
	printf("%s %ux%u %d\n", loom_version(), d->rows, d->cols, loom_design_at(d, 1, 0));
	loom_design_free(d);
	return strcmp(loom_strerror(LOOM_ECORRUPT), "success") == 0;
}
C
export PKG_CONFIG_PATH="$P/lib/pkgconfig"
# shared: the program finds libloom.so.0 through loom.pc's rpath, with no
# LD_LIBRARY_PATH and no ldconfig
if cc -std=c11 -Wall -Werror ${LOOM_SAN:-} "$T/prog.c" -o "$T/prog_shared" $(pkg-config --cflags --libs loom) >"$T/cc.log" 2>&1 &&
	env -u LD_LIBRARY_PATH "$T/prog_shared" >"$T/prog.out" 2>&1 && grep -q '^0.1.0 5x5 1$' "$T/prog.out"; then
	pass pkgconfig_shared
else
	fail pkgconfig_shared "$(cat "$T/cc.log" "$T/prog.out" 2>/dev/null | head -c 600)"
fi
if env -u LD_LIBRARY_PATH ldd "$T/prog_shared" 2>&1 | grep -q "libloom.so.0 => $P/lib/libloom.so.0"; then
	pass rpath_finds_installed_lib
else
	fail rpath_finds_installed_lib "$(env -u LD_LIBRARY_PATH ldd "$T/prog_shared" 2>&1 | grep -i loom)"
fi
# static: libloom.a (and the archives Debian has) linked in, the libraries
# Debian ships only shared (OpenEXRCore, OpenVDB, TBB) dynamically, as
# docs/api.md shows; the program runs with the prefix's lib moved away
if cc -std=c11 -Wall -Werror ${LOOM_SAN:-} "$T/prog.c" -o "$T/prog_static" $(pkg-config --cflags loom) \
	-Wl,-Bstatic $(pkg-config --static --libs loom) >"$T/cc2.log" 2>&1 &&
	mv "$P/lib" "$P/lib.away" && env -u LD_LIBRARY_PATH "$T/prog_static" >"$T/prog2.out" 2>&1; then
	mv "$P/lib.away" "$P/lib"
	if grep -q '^0.1.0 5x5 1$' "$T/prog2.out" && ! ldd "$T/prog_static" | grep -q libloom; then
		pass pkgconfig_static
	else
		fail pkgconfig_static "$(cat "$T/prog2.out"; ldd "$T/prog_static" | grep loom)"
	fi
else
	[ -d "$P/lib.away" ] && mv "$P/lib.away" "$P/lib"
	fail pkgconfig_static "$(cat "$T/cc2.log" "$T/prog2.out" 2>/dev/null | head -c 600)"
fi
# the plain --static flags also link (against the shared library)
if cc -std=c11 -Wall -Werror ${LOOM_SAN:-} "$T/prog.c" -o "$T/prog_static2" $(pkg-config --cflags loom) \
	$(pkg-config --static --libs loom) >"$T/cc2b.log" 2>&1 && env -u LD_LIBRARY_PATH "$T/prog_static2" >/dev/null 2>&1; then
	pass pkgconfig_static_flags_link
else
	fail pkgconfig_static_flags_link "$(head -c 600 "$T/cc2b.log")"
fi
# RPATH=0: no rpath in loom.pc; the program then needs the documented
# LD_LIBRARY_PATH (or ldconfig) step
P0=$T/prefix-norpath
if make -C "$LOOM_TOP" --no-print-directory -s BUILD="$LOOM_BUILD" PREFIX="$P0" RPATH=0 install >"$T/install0.log" 2>&1 &&
	! grep -q -- '-Wl,-rpath' "$P0/lib/pkgconfig/loom.pc" &&
	cc -std=c11 ${LOOM_SAN:-} "$T/prog.c" -o "$T/prog_norpath" $(PKG_CONFIG_PATH=$P0/lib/pkgconfig pkg-config --cflags --libs loom) >"$T/cc0.log" 2>&1 &&
	! env -u LD_LIBRARY_PATH "$T/prog_norpath" >/dev/null 2>&1 &&
	LD_LIBRARY_PATH="$P0/lib" "$T/prog_norpath" | grep -q '^0.1.0 5x5 1$'; then
	pass norpath_needs_ld_library_path
else
	fail norpath_needs_ld_library_path "$(tail -3 "$T/install0.log"; cat "$T/cc0.log")"
fi
if "$P/bin/loom" --version | grep -q '^loom 0.1.0$'; then pass installed_binary_runs; else fail installed_binary_runs "loom --version"; fi
if [ -f "$P/share/loom/README" ]; then pass installed_data; else fail installed_data "no share/loom"; fi
if [ -s "$P/share/loom/default.ldb" ]; then pass installed_default_db; else fail installed_default_db "no share/loom/default.ldb"; fi
# the installed command finds the installed database with no --db
if env -u LOOM_DB -u LOOM_DATA "$P/bin/loom" exemplar info >"$T/xinfo.out" 2>&1 &&
	grep -q "$P/bin/../share/loom/default.ldb\|$P/share/loom/default.ldb" "$T/xinfo.out"; then
	pass installed_finds_db; else fail installed_finds_db "$(head -c 400 "$T/xinfo.out")"; fi

# A renderer author's program (issue 5): open the installed database,
# synthesize a small fabric, open its virtual texture with a 64 MiB budget
# and look voxels up from two threads; both threads must see exactly what
# the main thread saw.
cat >"$T/tex.c" <<'C'
#include <loom.h>
#include <pthread.h>
#include <stdio.h>
#include <stdint.h>
static loom_texture *tex;
static uint64_t walk(void)
{
	uint64_t h = 1469598103934665603ull;
	for (int64_t y = -20; y < 40; y += 3)
		for (int64_t x = -30; x < 60; x += 5)
			for (int64_t z = -2; z < 50; z++) {
				loom_texel v;
				if (loom_texture_voxel(tex, x, y, z, &v) != LOOM_OK)
					return 0;
				h = (h ^ (uint64_t)(v.density * 255.0f + 0.5f)) * 1099511628211ull;
				h = (h ^ (uint64_t)(v.kind + 4u * v.type)) * 1099511628211ull;
			}
	return h;
}
static void *run(void *out)
{
	*(uint64_t *)out = walk();
	return NULL;
}
int main(int argc, char **argv)
{
	loom_diag diag = {0};
	loom_db *db = NULL;
	loom_design *d = NULL;
	loom_fabric *f = NULL;
	loom_weave_params p;
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_texture_stats st;
	uint64_t h0, h[2];
	pthread_t th[2];
	if (argc < 2 || loom_db_open(argv[1], &db, &diag) != LOOM_OK ||
	    loom_weave_parse("twill:2/3", &p, &diag) != LOOM_OK ||
	    loom_design_make(&p, 10, 10, &d, &diag) != LOOM_OK ||
	    loom_fabric_synthesize(d, db, argv[1], NULL, &f, &diag) != LOOM_OK) {
		fprintf(stderr, "setup: %s\n", diag.message);
		return 1;
	}
	o.budget_bytes = (size_t)64 << 20;
	if (loom_texture_open(f, NULL, &o, &tex, &diag) != LOOM_OK) {
		fprintf(stderr, "texture: %s\n", diag.message);
		return 1;
	}
	h0 = walk();
	for (int k = 0; k < 2; k++)
		pthread_create(&th[k], NULL, run, &h[k]);
	for (int k = 0; k < 2; k++)
		pthread_join(th[k], NULL);
	loom_texture_get_stats(tex, &st);
	printf("%d %d %d\n", h0 != 0 && h0 == h[0] && h0 == h[1],
	       st.peak_bytes <= st.budget_bytes, st.lookups > 0);
	loom_texture_close(tex);
	loom_fabric_free(f);
	loom_design_free(d);
	loom_db_close(db);
	return 0;
}
C
if cc -std=c11 -Wall -Werror -pthread ${LOOM_SAN:-} "$T/tex.c" -o "$T/tex" $(pkg-config --cflags --libs loom) >"$T/cc3.log" 2>&1 &&
	env -u LD_LIBRARY_PATH "$T/tex" "$P/share/loom/default.ldb" >"$T/tex.out" 2>&1 && grep -q '^1 1 1$' "$T/tex.out"; then
	pass pkgconfig_texture_threads
else
	fail pkgconfig_texture_threads "$(cat "$T/cc3.log" "$T/tex.out" 2>/dev/null | head -c 600)"
fi

# The example programs of docs/examples/, built against the installed
# library as its README says and run.
EX=$LOOM_TOP/docs/examples
DB=$P/share/loom/default.ldb
for ex in sample_threads read_region render_loop; do
	if cc -std=c11 -Wall -Wextra -Werror ${LOOM_SAN:-} "$EX/$ex.c" -o "$T/ex_$ex" \
		$(pkg-config --cflags --libs loom) -pthread -lm >"$T/ex_$ex.cc" 2>&1; then
		pass "example_${ex}_builds"
	else
		fail "example_${ex}_builds" "$(head -c 600 "$T/ex_$ex.cc")"
	fi
done
if env -u LD_LIBRARY_PATH "$T/ex_sample_threads" "$DB" >"$T/ex1.out" 2>&1 &&
	grep -q 'identical yes' "$T/ex1.out" && grep -q 'peak_within_budget yes' "$T/ex1.out" &&
	awk '{for (i = 1; i < NF; i++) if ($i == "filled") exit !($(i + 1) > 0.05 && $(i + 1) < 0.95)}' "$T/ex1.out"; then
	pass example_sample_threads_runs
else
	fail example_sample_threads_runs "$(head -c 600 "$T/ex1.out")"
fi
if env -u LD_LIBRARY_PATH "$T/ex_read_region" "$DB" >"$T/ex2.out" 2>&1 &&
	grep -q 'mismatches 0$' "$T/ex2.out" &&
	awk '{exit !($6 > 1000 && $8 > 1000 && $10 > 100)}' "$T/ex2.out"; then
	pass example_read_region_runs
else
	fail example_read_region_runs "$(head -c 600 "$T/ex2.out")"
fi
if env -u LD_LIBRARY_PATH "$T/ex_render_loop" "$DB" "$T/ex3.ppm" >"$T/ex3.out" 2>&1 &&
	head -c 15 "$T/ex3.ppm" | grep -q '^P6' &&
	awk '{exit !($4 > 0.3)}' "$T/ex3.out"; then
	pass example_render_loop_runs
else
	fail example_render_loop_runs "$(head -c 600 "$T/ex3.out")"
fi
# the installed loom finds the VDB plugin in PREFIX/lib (it lives in
# PREFIX/bin) and writes a .vdb; `make install` put the plugin there
case "${LOOM_SAN:-}" in *thread*) VDB_OK= ;; *) VDB_OK=1 ;; esac
# (not under ThreadSanitizer: OpenVDB and TBB are not instrumented, see test_vdb.sh)
if [ -n "$VDB_OK" ] && [ -x "$LOOM_BUILD/tests/vdb_check" ]; then
	if [ -f "$P/lib/libloom-vdb.so.0" ]; then pass vdb_plugin_installed; else
		fail vdb_plugin_installed "no $P/lib/libloom-vdb.so.0"; fi
	"$P/bin/loom" pattern make plain --size 4x4 -o "$T/ip.pbm" >/dev/null 2>&1 &&
	env -u LOOM_VDB_LIBRARY "$P/bin/loom" synth "$T/ip.pbm" --quiet -o "$T/ip.loomf" \
		>"$T/ivdb.out" 2>&1 &&
	env -u LOOM_VDB_LIBRARY "$P/bin/loom" export "$T/ip.loomf" --region 0,0,0:16,16,8 \
		--format vdb --quiet -o "$T/ivdb" >>"$T/ivdb.out" 2>&1
	if ls "$T"/ivdb/*.vdb >/dev/null 2>&1; then pass installed_vdb_export; else
		fail installed_vdb_export "$(head -c 600 "$T/ivdb.out")"; fi
fi
