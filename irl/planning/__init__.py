"""The planning driver whose reward is learned: a receding-horizon soft value over a small
action tree, the first action chosen on a fine acceleration grid, scored on the five paper
actions.

  - :mod:`irl.planning.decisions`: :class:`~irl.planning.decisions.PlanningDecisions` from encounter tables and
    car-following pair arrays;
  - :mod:`irl.planning.features`: the named reward features of a predicted step and their shape fit;
  - :mod:`irl.planning.model`: :class:`~irl.planning.model.PlannerConfig`, the fine grid and the path tensors
    (kinematics of every path of the tree);
  - :mod:`irl.planning.policy`: the backups, the log policy over fine actions and paper bins, the exact
    gradient;
  - :mod:`irl.planning.fit`: maximum-likelihood fit and held-out selection by group;
  - :mod:`irl.planning.driver`: :class:`~irl.planning.driver.PlanningDriver`, its file and :func:`~irl.planning.driver.learn_planning_driver`;
  - :mod:`irl.planning.replay`: held-out replay of real car-following pairs.

Pure numpy / scipy / pandas; nothing of ours outside ``irl`` and ``merge_irl``.
"""
