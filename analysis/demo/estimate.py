"""How long ``merge-irl demo`` will take on this machine, said before it starts (one line).

The demo's work is almost all SUMO runs (data runs, DAgger's labelling runs, evaluation
episodes), so its CPU time is modelled as a cost per simulated second, which grows with the
load average (CPU time runs longer on a busy machine), fitted to three measured demos
(:data:`MEASURED`). The wall time is that CPU time divided by the share
of the cores the demo's worker processes get next to the other runnable jobs (the 1-minute load
average), so a busy machine gets a longer, and said, estimate.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

from analysis.demo.config import DemoConfig
from analysis.experiments.dagger import DaggerConfig, labelling_duration_s
from scenarios.spec.model import ScenarioSpec

#: The measurements the constants come from: (what, simulated seconds, CPU seconds user + system of
#: every process, wall seconds, 1-minute load average), on the 2-core development machine,
#: 2026-12-03 (``--with-dagger`` was then the default), fresh network cache (``MERGE_IRL_CACHE`` an
#: empty folder), other people's jobs running.
MEASURED = (
    ("merge-irl demo --with-dagger", 20880.0, 165.5, 331.5, 11.4),  # the load rose from 0.5 to 11.4 during the run
    ("merge-irl demo", 5400.0, 41.5, 201.5, 11.4),  # the default demo (no DAgger); load about 11 throughout
    ("merge-irl demo --with-dagger", 20880.0, 104.2, 99.9, 2.9),  # 2.5 at the start, 3.3 at the end
)
#: CPU seconds of the demo's fixed part (imports, worker start-up, IRL and planner fits): the
#: measurements put it at about 0, so the simulated seconds carry it all.
FIXED_CPU_S = 0.0
#: CPU seconds per simulated second of a SUMO run with the closed loop, at load average 0, and
#: its growth per unit of load average: CPU time itself grows on a busy machine (0.0050 at load
#: about 3, 0.0077-0.0079 at about 11 in :data:`MEASURED`). At load 0 the line is an extrapolation.
CPU_PER_SIM_S = 0.0040
CPU_PER_SIM_S_PER_LOAD = 0.00035


@dataclass(frozen=True)
class DemoEstimate:
    """``cpu_s``: expected CPU seconds; ``wall_s``: expected wall seconds here; ``cores``,
    ``load``: what the wall time assumed."""

    cpu_s: float
    wall_s: float
    cores: int
    load: float

    def line(self) -> str:
        """One line for the user: 0.75 to 2 times the estimate. The load average of the moment
        says nothing of the load to come: the demo during which the load rose from 0.5 to 11
        took 331 s (:data:`MEASURED`), three times what its starting load predicts."""
        lo, hi = 0.75 * self.wall_s, 2.0 * self.wall_s

        def fmt(s: float) -> str:
            return f"{s:.0f} s" if s < 100 else f"{s / 60:.0f} min" if s >= 600 else f"{s / 60:.1f} min"

        busy = f", load average now {self.load:.1f}: other jobs share the cores" if self.load >= 0.5 else ", cores idle"
        return (f"merge-irl demo: expect about {fmt(lo)} to {fmt(hi)} here ({self.cores} core"
                f"{'s' * (self.cores != 1)}{busy}; about {self.cpu_s:.0f} s of CPU time)")


def simulated_seconds(config: DemoConfig, spec: ScenarioSpec) -> float:
    """Simulated seconds of every SUMO run of ``config`` on scenario ``spec``: the data runs,
    DAgger's labelling runs (:func:`analysis.experiments.dagger.labelling_duration_s`), the logged
    episode and the evaluation episodes of every policy."""
    own = spec.simulation.duration_s
    data = (len(config.train_seeds) + config.heldout_runs) * (config.data_duration_s or own)
    dag = DaggerConfig()
    dagger = config.dagger_rounds * dag.episodes_per_round * labelling_duration_s(spec, dag) if config.dagger_rounds else 0.0
    eval_s = config.eval_duration_s or own
    n_policies = len(config.methods) + 5 + (2 if config.dagger_rounds else 0) + 1  # baselines, cf drivers, planner
    return data + dagger + eval_s * (1 + n_policies * config.eval_episodes)


def estimate(config: DemoConfig, spec: ScenarioSpec, *, cores: int | None = None, load: float | None = None) -> DemoEstimate:
    """The expected CPU and wall seconds of ``run_demo(config)`` on scenario ``spec`` here.

    Args:
        cores: CPU cores (default ``os.cpu_count()``).
        load: runnable jobs of others (default the 1-minute load average, 0 where the platform has none).
    """
    cores = max(1, int(cores if cores is not None else (os.cpu_count() or 1)))
    if load is None:
        try:
            load = os.getloadavg()[0]
        except OSError:  # not available on this platform
            load = 0.0
    load = max(0.0, float(load))
    rate = CPU_PER_SIM_S + CPU_PER_SIM_S_PER_LOAD * load
    cpu = FIXED_CPU_S + rate * simulated_seconds(config, spec)
    w = max(1, int(config.workers))
    share = min(w, cores, cores * w / (load + w))  # cores the demo's processes get beside the others
    return DemoEstimate(cpu_s=cpu, wall_s=cpu / max(share, 1e-3) if math.isfinite(cpu) else math.inf,
                        cores=cores, load=load)
