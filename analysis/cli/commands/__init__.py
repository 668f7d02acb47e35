"""One module per ``merge-irl`` subcommand; each defines ``register(subparsers)`` (``_arg_types``,
not a command: the argparse types they share).

A command module imports the API it calls inside its functions, not at module top: every
``merge-irl`` call (``--help`` too) imports all command modules to build the parser, and the API
modules load pandas, scipy.optimize, rerun and the SUMO tools. Measured on the 2-core machine
(Nov 2026): ``merge-irl --help`` 1.2-2.6 s this way, 3.5-5.0 s with the API imported up front.
"""
