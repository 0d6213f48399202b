# Every figure from scratch: `make figures` (or `make fig1` ... `make fig18`), `make paper`,
# `make study`, `make convergence` (the rate study); `make smoke`: every recipe of those at a tiny scale (SCALE=smoke), as CI runs
# them; `make test`; `make bench`. Outputs go to out/ (out/smoke/ at the smoke scale; not
# tracked).

SHELL := /bin/bash
.SHELLFLAGS := -o pipefail -ec

# SCALE=smoke shrinks every size (pipelines/smoke.mk) and writes to out/smoke; the recipes,
# tools, flags and pipes stay the same.
SCALE ?= full
SMOKE_OUT := out/smoke
ifeq ($(SCALE),smoke)
include pipelines/smoke.mk
else ifneq ($(SCALE),full)
$(error SCALE is full or smoke, not '$(SCALE)')
endif

OUT ?= out
BIN := $(CURDIR)/target/release
export PATH := $(BIN):$(PATH)
# Every line a tool writes on standard error starts with its target's name (`make -j`).
export GRANULAR_TAG = $(patsubst $(OUT)/%,%,$@)

.PHONY: all figures build test fuzz bench clean smoke paper convergence fig1 fig2 fig4 fig5 fig6 fig7 fig8 fig9 fig10 fig11 fig12 figtriax \
  fig13 fig14 fig15 fig16 fig17 fig18
all: figures
figures: fig1 fig2 fig4 fig5 fig6 fig7 fig8 fig9 fig10 fig11 fig12 figtriax \
  fig13 fig14 fig15 fig16 fig17 fig18

# The tools, built when a source is newer than they are. Recipes need them only as files: a
# cluster job (docs/GUIDE.md) runs on binaries built before it was submitted, without cargo.
TOOLS := polygen abrade roundness render dem pack simplify plot triax fabric
BINS := $(addprefix $(BIN)/,$(TOOLS))
SOURCES := Cargo.toml Cargo.lock shared/Cargo.toml $(shell find shared/src tools -name '*.rs')
$(BINS) &: $(SOURCES)
	cargo build --release --locked --bins
	touch $(BINS)
build: $(BINS)

$(OUT):
	mkdir -p $(OUT)

include pipelines/geometry.mk
include pipelines/specimen.mk
include pipelines/triax.mk
include pipelines/bench.mk
include pipelines/paper.mk
include pipelines/fabric.mk
include pipelines/study.mk
include pipelines/convergence.mk

test:
	cargo test --release --locked --workspace

# Every recipe of `make figures`, `make paper`, `make study` and `make convergence`, from
# scratch, at the smoke scale; then every picture is checked (pipelines/pictures.txt).
smoke: build
	rm -rf $(SMOKE_OUT)
	$(MAKE) SCALE=smoke figures paper study convergence
	cargo run --release --locked --quiet -p xtask -- check-pictures pipelines/pictures.txt $(SMOKE_OUT)

# The readers' fuzzers (docs/GUIDE.md): FUZZ_SECONDS each, or 1e7 inputs.
FUZZ_SECONDS ?= 3600
fuzz:
	pipelines/fuzz.sh $(FUZZ_SECONDS) 10000000

clean:
	rm -rf $(OUT)
