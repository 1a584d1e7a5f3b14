# loom - structure-aware synthesis of woven fabric volumes.
#
#   make            build libloom.a, libloom.so, the loom command, default data
#   make demo       build and run `loom demo` on the built-in data
#   make gallery    render the gallery to docs/images (~10 min; docs/rendering.md)
#   make test       build with -Werror and run every test; ends "N passed, N failed"
#   make sanitize   the same suite under AddressSanitizer + UBSan
#   make tsan       the same suite under ThreadSanitizer
#   make test-portable  the unit tests built without SSE2 (generic C)
#   make test-slurm export and scan job arrays on a private Slurm (root)
#   make fuzz       libFuzzer targets (clang); make fuzz-run SECONDS=N runs them
#   make bench      run the benchmarks (figures, never pass/fail)
#   make fidelity   synthesis against the woven ground truth (docs/fidelity.md)
#   make fidelity-draws  the same over three seeds of the exemplar set (~15 min)
#   make install    PREFIX=/usr/local DESTDIR=
#   make help       this text
#
# Quiet unless V=1.  Build outputs go to $(BUILD) (default build/).

PREFIX  ?= /usr/local
DESTDIR ?=
BUILD   ?= build
CC      ?= cc
OPT     ?= -O2
SAN     ?=

ifeq ($(V),1)
Q :=
else
Q := @
endif

VERSION := 0.1.0
SOVER   := 0

# Dependencies (see ../shared/DEPENDENCIES.md): pkg-config where a .pc
# exists; OpenEXR's .pc pulls the C++ libraries, so only its cflags are used
# and the Core C library is linked by name.  Embree (no .pc) is not linked:
# engine/render/embree_dl.c dlopen()s libembree3.so.3 when a shell is first built,
# so processes that do not map cloth onto meshes do not pay its ~4.5 MiB.
# The probes run once per make invocation; before deps.sh has run they may
# print nothing, which is fine because nothing compiles before it.
PKGS      := libdeflate libpng
DEP_CFLAGS = $(shell pkg-config --cflags $(PKGS) OpenEXR 2>/dev/null)
DEP_LIBS   = $(shell pkg-config --libs $(PKGS) 2>/dev/null) -lOpenEXRCore-3_1 -lm -lpthread -ldl
# The VDB writers (io/volume/vdb_shim.cpp, loom's only C++, docs/interop.md)
# are a plugin, $(BUILD)/libloom-vdb.so.0, linked against OpenVDB and
# loaded by io/volume/vdb_dl.c on the first VDB export: OpenVDB, TBB and
# libstdc++ cost a process ~30 MiB before main, so only a VDB export pays
# for them and libloom itself links no C++.  Built when Debian's
# libopenvdb-dev is installed (probed when the recipe runs, i.e. after
# tools/deps.sh); without it loom names the package to install.
HAVE_VDB   = $(shell test -f /usr/include/openvdb/openvdb.h && echo 1)
VDB_LIBS   = -lopenvdb -lImath-3_1 -ltbb -lblosc -lz -lpthread
# The loom command alone links the HTTP server of `loom serve` (Debian's
# libmicrohttpd); libloom does not.
TOOL_CFLAGS = $(shell pkg-config --cflags libmicrohttpd 2>/dev/null)
TOOL_LIBS   = $(shell pkg-config --libs libmicrohttpd 2>/dev/null)

WARN    := -Wall -Wextra -Werror -Wshadow -Wstrict-prototypes -Wmissing-prototypes -Wno-unused-parameter
CFLAGS  ?= $(OPT) -g
# engine/ is compiled without the repository root on its include path, so
# an engine file cannot include an io/ or tools/ header (the layers point
# down: tools -> io -> engine).  tests/cli/test_layers.sh checks the same
# and the allowed edges between modules (engine/MODULES).
ENGINE_INC := -Iengine/include -Iengine
ALL_INC    := $(ENGINE_INC) -I.
BASE_CFLAGS = -std=c11 -D_GNU_SOURCE -fPIC -fvisibility=hidden $(WARN) $(CFLAGS) $(SAN) \
             $(DEP_CFLAGS) -DLOOM_BUILDING
ALL_CFLAGS = $(BASE_CFLAGS) $(ALL_INC)
CXX     ?= g++
CXX_CFLAGS = -std=c++17 -D_GNU_SOURCE -fPIC \
             -Wall -Wextra -Werror -Wshadow -Wno-unused-parameter $(CFLAGS) $(SAN) \
             -DLOOM_BUILDING $(ALL_INC)
