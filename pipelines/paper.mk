# The paper's scale: specimens of 300 x 600 mm (2259 particles of 10-40 mm) at relative density
# 0.8 against the void-ratio limits in pipelines/limits.csv, for the four groups and several
# seeds (`PAPER_SEEDS`, default 1 2 3). Each specimen is an independent target: `make -j N
# paper` runs N at once, and a cluster runs one target per job (docs/GUIDE.md).

PAPER := $(OUT)/paper
PAPER_SEEDS ?= 1 2 3
PAPER_RUNS := $(foreach g,$(GROUPS),$(foreach s,$(PAPER_SEEDS),$(g)-$(s)))
limits = $(shell awk -F, '$$1 == "$(1)" {print $$2 "," $$3}' pipelines/limits.csv)

.SECONDARY: $(foreach r,$(PAPER_RUNS),$(PAPER)/$(r).spec.jsonl)

paper-specimens: $(foreach r,$(PAPER_RUNS),$(PAPER)/$(r).spec.jsonl)

# $(PAPER)/G-S.spec.jsonl: group G's specimen, pack seed S (its summary beside it).
.SECONDEXPANSION:
$(PAPER)/%.spec.jsonl: $(OUT)/group-$$(word 1,$$(subst -, ,$$*)).obj
	mkdir -p $(PAPER)
	pack --relative-density 0.8 --refine-runs 1 --seed $(word 2,$(subst -, ,$*)) \
	  --void-ratio-limits $(call limits,$(word 1,$(subst -, ,$*))) --every 20000 \
	  --summary $(PAPER)/$*.spec.json < $< > $@.part 2> $(PAPER)/$*.spec.log
	mv $@.part $@
