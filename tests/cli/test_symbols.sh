# Every symbol libloom exports carries the loom_ prefix (libdeflate's test).
SUITE=symbols
. "$LOOM_TOP/tests/cli/lib.sh"
lib=$LOOM_BUILD/libloom.so
bad=$(nm -D --defined-only "$lib" | awk '$2 ~ /^[TDBRW]$/ {print $3}' | grep -v '^loom_' | grep -v -E '^(_init|_fini|_edata|_end|__bss_start)$')
if [ -z "$bad" ]; then pass exported_prefix; else fail exported_prefix "unprefixed: $bad"; fi
# (ASan adds an __odr_asan.NAME marker for each global variable NAME)
bad=$(nm --defined-only "$LOOM_BUILD/libloom.a" 2>/dev/null | awk '$2 ~ /^[TDBR]$/ {print $3}' |
	sed 's/^__odr_asan\.//' | grep -v -E '^loom_' )
if [ -z "$bad" ]; then pass static_prefix; else fail static_prefix "unprefixed globals in libloom.a: $(echo $bad | head -c 300)"; fi
n=$(nm -D --defined-only "$lib" | grep -c ' T loom_')
if [ "$n" -gt 5 ]; then pass exports_api; else fail exports_api "only $n loom_ functions exported"; fi
if nm -D --defined-only "$lib" | grep -q ' T loom__'; then fail internals_hidden "loom__ internals exported"; else pass internals_hidden; fi
