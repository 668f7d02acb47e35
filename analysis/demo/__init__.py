"""`merge-irl demo`: the whole pipeline on the default scenario."""
