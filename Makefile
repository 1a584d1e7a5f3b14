# loom - structure-aware synthesis of woven fabric volumes.
#
#   make            build libloom.a, libloom.so, the loom command, default data
#   make demo       build and run `loom demo` on the built-in data
#   make test       build with -Werror and run every test; ends "N passed, N failed"
#   make sanitize   the same suite under AddressSanitizer + UBSan
#   make tsan       the same suite under ThreadSanitizer
#   make test-slurm export and scan job arrays on a private Slurm (root)
#   make bench      run the benchmarks (figures, never pass/fail)
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
DEP_LIBS   = $(shell pkg-config --libs $(PKGS) 2>/dev/null) -lOpenEXRCore-3_1 $(VDB_LIBS) -lm -lpthread -ldl
# The VDB writers (io/volume/vdb_shim.cpp, libloom's only C++, docs/interop.md):
# OpenVDB (no .pc file) is linked when Debian's libopenvdb-dev is installed;
# without it the shim compiles to writers that name the missing package.
# Probed lazily (=), so on a fresh machine after deps.sh has run.
HAVE_VDB   = $(shell test -f /usr/include/openvdb/openvdb.h && echo 1)
VDB_LIBS   = $(if $(HAVE_VDB),-lopenvdb -lImath-3_1 -ltbb -lblosc -lz) -lstdc++
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

LIB_OBJ   := $(LIB_SRC:%.c=$(BUILD)/obj/%.o) $(BUILD)/obj/io/volume/vdb_shim.o
TOOL_OBJ  := $(TOOL_SRC:%.c=$(BUILD)/obj/%.o)
UNIT_BIN  := $(UNIT_SRC:tests/unit/%.c=$(BUILD)/tests/%)
FUZZ_BIN  := $(FUZZ_SRC:tests/fuzz/fuzz_%.c=$(BUILD)/tests/replay_%)
BENCH_BIN := $(BENCH_SRC:bench/%.c=$(BUILD)/bench/%)
SEED_DIRS := $(SEED_SRC:tests/fuzz/seeds/%.hex=$(BUILD)/fuzz-corpus/%/.made)

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
.PHONY: all demo test check sanitize tsan bench install uninstall clean help fuzz test-slurm
all: $(STATIC) $(SHARED) $(LOOM) $(DATA) $(DEFAULT_DB) $(WEB_OK)

help:
	@sed -n '3,13p' Makefile | sed 's/^# \{0,1\}//'

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

# The default exemplar database (small preset, fixed seed; docs/exemplars.md),
# made by the loom binary and remade when it changes.
$(DEFAULT_DB): $(LOOM) | $(DATA)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  GEN     $@")
	$(Q)$(LOOM) exemplar generate --preset small --seed 1 --quiet -o $@

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

# An independent reader of the .vdb / .nvdb exports (OpenVDB's and
# NanoVDB's own headers) for tests/cli/test_vdb.sh; not built without them.
VDB_CHECK := $(BUILD)/tests/vdb_check
$(VDB_CHECK): tests/cli/vdb_check.cpp | $(DEPS_OK)
	@mkdir -p $(@D)
	$(Q)if [ -n "$(HAVE_VDB)" ]; then $(if $(Q),echo "  CXX     $@";) \
	    $(CXX) -std=c++17 -O1 -o $@ $< -lopenvdb -lImath-3_1 -ltbb -lblosc -lz -lpthread; fi

# The loom command as built without OpenVDB (the shim's fallback linked
# first), for the missing-package message of tests/cli/test_vdb.sh.
NOVDB_LOOM := $(BUILD)/tests/loom_novdb
$(BUILD)/obj/tests/vdb_shim_missing.o: io/volume/vdb_shim.cpp | $(DEPS_OK)
	@mkdir -p $(@D)
	$(Q)$(CXX) $(CXX_CFLAGS) -DLOOM_VDB_PRETEND_MISSING -c $< -o $@
