"""The demo's settings (:class:`DemoConfig`, ``merge-irl demo``'s options) and their seed checks.

:func:`analysis.demo.pipeline.run_demo` runs a :class:`DemoConfig`; the checks here run before any
simulation: data seeds that are evaluation seeds, training seeds that are held-out seeds, and
DAgger labelling seeds that are either (:func:`check_dagger_seeds`).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from analysis.errors import AnalysisError
from analysis.experiments.dagger import DaggerConfig
from irl.errors import ConfigError
from sim.merges.rules import ENCOUNTER_RULES, check_rule

#: The demo's name (and policy name) of the car-following logit driver trained with DAgger.
CF_DRIVER = "cf-dagger"
#: The name of the planning driver (learned from the demonstrations alone) in the demo's reports.
PLANNER_DRIVER = "planner"
#: DAgger rounds of ``cf-dagger`` with ``merge-irl demo --with-dagger`` (the demo trains none by default).
WITH_DAGGER_ROUNDS = DaggerConfig.rounds


@dataclass(frozen=True)
class DemoConfig:
    """Sizes of the demo (its time: :mod:`analysis.demo.estimate`, which the demo prints before it starts).

    Attributes:
        scenario: preset name or TOML path.
        train_seeds: SUMO seeds of the training runs.
        heldout_seed, heldout_runs: the held-out runs have seeds ``heldout_seed`` ..
            ``heldout_seed + heldout_runs - 1`` (:attr:`heldout_seeds`). One run (the default)
            keeps the demo short; the held-out demonstrations of one run are a noisy reference for
            the Wasserstein distances, since gaps vary more between runs than within one (10 runs:
            docs/changelog.md, "Ten held-out runs, and High Brake by need").
        data_duration_s: simulated seconds of each data run (None: the scenario's).
        eval_seed: first seed of the evaluation episodes; eval_episodes: episodes per policy.
        eval_duration_s: simulated seconds per evaluation episode.
        methods: IRL methods to learn (default Q-Avg alone: with the driver state encoding
            (6250 states) MLIRL's Boltzmann backups take minutes per fit (its transition model is
            sparse, memory is not the limit), and Q-SM's fixed-point iteration took 26-57 s of the
            demo; all are optional, ``methods=irl.fit.method_names()`` or ``merge-irl demo --methods ...``).
        features: merge feature set (None: as ``merge-irl learn`` on encounter tables,
            :func:`analysis.experiments.learn.merge_features`, the driver set with A's previous action in the
            state); the IRL settings are :func:`analysis.experiments.learn.merge_config`'s (beta 1).
        unvisited: rule for states never seen in training (:mod:`irl.unvisited_states`).
        gamma: discount of the IRL fits. Default 0, chosen by held-out log-likelihood on this
            data: with the driver features Q-Avg scores -0.68 per held-out step at gamma 0
            against -0.96 to -0.99 at gamma 0.3-0.99 (model-free Q-Avg gives never-observed
            (s, a) pairs their reward alone, so at gamma > 0 observed and unobserved pairs are
            on different scales; at gamma 0 every pair is R = theta . phi and the policy is a
            conditional logit on the driver features), and it drives with fewer collisions
            (3 vs 9 A collisions in 6 episodes). Measured with the terminal rule for unobserved
            pairs; at gamma 0 the rule changes nothing, and the kinematic backup that the merge
            defaults now use at gamma > 0 (``irl.problems.DOMAINS["merge"].defaults.unobserved``) has not been
            compared in the closed loop yet.
        l2: L2 penalty of the IRL fits. Default 1: the likelihood is bounded without it, but at
            l2 0 the fit trades a positive weight on the inverse TTC to C (a reward for closing
            in) against a negative one on the relative speed to C; l2 1 keeps the held-out
            log-likelihood (-0.678 vs -0.680 per step) and removes that trade.
        fit_seed: seed of the IRL fits.
        dagger_rounds: DAgger rounds of the car-following logit driver ``cf-dagger``
            (:mod:`analysis.experiments.dagger`, its other settings the defaults of
            :class:`~analysis.experiments.dagger.DaggerConfig`, so the driver equals ``merge-irl dagger``'s
            on the same encounters), trained after the IRL methods and evaluated beside them;
            0 (the default): not trained. ``merge-irl demo --with-dagger`` sets
            :data:`WITH_DAGGER_ROUNDS` (``DaggerConfig.rounds``, 4): ``cf-dagger`` is the learned
            driver that meets the closed-loop targets (no collision by its As in 30 episodes on two
            seed sets; docs/closed-loop.md), but its rounds need SUMO's labels in the states it
            reaches and took 23 s of a 45-49 s demo on 2 idle cores, so the default demo leaves it out.
        encounter_rule: how the data runs become demonstrations (:mod:`sim.merges.demonstrators`;
            default ``in-lane``: SUMO's drivers observed as the controller observes them, A's lane
            held while observed, so that they are what the commanded drivers can do).
        workers: processes (``process:<workers>``).
        executor: where the data runs and evaluation episodes run (``analysis.sweep``
            executors); None: ``process:<workers>``.
    """

    scenario: str = "synthetic"
    train_seeds: tuple[int, ...] = (101, 102, 103)
    heldout_seed: int = 201
    heldout_runs: int = 1
    data_duration_s: float | None = None
    eval_seed: int = 1
    eval_episodes: int = 3
    eval_duration_s: float | None = 180.0
    methods: tuple[str, ...] = ("qavg",)
    features: str | None = None
    unvisited: str = "none"
    gamma: float = 0.0
    l2: float = 1.0
    fit_seed: int = 0
    dagger_rounds: int = 0
    encounter_rule: str = ENCOUNTER_RULES[0]
    workers: int = 2
    executor: str | None = None

    def __post_init__(self) -> None:
        check_rule(self.encounter_rule)
        for name, lowest in (("heldout_runs", 1), ("heldout_seed", 0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < lowest:
                raise ConfigError(f"DemoConfig.{name} must be a whole number >= {lowest}, got {v!r}")
        d = self.eval_duration_s
        if d is not None and not (isinstance(d, numbers.Real) and math.isfinite(d) and d > 0):
            raise ConfigError(f"DemoConfig.eval_duration_s must be a positive number of seconds or None, got {d!r}")
        shared = sorted(set(self.train_seeds) & set(self.heldout_seeds))
        if shared:
            raise ConfigError(f"DemoConfig: seed(s) {shared} are both training and held-out seeds "
                              f"(held-out: {self.heldout_seed}..{self.heldout_seeds[-1]})")
        scored = sorted(s for s in {*self.train_seeds, *self.heldout_seeds} if s in self.eval_seeds)
        if scored:
            raise ConfigError(f"DemoConfig: seed(s) {scored} are data seeds and evaluation seeds (evaluation: "
                              f"{self.eval_seed}..{self.eval_seeds[-1]}): the drivers would be "
                              "scored on the traffic of their own demonstrations")

    @property
    def eval_seeds(self) -> range:
        """The SUMO seeds of the evaluation episodes."""
        return range(self.eval_seed, self.eval_seed + self.eval_episodes)

    @property
    def heldout_seeds(self) -> tuple[int, ...]:
        """The SUMO seeds of the held-out runs."""
        return tuple(range(int(self.heldout_seed), int(self.heldout_seed) + int(self.heldout_runs)))



def check_dagger_seeds(config: DemoConfig) -> None:
    """Check that the DAgger labelling runs of ``config`` (when ``dagger_rounds`` > 0) use none of
    its data or evaluation seeds.

    Raises:
        ConfigError: a negative ``dagger_rounds`` (:class:`~analysis.experiments.dagger.DaggerConfig`).
        AnalysisError: a labelling seed is a training, held-out or evaluation seed.
    """
    if not config.dagger_rounds:
        return
    labelling = DaggerConfig(rounds=config.dagger_rounds).label_seeds()  # ranges: no set of every seed
    ev = config.eval_seeds
    if (max(labelling.start, ev.start) < min(labelling.stop, ev.stop)
            or any(s in labelling for s in (*config.train_seeds, *config.heldout_seeds))):
        raise AnalysisError(f"demo: the DAgger labelling seeds {labelling.start}..{labelling.stop - 1} overlap the data "
                       "or evaluation seeds")
