# gcpush -- guiding-centre and full-orbit charged-particle pusher.
# `make help` lists the targets.  The two commands of the README:
#   make run     installs missing Debian packages, builds, runs runs/dipole.run
#   make check   installs missing Debian packages, builds, runs every test

VERSION  := 0.1.0
PREFIX   ?= /usr/local
# `make` alone builds the product (the fuzzer rule below comes first in the file).
.DEFAULT_GOAL := all
DEBUG    ?= 0
JOBS     ?= 2

DEB_PACKAGES := build-essential pkg-config libhdf5-openmpi-dev libopenmpi-dev openmpi-bin \
                libgsl-dev libcriterion-dev libinih-dev python3-h5py python3-numpy \
                python3-matplotlib hdf5-tools clang libclang-rt-14-dev

ifeq ($(DEBUG),1)
BUILD    := build-debug
OPTFLAGS := -O1 -g -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=all
else
BUILD    := build
OPTFLAGS := -O3 -march=native -g
endif

CC       := mpicc
PKGS     := hdf5-openmpi gsl inih
# ISO C11 (not gnu11): GCC then keeps -ffp-contract=off, so no FMA contraction
# changes results between the scalar and batch kernels.  -fno-math-errno lets
# loops calling sqrt vectorise (IEEE results unchanged).  Never -ffast-math.
CSTD     := -std=c11 -D_POSIX_C_SOURCE=200809L -fno-math-errno
# GCC 12's straight-line (SLP) vectoriser fuses a product feeding an
# alternating subtract/add pair, (a b - c, d e + f) in two lanes, into one
# vfmaddsub although -ffp-contract=off (its addsub pattern ignores the flag):
# tokamak_potential's A = (g x - psi y, g y + psi x) and the 2x2 solves of
# gc_gauss_wlift.c and gc_gauss_tokamak.c.  Off in those objects only:
# everywhere, it cost the eqdsk field 20% (bench_flux DIII-D).
# tests/cli/test_layers.sh fails on any other FMA outside the explicit fma()
# of GCP_NR_FMA_/GCP_NR_CROSS_.
NOFUSE_OBJ := fields/tokamak.o src/pushers/gc_gauss_wlift.o src/pushers/gc_gauss_tokamak.o
WARN     := -Wall -Wextra -Werror
CPPFLAGS += -Iinclude -Isrc -Ifields
# -fvisibility=hidden: libgcpush.so exports only what the public headers
# declare (include/gcpush/api.h); tests/cli/test_layers.sh checks it.
CFLAGS   := $(CSTD) $(WARN) $(OPTFLAGS) -fPIC -fvisibility=hidden $(shell pkg-config --cflags $(PKGS) 2>/dev/null)
LDLIBS   := $(shell pkg-config --libs $(PKGS) 2>/dev/null) -lm
GIT_HASH := $(shell git rev-parse --short=12 HEAD 2>/dev/null || echo unknown)
CPPFLAGS += -DGCP_VERSION='"$(VERSION)"' -DGCP_GIT_HASH='"$(GIT_HASH)"' \
            -DGCP_BUILD_FLAGS='"$(CC) $(CSTD) $(OPTFLAGS)"'

# Open MPI's parameter files (src/par/transport.c reads them before MPI_Init)
OMPI_SYSCONFDIR := $(shell ompi_info --parsable --path sysconfdir 2>/dev/null | sed -n 's/^path:sysconfdir://p')
CPPFLAGS += $(if $(OMPI_SYSCONFDIR),-DGCP_OMPI_SYSCONFDIR='"$(OMPI_SYSCONFDIR)"')

