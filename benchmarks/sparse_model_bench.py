"""Dense vs sparse transition models for the model-based methods (MLIRL, REIRL) on the authors'
NGSIM merge data: peak memory and wall time per fit, side by side. Prints a table; not a timed test.

    python -m benchmarks.sparse_model_bench /work/shared/data/railusm/merge_ngsim \
        [--gamma 0.99] [--driver-dense] [--no-driver-fits]

Each case runs in a fresh process (``spawn``), so its peak resident set size (``ru_maxrss``) is
its own; ``tracemalloc`` counts the numpy arrays Python allocates (SuperLU's own buffers are not
traced). A case builds the estimated model (relative counts, kinematic fallback) and fits once
on all 12 trajectories (beta 1, l2 0.01, seed 0).

* ``dense``: the model as the project built it before, ``[S, A, S]`` float64 arrays (counts,
  the kinematic fallback, the estimate: :func:`irl.dense_transitions.dense_estimate`), handed to
  the fit as an array (the fit converts it to the sparse successor model: the solvers were
  already sparse).
* ``sparse``: :func:`irl.domains.merge.mdp.estimated_transitions` as it is now, a ``[S*A, S]`` CSR model.

Paper encoding: 1250 states; driver encoding: 6250 (A's previous action in the state). The dense
driver model (1.56 GB per array) is only built with ``--driver-dense`` (construction alone: the
fit after it is the sparse one).
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import resource
import time
import tracemalloc
from dataclasses import replace

import numpy as np

from analysis.experiments.learn import fit_problem
from irl.config import IRLConfig
from irl.dense_transitions import dense_estimate
from irl.domains.merge.mdp import estimated_transitions, kinematic_next_state
from irl.problems import load_problem
from irl.transitions import TransitionModel, model_successors


def dense_kinematic(problem) -> np.ndarray:
    """The former dense kinematic model ``[S, 5, S]``."""
    S, A = problem.demos.n_states, problem.demos.n_actions
    s = np.repeat(np.arange(S), A)
    a = np.tile(np.arange(A), S)
    nxt = kinematic_next_state(s, a, problem.bins, problem.decision_step_s, encoding=problem.state_encoding)
    t = np.zeros((S, A, S))
    t[s, a, nxt] = 1.0
    return t


def run_case(data: str, encoding: str, model: str, method: str | None, gamma: float, out) -> None:
    """Child process: build the model (and fit), send ``(seconds model, seconds fit, traced peak MB,
    RSS before MB, RSS peak MB, loglik, flags)``."""
    features = "driver" if encoding == "driver" else "paper"
    problem = load_problem("merge", data, encoding=encoding, features=features)
    assert problem.bins is not None, "merge problems carry their bins"
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    tracemalloc.start()
    t0 = time.perf_counter()
    transitions: TransitionModel
    if model == "dense":
        transitions = dense_estimate(problem.demos, dense_kinematic(problem))
        model_successors(transitions)  # what a fit does with it first
    else:
        transitions = estimated_transitions(problem.demos, problem.bins, problem.decision_step_s)
    t1 = time.perf_counter()
    ll, flags = float("nan"), "-"
    if method is not None:
        config = IRLConfig.paper(beta=1.0, gamma=gamma, l2=0.01)
        fit = fit_problem(replace(problem, transitions=transitions), method, config, 0)
        ll, flags = fit.loglik, ",".join(fit.flags) or "ok"
    t2 = time.perf_counter()
    _, peak = tracemalloc.get_traced_memory()
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    out.send((t1 - t0, t2 - t1, peak / 2**20, rss0, rss, ll, flags))


def measure(data, encoding, model, method, gamma):
    ctx = mp.get_context("spawn")
    recv, send = ctx.Pipe(duplex=False)
    p = ctx.Process(target=run_case, args=(data, encoding, model, method, gamma, send))
    p.start()
    result = recv.recv()
    p.join()
    return result


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("data")
    p.add_argument("--gamma", type=float, default=0.99)
    p.add_argument("--driver-dense", action="store_true",
                   help="also build the dense driver model (about 6 GB at its peak)")
    p.add_argument("--repeat", type=int, default=2,
                   help="runs per case (fresh process each); the fastest is shown (the machine is shared)")
    p.add_argument("--no-driver-fits", action="store_true", help="skip the (minutes-long) driver MLIRL fit")
    args = p.parse_args(argv)
    cases: list[tuple[str, str, str | None]] = [("paper", m, meth) for meth in ("mlirl", "reirl") for m in ("dense", "sparse")]
    if args.driver_dense:
        cases.append(("driver", "dense", None))
    cases.append(("driver", "sparse", None))
    cases.append(("driver", "sparse", "reirl"))
    if not args.no_driver_fits:
        cases.append(("driver", "sparse", "mlirl"))
    rows = {}
    print(f"gamma {args.gamma}, beta 1, l2 0.01, one fit on all 12 trajectories per case, fastest of "
          f"{args.repeat} runs (driver MLIRL: 1)", flush=True)
    head = (f"{'encoding':8s} {'model':7s} {'fit':6s} {'model s':>8s} {'fit s':>8s} {'traced MB':>10s} "
            f"{'RSS+ MB':>9s} {'RSS MB':>8s} {'loglik':>10s}  flags")
    print(head, flush=True)
    for enc, model, meth in cases:
        n = 1 if (enc, meth) == ("driver", "mlirl") else max(1, args.repeat)
        r = min((measure(args.data, enc, model, meth, args.gamma) for _ in range(n)), key=lambda x: x[0] + x[1])
        rows[(enc, model, meth)] = r
        tm, tf, traced, rss0, rss, ll, flags = r
        print(f"{enc:8s} {model:7s} {meth or '-':6s} {tm:8.2f} {tf:8.2f} {traced:10.1f} {rss - rss0:9.1f} "
              f"{rss:8.1f} {ll:10.2f}  {flags}", flush=True)
    print("\nratios dense / sparse (same encoding, same fit): time = model + fit")
    pairs: list[tuple[str, str | None]] = [("paper", "mlirl"), ("paper", "reirl"), ("driver", None)]
    for enc, meth in pairs:
        d, s = rows.get((enc, "dense", meth)), rows.get((enc, "sparse", meth))
        if d is None or s is None:
            continue
        print(f"  {enc:6s} {meth or 'model only':10s} time {(d[0] + d[1]) / (s[0] + s[1]):7.2f}x   "
              f"traced memory {d[2] / max(s[2], 1e-3):8.1f}x   RSS growth {(d[4] - d[3]) / max(s[4] - s[3], 1.0):7.1f}x")
    S = 6250
    print(f"\none dense driver array [{S}, 5, {S}] float64: {S * 5 * S * 8 / 2**30:.2f} GiB; "
          f"the sparse driver model: see the traced MB of 'driver sparse -'")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
