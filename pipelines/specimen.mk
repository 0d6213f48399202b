# Figure 8 of the paper: the specimens of the four groups (I_P, Ab_1, Ab_2, Ab_3), consolidated
# isotropically to 100 kPa by `pack`, drawn side by side. Quick scale by default (150 x 300 mm,
# 288 particles each, under 100 s a group on 2 cores); the paper's full scale with
#   make fig8 SPECIMEN="--diameter 0.3 --height 0.6"
# (2259 particles, 11-17 minutes a group). $(OUT)/fig8.jsonl: the specimens' summaries,
# one JSON line each (docs/models/pack.md, "Output").

SPECIMEN ?= --diameter 0.15 --height 0.3
GROUPS ?= ip ab1 ab2 ab3

# The specimens are worth keeping (dem runs on from them); a failed step leaves no output.
.SECONDARY: $(foreach g,$(GROUPS),$(OUT)/group-$(g).obj $(OUT)/specimen-$(g).jsonl)
.DELETE_ON_ERROR:

$(OUT)/group-ip.obj: $(OUT)/templates.obj
	cp $< $@

$(OUT)/group-ab%.obj: $(OUT)/templates.obj
	abrade --levels $* < $< > $@

# The specimen's state, its summary, and its bodies as OBJ objects of one render cell.
$(OUT)/specimen-%.jsonl: $(OUT)/group-%.obj
	pack $(SPECIMEN) --summary $(OUT)/specimen-$*.json < $< > $@.part
	mv $@.part $@

$(OUT)/specimen-%.obj: $(OUT)/specimen-%.jsonl
	dem --steps 0 --obj $@ --obj-group $(subst ip,I_P,$(subst ab,Ab_,$*)) < $< > /dev/null

fig8: $(foreach g,$(GROUPS),$(OUT)/specimen-$(g).obj)
	cat $(foreach g,$(GROUPS),$(OUT)/specimen-$(g).json) > $(OUT)/fig8.jsonl
	cat $^ | render --cols 4 --same-scale --size 1200x620 --no-edges \
	  --title "Fig. 8: the specimens of the four groups, consolidated isotropically by pack" > $(OUT)/fig8.png
