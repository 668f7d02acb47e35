"""Old import paths answer with their new home, in one line.

The packages were re-laid by concept: ``sim``'s flat modules went into ``sim/runtime``,
``sim/drivers``, ``sim/closed_loop`` and ``sim/merges`` on 2026-12-05, and the other packages'
prefix families into sub-packages on 2026-12-03 (a few pure moves came before). Scripts written
against a path the README or the docs once showed (``sim.ngsim_io``, ``irl.merge_mdp``,
``analysis.rrd_read``, ``sim.controller``, ...) would fail with a bare ``No module named``.
:data:`MOVED` maps every such path, and every other public module path of ours that existed
once and does not today, to its new home, and :class:`MovedModuleFinder`, appended to the
*end* of :data:`sys.meta_path` (so a real module always wins), turns an import of an old path into::

    ModuleNotFoundError: sim.controller moved to sim.closed_loop.controller (see "Moved import paths" in docs/changelog.md)

There is no alias: the old path never imports. Each package's ``__init__`` calls
:func:`install` (idempotent), so the finder is in place once the old path's top package is
imported, which Python always does first.

Four old paths are not here because the name exists again with another meaning: the modules
``analysis.cli``, ``irl.bellman``, ``scenarios.spec`` and ``irl.domains.merge`` are packages today
(their contents are in ``analysis.cli.main``, ``irl.bellman.operators``, ``scenarios.spec.model``
and the modules of ``irl.domains.merge``). Renamed attributes (``ControllerConfig.decision_s`` ->
``decision_step_s``, ...) have no alias either; docs/changelog.md lists them.

The finder and these entries go in version 0.3.0 (docs/changelog.md, "Moved import paths").

Data and the standard library only: this module imports nothing of ours.
"""

from __future__ import annotations

import importlib.abc
import sys
from collections.abc import Sequence
from importlib.machinery import ModuleSpec
from types import ModuleType

#: Old packages whose modules moved with them (``old.X`` -> ``new.X``).
MOVED_PACKAGES: dict[str, str] = {
    "analysis.benchmarks": "benchmarks",
    "analysis.commands": "analysis.cli.commands",
    "analysis.scripts": "tools",
    "irl.domains.merge.planning": "irl.planning",
    "scenarios.calibration": "analysis.calibration",
}

#: New homes that are folders of the source checkout, not installed with the package.
CHECKOUT_ONLY = ("benchmarks", "studies", "tools")

