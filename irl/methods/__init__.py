"""The IRL methods (Q-Avg, Q-SM, MLIRL, REIRL) and the conditional logit, with the solvers they share."""
