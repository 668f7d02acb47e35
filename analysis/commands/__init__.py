"""One module per ``merge-irl`` subcommand; each defines ``register(subparsers)``."""
