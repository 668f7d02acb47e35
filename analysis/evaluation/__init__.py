"""The closed-loop evaluation: episodes, the policies under test, metrics, distances to the demonstrations, reports, plots and thresholds."""
