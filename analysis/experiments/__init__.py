"""Learning and the paper's experiments: fitting IRL methods, DAgger, trials, leave-one-out and the paper's tables."""
