# The paper's scale (`make paper`): specimens of 300 x 600 mm (2259 particles of 10-40 mm) at relative density
# 0.8 against the void-ratio limits in pipelines/limits.csv, for the four groups and several
# seeds (`PAPER_SEEDS`, default 1 2 3). Each specimen is an independent target: `make -j N
# paper` runs N at once, and a cluster runs one target per job (docs/GUIDE.md).

PAPER := $(OUT)/paper
PAPER_SEEDS ?= 1 2 3
PAPER_GROUPS ?= $(GROUPS)
# The specimen: the container, the particles' sizes, and the calibration sample's scale.
PAPER_SPECIMEN ?= --diameter 0.3 --height 0.6 --size-min 0.01 --size-max 0.04 --calibration-scale 0.5
# The rigid boundary at 0.0625 /s, the fastest rate at which q and eps_v have converged in every
# group: I_P from 0.125 /s, Ab_3 from 0.0625 /s (docs/models/triax.md, "Rates"). The paper's
# membrane (`PAPER_TRIAX="--boundary membrane ..."`) costs about four times the steps' time, and
# its Eq. 20 q carries the stretched sleeve's growing confinement; the paper's 0.5 /s reads q
# 6-15 % of peak q above converged (I_P, rigid).
PAPER_TRIAX ?= --boundary rigid --rate 0.0625 --final-strain 0.15
# Seed by seed: a `make -j N paper` stopped part way has every group's first seed before any
# group's second.
PAPER_RUNS ?= $(foreach s,$(PAPER_SEEDS),$(foreach g,$(PAPER_GROUPS),$(g)-$(s)))
limits = $(shell awk -F, '$$1 == "$(1)" {print $$2 "," $$3}' pipelines/limits.csv)

.SECONDARY: $(foreach r,$(PAPER_RUNS),$(PAPER)/$(r).spec.jsonl)

paper-specimens: $(foreach r,$(PAPER_RUNS),$(PAPER)/$(r).spec.jsonl)

# $(PAPER)/G-S.spec.jsonl: group G's specimen, pack seed S (its summary beside it). A stopped
# pack made again takes the compactions it finished from its journal (G-S.spec.journal).
.SECONDEXPANSION:
$(PAPER)/%.spec.jsonl: $(OUT)/group-$$(word 1,$$(subst -, ,$$*)).obj
	mkdir -p $(PAPER)
	pack $(PAPER_SPECIMEN) --relative-density 0.8 --refine-runs 1 --seed $(word 2,$(subst -, ,$*)) \
	  --void-ratio-limits $(call limits,$(word 1,$(subst -, ,$*))) \
	  --journal $(PAPER)/$*.spec.journal --summary $(PAPER)/$*.spec.json < $< > $@.part 2> $(PAPER)/$*.spec.log
	mv $@.part $@

# The triaxial test of each specimen, and the paper's figures 9-12 with every group's curve the
# mean over its seeds and a band from the smallest to the largest (out/paper/fig*.png).
.SECONDARY: $(foreach r,$(PAPER_RUNS),$(PAPER)/$(r).triax.jsonl)

# A test stopped part way (a job's time limit) goes on from its last whole frame when its
# target is made again (pipelines/triax-resume.sh).
$(PAPER)/%.triax.jsonl: $(PAPER)/%.spec.jsonl
	pipelines/triax-resume.sh $< $@ $(PAPER_TRIAX) --summary $(PAPER)/$*.triax.json \
	  --csv $(PAPER)/$*.triax.csv --obj $(PAPER)/$*.triax.obj --obj-group $* \
	  2>> $(PAPER)/$*.triax.log

paper-runs: $(foreach r,$(PAPER_RUNS),$(PAPER)/$(r).triax.jsonl)

# The seeds' mean is taken at the strains all runs measure: the 0.1 % grid
# (pipelines/on-grid.sh).
group_name = $(subst ip,I_P,$(subst ab,Ab_,$(1)))
$(PAPER)/all.csv: $(foreach r,$(PAPER_RUNS),$(PAPER)/$(r).triax.jsonl)
	( head -n 1 $(PAPER)/$(firstword $(PAPER_RUNS)).triax.csv | sed 's/^/group,seed,/' ; \
	  $(foreach r,$(PAPER_RUNS),pipelines/on-grid.sh $(PAPER)/$(r).triax.csv | tail -n +2 | \
	    sed 's/^/$(call group_name,$(word 1,$(subst -, ,$(r)))),$(word 2,$(subst -, ,$(r))),/' ;) ) > $@

