# The seed study at quick scale (`make study`): the four groups' tests on STUDY_SEEDS specimens
# each (pack --seed S; seed 1 is the figures' run), and a table of their macro- and
# micro-mechanical results with each group's mean and standard deviation over the seeds
# (out/study/table.md; the runs' rows in out/study/runs.csv): how much of a difference between
# groups is beyond specimen-to-specimen scatter. `make -j 2 study` runs two at a time.

STUDY := $(OUT)/study
STUDY_SEEDS ?= 1 2 3
STUDY_RUNS := $(foreach g,$(GROUPS),$(foreach s,$(STUDY_SEEDS),$(g)-$(s)))

.SECONDARY: $(foreach r,$(STUDY_RUNS),$(STUDY)/$(r).spec.jsonl $(STUDY)/$(r).triax.jsonl $(STUDY)/$(r).fabric.csv)

# Seed 1: the figures' run.
$(STUDY)/%-1.triax.jsonl: $(OUT)/triax-%.jsonl
	mkdir -p $(STUDY)
	cp $(OUT)/triax-$*.json $(STUDY)/$*-1.triax.json
	cp $< $@

$(STUDY)/%.spec.jsonl: $(OUT)/group-$$(word 1,$$(subst -, ,$$*)).obj
	mkdir -p $(STUDY)
	pack $(SPECIMEN) --seed $(word 2,$(subst -, ,$*)) \
	  --summary $(STUDY)/$*.spec.json < $< > $@.part
	mv $@.part $@

$(STUDY)/%.triax.jsonl: $(STUDY)/%.spec.jsonl
	pipelines/triax-resume.sh $< $@ $(TRIAX) --summary $(STUDY)/$*.triax.json

$(STUDY)/%.fabric.csv: $(STUDY)/%.triax.jsonl
	fabric < $< > $@.part
	mv $@.part $@

# $(call study_rows,DIR,RUNS): the header and each run's row (pipelines/study-row.sh) of the
# runs G-S in DIR, from DIR/G-S.triax.json and DIR/G-S.fabric.csv (also make paper's table).
study_rows = ( pipelines/study-row.sh --header ; \
  $(foreach r,$(2),pipelines/study-row.sh $(call group_name,$(word 1,$(subst -, ,$(r)))) \
    $(word 2,$(subst -, ,$(r))) $(LEVEL_$(word 1,$(subst -, ,$(r)))) \
    $(1)/$(r).triax.json $(1)/$(r).fabric.csv ;) )

$(STUDY)/runs.csv: $(foreach r,$(STUDY_RUNS),$(STUDY)/$(r).fabric.csv)
	$(call study_rows,$(STUDY),$(STUDY_RUNS)) > $@

study: $(STUDY)/runs.csv
	pipelines/study-table.sh $< > $(STUDY)/table.md
	cat $(STUDY)/table.md

.PHONY: study
