"""rerun recordings: the blueprint, the per-step logger, the `.rrd` files and reading them back."""
