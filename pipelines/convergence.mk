# The rate study (`make convergence`; docs/models/triax.md, "Rates"): the paper's I_P specimen
# (seed 1) tested on the rigid boundary at rates halving from 0.5 /s, and its curves one per
# rate: q (q_section) and eps_v against the axial strain (out/convergence/macro.png), the
# sliding ratio and the particles' mean rotation (micro.png); the runs' tables beside them,
# and the study's tables, each rate and each rate against half of it (table.md).
# Two rates agree when q averaged over 0.5 % of strain is within 2 % of peak q, eps_v within
# 2 % of its range and S_p within 0.02. `make -j 2 convergence` runs two rates at a time.

CONV := $(OUT)/convergence
CONV_RATES ?= 0.5 0.25 0.125 0.0625
CONV_SPEC ?= $(PAPER)/ip-1.spec.jsonl
CONV_TRIAX ?= --boundary rigid --final-strain 0.15

.SECONDARY: $(foreach r,$(CONV_RATES),$(CONV)/r$(r).triax.jsonl $(CONV)/r$(r).fabric.csv)

$(CONV)/r%.triax.jsonl: $(CONV_SPEC)
	mkdir -p $(CONV)
	pipelines/triax-resume.sh $< $@ $(CONV_TRIAX) --rate $* --summary $(CONV)/r$*.triax.json \
	  --csv $(CONV)/r$*.triax.csv 2>> $(CONV)/r$*.triax.log

$(CONV)/r%.fabric.csv: $(CONV)/r%.triax.jsonl
	fabric --quiet < $< > $@.part
	mv $@.part $@

# Every rate's rows, its rate in front.
$(CONV)/triax.csv: $(foreach r,$(CONV_RATES),$(CONV)/r$(r).triax.jsonl)
	( head -n 1 $(CONV)/r$(firstword $(CONV_RATES)).triax.csv | sed 's/^/rate,/' ; \
	  $(foreach r,$(CONV_RATES),tail -n +2 $(CONV)/r$(r).triax.csv | sed 's/^/$(r),/' ;) ) > $@
$(CONV)/fabric.csv: $(foreach r,$(CONV_RATES),$(CONV)/r$(r).fabric.csv)
	( head -n 1 $(CONV)/r$(firstword $(CONV_RATES)).fabric.csv | sed 's/^/rate,/' ; \
	  $(foreach r,$(CONV_RATES),tail -n +2 $(CONV)/r$(r).fabric.csv | sed 's/^/$(r),/' ;) ) > $@

convergence: $(CONV)/triax.csv $(CONV)/fabric.csv
	pipelines/convergence-table.sh $(CONV) $(CONV_RATES) > $(CONV)/table.md
	cat $(CONV)/table.md
	plot --x nominal_strain --y q_section,volumetric_strain --series rate --size 1200x500 \
	  --xlabel "axial strain ln(H0/H)" --ylabel "q over the section V/H (Pa)" \
	  --ylabel "volumetric strain ln(V0/V)" \
	  --title "Rates (1/s), paper I_P, rigid boundary" < $(CONV)/triax.csv > $(CONV)/macro.png
	plot --x axial_strain --y sliding_ratio,rotation --series rate --size 1200x500 \
	  --xlabel "axial strain ln(H0/H)" --ylabel "sliding ratio S_p" --ylabel "mean rotation (rad)" \
	  --title "Rates (1/s), paper I_P, rigid boundary" < $(CONV)/fabric.csv > $(CONV)/micro.png

.PHONY: convergence
