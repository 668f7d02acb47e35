"""The IRL domains as pure definitions (no SUMO, nothing of ours outside ``irl``).

* :mod:`irl.domains.gridworld`: the paper's 5x5 gridworld (section 4.1).
* :mod:`irl.domains.merge`: the freeway merge (section 4.2): action bins, state bins and
  encoding, the encounter schema, the no-lead-car rule and the paper's three features.
"""
