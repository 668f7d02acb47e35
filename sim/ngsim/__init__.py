"""NGSIM trajectory files: read, validate, smooth, assemble and write the NGSIM-schema trajectory table."""
