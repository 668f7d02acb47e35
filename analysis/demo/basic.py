"""The basic demo: generate the default scenario, extract merge encounters, summarise them."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from scenarios.loader import DEFAULT_SCENARIO, load_scenario
from sim.merges.generate import GenerateResult, generate


@dataclass(frozen=True)
class BasicDemoSummary:
    """Counts and mean speeds of one generated run (speeds in ft/s, by I-80 lane number)."""

    scenario: str
    seed: int
    out_dir: Path
    n_vehicles: int
    n_frames: int
    n_merges: int
    n_merges_with_lag: int
    n_encounter_frames: int
    mean_speed_by_lane: tuple[tuple[int, float], ...]
    wall_time_s: float

    def format(self) -> str:
        lines = [
            f"scenario {self.scenario} (seed {self.seed}) -> {self.out_dir}",
            f"  vehicles: {self.n_vehicles}   frames: {self.n_frames}   wall time: {self.wall_time_s:.1f} s",
            f"  merges (lane 7 -> 6): {self.n_merges}, with a lag car A: {self.n_merges_with_lag}, "
            f"encounter frames: {self.n_encounter_frames}",
            "  mean speed per lane (ft/s):",
        ]
        lines += [f"    lane {lane}: {v:6.1f}  ({v * 0.681818:5.1f} mph)" for lane, v in self.mean_speed_by_lane]
        return "\n".join(lines)


def summarize(gen: GenerateResult) -> BasicDemoSummary:
    t = gen.simulation.table
    speeds = t.groupby("Lane_ID")["v_Vel"].mean()
    return BasicDemoSummary(
        scenario=gen.simulation.spec.name, seed=gen.simulation.seed, out_dir=gen.out_dir,
        n_vehicles=int(t["Vehicle_ID"].nunique()), n_frames=int(t["Frame_ID"].nunique()),
        n_merges=len(gen.encounters.merges),
        n_merges_with_lag=int((gen.encounters.merges["A_id"] != 0).sum()),
        n_encounter_frames=len(gen.encounters.frames),
        mean_speed_by_lane=tuple((int(k), float(v)) for k, v in speeds.items()),
        wall_time_s=gen.simulation.wall_time_s,
    )


def run_basic_demo(
    out_dir: str | Path | None = None,
    *,
    scenario: str | Path = DEFAULT_SCENARIO,
    seed: int | None = None,
    duration_s: float | None = None,
    progress: bool = True,
) -> BasicDemoSummary:
    """Generate ``scenario`` into ``out_dir`` (default ``./runs/demo-<scenario>``) and summarise."""
    spec = load_scenario(scenario)
    out = Path(out_dir) if out_dir is not None else Path("runs") / f"demo-{spec.name}"
    gen = generate(spec, out, seed=seed, duration_s=duration_s, progress=progress)
    return summarize(gen)
