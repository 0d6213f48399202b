# Figures 1, 2, 4, 5, 6, 7 of the paper: shapes, abrasion and roundness.
# Each figN writes $(OUT)/figN.csv (its data) and $(OUT)/figN.png.

TEMPLATE_SEED := 7
STATS_SEED := 11
STATS_COUNT ?= 1000

# The binaries are built first but do not make the data out of date: a second `make` runs only
# what is missing (`make clean` starts over).
$(OUT)/templates.obj: | $(BINS) $(OUT)
	polygen --faces 6..14 --seed $(TEMPLATE_SEED) > $@

fig1: | $(BINS) $(OUT)
	polygen --faces 8 --seed 19 | roundness > $(OUT)/fig1.csv
	polygen --faces 8 --seed 19 --construction \
	  | render --same-scale --size 1200x600 --title "Fig. 1: tangent planes of a sphere and the polyhedron they bound" > $(OUT)/fig1.png

fig2: $(OUT)/templates.obj
	roundness < $< > $(OUT)/fig2.csv
	render --cols 5 --size 1500x700 --title "Fig. 2: the nine templates, 6 to 14 faces (seed $(TEMPLATE_SEED))" < $< > $(OUT)/fig2.png

fig4: | $(BINS) $(OUT)
	abrade --levels 0..3 < pipelines/cube.obj | roundness > $(OUT)/fig4.csv
	abrade --levels 0..3 < pipelines/cube.obj \
	  | render --cols 4 --same-scale --size 1600x500 --title "Fig. 4: a cube after 0, 1, 2, 3 abrasions (Catmull-Clark)" > $(OUT)/fig4.png

fig5: $(OUT)/templates.obj
	abrade --levels 1..3 < $< | roundness > $(OUT)/fig5.csv
	abrade --levels 1..3 < $< | render --cols 9 --size 1400x600 --azimuth 35 \
	  --title "Fig. 5: the templates after 1, 2, 3 abrasions (rows: Ab_1, Ab_2, Ab_3)" > $(OUT)/fig5.png

fig6: $(OUT)/templates.obj
	abrade --levels 0..3 < $< | roundness > $(OUT)/fig6.csv
	plot --x k --y s3d --series level --xlabel "faces of the template" --ylabel "roundness S3D" \
	  --title "Fig. 6: S3D of the nine templates, per abrasion level" < $(OUT)/fig6.csv > $(OUT)/fig6.png

# fig7: S3D statistics over $(STATS_COUNT) random polyhedra per face count and level, with the
# default elongation cap and without one (cap=inf): the data shows what the cap changes.
fig7: | $(BINS) $(OUT)
	( polygen --faces 6..14 --count $(STATS_COUNT) --seed $(STATS_SEED) | abrade --levels 0..3 | roundness \
	    | awk 'NR==1{print $$0",cap";next}{print $$0",5"}' ; \
	  polygen --faces 6..14 --count $(STATS_COUNT) --seed $(STATS_SEED) --max-elongation inf | abrade --levels 0..3 | roundness \
	    | awk 'NR>1{print $$0",inf"}' ) > $(OUT)/fig7_all.csv
	plot --x k --y s3d --series level,cap --stats --band std --stats-out $(OUT)/fig7.csv \
	  --xlabel "faces" --ylabel "roundness S3D (mean, band: +-1 std)" \
	  --title "Fig. 7: S3D of $(STATS_COUNT) random polyhedra per face count (solid: cap 5 R, dashed: no cap)" \
	  < $(OUT)/fig7_all.csv > $(OUT)/fig7.png
