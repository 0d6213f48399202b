# The smoke scale (`make smoke`, or SCALE=smoke on any target): every recipe of `make figures`,
# `make paper`, `make study` and `make convergence` with the same tools, flags and pipes, only
# smaller, into out/smoke: 20 polyhedra a face count for fig7, specimens of a few dozen particles (30-40 mm in
# a 120 x 240 mm cylinder), triaxial tests stopped at 0.5 % of axial strain; at the paper's
# scale two groups and one seed (the calibration sample the specimen's size).
# What it shows is that each line runs and writes its outputs, not the paper's numbers.

OUT := $(SMOKE_OUT)
STATS_COUNT := 20
SPECIMEN := --diameter 0.12 --height 0.24 --size-min 0.03 --size-max 0.04
TRIAX := --rate 1 --final-strain 0.005
STUDY_SEEDS := 1 2
PAPER_GROUPS := ip ab1
PAPER_SEEDS := 1
PAPER_SPECIMEN := --diameter 0.12 --height 0.24 --size-min 0.03 --size-max 0.04 --calibration-scale 1
PAPER_TRIAX := --boundary rigid --rate 0.5 --final-strain 0.005
CONV_RATES := 2 1
CONV_TRIAX := --boundary rigid --final-strain 0.005
