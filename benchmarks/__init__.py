"""Benchmark scripts, each runnable as ``python -m benchmarks.<name>``; they print
figures and side-by-side ratios (speed targets are checked here, never in timed unit tests)."""
