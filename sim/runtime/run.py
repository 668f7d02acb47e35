"""Run a scenario headless through libsumo and record the NGSIM-schema trajectory table.

``run_scenario`` is a short loop over a :class:`sim.runtime.session.SumoSession` (which owns the
libsumo loop and the recording) that feeds each recorded frame to the step hooks; the
DataFrame is built once at the end, with Preceding/Following/headways computed vectorised
(``sim.runtime.table``).

Coordinates: ``Local_Y`` = SUMO x (distance along the main road from the section start),
``Local_X`` = -SUMO y (lateral distance from the left road edge), ``Global_X/Global_Y`` = SUMO
x/y; all in feet, of the front bumper centre. Lanes: SUMO lane -> the code of the scenario's site
profile (:func:`sim.runtime.sites.site_of`) by the lane's lateral position (I-80, every preset: main
lanes 7 - n .. 6 from left to right, ramp and auxiliary lane 7).
Vehicle_ID: consecutive from 1 in insertion order, assigned when a vehicle first appears in
a recorded frame. Frame_ID = simulated time / 0.1 s; Global_Time = Frame_ID * 100 (ms since
the simulation started). Frames before ``warmup_s`` are not recorded and not passed to hooks.

``run_scenario`` always closes its SUMO (the session's context manager, also on Ctrl-C), so runs
can follow each other in one process; a run started while another session is open goes through
TraCI (:mod:`sim.runtime.session`), and hooks call SUMO through ``ctx.sumo``.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

from scenarios.spec.model import ScenarioSpec
from sim.errors import SimulationError
from sim.runtime.hooks import StepHook
from sim.runtime.lanes import aux_lane_start_ft
from sim.runtime.run_result import SimulationResult
from sim.runtime.session import SumoSession


def run_scenario(
    spec: ScenarioSpec,
    *,
    seed: int | None = None,
    duration_s: float | None = None,
    hooks: Sequence[StepHook] = (),
    progress: bool = False,
    work_dir: Path | None = None,
) -> SimulationResult:
    """Simulate ``spec`` and record every vehicle at every 0.1 s frame after the warm-up.

    ``seed`` / ``duration_s`` override the spec's. ``hooks`` are called at every recorded
    frame (see :mod:`sim.runtime.hooks`). ``progress`` shows the progress of simulated time on stderr (a bar on a terminal, lines elsewhere).

    Raises:
        SimulationError: SUMO fails to start or to step.
    """
    t0 = time.perf_counter()
    with SumoSession(spec, seed, duration_s=duration_s, work_dir=work_dir, progress=progress) as session:
        ctx = session.start()
        ls = ctx.sumo  # libsumo, or TraCI for a second run in this process
        started: list[StepHook] = []
        ok = False  # set once every step ran: hooks then commit their outputs
        try:
            for h in hooks:
                h.on_start(ctx)
                started.append(h)
            while (st := session.step()) is not None:
                for h in hooks:
                    h.on_step(ctx, st.frame)
            ok = True
        except (KeyboardInterrupt, SimulationError):
            raise
        except (ls.TraCIException, ls.FatalTraCIError) as e:  # a hook's SUMO call
            raise SimulationError(f"SUMO error in scenario {session.spec.name!r}: {e}") from e
        finally:
            for h in started:
                # an aborted run (error, Ctrl-C) must not publish outputs: on_abort if defined
                (getattr(h, "on_abort", h.on_end) if not ok else h.on_end)(ctx)
        table = session.table()
        aux_start = aux_lane_start_ft(ctx)
    spec = session.spec
    return SimulationResult(
        table=table, spec=spec, seed=spec.simulation.seed, wall_time_s=time.perf_counter() - t0,
        sumo_time_s=session.sumo_time_s, n_vehicle_steps=len(table), sumo_ids=session.sumo_ids,
        events=session.events(), aux_lane_start_ft=aux_start,
    )
