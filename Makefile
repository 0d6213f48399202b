# Every figure from scratch: `make figures` (or `make fig1` ... `make fig8`); `make test`;
# `make bench`. Outputs go to out/ (not tracked).

OUT := out
BIN := $(CURDIR)/target/release
export PATH := $(BIN):$(PATH)
SHELL := /bin/bash
.SHELLFLAGS := -o pipefail -ec

.PHONY: all figures build test fuzz bench clean paper fig1 fig2 fig4 fig5 fig6 fig7 fig8 fig9 fig10 fig11 fig12 figtriax \
  fig13 fig14 fig15 fig16 fig17 fig18
all: figures
figures: fig1 fig2 fig4 fig5 fig6 fig7 fig8 fig9 fig10 fig11 fig12 figtriax \
  fig13 fig14 fig15 fig16 fig17 fig18

build:
	cargo build --release --locked --bins

$(OUT):
	mkdir -p $(OUT)

include pipelines/geometry.mk
include pipelines/specimen.mk
include pipelines/triax.mk
include pipelines/bench.mk
include pipelines/paper.mk
include pipelines/fabric.mk
include pipelines/study.mk

test:
	cargo test --release --locked --workspace

# The readers' fuzzers (docs/GUIDE.md): FUZZ_SECONDS each, or 1e7 inputs.
FUZZ_SECONDS ?= 3600
fuzz:
	pipelines/fuzz.sh $(FUZZ_SECONDS) 10000000

clean:
	rm -rf $(OUT)
