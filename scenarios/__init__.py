"""On-ramp merge scenarios: frozen specs loaded from TOML, presets, and SUMO networks."""