$(NOVDB_LOOM): $(BUILD)/obj/tests/vdb_shim_missing.o $(TOOL_OBJ) $(STATIC)
	@mkdir -p $(@D)
	$(Q)$(CC) $(SAN) $(LDFLAGS) -o $@ $(TOOL_OBJ) $< $(STATIC) $(DEP_LIBS) $(TOOL_LIBS)

test check: all $(UNIT_BIN) $(FUZZ_BIN) $(SEED_DIRS) $(TESTDEPS_OK) $(VDB_CHECK) $(NOVDB_LOOM)
	$(Q)BUILD=$(BUILD) LOOM_SAN="$(SAN)" sh tests/run.sh

# tools/slurm/ on a real single-node Slurm that the script starts and stops
# (installs slurm-wlm and munge through tools/deps.sh slurm; needs root).
test-slurm: all
	$(Q)BUILD=$(BUILD) bash tests/slurm/run.sh

sanitize:
	$(Q)$(MAKE) --no-print-directory BUILD=build/asan OPT=-O1 \
	    SAN="-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer" test

tsan:
	$(Q)$(MAKE) --no-print-directory BUILD=build/tsan OPT=-O1 \
	    SAN="-fsanitize=thread" test

bench: all $(BENCH_BIN)
	$(Q)BUILD=$(BUILD) sh bench/run.sh

# libFuzzer builds (clang): make fuzz, then build/fuzz/fuzz_wif tests/fuzz/corpus/wif
# (the vol seeds: build/fuzz/fuzz_vol build/fuzz-corpus/vol, made by make test)
fuzz: | $(DEPS_OK)
	@mkdir -p $(BUILD)/fuzz
	$(Q)for f in $(FUZZ_SRC); do n=$$(basename $$f .c); \
	  clang -std=c11 -D_GNU_SOURCE -g -O1 -fsanitize=fuzzer,address,undefined \
	    $(ALL_INC) $(DEP_CFLAGS) $$f $(LIB_SRC) \
	    -o $(BUILD)/fuzz/$$n $(DEP_LIBS) || exit 1; echo "  FUZZ    $(BUILD)/fuzz/$$n"; done

# loom.pc (docs/api.md, "Building against the installed library"): an rpath
# to libdir for every prefix but /usr, whose lib the dynamic linker searches
# (RPATH=0 leaves it out: then run ldconfig or set LD_LIBRARY_PATH); the
# libraries libloom.a needs, those with Debian archives first (libdeflate,
# libpng, zlib) and then, after -Wl,-Bdynamic, those Debian ships only
# shared (OpenEXRCore, OpenVDB, TBB) and the system's.
RPATH     ?= 1
PC_RPATH   = $(if $(filter /usr,$(PREFIX))$(filter 0,$(RPATH)),,-Wl,-rpath,$${libdir})
PC_PRIVATE = -ldeflate -lpng16 -lz -Wl,-Bdynamic -lOpenEXRCore-3_1 $(VDB_LIBS) -lm -lpthread -ldl

install: all
	install -d $(DESTDIR)$(PREFIX)/lib $(DESTDIR)$(PREFIX)/include/loom \
	    $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(PREFIX)/lib/pkgconfig $(DESTDIR)$(PREFIX)/share/loom
	install -m 644 $(STATIC) $(DESTDIR)$(PREFIX)/lib/
	install -m 755 $(SHARED) $(DESTDIR)$(PREFIX)/lib/
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
	rm -f $(DESTDIR)$(PREFIX)/lib/libloom.* $(DESTDIR)$(PREFIX)/include/loom.h \
	    $(DESTDIR)$(PREFIX)/bin/loom $(DESTDIR)$(PREFIX)/lib/pkgconfig/loom.pc
	rm -rf $(DESTDIR)$(PREFIX)/include/loom $(DESTDIR)$(PREFIX)/share/loom

clean:
	rm -rf build

-include $(shell find $(BUILD)/obj -name '*.d' 2>/dev/null)
