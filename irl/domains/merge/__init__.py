"""The freeway merge (paper section 4.2) as pure definitions, one module per concept:

  - :mod:`irl.domains.merge.actions`: the action bins (A's acceleration) and the action at a frame;
  - :mod:`irl.domains.merge.states`: the state variables, the state index and the state encodings;
  - :mod:`irl.domains.merge.bins`: the state bins (:class:`~irl.domains.merge.bins.MergeBins`),
    the encoder of continuous variables into states, the no-lead-car rule and the quantile fit;
  - :mod:`irl.domains.merge.encounters`: the encounter table schema and its check;
  - :mod:`irl.domains.merge.features`: the paper's three features and the named feature sets;
  - :mod:`irl.domains.merge.mdp`: encounters to tabular demonstrations, transitions, the
    kinematic successors;
  - :mod:`irl.domains.merge.car_following`, :mod:`irl.domains.merge.cf_logit`: the continuous
    observation, its car-following features and the car-following logit driver.

Everything that says what a merge state, action or encounter row *is* lives in these modules,
and nowhere else: the simulator (``sim``: encounter extraction, closed-loop controller) and the
learner (``irl.domains.merge.mdp``: transitions, tabular demonstrations) both import them, so the
closed loop encodes states exactly as learning does. Pure definitions: numpy, pandas, no SUMO,
nothing of ours outside ``irl``.

Roles: car B merges from the ramp (lane 7) into the rightmost main lane (lane 6); A is the lag
car behind B in lane 6 (the driver modelled), C the lead car ahead of B in lane 6. Units are
NGSIM's: feet, ft/s, ft/s^2, frames of 0.1 s (:mod:`merge_irl.units`).
"""
