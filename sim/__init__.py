"""SUMO runs through libsumo, the NGSIM-schema trajectory table, and merge encounters."""
