# Figures 13-18 of the paper: the micro-mechanics of the triaxial tests (fig9's runs), from
# every frame of their streams (every 0.5 % of axial strain).
#   fig13: coordination; fig14: sliding ratio; fig15: mean particle rotation; fig16: roses of
#   the normal contact force at the start, at peak q and at the end; fig17: the anisotropies;
#   fig18: the stress ratio from the anisotropies (Eq. 19), the contacts (Eq. 9) and the
#   boundary (Eq. 20).

# Quick specimens have about 600 contacts: 5 bands (50 bins) keep a few per bin.
FABRIC ?= --rose-bands 5

.SECONDARY: $(foreach g,$(GROUPS),$(OUT)/fabric-$(g).csv)

$(OUT)/fabric-%.csv: $(OUT)/triax-%.jsonl
	fabric --roses $(OUT)/fabric-$*-roses.csv --rose-obj $(OUT)/fabric-$*-roses.obj \
	  --group $(call group_name,$*) $(FABRIC) < $< > $@.part
	mv $@.part $@

$(OUT)/fabric-all.csv: $(foreach g,$(GROUPS),$(OUT)/fabric-$(g).csv)
	( head -n 1 $(OUT)/fabric-ip.csv | sed 's/^/group,/' ; \
	  $(foreach g,$(GROUPS),tail -n +2 $(OUT)/fabric-$(g).csv | sed 's/^/$(call group_name,$(g)),/' ;) ) > $@

fig13: $(OUT)/fabric-all.csv
	plot --x axial_strain --y coordination,mechanical_coordination --series group --size 1200x500 \
	  --xlabel "axial strain ln(H0/H)" --ylabel "coordination 2Nc/Np" --ylabel "without rattlers" \
	  --title "Fig. 13: coordination number during loading" < $< > $(OUT)/fig13.png

fig14: $(OUT)/fabric-all.csv
	plot --x axial_strain --y sliding_ratio --series group --xlabel "axial strain ln(H0/H)" \
	  --ylabel "sliding ratio Sp (mobility > 0.9999)" \
	  --title "Fig. 14: sliding contacts during loading" < $< > $(OUT)/fig14.png

fig15: $(OUT)/fabric-all.csv
	plot --x axial_strain --y rotation,rotation_accumulated --series group --size 1200x500 \
	  --xlabel "axial strain ln(H0/H)" --ylabel "mean rotation (rad)" --ylabel "accumulated (rad)" \
	  --title "Fig. 15: mean particle rotation since the start of loading" < $< > $(OUT)/fig15.png

fig16: $(foreach g,$(GROUPS),$(OUT)/fabric-$(g).csv)
	cat $(foreach g,$(GROUPS),$(OUT)/fabric-$(g)-roses.obj) | render --cols 3 --same-scale \
	  --size 1200x1500 --no-edges --elevation 15 \
	  --title "Fig. 16: roses of the normal contact force (z: the loading axis)" > $(OUT)/fig16.png

fig17: $(OUT)/fabric-all.csv
	plot --x axial_strain --y a_c,a_bn,a_fn,a_ft --series group --size 1600x500 \
	  --xlabel "axial strain ln(H0/H)" --ylabel "a_c (normals)" --ylabel "a_bn (branch)" --ylabel "a_fn (normal force)" --ylabel "a_ft (shear force)" \
	  --title "Fig. 17: anisotropies during loading" < $< > $(OUT)/fig17.png

fig18: $(OUT)/fabric-all.csv
	plot --x axial_strain --y ratio_anisotropy,ratio_contacts,ratio_boundary --series group \
	  --size 1500x500 --xlabel "axial strain ln(H0/H)" \
	  --ylabel "q/p from anisotropy (Eq. 19)" --ylabel "q/p from contacts (Eq. 9)" --ylabel "q/p from boundary (Eq. 20)" \
	  --title "Fig. 18: stress ratios during loading" < $< > $(OUT)/fig18.png

# The paper's scale: the fabric of every run of `make paper`, figures 13-18 with each group's
# curve the mean over its seeds and a band from the smallest to the largest
# (out/paper/fig13.png ...), and the roses of each group's first seed.
.SECONDARY: $(foreach r,$(PAPER_RUNS),$(PAPER)/$(r).fabric.csv)