#: Old module path -> where its names live today.
MOVED: dict[str, str] = {
    # 2026-12-07: the callable drivers one sub-package
    "sim.drivers.callable_actions": "sim.drivers.callables.actions",
    "sim.drivers.callable_limits": "sim.drivers.callables.limits",
    "sim.drivers.callable_specs": "sim.drivers.callables.specs",
    # 2026-12-05: sim/ by concept (ca94975)
    "sim.actuation": "sim.closed_loop.actuation",
    "sim.callable_policy": "sim.drivers.callables",
    "sim.control_records": "sim.closed_loop.records",
    "sim.controller": "sim.closed_loop.controller",
    "sim.controller_config": "sim.closed_loop.config",
    "sim.demonstrators": "sim.merges.demonstrators",
    "sim.encounter_rules": "sim.merges.rules",
    "sim.encounters": "sim.merges.encounters",
    "sim.expert_labels": "sim.merges.expert_labels",
    "sim.generate": "sim.merges.generate",
    "sim.hooks": "sim.runtime.hooks",
    "sim.idm_policy": "sim.drivers.idm",
    "sim.lanes": "sim.runtime.lanes",
    "sim.learned_policies": "sim.drivers.learned",
    "sim.observe": "sim.drivers.observe",
    "sim.outputs": "sim.runtime.outputs",
    "sim.planning_policy": "sim.drivers.planning",
    "sim.policy": "sim.drivers.policy",
    "sim.recorder": "sim.runtime.recorder",
    "sim.run": "sim.runtime.run",
    "sim.run_result": "sim.runtime.run_result",
    "sim.schema": "sim.runtime.schema",
    "sim.session": "sim.runtime.session",
    "sim.sites": "sim.runtime.sites",
    "sim.sumo_inputs": "sim.runtime.sumo_inputs",
    "sim.table": "sim.runtime.table",
    "sim.take_over": "sim.merges.take_over",
    "sim.transitions": "sim.merges.transitions",
    # 2026-12-03: the re-lay by concept (9019ac7); 2026-12-01 split of irl.domains.merge (b335606)
    "sim.demonstrations": "sim.merges.demonstrators",
    "sim.ngsim_assemble": "sim.ngsim.assemble",
    "sim.ngsim_format": "sim.ngsim.format",
    "sim.ngsim_io": "sim.ngsim.io",
    "sim.ngsim_parse": "sim.ngsim.parse",
    "sim.ngsim_read": "sim.ngsim.read",
    "sim.ngsim_recordings": "sim.ngsim.recordings",
    "sim.ngsim_smooth": "sim.ngsim.smooth",
    "sim.ngsim_validate": "sim.ngsim.validate",
    "sim.ngsim_write": "sim.ngsim.write",
    "irl.atomic": "merge_irl.atomic",
    "irl.bellman_fixed_point": "irl.bellman.fixed_point",
    "irl.bellman_stability": "irl.bellman.stability",
    "irl.boltzmann_fit": "irl.methods.boltzmann_fit",
    "irl.conditional_logit": "irl.methods.conditional_logit",
    "irl.damped_sweeps": "irl.methods.damped_sweeps",
    "irl.domains.merge_actions": "irl.domains.merge.actions",
    "irl.domains.merge_bins": "irl.domains.merge.bins",
    "irl.domains.merge_car_following": "irl.domains.merge.car_following",
    "irl.domains.merge_cf_logit": "irl.domains.merge.cf_logit",
    "irl.domains.merge_encounters": "irl.domains.merge.encounters",
    "irl.domains.merge_features": "irl.domains.merge.features",
    "irl.domains.merge_states": "irl.domains.merge.states",
    "irl.faithful": "irl.methods.faithful",
    "irl.fit_common": "irl.methods.common",
    "irl.merge_mdp": "irl.domains.merge.mdp",
    "irl.mlirl": "irl.methods.mlirl",
    "irl.qavg": "irl.methods.qavg",
    "irl.qsm": "irl.methods.qsm",
    "irl.reirl": "irl.methods.reirl",
    "irl.run_folder": "merge_irl.run_folder",
    "irl.spawn_guard": "merge_irl.spawn_guard",
    "irl.units": "merge_irl.units",
    "irl.unobserved": "irl.unobserved_successors",
    "irl.unvisited": "irl.unvisited_states",
    "scenarios.calibration": "analysis.calibration",
    "scenarios.calibration.class_fit": "analysis.calibration.class_fit",
    "scenarios.calibration.classes": "analysis.calibration.classes",
    "scenarios.calibration.evaluate": "analysis.calibration.evaluate",
    "scenarios.calibration.fit": "analysis.calibration.fit",
    "scenarios.calibration.models": "analysis.calibration.models",
    "scenarios.calibration.objective": "analysis.calibration.objective",
    "scenarios.calibration.pairs": "analysis.calibration.pairs",
    "scenarios.calibration.params_file": "analysis.calibration.params_file",
    "scenarios.calibration.result": "analysis.calibration.result",
    "scenarios.calibration.sumo_fit": "analysis.calibration.sumo_fit",
    "scenarios.calibration.sumo_replay": "analysis.calibration.sumo_replay",
    "scenarios.calibration.vtypes": "analysis.calibration.vtypes",
    "scenarios.spec_fields": "scenarios.spec.fields",
    "scenarios.spec_parse": "scenarios.spec.parse",
    "analysis.calibration_check": "analysis.calibration.check",
    "analysis.calibration_preset": "analysis.calibration.preset",
    "analysis.calibration_sweep": "analysis.calibration.sweep",
    "analysis.commands": "analysis.cli.commands",
    "analysis.commands.calibrate": "analysis.cli.commands.calibrate",
    "analysis.commands.check_metrics": "analysis.cli.commands.check_metrics",
    "analysis.commands.dagger": "analysis.cli.commands.dagger",
    "analysis.commands.demo": "analysis.cli.commands.demo",
    "analysis.commands.encounters": "analysis.cli.commands.encounters",
    "analysis.commands.evaluate": "analysis.cli.commands.evaluate",
    "analysis.commands.generate": "analysis.cli.commands.generate",
    "analysis.commands.learn": "analysis.cli.commands.learn",
    "analysis.commands.reproduce": "analysis.cli.commands.reproduce",
    "analysis.commands.score": "analysis.cli.commands.score",
    "analysis.commands.view": "analysis.cli.commands.view",
    "analysis.dagger": "analysis.experiments.dagger",
    "analysis.demo_basic": "analysis.demo.basic",
    "analysis.demo_config": "analysis.demo.config",
    "analysis.demo_signal": "studies.support.signal",
    "analysis.episode": "analysis.evaluation.episode",
    "analysis.evaluate": "analysis.evaluation.evaluate",
    "analysis.evaluate_heldout": "analysis.evaluation.heldout_scoring",
    "analysis.evaluate_policies": "analysis.evaluation.policies",
    "analysis.evaluate_report": "analysis.evaluation.report",
    "analysis.generate_sweep": "analysis.sweep.generate",
    "analysis.heldout": "analysis.experiments.leave_one_out",
    "analysis.learn": "analysis.experiments.learn",
    "analysis.metrics": "analysis.evaluation.metrics",
    "analysis.metrics_aggregate": "analysis.evaluation.aggregate",
    "analysis.metrics_demos": "analysis.evaluation.distances",
    "analysis.palette": "analysis.evaluation.palette",
    "analysis.pipeline": "analysis.demo.pipeline",
    "analysis.provenance": "merge_irl.provenance",
    "analysis.report_plots": "analysis.evaluation.plots",
    "analysis.reproduce": "analysis.experiments.reproduce",
    "analysis.reproduce_report": "analysis.experiments.reproduce_report",
    "analysis.rerun_blueprint": "analysis.recording.blueprint",
    "analysis.rerun_columns": "analysis.recording.columns",
    "analysis.rerun_log": "analysis.recording.log",
    "analysis.rerun_recording": "analysis.recording.files",
    "analysis.rrd_read": "analysis.recording.read",
    "analysis.thresholds": "analysis.evaluation.thresholds",
    "analysis.trials": "analysis.experiments.trials",
    "analysis.view": "analysis.recording.view",
    # 2026-11-30: pure moves (32749be, 757e03b)
    "irl.gridworld": "irl.domains.gridworld",
    "irl.boltzmann_backup": "irl.methods.boltzmann_fit",
    "irl.sweeps": "irl.methods.damped_sweeps",
    "analysis.problem": "irl.problems",
    "analysis.benchmarks": "benchmarks",
    "analysis.benchmarks.bare_sumo": "benchmarks.bare_sumo",
    "analysis.benchmarks.closed_loop_bench": "benchmarks.closed_loop_bench",
    "analysis.benchmarks.generate_bench": "benchmarks.generate_bench",
    "analysis.benchmarks.generate_sweep_bench": "benchmarks.generate_sweep_bench",
    "analysis.benchmarks.irl_bench": "benchmarks.irl_bench",
    "analysis.benchmarks.irl_exact_bench": "benchmarks.irl_exact_bench",
    "analysis.benchmarks.ngsim_bench": "benchmarks.ngsim_bench",
    "analysis.benchmarks.sweep_bench": "benchmarks.sweep_bench",
    "analysis.scripts": "tools",
    "analysis.scripts.derive_i80_geometry": "tools.derive_i80_geometry",
    # 2026-12-07: the planning learner out of irl.domains into a package named for it
    "irl.domains.merge.planning": "irl.planning",
    "irl.domains.merge.planning.decisions": "irl.planning.decisions",
    "irl.domains.merge.planning.driver": "irl.planning.driver",
    "irl.domains.merge.planning.features": "irl.planning.features",
    "irl.domains.merge.planning.fit": "irl.planning.fit",
    "irl.domains.merge.planning.model": "irl.planning.model",
    "irl.domains.merge.planning.policy": "irl.planning.policy",
    "irl.domains.merge.planning.replay": "irl.planning.replay",
    "irl.domains.merge.planning.replay_fit": "irl.planning.replay_fit",
    # 2026-12-07: study support out of the installed packages
    "analysis.demo.signal": "studies.support.signal",
    "analysis.evaluation.closed_loop_targets": "studies.support.closed_loop_targets",
    "analysis.experiments.gail_config": "studies.support.gail_config",
    "analysis.experiments.obs_scaler": "studies.support.obs_scaler",
}


def message(old: str) -> str:
    """The one line an import of ``old`` fails with."""
    new = MOVED[old]
    where = ", a folder of the source checkout (not installed)" if new.split(".")[0] in CHECKOUT_ONLY else ""
    with_it = ", its modules with it" if old in MOVED_PACKAGES else ""
    return f'{old} moved to {new}{where}{with_it} (see "Moved import paths" in docs/changelog.md)'


class MovedModuleFinder(importlib.abc.MetaPathFinder):
    """Last on :data:`sys.meta_path`: asked only for a name no real finder found; raises for the
    old paths of :data:`MOVED` and leaves every other name to the usual ``No module named``."""

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> ModuleSpec | None:
        if fullname in MOVED:
            raise ModuleNotFoundError(message(fullname), name=fullname)
        return None


def install() -> None:
    """Append the finder to the end of :data:`sys.meta_path`, once."""
    if not any(isinstance(f, MovedModuleFinder) for f in sys.meta_path):
        sys.meta_path.append(MovedModuleFinder())
