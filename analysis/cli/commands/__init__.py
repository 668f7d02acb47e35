"""One module per ``merge-irl`` subcommand; each defines ``register(subparsers)`` (``_arg_types``,
not a command: the argparse types they share).

:data:`COMMANDS` names them with their one-line help, so that ``merge-irl --help`` lists every
command without importing any: a command's module (and the API it imports at its top: pandas,
scipy.optimize, rerun, the SUMO tools) is imported only when that command is chosen
(``analysis.cli.main``). Adding a command adds its module here.
"""

from __future__ import annotations

#: command -> its line in ``merge-irl --help``; the module is ``analysis.cli.commands.<command
#: with - as _>``.
COMMANDS: dict[str, str] = {
    "calibrate": "fit / evaluate / check car-following parameters on real NGSIM pairs",
    "check-metrics": "check an evaluation's metrics.json against thresholds (CI gate)",
    "dagger": "train a car-following logit driver with SUMO as the expert in its own states",
    "demo": "the whole pipeline on the default scenario (generate, learn, evaluate, log)",
    "encounters": "extract merge encounters (B merging, lag A, lead C) from a trajectory file",
    "evaluate": "drive merge lag cars with learned models in SUMO and compare with baselines",
    "export-transitions": "export demonstrations as transition arrays (obs, acts, next_obs, dones) in .npz",
    "generate": "simulate a scenario in SUMO and write NGSIM-schema trajectories + merge encounters",
    "learn": "fit reward weights (Q-Avg, Q-SM, MLIRL or REIRL) and save model.json",
    "learn-driver": "learn a planning driver (reward over continuous merge features) from demonstrations",
    "reproduce": "reproduce the paper's Table 1, 2 or 3 (all four methods, N trials)",
    "score": "log-likelihood of demonstrations under a saved model.json",
    "view": "open a run's rerun recordings (.rrd) in the rerun viewer",
}


def module_name(command: str) -> str:
    """The module of ``command``, e.g. ``analysis.cli.commands.learn_driver``."""
    return f"{__name__}.{command.replace('-', '_')}"
