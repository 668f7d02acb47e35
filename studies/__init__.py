"""Studies, each runnable as ``python -m studies.<name>`` from the checkout root: target checks
and one-off diagnostics that measure what a model does (held-out likelihoods, closed-loop
targets, calibration bounds, comparisons of learners). Their figures are printed, never
asserted in tests; speed benchmarks (a code path timed against a baseline) are in ``benchmarks``."""