LIB_SRC  := $(wildcard src/*.c src/*/*.c fields/*.c)
LIB_SRC  := $(filter-out src/gcpush.c,$(LIB_SRC))
LIB_OBJ  := $(LIB_SRC:%.c=$(BUILD)/%.o)
TEST_SRC := $(wildcard tests/unit/*.c)
TEST_OBJ := $(TEST_SRC:%.c=$(BUILD)/%.o)

# The run-file reader under libFuzzer with ASan+UBSan: the parsing layers
# only (no MPI, no HDF5), compiled by clang into one binary.
FUZZ_SECONDS ?= 600
FUZZER   := build-fuzz/fuzz_runfile
FUZZ_SRC := src/error.c src/units.c src/particles.c src/run/section.c src/run/runfile.c src/run/field_keys.c \
            $(wildcard src/run/scene*.c) $(wildcard src/pushers/hybrid*.c) src/run/sweep_spec.c src/run/sweep_exact.c src/diag/periods.c $(wildcard src/diag/invariants*.c) \
            src/pushers/block.c src/pushers/evolve.c src/pushers/fo_step.c src/pushers/fo_rk8pd.c \
            $(wildcard src/pushers/boris*.c src/pushers/vay.c src/pushers/higuera_cary.c) \
            $(wildcard src/pushers/gc_*.c src/pushers/canon_*.c) $(wildcard fields/*.c) tests/fuzz/fuzz_runfile.c
$(FUZZER): $(FUZZ_SRC) $(wildcard include/gcpush/*.h src/*/*.h fields/*.h)
	@mkdir -p build-fuzz
	@echo "  CLANG $@"
	@clang $(CSTD) -Wall -Wextra -Werror -O1 -g -fsanitize=fuzzer,address,undefined \
	  -fno-sanitize-recover=all $(CPPFLAGS) $(shell pkg-config --cflags $(PKGS) 2>/dev/null) \
	  -o $@ $(FUZZ_SRC) $(LDLIBS)

# The restart path (checkpoint files as input) under the same sanitizers:
# the run-file layers again (a checkpoint holds its run file) plus io/'s
# checkpoints and the run layer's result rows (no MPI or HDF5 call among them).
FUZZER_CKPT := build-fuzz/fuzz_checkpoint
FUZZ_CKPT_SRC := $(filter-out tests/fuzz/fuzz_runfile.c,$(FUZZ_SRC)) src/io/checkpoint.c \
            src/run/results.c tests/fuzz/fuzz_checkpoint.c
$(FUZZER_CKPT): $(FUZZ_CKPT_SRC) $(wildcard include/gcpush/*.h src/*/*.h fields/*.h)
	@mkdir -p build-fuzz
	@echo "  CLANG $@"
	@clang $(CSTD) -Wall -Wextra -Werror -O1 -g -fsanitize=fuzzer,address,undefined \
	  -fno-sanitize-recover=all $(CPPFLAGS) $(shell pkg-config --cflags $(PKGS) 2>/dev/null) \
	  -o $@ $(FUZZ_CKPT_SRC) $(LDLIBS)

LIBA     := $(BUILD)/libgcpush.a
LIBSO    := $(BUILD)/libgcpush.so
# The debug binary lives apart, so DEBUG=1 and normal builds never mix.
BIN      := $(if $(filter 1,$(DEBUG)),$(BUILD)/gcpush,bin/gcpush)
UNIT     := $(BUILD)/test_unit
PY       := /usr/bin/python3

.PHONY: all help deps build run check check-built test-unit test-cli bench fuzz install clean

all: build

help:
	@echo "make run        install missing packages, build, run runs/dipole.run, plot it"
	@echo "make check      install missing packages, build, run every test"
	@echo "make DEBUG=1 check   the same under AddressSanitizer + UBSan"
	@echo "make build      build lib (build/libgcpush.a .so), bin/gcpush, gcpush.pc"
	@echo "make bench      benchmarks (ratios, not tests)"
	@echo "make fuzz FUZZ_SECONDS=600   fuzz the run-file reader (libFuzzer + ASan/UBSan)"
	@echo "make install PREFIX=/opt/gcpush   headers, libs, binary, pkg-config file"
	@echo "make deps       apt-get install the Debian packages that are missing"
	@echo "make clean"

# Installs only what is missing; does nothing (and needs no network) when all is there.
deps:
	@missing=""; for p in $(DEB_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "deps: installing$$missing"; \
	  if [ "$$(id -u)" != 0 ]; then echo "deps: run as root to install:$$missing" >&2; exit 1; fi; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing; \
	fi

build: $(LIBA) $(LIBSO) $(BIN) gcpush.pc fields/data/dipole.h5

# The dipole as a gridded field (2D R-Z, 0.05 R_E), sampled by gcpush itself.
fields/data/dipole.h5: runs/grid-dipole.run $(BIN)
	@echo "  GRID  $@"
	@ASAN_OPTIONS=detect_leaks=0 ./$(BIN) grid runs/grid-dipole.run > /dev/null

$(BUILD)/%.o: %.c $(wildcard include/gcpush/*.h src/*.h src/*/*.h fields/*.h tests/unit/*.h)
	@mkdir -p $(dir $@)
	@echo "  CC    $<"
	@$(CC) $(CPPFLAGS) $(CFLAGS) -c $< -o $@

$(addprefix $(BUILD)/,$(NOFUSE_OBJ)): CFLAGS += -fno-tree-slp-vectorize

$(LIBA): $(LIB_OBJ)
	@rm -f $@
	@echo "  AR    $@"; ar rcs $@ $^

$(LIBSO): $(LIB_OBJ)
	@echo "  LD    $@"; $(CC) -shared -o $@ $^ $(OPTFLAGS) $(LDLIBS)

# bin/gcpush links HDF5, GSL, inih and szip statically where their static
# libraries exist (Debian's -dev packages ship them), else as LDLIBS: the
# shared libhdf5 pulls in libcurl for its S3 driver and with it 30 more
# libraries (TLS, Kerberos, LDAP, SSH, IDN) that every rank maps and
# relocates at start-up; linked statically, only the HDF5 objects gcpush
# calls come in.  Each rank's start-up then loads 12 libraries, not 47:
# 0.025-0.03 s less CPU and ~450 fewer page faults per rank (2-rank runs,
# medians of 12).  Open MPI and zlib (which Open MPI loads anyway) stay
# shared.  A filter plugin (HDF5_PLUGIN_PATH) built against the shared
# libhdf5 would see a second HDF5; gcpush needs none (deflate, shuffle).
BIN_LDLIBS := $(shell pkg-config --libs-only-L $(PKGS) 2>/dev/null) \
              -Wl,-Bstatic -lhdf5 -lgsl -lgslcblas -linih -lsz -laec -Wl,-Bdynamic -lz -ldl -lm
$(BIN): $(BUILD)/src/gcpush.o $(LIBA)
	@mkdir -p $(dir $@)
	$(CC) $(OPTFLAGS) -o $@ $^ $(BIN_LDLIBS) 2>/dev/null || $(CC) $(OPTFLAGS) -o $@ $^ $(LDLIBS)

gcpush.pc: Makefile
	@printf 'prefix=%s\nincludedir=$${prefix}/include\nlibdir=$${prefix}/lib\n\nName: gcpush\nDescription: guiding-centre and full-orbit charged-particle pusher\nVersion: %s\nRequires.private: %s\nCflags: -I$${includedir}\nLibs: -L$${libdir} -lgcpush\nLibs.private: -lm\n' \
	  "$(PREFIX)" "$(VERSION)" "$(PKGS)" > $@

$(UNIT): $(TEST_OBJ) $(LIBA)
	$(CC) $(OPTFLAGS) -o $@ $(TEST_OBJ) $(LIBA) $(LDLIBS) -lcriterion

# The README's commands: install, build, then the work.
run: deps
	@$(MAKE) --no-print-directory build
	./$(BIN) --force runs/dipole.run
	$(PY) analysis/plot_orbits.py dipole.h5 -o dipole.png --max 12
	@echo "output: $$(pwd)/dipole.h5   plot: $$(pwd)/dipole.png"

check: deps
	@$(MAKE) --no-print-directory check-built

check-built: build $(UNIT) $(FUZZER) $(FUZZER_CKPT)
	LSAN_OPTIONS="suppressions=$(CURDIR)/tests/lsan.supp:print_suppressions=0" $(UNIT) --jobs=$(JOBS)
	BUILD=$(BUILD) PY=$(PY) GCPUSH=$(CURDIR)/$(BIN) sh tests/cli/run_all.sh
	@$(MAKE) --no-print-directory fuzz-run FUZZ_SECONDS=20

fuzz: deps
	@$(MAKE) --no-print-directory $(FUZZER) $(FUZZER_CKPT)
	@$(MAKE) --no-print-directory fuzz-run

fuzz-run: $(FUZZER) $(FUZZER_CKPT)
	@mkdir -p build-fuzz/corpus build-fuzz/corpus-ckpt
	@echo "fuzzing the run-file reader for $(FUZZ_SECONDS) s"
	@$(FUZZER) -max_total_time=$(FUZZ_SECONDS) -timeout=20 -rss_limit_mb=4096 \
	  -dict=tests/fuzz/runfile.dict -print_final_stats=0 build-fuzz/corpus tests/fuzz/corpus \
	  > build-fuzz/last.log 2>&1 || { tail -40 build-fuzz/last.log; exit 1; }
	@grep -E "^(Done|#[0-9]+ +DONE)" build-fuzz/last.log | tail -1
	@echo "fuzzing the restart path (checkpoint files) for $(FUZZ_SECONDS) s"
	@$(FUZZER_CKPT) -max_total_time=$(FUZZ_SECONDS) -timeout=20 -rss_limit_mb=2048 \
	  -malloc_limit_mb=256 -print_final_stats=0 build-fuzz/corpus-ckpt tests/fuzz/corpus-ckpt \
	  > build-fuzz/last-ckpt.log 2>&1 || { tail -40 build-fuzz/last-ckpt.log; exit 1; }
	@grep -E "^(Done|#[0-9]+ +DONE)" build-fuzz/last-ckpt.log | tail -1

bench: deps
	@$(MAKE) --no-print-directory build
	@$(MAKE) --no-print-directory -C tests/bench BUILD=../../$(BUILD) run

install: build
	install -d $(DESTDIR)$(PREFIX)/include/gcpush $(DESTDIR)$(PREFIX)/lib/pkgconfig $(DESTDIR)$(PREFIX)/bin
	install -m 644 include/gcpush/*.h $(DESTDIR)$(PREFIX)/include/gcpush/
	install -m 644 $(LIBA) $(DESTDIR)$(PREFIX)/lib/
	install -m 755 $(LIBSO) $(DESTDIR)$(PREFIX)/lib/
	install -m 755 $(BIN) $(DESTDIR)$(PREFIX)/bin/
	sed 's|^prefix=.*|prefix=$(PREFIX)|' gcpush.pc > $(DESTDIR)$(PREFIX)/lib/pkgconfig/gcpush.pc

clean:
	rm -rf build build-debug build-fuzz bin gcpush.pc
