"""The planning driver whose reward is learned: a receding-horizon soft value over a small
action tree, the first action chosen on a fine acceleration grid, scored on the five paper
actions.

  - :mod:`irl.domains.merge.planning.decisions`: :class:`~irl.domains.merge.planning.decisions.PlanningDecisions` from encounter tables and
    car-following pair arrays;
  - :mod:`irl.domains.merge.planning.features`: the named reward features of a predicted step and their shape fit;
  - :mod:`irl.domains.merge.planning.model`: :class:`~irl.domains.merge.planning.model.PlannerConfig`, the fine grid and the path tensors
    (kinematics of every path of the tree);
  - :mod:`irl.domains.merge.planning.policy`: the backups, the log policy over fine actions and paper bins, the exact
    gradient;
  - :mod:`irl.domains.merge.planning.fit`: maximum-likelihood fit and held-out selection by group;
  - :mod:`irl.domains.merge.planning.driver`: :class:`~irl.domains.merge.planning.driver.PlanningDriver`, its file and :func:`~irl.domains.merge.planning.driver.learn_planning_driver`;
  - :mod:`irl.domains.merge.planning.replay`: held-out replay of real car-following pairs.

Pure numpy / scipy / pandas; nothing of ours outside ``irl`` and ``merge_irl``.
"""