$(PAPER)/%.fabric.csv: $(PAPER)/%.triax.jsonl
	fabric --roses $(PAPER)/$*.roses.csv --rose-obj $(PAPER)/$*.roses.obj \
	  --group $(call group_name,$(word 1,$(subst -, ,$*)))-$(word 2,$(subst -, ,$*)) < $< > $@.part
	mv $@.part $@

# The runs' rows with group, seed and the frame's nominal strain (a multiple of 0.5 %), so
# that the seeds' rows meet at the same x.
$(PAPER)/fabric-all.csv: $(foreach r,$(PAPER_RUNS),$(PAPER)/$(r).fabric.csv)
	( head -n 1 $(PAPER)/$(firstword $(PAPER_RUNS)).fabric.csv | sed 's/^/group,seed,nominal_strain,/' ; \
	  $(foreach r,$(PAPER_RUNS),tail -n +2 $(PAPER)/$(r).fabric.csv | \
	    awk -F, -v OFS=, '{ printf "%s,%s,%.3f,%s\n", "$(call group_name,$(word 1,$(subst -, ,$(r))))", \
	      "$(word 2,$(subst -, ,$(r)))", int($$5 / 0.005 + 0.5) * 0.005, $$0 }' ;) ) > $@

paper-fabric: $(PAPER)/fabric-all.csv
	plot --x nominal_strain --y coordination,mechanical_coordination --series group --stats --band minmax \
	  --size 1200x500 --xlabel "axial strain ln(H0/H)" --ylabel "coordination 2Nc/Np" --ylabel "without rattlers" \
	  --title "Fig. 13 at the paper's scale: mean over seeds, band min-max" < $< > $(PAPER)/fig13.png
	plot --x nominal_strain --y sliding_ratio --series group --stats --band minmax \
	  --xlabel "axial strain ln(H0/H)" --ylabel "sliding ratio Sp (mobility > 0.9999)" \
	  --title "Fig. 14 at the paper's scale" < $< > $(PAPER)/fig14.png
	plot --x nominal_strain --y rotation,rotation_accumulated --series group --stats --band minmax \
	  --size 1200x500 --xlabel "axial strain ln(H0/H)" --ylabel "mean rotation (rad)" --ylabel "accumulated (rad)" \
	  --title "Fig. 15 at the paper's scale" < $< > $(PAPER)/fig15.png
	cat $(foreach g,$(PAPER_GROUPS),$(PAPER)/$(g)-$(firstword $(PAPER_SEEDS)).roses.obj) | render --cols 3 \
	  --same-scale --size 1200x$(shell echo $$((375 * $(words $(PAPER_GROUPS))))) --no-edges --elevation 15 \
	  --title "Fig. 16 at the paper's scale: roses of the normal contact force" \
	  > $(PAPER)/fig16.png
	plot --x nominal_strain --y a_c,a_bn,a_fn,a_ft --series group --stats --band minmax --size 1600x500 \
	  --xlabel "axial strain ln(H0/H)" --ylabel "a_c (normals)" --ylabel "a_bn (branch)" --ylabel "a_fn (normal force)" --ylabel "a_ft (shear force)" \
	  --title "Fig. 17 at the paper's scale" < $< > $(PAPER)/fig17.png
	plot --x nominal_strain --y ratio_anisotropy,ratio_contacts,ratio_boundary --series group --stats \
	  --band minmax --size 1500x500 --xlabel "axial strain ln(H0/H)" \
	  --ylabel "q/p from anisotropy (Eq. 19)" --ylabel "q/p from contacts (Eq. 9)" --ylabel "q/p from boundary (Eq. 20)" \
	  --title "Fig. 18 at the paper's scale" < $< > $(PAPER)/fig18.png

# Each run's macro and micro results in a row, and the groups' table with the mean and standard
# deviation over the seeds (out/paper/table.md), as the seed study's (pipelines/study-row.sh).
$(PAPER)/runs.csv: $(foreach r,$(PAPER_RUNS),$(PAPER)/$(r).fabric.csv)
	$(call study_rows,$(PAPER),$(PAPER_RUNS)) > $@

paper-table: $(PAPER)/runs.csv
	pipelines/study-table.sh $< > $(PAPER)/table.md
	cat $(PAPER)/table.md

paper: paper-fabric paper-table
.PHONY: paper-fabric paper-table
