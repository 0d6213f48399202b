# Throughput benchmarks: kernels in process (criterion; one thread), the time step against
# energy error (benches/timestep.rs, ~2 min), and the tools through the pipe
# (pipelines/bench.sh), side by side in one run; the DEM rows between two readings of what the
# machine gives this hour (benches/machine.rs: clock and load latency, 8 s), with the price of
# facet walls against planes on the 2000 I_P bed (benches/walls.rs); the triaxial test at the
# paper's scale on the I_P and Ab_3 specimens of seed 1 when they exist (pipelines/bench-triax.sh:
# a loading step against an engine step); fabric against the state
# reader on a triax stream (pipelines/bench-fabric.sh). Results: docs/performance.md.
bench: build
	cargo bench --locked -p granular-shared --bench geometry -- --noplot 2>&1 \
	  | awk '/^geometry\// {name=$$0} /thrpt:/ && name {print name " " $$0; name=""}'
	cargo bench --locked -p granular-shared --bench contacts -- --noplot 2>&1 \
	  | awk '/^contacts\// {name=$$0} /thrpt:/ && name {print name " " $$0; name=""}'
	cargo bench --locked -p granular-shared --bench timestep
	pipelines/bench.sh
	cargo bench --locked -p granular-shared --bench machine
	for g in ip ab3; do pipelines/bench-triax.sh out/paper/$$g-1.spec.jsonl; done
	pipelines/bench-fabric.sh
	pipelines/bench-dem.sh
	if [ -f out/bench/nine2000.jsonl ]; then \
	  cargo bench --locked -p granular-shared --bench walls -- out/bench/nine2000.jsonl; fi
	cargo bench --locked -p granular-shared --bench machine