# E50 and the initial Poisson's ratio of a run whose platens started at full speed (--ramp 0,
# the streams from before the ramp) are the stress wave's, not the specimen's: nan, which plot
# leaves out of the figure and the seeds' mean (docs/models/triax.md, "The start of loading").
$(PAPER)/summary.csv: $(foreach r,$(PAPER_RUNS),$(PAPER)/$(r).triax.jsonl)
	( echo "group,seed,level,e50_mpa,poisson,friction_angle,friction_angle_section,dilatancy_angle,peak_q_kpa,peak_strain,final_volumetric_strain,consolidation_steps,loading_steps,wall_clock" ; \
	  $(foreach r,$(PAPER_RUNS),f=$(PAPER)/$(r).triax.json; \
	    echo "$(call group_name,$(word 1,$(subst -, ,$(r)))),$(word 2,$(subst -, ,$(r))),$(LEVEL_$(word 1,$(subst -, ,$(r)))),$$(awk -v r="$$($(call summary_field,$$f,ramp))" -v e="$$($(call summary_field,$$f,e50))" -v nu="$$($(call summary_field,$$f,poisson_ratio))" 'BEGIN { if (r > 0) print e / 1e6 "," nu; else print "nan,nan" }'),$$($(call summary_field,$$f,friction_angle)),$$($(call summary_field,$$f,friction_angle_section)),$$($(call summary_field,$$f,dilatancy_angle)),$$(awk "BEGIN{print $$($(call summary_field,$$f,peak_q))/1e3}"),$$($(call summary_field,$$f,peak_strain)),$$($(call summary_field,$$f,final_volumetric_strain)),$$($(call summary_field,$$f,consolidation_steps)),$$($(call summary_field,$$f,loading_steps)),$$($(call summary_field,$$f,wall_clock))" ;) ) > $@

paper: $(PAPER)/all.csv $(PAPER)/summary.csv
	plot --x nominal_strain --y q_boundary --series group --stats --band minmax \
	  --stats-out $(PAPER)/fig9.csv --xlabel "axial strain ln(H0/H)" --ylabel "q = s1 - s3 (Pa)" \
	  --title "Fig. 9 at the paper's scale: mean over seeds, band min-max" < $(PAPER)/all.csv > $(PAPER)/fig9.png
	plot --x nominal_strain --y volumetric_strain --series group --stats --band minmax \
	  --stats-out $(PAPER)/fig10.csv --xlabel "axial strain ln(H0/H)" --ylabel "volumetric strain ln(V0/V)" \
	  --title "Fig. 10 at the paper's scale: mean over seeds, band min-max" < $(PAPER)/all.csv > $(PAPER)/fig10.png
	plot --x level --y e50_mpa,poisson --stats --band minmax --size 1200x500 \
	  --xlabel "abrasion level (0: I_P)" --ylabel "E50 (MPa)" --ylabel "Poisson's ratio" \
	  --title "Fig. 11 at the paper's scale" < $(PAPER)/summary.csv > $(PAPER)/fig11.png
	plot --x level --y friction_angle,dilatancy_angle --stats --band minmax --size 1200x500 \
	  --xlabel "abrasion level (0: I_P)" --ylabel "peak friction angle (deg)" --ylabel "dilatancy angle (deg)" \
	  --title "Fig. 12 at the paper's scale" < $(PAPER)/summary.csv > $(PAPER)/fig12.png

# For pipelines/slurm-submit.sh: the folder and the runs (one line each), and the groups'
# templates, which every run's job shares and which are made before the jobs are submitted.
paper-list:
	@echo $(PAPER)
	@echo $(PAPER_RUNS)
paper-templates: $(foreach g,$(PAPER_GROUPS),$(OUT)/group-$(g).obj)
.PHONY: paper-list paper-templates
