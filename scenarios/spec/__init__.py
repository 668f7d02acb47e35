"""The scenario spec: the frozen dataclasses, their fields and the TOML parser."""
