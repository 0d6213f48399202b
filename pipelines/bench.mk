# Throughput benchmarks: kernels in process (criterion) and the tools through the pipe.
bench: build
	cargo bench --locked -p granular-shared --bench geometry -- --noplot 2>&1 | grep -E 'geometry/|thrpt'
	pipelines/bench.sh
