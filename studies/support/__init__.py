"""What the studies share and the tests check, kept out of the installed packages: the scorers
of the likelihood ceiling (:mod:`studies.support.ceiling`), the closed-loop target checks
(:mod:`studies.support.closed_loop_targets`), the action-bin change rate of a demonstrator
(:mod:`studies.support.signal`) and the torch-free parts of the imitation study
(:mod:`studies.support.gail_config`, :mod:`studies.support.obs_scaler`).

A folder of the source checkout, not installed (pyproject's ``packages.find`` lists the five
packages only); tests import it from the checkout root (pytest's ``pythonpath``). Nothing in
the packages imports it (``tests/test_import_graph.py``)."""
