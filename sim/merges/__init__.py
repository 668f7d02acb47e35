"""Merges as demonstrations: encounters and their rules, the take-over rule, demonstrators, generate, SUMO's expert labels, transitions out."""
