"""Speed benchmarks, each runnable as ``python -m benchmarks.<name>`` from the checkout root: a
code path timed against a baseline in one run, figures and ratios printed side by side (speed
targets are checked here, never in timed unit tests). Target checks and diagnostics of what a
model does are in ``studies``."""
