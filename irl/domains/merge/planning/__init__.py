"""The planning driver whose reward is learned: a receding-horizon soft value over a small
action tree, the first action chosen on a fine acceleration grid, scored on the five paper
actions.

  - :mod:`.decisions`: :class:`~.decisions.PlanningDecisions` from encounter tables and
    car-following pair arrays;
  - :mod:`.features`: the named reward features of a predicted step and their shape fit;
  - :mod:`.model`: :class:`~.model.PlannerConfig`, the fine grid and the path tensors
    (kinematics of every path of the tree);
  - :mod:`.policy`: the backups, the log policy over fine actions and paper bins, the exact
    gradient;
  - :mod:`.fit`: maximum-likelihood fit and held-out selection by group;
  - :mod:`.driver`: :class:`~.driver.PlanningDriver`, its file and :func:`~.driver.learn_planning_driver`;
  - :mod:`.replay`: held-out replay of real car-following pairs.

Pure numpy / scipy / pandas; nothing of ours outside ``irl`` and ``merge_irl``.
"""
