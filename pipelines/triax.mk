# Figures 9-12 of the paper: the triaxial test of the four groups' specimens (those of fig8),
# at quick scale by default (150 x 300 mm, 288 particles each). Each run writes its stream
# (out/triax-G.jsonl), its measurements (.csv), its summary (.json), the bodies at the end
# coloured by rotation (.obj) and VTK snapshots (out/triax-G-vtk/).
#   fig9: deviatoric stress q against axial strain; fig10: volumetric strain;
#   fig11: E50 and Poisson's ratio against the abrasion level; fig12: peak friction and
#   dilatancy angles; figtriax: the specimens at the end.

# 1 /s keeps `make figures` quick: up to 5 % of strain its q is about 10 % of peak q above the
# converged curve, and its sliding ratio 0.11 above 0.1 /s's (docs/models/triax.md, "Rates").
TRIAX ?= --rate 1 --final-strain 0.15
LEVEL_ip := 0
LEVEL_ab1 := 1
LEVEL_ab2 := 2
LEVEL_ab3 := 3

.SECONDARY: $(foreach g,$(GROUPS),$(OUT)/triax-$(g).jsonl)

# A test stopped part way goes on from its last whole frame when its target is made again
# (pipelines/triax-resume.sh).
$(OUT)/triax-%.jsonl: $(OUT)/specimen-%.jsonl
	pipelines/triax-resume.sh $< $@ $(TRIAX) --summary $(OUT)/triax-$*.json --csv $(OUT)/triax-$*.csv \
	  --obj $(OUT)/triax-$*.obj --obj-group $(subst ip,I_P,$(subst ab,Ab_,$*)) \
	  --vtk $(OUT)/triax-$*-vtk

# The four groups' measurements in one table, with a group column.
$(OUT)/triax-all.csv: $(foreach g,$(GROUPS),$(OUT)/triax-$(g).jsonl)
	( head -n 1 $(OUT)/triax-ip.csv | sed 's/^/group,/' ; \
	  $(foreach g,$(GROUPS),tail -n +2 $(OUT)/triax-$(g).csv | sed 's/^/$(subst ip,I_P,$(subst ab,Ab_,$(g))),/' ;) ) > $@

# The summaries as a table: group, level, E50 (MPa), Poisson's ratio, angles (degrees).
summary_field = sed -nE 's/.*"$(2)":(-?[0-9.eE+-]+).*/\1/p' $(1)
$(OUT)/triax-summary.csv: $(foreach g,$(GROUPS),$(OUT)/triax-$(g).jsonl)
	( echo "group,level,e50_mpa,poisson,friction_angle,dilatancy_angle,peak_q_kpa,peak_strain,final_volumetric_strain" ; \
	  $(foreach g,$(GROUPS),echo "$(subst ip,I_P,$(subst ab,Ab_,$(g))),$(LEVEL_$(g)),$$(awk "BEGIN{print $$($(call summary_field,$(OUT)/triax-$(g).json,e50))/1e6}"),$$($(call summary_field,$(OUT)/triax-$(g).json,poisson_ratio)),$$($(call summary_field,$(OUT)/triax-$(g).json,friction_angle)),$$($(call summary_field,$(OUT)/triax-$(g).json,dilatancy_angle)),$$(awk "BEGIN{print $$($(call summary_field,$(OUT)/triax-$(g).json,peak_q))/1e3}"),$$($(call summary_field,$(OUT)/triax-$(g).json,peak_strain)),$$($(call summary_field,$(OUT)/triax-$(g).json,final_volumetric_strain))" ;) ) > $@

fig9: $(OUT)/triax-all.csv
	cp $< $(OUT)/fig9.csv
	plot --x axial_strain --y q_boundary --series group --xlabel "axial strain ln(H0/H)" \
	  --ylabel "deviatoric stress q = s1 - s3 (Pa)" \
	  --title "Fig. 9: deviatoric stress against axial strain, 100 kPa" < $< > $(OUT)/fig9.png

fig10: $(OUT)/triax-all.csv
	cp $< $(OUT)/fig10.csv
	plot --x axial_strain --y volumetric_strain --series group --xlabel "axial strain ln(H0/H)" \
	  --ylabel "volumetric strain ln(V0/V) (compression +)" \
	  --title "Fig. 10: volumetric strain against axial strain" < $< > $(OUT)/fig10.png

fig11: $(OUT)/triax-summary.csv
	cp $< $(OUT)/fig11.csv
	plot --x level --y e50_mpa,poisson --xlabel "abrasion level (0: I_P)" \
	  --ylabel "secant modulus E50 (MPa)" --ylabel "Poisson's ratio (initial)" --size 1200x500 \
	  --title "Fig. 11: E50 and Poisson's ratio against abrasion" < $< > $(OUT)/fig11.png

fig12: $(OUT)/triax-summary.csv
	cp $< $(OUT)/fig12.csv
	plot --x level --y friction_angle,dilatancy_angle --xlabel "abrasion level (0: I_P)" \
	  --ylabel "peak friction angle (deg)" --ylabel "dilatancy angle (deg)" --size 1200x500 \
	  --title "Fig. 12: peak friction and dilatancy angles against abrasion" < $< > $(OUT)/fig12.png

figtriax: $(foreach g,$(GROUPS),$(OUT)/triax-$(g).jsonl)
	cat $(foreach g,$(GROUPS),$(OUT)/triax-$(g).obj) | render --cols 4 --same-scale --size 1200x620 \
	  --no-edges --title "The specimens at the end of the test, coloured by rotation (blue none, red most)" \
	  > $(OUT)/figtriax.png