LDFLAGS ?=

# Sources by folder: one folder per module (docs/architecture.md).
ENGINE_SRC := $(sort $(wildcard engine/*/*.c))
IO_SRC     := $(sort $(wildcard io/*/*.c))
LIB_SRC    := $(ENGINE_SRC) $(IO_SRC)
TOOL_SRC   := $(sort $(wildcard tools/loom/*.c))
UNIT_SRC   := $(sort $(wildcard tests/unit/test_*.c))
FUZZ_SRC   := $(sort $(wildcard tests/fuzz/fuzz_*.c))
BENCH_SRC  := $(sort $(wildcard bench/bench_*.c))
SEED_SRC   := $(sort $(wildcard tests/fuzz/seeds/*.hex))

LIB_OBJ   := $(LIB_SRC:%.c=$(BUILD)/obj/%.o)
VDB_PLUGIN := $(BUILD)/libloom-vdb.so.0
TOOL_OBJ  := $(TOOL_SRC:%.c=$(BUILD)/obj/%.o)
UNIT_BIN  := $(UNIT_SRC:tests/unit/%.c=$(BUILD)/tests/%)
FUZZ_BIN  := $(FUZZ_SRC:tests/fuzz/fuzz_%.c=$(BUILD)/tests/replay_%)
BENCH_BIN := $(BENCH_SRC:bench/%.c=$(BUILD)/bench/%)
SEED_DIRS := $(SEED_SRC:tests/fuzz/seeds/%.hex=$(BUILD)/fuzz-corpus/%/.made)
# bench_vdb only when OpenVDB and NanoVDB are installed (tools/deps.sh openvdb)
VDB_HDRS  := $(wildcard /usr/include/openvdb/openvdb.h /usr/include/nanovdb/NanoVDB.h)
VDB_BIN   := $(if $(word 2,$(VDB_HDRS)),$(BUILD)/bench/bench_vdb)

STATIC := $(BUILD)/libloom.a
SHARED := $(BUILD)/libloom.so.$(VERSION)
LOOM   := $(BUILD)/loom
DEPS_OK := $(BUILD)/.deps-ok
TESTDEPS_OK := $(BUILD)/.testdeps-ok

# Default data built by make (issue 3 adds the exemplar database here).
DATA_DIR := $(BUILD)/share/loom
DATA     := $(DATA_DIR)/README
DEFAULT_DB := $(DATA_DIR)/default.ldb
WEB_OK     := $(DATA_DIR)/web/.made

.SECONDARY:
.PHONY: all demo gallery test check sanitize tsan test-portable bench install uninstall clean help fuzz fuzz-run test-slurm fidelity fidelity-draws
all: $(STATIC) $(SHARED) $(LOOM) $(VDB_PLUGIN) $(DATA) $(DEFAULT_DB) $(WEB_OK)

help:
	@sed -n '3,17p' Makefile | sed 's/^# \{0,1\}//'

$(DEPS_OK): tools/deps.sh
	@mkdir -p $(@D)
	$(Q)sh tools/deps.sh build
	@touch $@

$(TESTDEPS_OK): tools/deps.sh
	@mkdir -p $(@D)
	$(Q)sh tools/deps.sh test
	@touch $@

$(BUILD)/obj/engine/%.o: engine/%.c | $(DEPS_OK)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  CC      $<")
	$(Q)$(CC) $(BASE_CFLAGS) $(ENGINE_INC) -MMD -MP -c $< -o $@

$(BUILD)/obj/tools/%.o: tools/%.c | $(DEPS_OK)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  CC      $<")
	$(Q)$(CC) $(ALL_CFLAGS) $(TOOL_CFLAGS) -MMD -MP -c $< -o $@

$(BUILD)/obj/%.o: %.cpp | $(DEPS_OK)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  CXX     $<")
	$(Q)$(CXX) $(CXX_CFLAGS) -MMD -MP -c $< -o $@

$(BUILD)/obj/%.o: %.c | $(DEPS_OK)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  CC      $<")
	$(Q)$(CC) $(ALL_CFLAGS) -MMD -MP -c $< -o $@

$(STATIC): $(LIB_OBJ)
	@$(if $(Q),echo "  AR      $@")
	$(Q)rm -f $@ && ar rcs $@ $^

$(SHARED): $(LIB_OBJ) libloom.map
	@$(if $(Q),echo "  LD      $@")
	$(Q)$(CC) -shared -Wl,-soname,libloom.so.$(SOVER) -Wl,--version-script=libloom.map \
	    $(SAN) $(LDFLAGS) -o $@ $(LIB_OBJ) $(DEP_LIBS)
	$(Q)ln -sf libloom.so.$(VERSION) $(BUILD)/libloom.so.$(SOVER)
	$(Q)ln -sf libloom.so.$(VERSION) $(BUILD)/libloom.so

$(LOOM): $(TOOL_OBJ) $(STATIC)
	@$(if $(Q),echo "  LD      $@")
	$(Q)$(CC) $(SAN) $(LDFLAGS) -o $@ $(TOOL_OBJ) $(STATIC) $(DEP_LIBS) $(TOOL_LIBS)

$(DATA): $(wildcard data/*)
	@mkdir -p $(@D)
	$(Q)cp data/* $(DATA_DIR)/

# The default exemplar database (small preset, fixed seed, exemplars of at
# least 10 crossings a side: docs/exemplars.md, docs/fidelity.md "The
# satins' seams follow their exemplar"), made by the loom binary and remade
# when it changes.
$(DEFAULT_DB): $(LOOM) | $(DATA)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  GEN     $@")
	$(Q)$(LOOM) exemplar generate --preset small --seed 1 --min-crossings 10 --quiet -o $@

# The page of `loom serve` (tools/web): OpenSeadragon from npm, installed
# into the build tree by `npm ci` from the committed package-lock.json when
# node_modules is missing (never at run time), then copied with the page
# into the data directory, which `make install` installs.  playwright-core
# (the browser test's driver; it downloads no browser) comes with it.
WEB_SRC := $(wildcard tools/web/*.html tools/web/*.js tools/web/*.css)
$(BUILD)/web/node_modules/.package-lock.json: tools/web/package.json tools/web/package-lock.json | $(DEPS_OK)
	@mkdir -p $(BUILD)/web
	@$(if $(Q),echo "  NPM     $(BUILD)/web (openseadragon, playwright-core)")
	$(Q)cp tools/web/package.json tools/web/package-lock.json $(BUILD)/web/
	$(Q)cd $(BUILD)/web && npm ci --no-audit --no-fund --loglevel=error >/dev/null || \
	    { echo "loom: npm ci failed in $(BUILD)/web: the viewer of loom serve needs it" >&2; exit 1; }
$(WEB_OK): $(BUILD)/web/node_modules/.package-lock.json $(WEB_SRC) | $(DATA)
	@mkdir -p $(DATA_DIR)/web/images
	$(Q)cp $(WEB_SRC) $(DATA_DIR)/web/
	$(Q)cp $(BUILD)/web/node_modules/openseadragon/build/openseadragon/openseadragon.min.js \
	    $(DATA_DIR)/web/
	$(Q)cp $(BUILD)/web/node_modules/openseadragon/build/openseadragon/images/*.png \
	    $(DATA_DIR)/web/images/
	@touch $@

# Unit tests: one program per module, linked against the static library.
$(BUILD)/tests/%: $(BUILD)/obj/tests/unit/%.o $(STATIC)
	@mkdir -p $(@D)
	$(Q)$(CC) $(SAN) $(LDFLAGS) -o $@ $< $(STATIC) $(DEP_LIBS)

# The child runner of the hostile-input table (tests/cli/test_hostile.sh).
$(BUILD)/tests/childrun: $(BUILD)/obj/tests/cli/childrun.o $(STATIC)
	@mkdir -p $(@D)
	$(Q)$(CC) $(SAN) $(LDFLAGS) -o $@ $< $(STATIC) $(DEP_LIBS)

# Fuzz targets replayed over their corpus as plain tests.
$(BUILD)/tests/replay_%: $(BUILD)/obj/tests/fuzz/fuzz_%.o $(BUILD)/obj/tests/fuzz/replay_main.o $(STATIC)
	@mkdir -p $(@D)
	$(Q)$(CC) $(SAN) $(LDFLAGS) -o $@ $^ $(DEP_LIBS)

# Binary seed corpora kept in git as hex text (tests/fuzz/seeds/NAME.hex),
# written to $(BUILD)/fuzz-corpus/NAME/ and replayed with tests/fuzz/corpus/NAME/.
$(BUILD)/tests/unhex: $(BUILD)/obj/tests/fuzz/unhex.o
	@mkdir -p $(@D)
	$(Q)$(CC) $(SAN) $(LDFLAGS) -o $@ $<

$(BUILD)/fuzz-corpus/%/.made: tests/fuzz/seeds/%.hex $(BUILD)/tests/unhex
	$(Q)rm -rf $(@D) && mkdir -p $(@D)
	$(Q)$(BUILD)/tests/unhex $< $(@D)
	@touch $@

$(BUILD)/bench/%: $(BUILD)/obj/bench/%.o $(STATIC)
	@mkdir -p $(@D)
	$(Q)$(CC) $(SAN) $(LDFLAGS) -o $@ $< $(STATIC) $(DEP_LIBS)

demo: all
	$(LOOM) demo

# The figure 13 subjects on the scene meshes (tools/gallery.sh; not part of
# make test: about 10 minutes on 2 cores).  GALLERY_ARGS="W H SPP" to change.
gallery: all
	nice sh tools/gallery.sh $(LOOM) docs/images $(GALLERY_ARGS)

# An independent reader of the .vdb / .nvdb exports (OpenVDB's and
# NanoVDB's own headers) for tests/cli/test_vdb.sh; not built without them.
VDB_CHECK := $(BUILD)/tests/vdb_check
$(VDB_CHECK): tests/cli/vdb_check.cpp | $(DEPS_OK)
	@mkdir -p $(@D)
	$(Q)if [ -n "$(HAVE_VDB)" ]; then $(if $(Q),echo "  CXX     $@";) \
	    $(CXX) -std=c++17 -O1 -o $@ $< -lopenvdb -lImath-3_1 -ltbb -lblosc -lz -lpthread; fi

# The VDB plugin (see HAVE_VDB above): built only where OpenVDB is
# installed, checked when the recipe runs; elsewhere nothing is made and
# loom names the missing package.
$(VDB_PLUGIN): io/volume/vdb_shim.cpp io/volume/vdb.h | $(DEPS_OK)
	@mkdir -p $(@D)
	$(Q)if [ -n "$(HAVE_VDB)" ]; then $(if $(Q),echo "  CXX     $@";) \
	    $(CXX) $(CXX_CFLAGS) -DLOOM_VDB_PLUGIN -shared -Wl,-soname,libloom-vdb.so.0 \
	    -o $@ $< $(VDB_LIBS); else echo "  SKIP    $@ (OpenVDB not installed)"; fi

test check: all $(UNIT_BIN) $(BENCH_BIN) $(FUZZ_BIN) $(SEED_DIRS) $(BUILD)/tests/childrun $(TESTDEPS_OK) $(VDB_CHECK) $(if $(SAN),,$(VDB_BIN))
	$(Q)BUILD=$(BUILD) LOOM_SAN="$(SAN)" sh tests/run.sh

# tools/slurm/ on a real single-node Slurm that the script starts and stops
# (installs slurm-wlm and munge through tools/deps.sh slurm; needs root).
test-slurm: all
	$(Q)BUILD=$(BUILD) bash tests/slurm/run.sh

# intercept_tls_get_addr=0: LeakSanitizer (gcc 12) guesses the glibc
# version from the heap word before a dlopen'd library's TLS block (Embree's
# TBB, module 8 in `loom render --mesh`); when a small allocation of ours
# happens to lie there it misreads it as a TLS range starting at 0x178 and
# its tracer crashes at exit ("Tracer caught signal 11", seen 2026-12-07).
# Without the interception the leak check scans static TLS only.
sanitize:
	$(Q)ASAN_OPTIONS=intercept_tls_get_addr=0$${ASAN_OPTIONS:+:$$ASAN_OPTIONS} \
	    $(MAKE) --no-print-directory BUILD=build/asan OPT=-O1 \
	    SAN="-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer" test

tsan:
	$(Q)$(MAKE) --no-print-directory BUILD=build/tsan OPT=-O1 \
	    SAN="-fsanitize=thread" test

# The generic C paths (what a host without SSE2, ARM or RISC-V, compiles;
# x86-64 always has SSE2, so nothing else runs them): every unit test built
# with __SSE2__ undefined (the texture's region reads and lookups against
# brute-force point lookups among them), about 2 minutes.
PORTABLE_TESTS := $(UNIT_SRC:tests/unit/%.c=%)
test-portable:
	$(Q)$(MAKE) --no-print-directory BUILD=build/portable SAN="-U__SSE2__" \
	    $(PORTABLE_TESTS:%=build/portable/tests/%)
	@echo "unit tests built without SSE2:"
	$(Q)BUILD=build/portable sh tests/run.sh units

# The peer benchmark (bench/bench_vdb.cpp, the only C++ in bench/): built
# with g++ against OpenVDB and NanoVDB (no .pc file, so the libraries are
# named here).
$(BUILD)/bench/bench_vdb: bench/bench_vdb.cpp $(STATIC) $(BUILD)/bench/bench_texture
	@mkdir -p $(@D)
	@$(if $(Q),echo "  CXX     $<")
	$(Q)$(CXX) -std=c++17 $(OPT) -g -Wall -Wextra -Werror -Wno-unused-parameter \
	    -Wno-deprecated-declarations -Iengine/include $(SAN) $(LDFLAGS) -o $@ $< $(STATIC) \
	    -lopenvdb -lImath-3_1 -ltbb -lblosc -lz $(DEP_LIBS)

bench: all $(BENCH_BIN) $(VDB_BIN)
	$(Q)$(if $(VDB_BIN),,echo "bench_vdb: skipped (OpenVDB/NanoVDB not installed: tools/deps.sh openvdb)")
	$(Q)BUILD=$(BUILD) sh bench/run.sh

# synthesis against the woven ground truth (docs/fidelity.md)
fidelity: all
	$(Q)sh bench/fidelity.sh $(BUILD)/loom $(DEFAULT_DB) $(BUILD)/fidelity

# the same over several draws of the exemplar set (FIDELITY_DB_SEEDS)
fidelity-draws: all
	$(Q)sh bench/fidelity-draws.sh $(BUILD)/loom $(BUILD)/fidelity-draws

# libFuzzer builds (clang, Debian's clang package: tools/deps.sh fuzz).
# The library is compiled once into $(BUILD)/fuzz/libloom-fuzz.a with
# ASan + UBSan, and any finding stops the fuzzer and saves a reproducer
# (-fno-sanitize-recover=all); each target links against it.
#   make fuzz                  build $(BUILD)/fuzz/fuzz_NAME for every target
#   make fuzz-run SECONDS=N    run every target N s (default 60) from its
#                              corpus (tests/fuzz/corpus/NAME and the seeds
#                              of tests/fuzz/seeds/NAME.hex); fails on any
#                              crash, leak, timeout (10 s per input) or
#                              out-of-memory (2 GiB); reproducers go to
#                              $(BUILD)/fuzz-artifacts/, new inputs to
#                              $(BUILD)/fuzz-work/NAME (never into git)
FUZZ_CC    ?= clang
FUZZ_SAN   := -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
FUZZ_FLAGS  = -std=c11 -D_GNU_SOURCE -g -O1 $(FUZZ_SAN) $(ALL_INC) $(DEP_CFLAGS) -DLOOM_BUILDING
FUZZ_OBJ   := $(LIB_SRC:%.c=$(BUILD)/fuzz/obj/%.o)
FUZZ_LIB   := $(BUILD)/fuzz/libloom-fuzz.a
FUZZ_TGT   := $(FUZZ_SRC:tests/fuzz/%.c=$(BUILD)/fuzz/%)
SECONDS    ?= 60

FUZZDEPS_OK := $(BUILD)/.fuzzdeps-ok
$(FUZZDEPS_OK): tools/deps.sh
	@mkdir -p $(@D)
	$(Q)sh tools/deps.sh fuzz
	@touch $@

$(BUILD)/fuzz/obj/%.o: %.c | $(DEPS_OK) $(FUZZDEPS_OK)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  FUZZCC  $<")
	$(Q)$(FUZZ_CC) $(FUZZ_FLAGS) -fsanitize=fuzzer-no-link -MMD -MP -c $< -o $@

$(FUZZ_LIB): $(FUZZ_OBJ)
	$(Q)rm -f $@ && ar rcs $@ $^

$(BUILD)/fuzz/fuzz_%: tests/fuzz/fuzz_%.c $(FUZZ_LIB)
	@$(if $(Q),echo "  FUZZ    $@")
	$(Q)$(FUZZ_CC) $(FUZZ_FLAGS) -fsanitize=fuzzer $< $(FUZZ_LIB) -o $@ $(DEP_LIBS)

fuzz: $(FUZZ_TGT)

fuzz-run: $(FUZZ_TGT) $(SEED_DIRS)
	$(Q)fails=""; for t in $(FUZZ_TGT); do n=$$(basename $$t | sed 's/^fuzz_//'); \
	  work=$(BUILD)/fuzz-work/$$n; mkdir -p $$work $(BUILD)/fuzz-artifacts; \
	  dirs=""; for d in tests/fuzz/corpus/$$n $(BUILD)/fuzz-corpus/$$n; do \
	    [ -d $$d ] && dirs="$$dirs $$d"; done; \
	  echo "  FUZZ    $$n: $(SECONDS) s"; \
	  if ! $$t -max_total_time=$(SECONDS) -timeout=10 -rss_limit_mb=2048 \
	      -print_final_stats=1 -artifact_prefix=$(BUILD)/fuzz-artifacts/$$n- \
	      $$work $$dirs >$(BUILD)/fuzz-work/$$n.log 2>&1; then \
	    echo "  FAIL    $$n (log $(BUILD)/fuzz-work/$$n.log)"; \
	    grep -E "^(==[0-9]+==ERROR|SUMMARY|artifact_prefix|Test unit written)" \
	      $(BUILD)/fuzz-work/$$n.log | head -n 8; fails="$$fails $$n"; \
	  else grep -E "^stat::number_of_executed_units" $(BUILD)/fuzz-work/$$n.log | \
	    sed "s/^/          /"; fi; done; \
	  if [ -n "$$fails" ]; then echo "fuzz-run: failed:$$fails"; exit 1; fi

# loom.pc (docs/api.md, "Building against the installed library"): an rpath
# to libdir for every prefix but /usr, whose lib the dynamic linker searches
# (RPATH=0 leaves it out: then run ldconfig or set LD_LIBRARY_PATH); the
# libraries libloom.a needs, those with Debian archives first (libdeflate,
# libpng, zlib) and then, after -Wl,-Bdynamic, those Debian ships only
# shared (OpenEXRCore, OpenVDB, TBB) and the system's.
RPATH     ?= 1
PC_RPATH   = $(if $(filter /usr,$(PREFIX))$(filter 0,$(RPATH)),,-Wl,-rpath,$${libdir})
PC_PRIVATE = -ldeflate -lpng16 -lz -Wl,-Bdynamic -lOpenEXRCore-3_1 -lm -lpthread -ldl

install: all
	install -d $(DESTDIR)$(PREFIX)/lib $(DESTDIR)$(PREFIX)/include/loom \
	    $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(PREFIX)/lib/pkgconfig $(DESTDIR)$(PREFIX)/share/loom
	install -m 644 $(STATIC) $(DESTDIR)$(PREFIX)/lib/
	install -m 755 $(SHARED) $(DESTDIR)$(PREFIX)/lib/
	if [ -f $(VDB_PLUGIN) ]; then install -m 755 $(VDB_PLUGIN) $(DESTDIR)$(PREFIX)/lib/; fi
	ln -sf libloom.so.$(VERSION) $(DESTDIR)$(PREFIX)/lib/libloom.so.$(SOVER)
	ln -sf libloom.so.$(VERSION) $(DESTDIR)$(PREFIX)/lib/libloom.so
	install -m 644 engine/include/loom.h $(DESTDIR)$(PREFIX)/include/
	install -m 644 engine/include/loom/*.h $(DESTDIR)$(PREFIX)/include/loom/
	install -m 755 $(LOOM) $(DESTDIR)$(PREFIX)/bin/
	cp -R $(DATA_DIR)/. $(DESTDIR)$(PREFIX)/share/loom/
	sed -e 's|@PREFIX@|$(PREFIX)|g' -e 's|@VERSION@|$(VERSION)|g' \
	    -e 's|@RPATH@|$(PC_RPATH)|' -e 's|@PRIVATE@|$(PC_PRIVATE)|' loom.pc.in \
	    > $(DESTDIR)$(PREFIX)/lib/pkgconfig/loom.pc

uninstall:
	rm -f $(DESTDIR)$(PREFIX)/lib/libloom.* $(DESTDIR)$(PREFIX)/lib/libloom-vdb.so.0 $(DESTDIR)$(PREFIX)/include/loom.h \
	    $(DESTDIR)$(PREFIX)/bin/loom $(DESTDIR)$(PREFIX)/lib/pkgconfig/loom.pc
	rm -rf $(DESTDIR)$(PREFIX)/include/loom $(DESTDIR)$(PREFIX)/share/loom

clean:
	rm -rf build

-include $(shell find $(BUILD)/obj $(BUILD)/fuzz/obj -name '*.d' 2>/dev/null)
