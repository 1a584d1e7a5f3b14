# make install into a temporary prefix, then build and run a small C
# program against it with pkg-config, as a renderer author would.
SUITE=install
. "$LOOM_TOP/tests/cli/lib.sh"
P=$T/prefix
if make -C "$LOOM_TOP" --no-print-directory -s BUILD="$LOOM_BUILD" PREFIX="$P" install >"$T/install.log" 2>&1; then
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
if cc -std=c11 -Wall -Werror ${LOOM_SAN:-} "$T/prog.c" -o "$T/prog_shared" $(pkg-config --cflags --libs loom) >"$T/cc.log" 2>&1 &&
	LD_LIBRARY_PATH="$P/lib" "$T/prog_shared" >"$T/prog.out" && grep -q '^0.1.0 5x5 1$' "$T/prog.out"; then
	pass pkgconfig_shared
else
	fail pkgconfig_shared "$(cat "$T/cc.log" "$T/prog.out" 2>/dev/null | head -c 600)"
fi
if cc -std=c11 -Wall -Werror ${LOOM_SAN:-} "$T/prog.c" -o "$T/prog_static" $(pkg-config --cflags loom) "$P/lib/libloom.a" $(pkg-config --static --libs-only-l loom | sed 's/-lloom//') >"$T/cc2.log" 2>&1 &&
	"$T/prog_static" >"$T/prog2.out" && grep -q '^0.1.0 5x5 1$' "$T/prog2.out"; then
	pass pkgconfig_static
else
	fail pkgconfig_static "$(cat "$T/cc2.log" "$T/prog2.out" 2>/dev/null | head -c 600)"
fi
if "$P/bin/loom" --version | grep -q '^loom 0.1.0$'; then pass installed_binary_runs; else fail installed_binary_runs "loom --version"; fi
if [ -f "$P/share/loom/README" ]; then pass installed_data; else fail installed_data "no share/loom"; fi
