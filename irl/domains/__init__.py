"""The IRL domains as pure definitions (no SUMO, nothing of ours outside ``irl``).

* :mod:`irl.domains.gridworld`: the paper's 5x5 gridworld (section 4.1).
* :mod:`irl.domains.merge`: the freeway merge (section 4.2).

What a domain's problems are loaded with and what the methods get from them is the domain's
:class:`irl.problems.Domain` (:data:`irl.problems.DOMAINS`).
"""
