"""Bellman operators of the tabular methods, their fixed points and their stability."""
